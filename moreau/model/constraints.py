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

import numpy as np

from moreau.model.barriers import Barrier

__all__ = ["Bilateral", "HOLD_TOL"]

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
        """Per row, the |g| positions are held to (see ``HOLD_TOL``)."""
        return HOLD_TOL * np.maximum(1.0, np.asarray(self.geometry.gap_scale(), dtype=float))

    def describe(self) -> dict:
        return {"name": self.name, "geometry": self.geometry.describe()}
