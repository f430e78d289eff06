"""What a step checks of the model: the initial state, and an output of the wrong shape
named by the part that returned it."""

from __future__ import annotations

import logging
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from moreau.model.scene import Scene
from moreau.step.checks import check_initial_state

__all__ = ["NonFiniteState", "NotConverged", "BadModelOutput", "check_initial_state"]

log = logging.getLogger(__name__)


class NonFiniteState(FloatingPointError):
    """The state became NaN or infinite during a step (``step`` and ``t`` say where)."""

    def __init__(self, message: str, step: int, t: float) -> None:
        super().__init__(message)
        self.step = step
        self.t = t


class NotConverged(ArithmeticError):
    """An implicit step's iteration did not converge (``step`` and ``t`` say where)."""

    def __init__(self, message: str, step: int, t: float) -> None:
        super().__init__(message)
        self.step = step
        self.t = t


class BadModelOutput(ValueError):
    """A model function (mass matrix, force, gap, Jacobian) returned an array of another
    shape during a step; the message names it with the expected and the received shape
    (``step`` and ``t`` say where)."""

    def __init__(self, message: str, step: int, t: float) -> None:
        super().__init__(message)
        self.step = step
        self.t = t


_COMPOSITE = {"mass": "mass matrix", "force": "force of the scene", "gaps": "gaps of the scene",
              "jacobian": "Jacobian of the scene", "tangent": "tangent rows of the scene"}


def _locate_bad_shape(scene: Scene, kind: str, t, q, v, where: str) -> str | None:
    """The part of ``scene`` behind a composite of another shape: evaluate its parts of
    ``kind`` one by one and name the first whose shape is not the expected one (as
    :meth:`Scene.check_state` names them at the initial state); None when every part that
    evaluates has its shape (a part that raises is skipped: its own error stands)."""
    n = scene.ndof
    parts: list[tuple[str, Callable[[], Any], tuple[int, ...]]] = []
    if kind == "mass":
        parts.append(("mass matrix", partial(scene.system.mass_matrix, q), (n, n)))
    elif kind == "force":
        vv = np.zeros(n) if v is None else v
        if scene.system.has_bias:
            parts.append(("bias force", partial(scene.system.bias_force, q, vv), (n,)))
        for e in scene.effects:
            parts.append((f"force of effect {e.name!r}", partial(e.force, t, q, vv), (n,)))
    else:
        for c in scene.contacts:
            b = c.barrier
            if kind == "gaps":
                parts.append((f"gap of contact {c.name!r}", partial(b.gap, q), (b.nrows,)))
            elif kind == "tangent":
                if np.any(c.friction > 0.0):
                    parts.append((f"tangent rows of contact {c.name!r}", partial(b.tangent_jacobian, q),
                                  (b.nrows, n)))
            else:
                parts.append((f"Jacobian of contact {c.name!r}", partial(b.jacobian, q), (b.nrows, n)))
    for what, call, shape in parts:
        try:
            got = np.shape(call())
        except Exception:  # noqa: BLE001 - its own error is reported by the caller
            continue
        if got != shape:
            return f"{what}{where} has shape {got}, expected {shape}"
    return None
