"""Contact solvers: backends that solve the one-step QP and know no mechanics.

Every solver takes the step's data for *all* m rows of the scene and the indices of the
active ones, and returns ``(v, P)`` with P for the active rows only:

``solve(M, b, G, c, rows) -> (v (n,), P (k,))``

where G (m, n) and c (m,) are full-size (entries of inactive rows are ignored).

Backends
--------
``"osqp"`` : :class:`OSQPSolver` (default). Set up once per scene, changed each step with
    OSQP's ``update()`` on a fixed sparsity pattern (inactive rows opened with l = −∞),
    warm-started, eps 1e-9 with polishing, on the QP in mass-normalized units (identity
    Hessian, rows of unit length); its active set is then made exact (and corrected where
    it is not complementary). Rebuilding OSQP every step through ``qpsolvers.solve_qp``
    costs ~20x more (see ``benchmarks/step_cost.py``).
``"enum"`` : :class:`EnumerationSolver`, exact: enumerates the active sets of the LCP,
    smallest first. Fast for the few active rows of a typical step; the default fallback.
``"daqp"``, ``"quadprog"``, ``"qpsolvers:<name>"`` : :class:`QpsolversSolver`, exact
    active-set QPs through qpsolvers.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np
from numba import njit

from moreau.core.kernels import lt_solve, sym_product

__all__ = [
    "ContactSolver",
    "OSQPSolver",
    "EnumerationSolver",
    "ExactSolver",
    "QpsolversSolver",
    "SolveFailed",
    "make_solver",
    "available_solvers",
]


_jit = njit(cache=True, nogil=True)


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

    def describe(self) -> dict:
        return {"name": self.name}


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

    def describe(self):
        return {"name": self.name, "eps": self.eps, "polish": self.polish}


def _cholesky(M):
    """Lower Cholesky factor of M, or None when M is not positive definite."""
    from moreau.core.kernels import cholesky

    M = np.ascontiguousarray(M, dtype=float)
    n = M.shape[0]
    L = np.empty((n, n))
    return None if cholesky(M, L, n) >= 0 else L


# -- the exact refinement (numba: small dense loops, called at every solve; LAPACK's
# -- triangular solves go through a threaded BLAS whose start-up costs milliseconds here)
@_jit
def _normalized(L, b, G, A, r, uf):
    """``u_free = L⁻¹ b`` into uf and the rows of ``G L⁻ᵀ`` scaled to unit length into A,
    their scales ``1 / ‖(G L⁻ᵀ)_i‖`` into r (1 for a zero row)."""
    n = L.shape[0]
    for i in range(n):
        t = b[i]
        for j in range(i):
            t -= L[i, j] * uf[j]
        uf[i] = t / L[i, i]
    for row in range(G.shape[0]):
        nrm = 0.0
        for i in range(n):
            t = G[row, i]
            for j in range(i):
                t -= L[i, j] * A[row, j]
            A[row, i] = t / L[i, i]
            nrm += A[row, i] * A[row, i]
        s = 1.0 / math.sqrt(nrm) if nrm > 0.0 else 1.0
        r[row] = s
        for i in range(n):
            A[row, i] *= s


@_jit
def _upper_solve(L, x):
    """L⁻ᵀ x for a lower triangular L (a new array)."""
    y = x.copy()
    lt_solve(L, y, y.shape[0])
    return y


@_jit
def _solve_on(W, w, S, ns, kept, out, F):
    """``W_SS p_S = −w_S`` on the rows ``S[:ns]`` by Cholesky, taking them in order and
    leaving out a row whose pivot shows it dependent on those before it (below 1e-13 of its
    W_ii, the exact solver's test: a redundant contact gets no impulse). The rows kept go
    to ``kept``, their impulses to ``out``; returns how many were kept. F: work (>= ns)²."""
    nk = 0
    for a in range(ns):
        i = S[a]
        d = W[i, i]
        for r in range(nk):  # row nk of F: F[:nk, :nk]⁻¹ W[kept, i]
            t = W[i, kept[r]]
            for m in range(r):
                t -= F[nk, m] * F[r, m]
            F[nk, r] = t / F[r, r]
            d -= F[nk, r] * F[nk, r]
        if not d > 1e-13 * W[i, i]:
            continue
        F[nk, nk] = math.sqrt(d)
        kept[nk] = i
        nk += 1
    for r in range(nk):
        t = -w[kept[r]]
        for m in range(r):
            t -= F[r, m] * out[m]
        out[r] = t / F[r, r]
    for r in range(nk - 1, -1, -1):
        t = out[r]
        for m in range(r + 1, nk):
            t -= F[m, r] * out[m]
        out[r] = t / F[r, r]
    return nk


@_jit
def _nonnegative_on(W, w, S, ns, kept, out, F):
    """:func:`_solve_on` on ``S[:ns]``, dropping the most negative impulse and solving again
    until none is negative; S[:returned] holds the rows, ``out`` their impulses. Returns
    ``(rows, rows dropped)``."""
    dropped = 0
    while True:
        nk = _solve_on(W, w, S, ns, kept, out, F)
        for a in range(nk):
            S[a] = kept[a]
        ns = nk
        worst = -1
        for a in range(nk):
            if out[a] < 0.0 and (worst < 0 or out[a] < out[worst]):
                worst = a
        if worst < 0:
            return ns, dropped
        for a in range(worst, ns - 1):
            S[a] = S[a + 1]
        ns -= 1
        dropped += 1


@_jit
def _exact_from_proposed_set(L, GR, cRo, A, uf, c, rR, u, p, v, P, info):
    """The exact solution of the normalized one-step problem ``min ½|u|² − u_freeᵀu,
    A u >= c`` (rows of A of unit length) from the active set an approximate ``(u, p)``
    proposes: v (original units) and P into ``v``, ``P``; returns False when it does not
    settle (an infeasible problem, or active rows that lose independence to round-off).
    ``info[0]``: the corrections the proposed set needed.

    In the LCP form ``0 <= p ⟂ s = w + W p >= 0`` (``W = A Aᵀ``, unit diagonal;
    ``w = A u_free − c``) p and s are both velocities, and the proposed set is
    ``{i : p_i > s_i, p_i > 0}`` (the primal–dual active-set rule: for OSQP's polished
    answer, the rows it holds at their bound with an impulse), taken in decreasing
    ``p_i − s_i``. On that set solve ``W_SS p_S = −w_S`` (a row dependent on those before
    it, a redundant contact, gets no impulse) and drop the most negative impulse until
    none is negative: a dual-feasible start. Then check complementarity, and while a row is
    violated (slack below ``−tol``, 1e-12 of the problem's velocity scale as in the exact
    solver, less the round-off of ``W p``) correct the set as the dual active-set method of
    Goldfarb & Idnani does (the exact solver's, :mod:`moreau.contact.lcp`): add the most violated
    row, moving the impulses of the set so that their slacks stay zero, and drop a row
    whose impulse reaches zero first. From a right proposal this is one solve. Last,
    ``u = u_free + Aᵀ p``, ``v = L⁻ᵀ u`` and iterative refinement in the original units
    (``G v − c`` on the set, back through W) while it reduces that residual: large
    cancelling impulses (nearly opposed rows) leave it at round-off of the large terms.
    """
    k, n = A.shape
    eps = 2.220446049250313e-16
    W = np.empty((k, k))
    w = np.empty(k)
    s = np.empty(k)
    scale = 1e-300
    for j in range(n):
        scale = max(scale, abs(uf[j]))
    for i in range(k):
        t = -c[i]
        t0 = -c[i]
        for j in range(n):
            t += A[i, j] * uf[j]
            t0 += A[i, j] * u[j]
        w[i] = t
        s[i] = t0
        scale = max(scale, abs(t), abs(c[i]))
    sym_product(A, A, W, k, n)
    tol = 1e-12 * scale
    # the proposed set, in decreasing p − s
    S = np.empty(k, dtype=np.int64)
    key = np.empty(k)
    ns = 0
    for i in range(k):
        if p[i] > s[i] and p[i] > 0.0:
            S[ns] = i
            key[ns] = s[i] - p[i]
            ns += 1
    order = np.argsort(key[:ns])
    Ssorted = np.empty(k, dtype=np.int64)
    for a in range(ns):
        Ssorted[a] = S[order[a]]
    S = Ssorted
    kept = np.empty(k, dtype=np.int64)
    out = np.empty(k)
    F = np.empty((k, k))
    ns, corrections = _nonnegative_on(W, w, S, ns, kept, out, F)
    q = np.zeros(k)
    inA = np.zeros(k, dtype=np.bool_)
    for a in range(ns):
        q[S[a]] = out[a]
        inA[S[a]] = True
    dp = np.empty(k)
    settled = False
    for _ in range(4 * k + 10):
        # the most violated row outside the set (those in it have zero slack)
        j = -1
        worst = 0.0
        for i in range(k):
            if inA[i]:
                continue
            t = w[i]
            fl = 0.0
            for m in range(k):
                t += W[i, m] * q[m]
                fl += abs(W[i, m] * q[m])
            t += 8.0 * eps * fl
            if t < -tol and (j < 0 or t < worst):
                j, worst = i, t
        if j < 0:
            settled = True
            break
        corrections += 1
        slj = w[j]
        for m in range(k):
            slj += W[j, m] * q[m]
        added = False
        for _inner in range(k + 1):  # bring row j to its bound (Goldfarb–Idnani step)
            ds = W[j, j]
            if ns > 0:
                if _solve_on(W, W[j], S, ns, kept, dp, F) != ns:  # dp = −W_AA⁻¹ W_Aj
                    return False  # the set lost independence to round-off
                for a in range(ns):
                    ds += W[j, S[a]] * dp[a]
            t_full = -slj / ds if ds > 1e-13 * W[j, j] else math.inf
            t_part = math.inf
            blocking = -1
            for a in range(ns):
                if dp[a] < 0.0:
                    ratio = -q[S[a]] / dp[a]
                    if ratio < t_part:
                        t_part, blocking = ratio, a
            t = min(t_full, t_part)
            if t == math.inf:
                return False  # row j cannot be satisfied: infeasible
            for a in range(ns):
                q[S[a]] += t * dp[a]
            q[j] += t
            slj += t * ds
            if t_full <= t_part:
                S[ns] = j
                ns += 1
                ns, dropped = _nonnegative_on(W, w, S, ns, kept, out, F)  # exactly on the new set
                corrections += dropped
                q[:] = 0.0
                inA[:] = False
                for a in range(ns):
                    q[S[a]] = out[a]
                    inA[S[a]] = True
                added = True
                break
            q[S[blocking]] = 0.0
            inA[S[blocking]] = False
            for a in range(blocking, ns - 1):
                S[a] = S[a + 1]
            ns -= 1
        if not added:
            return False
    if not settled:
        return False
    info[0] = corrections
    ut = uf.copy()
    for i in range(k):
        if q[i] != 0.0:
            for j in range(n):
                ut[j] += A[i, j] * q[i]
    vv = _upper_solve(L, ut)
    # iterative refinement in the original units, keeping the best answer
    best = math.inf
    vbest = vv.copy()
    qbest = q.copy()
    t = np.zeros(k)
    for step in range(4 if ns > 0 else 0):
        err = 0.0
        for i in range(k):
            t[i] = 0.0
        for a in range(ns):
            i = S[a]
            g = -cRo[i]
            for j in range(n):
                g += GR[i, j] * vv[j]
            t[i] = rR[i] * g  # the set's slacks, in the normalized units
            err = max(err, abs(t[i]))
        if not err < best:
            break
        best = err
        vbest[:] = vv
        qbest[:] = q
        if err == 0.0 or step == 3:
            break
        if _solve_on(W, t, S, ns, kept, dp, F) != ns:
            break
        ok = True
        for a in range(ns):
            if q[S[a]] + dp[a] < 0.0:
                ok = False
        if not ok:
            break
        du = np.zeros(n)
        for a in range(ns):
            q[S[a]] += dp[a]
            for j in range(n):
                du[j] += A[S[a], j] * dp[a]
        dv = _upper_solve(L, du)
        for j in range(n):
            vv[j] += dv[j]
    for j in range(n):
        v[j] = vbest[j]
    for i in range(k):
        P[i] = qbest[i] * rR[i]
    return True


class _CompiledLCPSolver(ContactSolver):
    """A compiled LCP method of :mod:`moreau.contact.lcp` called from the Python path."""

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
                          workspace(n, k)) != 0:
            raise SolveFailed(f"{self.name} found no solution for {k} active rows")
        return v, P

    def _check_rows(self, k: int) -> None:
        pass


class ExactSolver(_CompiledLCPSolver):
    """Exact dual active-set solver (Goldfarb–Idnani on the LCP, :mod:`moreau.contact.lcp`):
    any number of active rows, redundant rows included. The default of the compiled path,
    and the same code here."""

    name = "exact"
    _method = 0


class EnumerationSolver(_CompiledLCPSolver):
    """Exact LCP solver by enumeration of active sets, smallest first (:mod:`moreau.contact.lcp`).

    For k active rows it tries at most 2^k sets, each a k x k Cholesky solve; singular
    sub-blocks (redundant rows) are skipped. The default fallback.

    Parameters
    ----------
    max_rows : int
        Refuse (raise :class:`~moreau.contact.solvers.SolveFailed`) above this many active rows (at most 12).
    """

    name = "enum"
    _method = 1

    def __init__(self, max_rows: int = 12) -> None:
        self.max_rows = min(int(max_rows), 12)

    def _check_rows(self, k: int) -> None:
        if k > self.max_rows:
            raise SolveFailed(f"enumeration refuses {k} active rows (max_rows={self.max_rows})")


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

    def solve(self, M, b, G, c, rows):
        qp = self._qpsolvers
        if self.backend == "osqp":  # keeps OSQP's polishing from printing
            free = _unconstrained_if_feasible(M, b, G, c, rows)
            if free is not None:
                return free, np.zeros(rows.shape[0])
        problem = qp.Problem(P=M, q=-b, G=-G[rows], h=-c[rows])
        sol = qp.solve_problem(problem, solver=self.backend, **self.options)
        if not sol.found or sol.x is None:
            raise SolveFailed(f"{self.backend} found no solution")
        P = sol.z if sol.z is not None else np.zeros(rows.shape[0])
        return np.asarray(sol.x, dtype=float), np.asarray(P, dtype=float)

    def describe(self):
        return {"name": self.name, "options": self.options}


_SIMPLE = {
    "osqp": lambda: OSQPSolver(),
    "enum": lambda: EnumerationSolver(),
    "exact": lambda: ExactSolver(),
}


def available_solvers() -> list[str]:
    """Names accepted by :func:`make_solver`."""
    import qpsolvers

    exact_qp = [s for s in ("daqp", "quadprog") if s in qpsolvers.available_solvers]
    return sorted(_SIMPLE) + exact_qp


def make_solver(spec: str | ContactSolver) -> ContactSolver:
    """A solver from a name (``"osqp"``, ``"enum"``, ``"daqp"``, ``"quadprog"``,
    ``"qpsolvers:<backend>"``) or an instance (returned as is).

    Raises
    ------
    ValueError
        For an unknown name.
    """
    if isinstance(spec, ContactSolver):
        return spec
    if not isinstance(spec, str):
        raise ValueError(f"solver must be a name or a ContactSolver, got {spec!r}")
    if spec in _SIMPLE:
        return _SIMPLE[spec]()
    name = spec.split(":", 1)[1] if spec.startswith("qpsolvers:") else spec
    if name in ("daqp", "quadprog") or spec.startswith("qpsolvers:"):
        return QpsolversSolver(name)
    raise ValueError(f"unknown solver {spec!r}; choose one of {available_solvers()}")
