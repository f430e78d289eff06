"""The base of the contact solvers: :class:`ContactSolver`, the interface every backend
implements, and :class:`SolveFailed`, what a backend raises when it gives up.

Imported by the backends (:mod:`~moreau.contact.osqp`, :mod:`~moreau.contact.exact`,
:mod:`~moreau.contact.qp`) and re-exported by :mod:`moreau.contact.solvers`; it imports
none of them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

__all__ = ["ContactSolver", "SolveFailed"]


class SolveFailed(RuntimeError):
    """A backend could not solve a one-step problem (the integrator then falls back)."""


class ContactSolver(ABC):
    """Base class of the one-step contact solvers.

    Attributes
    ----------
    name : str
        Name used in results and on the command line.
    exact : bool
        True for solvers that return the exact (round-off level) solution.
    """

    name: str = "solver"
    exact: bool = False

    def setup(self, ndof: int, nrows: int, mass: np.ndarray | None = None) -> None:  # noqa: B027 - optional hook
        """Prepare for a scene with ``ndof`` coordinates and ``nrows`` contact rows.

        ``mass`` is the constant mass matrix when the system has one (None otherwise).
        """

    @abstractmethod
    def solve(
        self, M: np.ndarray, b: np.ndarray, G: np.ndarray, c: np.ndarray, rows: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Solve ``min ½ vᵀMv − bᵀv  s.t.  G[rows] v >= c[rows]``; return ``(v, P[rows])``."""

    def solve_friction(
        self, M: np.ndarray, b: np.ndarray, G: np.ndarray, c: np.ndarray, T: np.ndarray, mu: np.ndarray,
        rows: np.ndarray, cT: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve the one-step problem with planar Coulomb friction (see
        :mod:`moreau.contact.friction`) on the active ``rows``; ``T`` (m, n) the tangent
        rows, ``mu`` (m,) the friction coefficients (tangent rows are used where mu > 0),
        ``cT`` (m,) the offsets of the slip velocities ``T v − cT`` (None: 0; set in the
        reduced problem of a scene with bilateral rows).
        Return ``(v, P_N[rows], P_T[rows])`` (P_T zero where mu = 0).

        Raises :class:`~moreau.contact.solvers.SolveFailed` when the backend has no
        friction solve (this default) or found no answer."""
        raise SolveFailed(f"solver {self.name!r} does not solve problems with friction")

    def describe(self) -> dict:
        return {"name": self.name}
