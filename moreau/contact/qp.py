"""Exact QP backends through qpsolvers (:class:`QpsolversSolver`: ``"daqp"``,
``"quadprog"``, ``"qpsolvers:<name>"``), rebuilding the problem every step."""

from __future__ import annotations

import numpy as np

from moreau.contact.base import ContactSolver, SolveFailed

__all__ = ["QpsolversSolver"]


def _unconstrained_if_feasible(M, b, G, c, rows):
    """The unconstrained minimizer ``v = M⁻¹ b`` when it satisfies every active row, else None.

    Then it is the exact solution, with P = 0 (the QP is strictly convex). OSQP (1.x)
    prints "Polishing not needed - no active set detected at optimal point" through
    ``sys.stdout`` whenever polishing finds no active row, whatever ``verbose`` says; the
    OSQP backends use this test (:class:`OSQPSolver` in its own units) to switch polishing
    off for such a solve (polishing would not change the answer). Redirecting
    ``sys.stdout`` or file descriptor 1 around each solve instead is process-global state
    and breaks under threads. What remains: a solve whose true impulses are nonzero but
    below OSQP's detection threshold can still print that line (measured: 1 in ~6 000
    piston solves); it changes no result.
    """
    try:
        v = np.linalg.solve(M, b)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(v)) or not np.all(G[rows] @ v >= c[rows]):
        return None
    return v


def _csc(a):
    """``a`` as a SciPy CSC matrix."""
    from scipy import sparse

    return sparse.csc_matrix(a)


class QpsolversSolver(ContactSolver):
    """An exact QP backend through qpsolvers (``"daqp"``, ``"quadprog"``, ...).

    Each step builds the QP on the active rows only and calls ``qpsolvers.solve_problem``
    (so ``QpsolversSolver("osqp")`` rebuilds the OSQP workspace every step: the slow way,
    kept for the benchmark that measures it).

    Parameters
    ----------
    backend : str
        A name in ``qpsolvers.available_solvers``.
    **options
        Passed to the backend (e.g. ``eps_abs=1e-9`` for OSQP).
    """

    def __init__(self, backend: str, **options) -> None:
        import qpsolvers

        if backend not in qpsolvers.available_solvers:
            raise ValueError(
                f"unknown or not installed qpsolvers backend {backend!r}; "
                f"available: {sorted(qpsolvers.available_solvers)}"
            )
        self.backend = backend
        self.name = backend if backend != "osqp" else "qpsolvers:osqp"
        self.exact = backend != "osqp"
        self.options = options
        self._qpsolvers = qpsolvers
        # a sparse backend (OSQP, ...) gets its matrices as CSC: qpsolvers would convert
        # dense ones itself and warn (SparseConversionWarning) at every run
        self._matrix = _csc if backend in qpsolvers.sparse_solvers else np.asarray

    def solve(self, M, b, G, c, rows):
        qp = self._qpsolvers
        if self.backend == "osqp":  # keeps OSQP's polishing from printing
            free = _unconstrained_if_feasible(M, b, G, c, rows)
            if free is not None:
                return free, np.zeros(rows.shape[0])
        # the QP is homogeneous in (b, c): solved where they are O(1) (a drift projection's
        # 1e-10 data would drown in the backend's absolute tolerances) and scaled back
        scale = max(float(np.abs(b).max(initial=0.0)), float(np.abs(c[rows]).max(initial=0.0)))
        if scale == 0.0:  # b = 0, c = 0: v = 0 is the solution
            return np.zeros(M.shape[0]), np.zeros(rows.shape[0])
        problem = qp.Problem(P=self._matrix(M), q=-b / scale, G=self._matrix(-G[rows]), h=-c[rows] / scale)
        sol = qp.solve_problem(problem, solver=self.backend, **self.options)
        if not sol.found or sol.x is None:
            raise SolveFailed(f"{self.backend} found no solution")
        P = sol.z if sol.z is not None else np.zeros(rows.shape[0])
        return scale * np.asarray(sol.x, dtype=float), scale * np.asarray(P, dtype=float)

    def solve_friction(self, M, b, G, c, T, mu, rows, cT=None):
        """Coulomb friction as a fixed point over Tresca QPs (:mod:`moreau.contact.tresca`)."""
        from moreau.contact.tresca import solve_by_tresca

        qp = self._qpsolvers

        def box_qp(W, w, lower, upper):
            sol = qp.solve_problem(qp.Problem(P=self._matrix(W), q=w, lb=lower, ub=upper), solver=self.backend,
                                   **self.options)
            if not sol.found or sol.x is None:
                raise SolveFailed(f"{self.backend} found no solution of a Tresca problem")
            return np.clip(np.asarray(sol.x, dtype=float), lower, upper)

        return solve_by_tresca(M, b, G, c, T, mu, rows, box_qp, cT)

    def describe(self):
        return {"name": self.name, "options": self.options}
