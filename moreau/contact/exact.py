"""The compiled exact backends as ContactSolvers, callable from Python: :class:`ExactSolver` (dual
active set) and :class:`EnumerationSolver`, both running the kernels of
:mod:`moreau.contact.lcp`."""

from __future__ import annotations

import numpy as np

from moreau.contact.base import ContactSolver, SolveFailed

__all__ = ["ExactSolver", "EnumerationSolver"]


class _CompiledLCPSolver(ContactSolver):
    """A compiled LCP method of :mod:`moreau.contact.lcp` called from Python."""

    exact = True
    _method = 0

    def solve(self, M, b, G, c, rows):
        from moreau.contact.lcp import solve_one_step, workspace
        from moreau.core.kernels import cholesky

        k = rows.shape[0]
        self._check_rows(k)
        n = M.shape[0]
        L = np.empty((n, n))
        if cholesky(M, L, n) >= 0:
            raise SolveFailed("the mass matrix is not positive definite")
        P = np.zeros(k)
        v = np.empty(n)
        GA = np.ascontiguousarray(G[rows], dtype=float)
        if solve_one_step(M, L, np.ascontiguousarray(b, dtype=float), GA,
                          np.ascontiguousarray(c[rows], dtype=float), P, v, k, self._method, 1e-12,
                          workspace(n, k), True, False) != 0:  # every argument given: numba's fast dispatch
            raise SolveFailed(f"{self.name} found no solution for {k} active rows")
        return v, P

    def _check_rows(self, k: int) -> None:
        pass

    def solve_friction(self, M, b, G, c, T, mu, rows, cT=None):
        """Lemke's method on the friction LCP (:func:`moreau.contact.friction.friction_one_step`)."""
        from moreau.contact.friction import friction_one_step

        self._check_rows(rows.shape[0])
        status, v, PN, PT = friction_one_step(M, b, np.ascontiguousarray(G[rows]), c[rows],
                                              np.ascontiguousarray(T[rows]), mu[rows],
                                              cT=None if cT is None else cT[rows])
        if status != 0:
            what = ("and the enumeration of contact states found no solution" if status == 2 else
                    "found no answer that passes its own checks")
            raise SolveFailed(f"Lemke's method {what} for {rows.shape[0]} active rows, mu = {mu[rows].tolist()}")
        return v, PN, PT


class ExactSolver(_CompiledLCPSolver):
    """Exact LCP solver (:mod:`moreau.contact.lcp`): block principal pivoting from 8 rows,
    and the dual active-set method (Goldfarb–Idnani on the LCP) below that or when the
    pivoting gives up; any number of active rows, redundant rows included. The default
    of the compiled loop (also as ``solver="auto"``), and the same code here; an instance
    passed as ``solver`` runs as ``"exact"`` does, in the loop."""

    name = "exact"
    _method = 0


class EnumerationSolver(_CompiledLCPSolver):
    """Exact LCP solver by enumeration of active sets, smallest first (:mod:`moreau.contact.lcp`).

    For k active rows it tries at most 2^k sets, each a k x k Cholesky solve; singular
    sub-blocks (redundant rows) are skipped. The default fallback; an instance with the
    default ``max_rows`` passed as ``solver`` runs as ``"enum"`` does, in the loop.

    Parameters
    ----------
    max_rows : int
        Refuse (raise :class:`~moreau.contact.solvers.SolveFailed`) above this many active rows (at most 12).
    """

    name = "enum"
    _method = 1

    def __init__(self, max_rows: int = 12) -> None:
        self.max_rows = min(int(max_rows), 12)

    def solve_friction(self, M, b, G, c, T, mu, rows, cT=None):
        """Enumeration of open/stick/slip states (:mod:`moreau.contact.friction_enum`, at
        most 6 active rows): independent of Lemke's LCP."""
        from moreau.contact.friction_enum import MAX_CONTACTS, friction_enumerate
        from moreau.contact.tresca import delassus

        k = rows.shape[0]
        if k > min(self.max_rows, MAX_CONTACTS):
            raise SolveFailed(f"enumeration with friction refuses {k} active rows (max {MAX_CONTACTS})")
        W, w, _, MinvGt, vfree = delassus(M, b, G, c, T, mu, rows, cT)
        fidx = np.flatnonzero(mu[rows] > 0.0)
        P = friction_enumerate(W, w, mu[rows], fidx)
        if P is None:
            raise SolveFailed(f"no contact state satisfies the friction law for {k} active rows, "
                              f"mu = {mu[rows].tolist()}")
        PT = np.zeros(k)
        PT[fidx] = P[k:]
        return vfree + MinvGt @ P, P[:k].copy(), PT

    def _check_rows(self, k: int) -> None:
        if k > self.max_rows:
            raise SolveFailed(f"enumeration refuses {k} active rows (max_rows={self.max_rows})")
