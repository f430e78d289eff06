"""The OSQP backend (:class:`OSQPSolver`, the default): set up once per scene, updated
every step, on the QP in mass-normalized units; its active set is then made exact by
:func:`~moreau.contact.refine._exact_from_proposed_set`."""

from __future__ import annotations

from typing import Any

import numpy as np

from moreau.contact.base import ContactSolver, SolveFailed
from moreau.contact.refine import _cholesky, _exact_from_proposed_set, _normalized, _upper_solve, ensure_loaded

__all__ = ["OSQPSolver"]


class OSQPSolver(ContactSolver):
    """OSQP, set up once and updated every step, on the QP in mass-normalized units.

    The one-step QP ``min ½ vᵀMv − bᵀv, G v >= c`` is handed to OSQP in the variables
    ``u = Lᵀ v`` (``M = L Lᵀ``, Cholesky) with every row scaled to unit length:

        minimize ½ uᵀu − u_freeᵀ u   subject to   Â u >= ĉ,
        u_free = L⁻¹ b,   Â = R G L⁻ᵀ,   ĉ = R c,   R = diag(1 / ‖(G L⁻ᵀ)_i‖)

    so that its Hessian is the identity and its Delassus matrix ``Â Âᵀ`` has a unit
    diagonal, whatever the units of the coordinates (a change of units rescales M, G and
    b and leaves this problem unchanged): ADMM's convergence and its tolerances no longer
    depend on how the mass matrix is scaled. OSQP's answer then only proposes the
    active set; the answer returned is the exact solution on that set (see ``refine``).

    Parameters
    ----------
    eps : float
        Absolute and relative tolerance (``eps_abs = eps_rel``) of ADMM, in the units
        above (default 1e-9).
    polish : bool
        Polish the solution (solve the reduced KKT system on the detected active set).
    max_iter : int
        Iteration limit.
    refine : bool
        Make the answer exact (default True): solve the LCP ``0 <= p ⟂ ŵ + Ŵ p >= 0``
        (``Ŵ = Â Âᵀ``, ``ŵ = Â u_free − ĉ``) exactly on the active set OSQP found (also
        from an iterate ADMM stopped short of its tolerance), check complementarity (no
        negative impulse, no violated row), and correct the set where it fails, by the
        steps of the exact solver's dual active-set method (``_exact_from_proposed_set``).
        What does not settle (an infeasible problem, or rows that lose independence to
        round-off) is returned as OSQP answered and left to the integrator's KKT check and
        its fallback. With False: OSQP's own answer, in the original units.
    name : str, optional
        Name in results (default ``"osqp"`` or ``"osqp(eps=...)"``).

    Attributes
    ----------
    n_corrections : int
        Solves whose active set had to be corrected after OSQP (statistics).
    n_unsettled : int
        Solves whose refinement did not settle (their answer is OSQP's).
    """

    exact = False

    def __init__(self, eps: float = 1e-9, polish: bool = True, max_iter: int = 20000, name: str | None = None,
                 refine: bool = True) -> None:
        if not (np.isfinite(eps) and eps > 0):
            raise ValueError(f"OSQPSolver: eps must be positive, got {eps!r}")
        self.eps = float(eps)
        self.polish = bool(polish)
        self.max_iter = int(max_iter)
        self.refine = bool(refine)
        self.name = name or ("osqp" if (eps == 1e-9 and polish) else f"osqp(eps={eps:g},polish={polish})")
        self._solver = None
        self.n_corrections = self.n_unsettled = 0

    def setup(self, ndof, nrows, mass=None):
        import osqp
        import scipy.sparse as sp

        if self.refine:  # its kernels before the first solve (compiled, with a word, on a new machine)
            ensure_loaded()
        n, m = ndof, nrows
        self._n, self._m = n, m
        self._l = np.full(m, -np.inf)
        self._u = np.full(m, np.inf)
        self._L = None
        if mass is not None:  # constant M: factorized once
            self._L = _cholesky(np.asarray(mass, dtype=float))
        self._last_G = None
        s = osqp.OSQP()
        s.setup(
            sp.identity(n, format="csc"), np.zeros(n), sp.csc_matrix(np.ones((m, n))), self._l, self._u,
            verbose=False, eps_abs=self.eps, eps_rel=self.eps, polishing=self.polish,
            warm_starting=True, max_iter=self.max_iter, eps_prim_inf=1e-12, eps_dual_inf=1e-12,
        )
        self._solver = s
        self._solved_status = osqp.SolverStatus.OSQP_SOLVED

    def solve(self, M, b, G, c, rows):
        import osqp

        if self._solver is None:
            raise SolveFailed("OSQPSolver.solve called before setup()")
        L = self._L if self._L is not None else _cholesky(M)
        if L is None:
            raise SolveFailed("the mass matrix is not positive definite")
        n, m = self._n, self._m
        uf = np.empty(n)
        kw = {}
        if self._L is None or G is not self._last_G:  # Â is kept for a constant M and Jacobian
            A, r = np.empty((m, n)), np.empty(m)
            _normalized(L, np.ascontiguousarray(b, dtype=float), np.ascontiguousarray(G, dtype=float), A, r, uf)
            self._last_G = G
            self._A, self._r = A, r
            kw["Ax"] = A.ravel(order="F")
        else:
            A, r = self._A, self._r
            _normalized(L, np.ascontiguousarray(b, dtype=float), np.zeros((0, n)), A[:0], r[:0], uf)
        AR = A[rows]
        cR = c[rows] * r[rows]
        # the QP is homogeneous in (u_free, ĉ): solve it in units where they are O(1) (the
        # 1e-10 corrections of a drift-control projection, b = 0 and c = −g, would
        # otherwise drown in OSQP's absolute tolerance) and scale (u, p) back
        scale = max(float(np.abs(uf).max()) if n else 0.0, float(np.abs(cR).max()) if rows.size else 0.0)
        if scale == 0.0:  # b = 0, c = 0: v = 0 is the solution
            scale = 1.0
        l = self._l
        l.fill(-np.inf)
        l[rows] = cR / scale
        self._solver.update(q=-uf / scale, l=l, **kw)
        # polishing would find no active row: skip it, it would only print that (see
        # _unconstrained_if_feasible); the answer is the same
        if self.polish and bool(np.all(AR @ uf >= cR)):
            self._solver.update_settings(polishing=False)
            res = self._solver.solve(raise_error=False)
            self._solver.update_settings(polishing=True)
        else:
            res = self._solver.solve(raise_error=False)
        st = res.info.status_val  # an IntEnum: compares with the int
        nearly = st in (osqp.SolverStatus.OSQP_SOLVED_INACCURATE, osqp.SolverStatus.OSQP_MAX_ITER_REACHED)
        if st != self._solved_status and not (self.refine and nearly):
            raise SolveFailed(f"OSQP status {res.info.status!r} after {res.info.iter} iterations")
        # OSQP: l <= Ax <= u with y < 0 on active lower bounds; p = -y
        u, p = scale * res.x, -scale * res.y[rows]
        if self.refine:
            k = rows.shape[0]
            v, P, info = np.empty(n), np.empty(k), np.zeros(2, dtype=np.int64)
            if _exact_from_proposed_set(L, np.ascontiguousarray(G[rows], dtype=float),
                                        np.ascontiguousarray(c[rows], dtype=float), AR, uf, cR, r[rows], u, p,
                                        v, P, info):
                self.n_corrections += bool(info[0])
                return v, P
            self.n_unsettled += 1
        return _upper_solve(L, u), p * r[rows]

    def solve_friction(self, M, b, G, c, T, mu, rows, cT=None):
        """Coulomb friction as a fixed point over Tresca QPs (:mod:`moreau.contact.tresca`),
        each solved by OSQP, set up once per step and updated with the new friction bounds."""
        from moreau.contact.tresca import solve_by_tresca

        return solve_by_tresca(M, b, G, c, T, mu, rows, _BoxQP(self.eps, self.max_iter), cT)

    def describe(self):
        return {"name": self.name, "eps": self.eps, "polish": self.polish}


class _BoxQP:
    """``min ½ pᵀWp + wᵀp, lower <= p <= upper`` by OSQP with polishing: set up at the
    first call, then only the bounds updated (warm-started) while W and w stay the same
    arrays (the QPs of one Tresca fixed point)."""

    def __init__(self, eps: float, max_iter: int) -> None:
        self.eps, self.max_iter = eps, max_iter
        self._W: np.ndarray | None = None
        self._s: Any = None

    def __call__(self, W, w, lower, upper):
        import osqp
        import scipy.sparse as sp

        try:  # the unconstrained minimum when it is inside the box (OSQP's polishing
            # would only print that it found no active bound); the least-norm one when W is
            # singular (a zero tangent row)
            p = np.linalg.lstsq(W, -w, rcond=None)[0]
            scale = float(np.abs(w).sum() + np.abs(W).sum() * np.abs(p).max(initial=0.0))
            if np.all(p >= lower) and np.all(p <= upper) and np.abs(W @ p + w).max(initial=0.0) <= 1e-12 * scale:
                return p
        except np.linalg.LinAlgError:
            pass
        if self._s is None or W is not self._W:
            self._s = osqp.OSQP()
            n = w.shape[0]
            self._s.setup(sp.triu(sp.csc_matrix(W), format="csc"), w, sp.identity(n, format="csc"), lower, upper,
                          verbose=False, eps_abs=self.eps, eps_rel=self.eps, polishing=True, warm_starting=True,
                          max_iter=self.max_iter)
            self._W = W
        else:
            self._s.update(l=lower, u=upper)
        res = self._s.solve(raise_error=False)
        if res.info.status_val != osqp.SolverStatus.OSQP_SOLVED:
            raise SolveFailed(f"OSQP status {res.info.status!r} on a Tresca problem after {res.info.iter} iterations")
        return np.clip(res.x, lower, upper)
