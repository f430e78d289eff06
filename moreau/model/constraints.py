"""Bilateral constraints: rows g(q) = 0 held both ways (joints, closed loops).

A :class:`Bilateral` takes any barrier object for its geometry (``gap(q)``,
``jacobian(q)``: :class:`~moreau.model.barriers.FunctionBarrier`,
:class:`~moreau.model.barriers.LinearBarrier`, a chain's point rows) and holds its rows
at 0: their impulses have either sign (Siconos: an interaction with an equality law).
The scene's one-step problem then seeks the velocity in the null space of these rows
(:mod:`moreau.contact.equality`), so joint reactions and contact impulses come out of
one solve, and positions are projected back onto g(q) = 0 after every step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from moreau.model.barriers import Barrier

__all__ = ["Bilateral", "HOLD_TOL", "check_constraints", "constrained_velocity"]

#: positions are held on the constraint manifold to this, times max(1, the row's gap
#: scale) (the gap's length unit): |g(q)| <= 1e-10 for rows of unit scale
HOLD_TOL = 1e-12


@dataclass(frozen=True)
class Bilateral:
    """Rows g(q) = 0 held both ways (a joint, a closed loop, a rod of fixed length).

    Parameters
    ----------
    geometry : Barrier
        The rows (``gap(q)`` (k,), ``jacobian(q)`` (k, n)); its sign convention does not
        matter, both directions are held.
    name : str
        Label of the constraint in results and errors.

    Raises
    ------
    ValueError
        When ``geometry`` is not a :class:`~moreau.model.barriers.Barrier`.
    """

    geometry: Barrier
    name: str = "joint"

    def __post_init__(self) -> None:
        if not isinstance(self.geometry, Barrier):
            raise ValueError(f"Bilateral {self.name!r}: geometry must be a Barrier (FunctionBarrier, "
                             f"LinearBarrier, a chain's point rows), got {self.geometry!r}")
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Bilateral: name must be a non-empty string, got {self.name!r}")

    @property
    def nrows(self) -> int:
        return int(self.geometry.nrows)

    def row_names(self) -> list[str]:
        return list(self.geometry.row_names(self.name))

    def hold_tol(self) -> np.ndarray:
        """Per row, the ``|g|`` positions are held to (see ``HOLD_TOL``)."""
        return HOLD_TOL * np.maximum(1.0, np.asarray(self.geometry.gap_scale(), dtype=float))

    def describe(self) -> dict:
        return {"name": self.name, "geometry": self.geometry.describe()}


def check_constraints(scene: Any, q: np.ndarray, v: np.ndarray, tol: float = 1e-8, where: str = "") -> None:
    """Refuse a state off the constraints: ``|g_E(q)|`` above ``tol`` (times max(1,
    the row's gap scale)), or a velocity that breaks them, ``|G_E v|`` above ``tol``
    times the velocity scale ``max(1e-300, |G_E||v|)``; ``ValueError`` naming the rows
    and values (:func:`constrained_velocity` gives a consistent v)."""
    if not scene.nconstraints:
        return
    assert scene.constraint_gaps is not None and scene.constraint_jacobian is not None
    g = np.asarray(scene.constraint_gaps(q), dtype=float)
    lim = tol * np.maximum(1.0, scene.constraint_hold_tol / 1e-12)
    bad = np.flatnonzero(~(np.abs(g) <= lim))
    if bad.size:
        rows = {scene.constraint_names[i]: float(g[i]) for i in bad}
        raise ValueError(f"the constraints are not satisfied{where}: g(q0) = {rows} (|g| must be at most "
                         f"{tol:g} in the gap's unit; the rows are held at 0)")
    G = np.asarray(scene.constraint_jacobian(q), dtype=float)
    u = G @ v
    scale = np.abs(G) @ np.abs(v)
    bad = np.flatnonzero(~(np.abs(u) <= tol * np.maximum(scale, 1e-300)))
    if bad.size:
        rows = {scene.constraint_names[i]: float(u[i]) for i in bad}
        raise ValueError(f"the velocity breaks the constraints{where}: G v0 = {rows} (must be 0; "
                         "scene.constrained_velocity(q0, v0) projects v0 onto them)")


def constrained_velocity(scene: Any, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The velocity closest to v in the metric of M(q) with ``G_E(q) v = 0`` (the
    same projection the step uses); v itself without constraints."""
    v = np.asarray(v, dtype=float)
    if not scene.nconstraints or scene.constraint_jacobian is None:
        return v.copy()
    M = np.asarray(scene.system.mass_matrix(q), dtype=float)
    G = np.asarray(scene.constraint_jacobian(q), dtype=float)
    MinvGt = np.linalg.solve(M, G.T)
    lam = np.linalg.lstsq(G @ MinvGt, G @ v, rcond=1e-12)[0]
    out: np.ndarray = v - MinvGt @ lam
    return out
