"""Input checks shared by the public constructors and :func:`moreau.simulate`: each
refuses what is not documented and names the bad value and the argument.

A *number* is a real int or float (Python or numpy); bools, strings, None and complex
numbers are refused, not converted (``h=True`` is not a step of 1, ``"0.1"`` is not 0.1).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any, TypeVar

import numpy as np


def is_number(x) -> bool:
    """True for a real number that is not a bool (Python or numpy scalar, or 0-d array)."""
    if type(x) is float or type(x) is int:  # the common case, before the ABC's slower test
        return True
    if isinstance(x, np.ndarray) and x.ndim == 0:
        return x.dtype.kind in "iuf"
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _numeric_array(x, name: str) -> np.ndarray:
    """``x`` as a float array when every entry is a number, else ``ValueError``."""
    def bad() -> ValueError:  # the message's repr of x only when it is raised
        return ValueError(f"{name} must be an array of numbers, got {x!r}")

    if x is None or isinstance(x, (str, bytes, bool, np.bool_)):
        raise bad()
    try:
        # entry by entry: numpy would turn [1.0, True] into floats without a word
        raw = x if isinstance(x, np.ndarray) else np.array(x, dtype=object)
    except (TypeError, ValueError):
        raise bad() from None
    if raw.dtype.kind == "O":
        if not all(is_number(el) for el in raw.flat):
            raise bad()
    elif raw.dtype.kind not in "iuf":
        raise bad()
    try:
        return raw.astype(float)
    except (TypeError, ValueError, OverflowError):
        raise bad() from None


def as_vector(x, name: str, size: int | None = None) -> np.ndarray:
    """A finite float vector of the given size, or ``ValueError`` naming ``name``."""
    a = _numeric_array(x, name)
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {a.shape}")
    if size is not None and a.shape[0] != size:
        raise ValueError(f"{name} must have shape ({size},), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} has non-finite entries: {a.tolist()}")
    return a


def as_matrix(x, name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A finite, non-empty 2-D float array (a scalar becomes 1 x 1), or ``ValueError``."""
    a = _numeric_array(x, name)
    if a.ndim == 0:
        a = a.reshape(1, 1)
    if a.ndim != 2:
        raise ValueError(f"{name} must be two-dimensional, got shape {a.shape}")
    if a.size == 0:
        raise ValueError(f"{name} must not be empty, got shape {a.shape}")
    if shape is not None and a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} has non-finite entries: {a.tolist()}")
    return a


def as_positive(x, name: str, allow_zero: bool = False) -> float:
    """A finite positive float, or ``ValueError`` naming the value."""
    if not is_number(x):
        raise ValueError(f"{name} must be a number, got {x!r}")
    val = float(x)
    if not math.isfinite(val) or val < 0 or (val == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be finite and {kind}, got {val!r}")
    return val


# -- simulate()'s arguments -----------------------------------------------------------------
def as_time_span(t_span) -> tuple[float, float]:
    """``(t0, t1)`` as floats: a tuple, list or array of two finite numbers with t1 > t0."""
    two = isinstance(t_span, (Sequence, np.ndarray)) and not isinstance(t_span, (str, bytes)) and len(t_span) == 2
    if not two or not all(is_number(x) for x in t_span):
        raise ValueError(f"t_span must be two numbers (t0, t1), got {t_span!r}")
    t0, t1 = float(t_span[0]), float(t_span[1])
    if not (math.isfinite(t0) and math.isfinite(t1)):
        raise ValueError(f"t_span must be finite, got {t_span!r}")
    if t1 <= t0:
        raise ValueError(f"t_span must satisfy t1 > t0, got t_span = ({t0!r}, {t1!r})")
    return t0, t1


def as_record_every(k) -> int:
    """A positive int (bools refused)."""
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"record_every must be a positive integer, got {k!r}")
    return int(k)


_T = TypeVar("_T")


def checked_start(start: Callable[[], _T], scene: Any, t0: float, q0: Any, v0: Any) -> _T:
    """``start()`` (the validation of an initial state), with a user callable of the scene
    that raises at the initial state reported as a ``ValueError`` naming the part, the
    exception and t0 (instead of a bare ``ZeroDivisionError`` escaping). Nothing is
    evaluated twice when the start succeeds. Returns what ``start()`` returns.
    """
    try:
        return start()
    except (ValueError, ImportError):
        raise
    except Exception as exc:  # noqa: BLE001 - a user callable raised: find and name it
        _name_failing_part(scene, t0, q0, v0)
        raise ValueError(f"starting the integration at t0 = {t0!r} raised {type(exc).__name__}: {exc}") from exc


def _name_failing_part(scene, t0: float, q0, v0) -> None:
    """Evaluate each user part of ``scene`` once at the initial state; raise ``ValueError``
    naming the first that raises."""
    n = scene.ndof
    q = as_vector(q0, "q0", n)
    v = as_vector(v0, "v0", n)
    system = scene.system
    parts: list[tuple[str, Callable[[], Any]]] = [("mass matrix", lambda: system.mass_matrix(q))]
    if system.has_bias:
        parts.append(("bias force", lambda: system.bias_force(q, v)))
    for eff in scene.effects:
        parts.append((f"force of effect {eff.name!r}", partial(eff.force, t0, q, v)))
    for c in scene.contacts:
        parts.append((f"gap of contact {c.name!r}", partial(c.barrier.gap, q)))
        parts.append((f"Jacobian of contact {c.name!r}", partial(c.barrier.jacobian, q)))
    for what, call in parts:
        try:
            call()
        except Exception as exc:  # noqa: BLE001 - a user callable: reported with its name
            raise ValueError(f"{what} raised {type(exc).__name__} at the initial state "
                             f"(t0 = {t0!r}, q0 = {q.tolist()}): {exc}") from exc
