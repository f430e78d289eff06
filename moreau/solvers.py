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
        steps of the exact solver's dual active-set method (:func:`_lcp_from_proposed_set`).
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
        # u_free = L⁻¹ b and L⁻¹ Gᵀ in one triangular solve (Ax is refreshed only when G
        # or M changed: a constant M and a constant Jacobian keep it)
        kw = {}
        if self._L is None or G is not self._last_G:
            X = _lower_solve(L, np.column_stack([b, G.T]).astype(float))
            uf, AT = X[:, 0], X[:, 1:]
            norms = np.sqrt(np.einsum("ij,ij->j", AT, AT))
            r = 1.0 / np.where(norms > 0.0, norms, 1.0)
            A = AT.T * r[:, None]
            self._last_G = G
            self._A, self._r = A, r
            kw["Ax"] = A.ravel(order="F")
        else:
            uf = _lower_solve(L, np.asarray(b, dtype=float).reshape(-1, 1))[:, 0]
            A, r = self._A, self._r
        AR = A[rows]
        cR = c[rows] * r[rows]
        # the QP is homogeneous in (u_free, ĉ): solve it in units where they are O(1) (the
        # 1e-10 corrections of a drift-control projection, b = 0 and c = −g, would
        # otherwise drown in OSQP's absolute tolerance) and scale (u, p) back
        scale = max(float(np.abs(uf).max()) if uf.size else 0.0, float(np.abs(cR).max()) if rows.size else 0.0)
        if scale == 0.0:  # b = 0, c = 0: v = 0 is the solution
            scale = 1.0
        free_ok = bool(np.all(AR @ uf >= cR))
        l = self._l
        l.fill(-np.inf)
        l[rows] = cR / scale
        self._solver.update(q=-uf / scale, l=l, **kw)
        # polishing would find no active row: skip it, it would only print that (see
        # _unconstrained_if_feasible); the answer is the same
        quiet = self.polish and free_ok
        if quiet:
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
            exact = self._exact_on_proposed_set(L, G[rows], c[rows], AR, uf, cR, r[rows], u, p)
            if exact is not None:
                return exact
            self.n_unsettled += 1
        return _upper_solve(L, u), p * r[rows]

    def _exact_on_proposed_set(self, L, GR, cR_orig, AR, uf, cR, rR, u, p):
        """(v, P) exact on the active set OSQP proposes, corrected if it is not
        complementary (:func:`_lcp_from_proposed_set`); None when that does not settle.
        Ends with iterative refinement in the original units, as the exact solver does:
        ``v⁺ = v_free + M⁻¹GᵀP`` cancels large free velocities, leaving G v⁺ off its bound by
        round-off of the large terms; P and v are corrected by that residual."""
        k = AR.shape[0]
        if k == 0:
            return _upper_solve(L, uf), np.zeros(0)
        W = AR @ AR.T
        w = AR @ uf - cR
        tol = 1e-12 * max(1e-300, float(np.abs(w).max()), float(np.abs(cR).max()), float(np.abs(uf).max()))
        found = _lcp_from_proposed_set(W, w, p, AR @ u - cR, tol, 4 * k + 10)
        if found is None:
            return None
        q, act, corrections = found
        self.n_corrections += bool(corrections)
        v = _upper_solve(L, uf + AR.T @ q)
        # iterative refinement while it reduces the set's slacks (nearly opposed rows,
        # whose large impulses cancel, take two steps), keeping the best answer
        best = None
        for step in range(4 if act else 0):
            t = np.zeros(k)
            t[act] = rR[act] * (GR[act] @ v - cR_orig[act])  # the set's slacks, in these units
            err = float(np.abs(t[act]).max())
            if best is not None and not err < best[0]:
                v, q = best[1], best[2]
                break
            best = (err, v, q.copy())
            if err == 0.0 or step == 3:
                break
            kept, dq = _solve_on(W, t, act)
            if len(kept) != len(act) or not np.all(q[act] + dq >= 0.0):
                break
            q[act] += dq
            v = v + _upper_solve(L, AR[act].T @ dq)
        return v, q * rR

    def describe(self):
        return {"name": self.name, "eps": self.eps, "polish": self.polish}


def _cholesky(M):
    """Lower Cholesky factor of M, or None when M is not positive definite."""
    from .kernels import cholesky

    M = np.ascontiguousarray(M, dtype=float)
    n = M.shape[0]
    L = np.empty((n, n))
    return None if cholesky(M, L, n) >= 0 else L


def _lcp_from_proposed_set(W, w, p, s, tol, max_steps):
    """The exact solution of the LCP ``0 <= p ⟂ w + W p >= 0`` (W = A Aᵀ of rows of unit
    length, positive semi-definite) from the active set an approximate ``(p, s)`` proposes;
    ``(p, active rows, corrections)`` or None when it does not settle in ``max_steps``.

    p and s are both velocities in these units, and the proposed set is
    ``{i : p_i > s_i, p_i > 0}`` (the primal–dual active-set rule: for OSQP's polished
    answer, the rows it holds at their bound with an impulse). On that set solve
    ``W_SS p_S = −w_S`` (a row dependent on those before it, a redundant contact, gets no
    impulse) and drop the most negative impulse until none is negative: a dual-feasible
    start. Then check complementarity, and while a row is violated (slack below ``−tol``,
    less the round-off of ``W p``) correct the set as the dual active-set method of
    Goldfarb & Idnani does (the exact solver's, :mod:`moreau.lcp`): add the most violated
    row, moving the impulses of the set so that their slacks stay zero, and drop a row
    whose impulse reaches zero first. From a right proposal this is one solve.
    """
    k = w.shape[0]
    order = np.argsort(-(p - s), kind="stable")
    A = [int(i) for i in order if p[i] > s[i] and p[i] > 0.0]
    A, pA, corrections = _nonnegative_on(W, w, A)
    q = np.zeros(k)
    q[A] = pA
    absW = np.abs(W)
    for _ in range(max_steps):
        # slacks of the rows outside the set (those in it are zero by construction), less
        # the round-off of W p where large impulses cancel (nearly opposed rows)
        sl = w + W @ q
        sl[A] = np.inf
        sl += 8.0 * np.finfo(float).eps * (absW @ np.abs(q))
        j = int(np.argmin(sl))
        if not sl[j] < -tol:
            return q, A, corrections
        sl[j] = w[j] + float(W[j] @ q)
        corrections += 1
        while True:  # bring row j to its bound (Goldfarb–Idnani step)
            if A:
                kept, dpA = _solve_on(W, W[:, j], A)  # −W_AA⁻¹ W_Aj
                if len(kept) != len(A):
                    return None  # the set lost independence to round-off
                ds = W[j, j] + float(W[j, A] @ dpA)
            else:
                dpA, ds = np.zeros(0), W[j, j]
            t_full = -sl[j] / ds if ds > 1e-13 * W[j, j] else np.inf
            shrink = np.flatnonzero(dpA < 0.0)
            t_part, blocking = np.inf, -1
            if shrink.size:
                ratios = -q[np.array(A)[shrink]] / dpA[shrink]
                blocking = int(shrink[np.argmin(ratios)])
                t_part = float(ratios.min())
            t = min(t_full, t_part)
            if not np.isfinite(t):
                return None  # row j cannot be satisfied: infeasible
            if A:
                q[A] += t * dpA
            q[j] += t
            sl[j] += t * ds
            if t_full <= t_part:
                A.append(j)
                A, pA, dropped = _nonnegative_on(W, w, A)  # exactly on the new set
                corrections += dropped
                q[:] = 0.0
                q[A] = pA
                break
            q[A[blocking]] = 0.0
            del A[blocking]
    return None


def _nonnegative_on(W, w, S):
    """:func:`_solve_on` on S, dropping the most negative impulse and solving again until
    none is negative; ``(rows, impulses, rows dropped)``."""
    dropped = 0
    while True:
        S, pS = _solve_on(W, w, S)
        if not S or pS.min() >= 0.0:
            return S, pS, dropped
        del S[int(np.argmin(pS))]
        dropped += 1


def _solve_on(W, w, S):
    """``W_SS p_S = −w_S`` by Cholesky, taking the rows of S in order and leaving out a row
    whose pivot shows it dependent on those before it (below 1e-13 of its W_ii, the exact
    solver's test); ``(kept rows, p_kept)``."""
    S = np.asarray(S, dtype=np.int64)
    ns = S.shape[0]
    kept = np.empty(ns, dtype=np.int64)
    out = np.empty(ns)
    nk = _solve_on_kernel(W, np.ascontiguousarray(w), S, kept, out, np.empty((max(ns, 1), max(ns, 1))))
    return [int(i) for i in kept[:nk]], out[:nk]


# small dense kernels (numba: LAPACK's triangular solves go through a threaded BLAS whose
# start-up costs milliseconds on these 3 x 3 … 30 x 30 problems)
@_jit
def _solve_on_kernel(W, w, S, kept, out, F):
    nk = 0
    for a in range(S.shape[0]):
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
def _lower_solve(L, B):
    """L⁻¹ B for a lower triangular L (n x n) and B (n x p)."""
    n, p = B.shape
    X = np.empty((n, p))
    for c in range(p):
        for i in range(n):
            t = B[i, c]
            for m in range(i):
                t -= L[i, m] * X[m, c]
            X[i, c] = t / L[i, i]
    return X


@_jit
def _upper_solve(L, x):
    """L⁻ᵀ x for a lower triangular L."""
    n = x.shape[0]
    y = np.empty(n)
    for i in range(n - 1, -1, -1):
        t = x[i]
        for m in range(i + 1, n):
            t -= L[m, i] * y[m]
        y[i] = t / L[i, i]
    return y


class _CompiledLCPSolver(ContactSolver):
    """A compiled LCP method of :mod:`moreau.lcp` called from the Python path."""

    exact = True
    _method = 0

    def solve(self, M, b, G, c, rows):
        from .kernels import cholesky
        from .lcp import solve_one_step, workspace

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
    """Exact dual active-set solver (Goldfarb–Idnani on the LCP, :mod:`moreau.lcp`):
    any number of active rows, redundant rows included. The default of the compiled path,
    and the same code here."""

    name = "exact"
    _method = 0


class EnumerationSolver(_CompiledLCPSolver):
    """Exact LCP solver by enumeration of active sets, smallest first (:mod:`moreau.lcp`).

    For k active rows it tries at most 2^k sets, each a k x k Cholesky solve; singular
    sub-blocks (redundant rows) are skipped. The default fallback.

    Parameters
    ----------
    max_rows : int
        Refuse (raise :class:`~moreau.solvers.SolveFailed`) above this many active rows (at most 12).
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
