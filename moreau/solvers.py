"""Contact solvers: backends that solve the one-step QP and know no mechanics.

Every solver takes the step's data for *all* m rows of the scene and the indices of the
active ones, and returns ``(v, P)`` with P for the active rows only:

``solve(M, b, G, c, rows) -> (v (n,), P (k,))``

where G (m, n) and c (m,) are full-size (entries of inactive rows are ignored).

Backends
--------
``"osqp"`` : :class:`OSQPSolver` (default). Set up once per scene, changed each step with
    OSQP's ``update()`` on a fixed sparsity pattern (inactive rows opened with l = −∞),
    warm-started, eps 1e-9 with polishing. Rebuilding OSQP every step through
    ``qpsolvers.solve_qp`` costs ~20x more (see ``benchmarks/step_cost.py``).
``"enum"`` : :class:`EnumerationSolver`, exact: enumerates the active sets of the LCP,
    smallest first. Fast for the few active rows of a typical step; the default fallback.
``"daqp"``, ``"quadprog"``, ``"qpsolvers:<name>"`` : :class:`QpsolversSolver`, exact
    active-set QPs through qpsolvers.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

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


def _unconstrained_if_feasible(M, b, G, c, rows, factor=None):
    """The unconstrained minimizer ``v = M⁻¹ b`` when it satisfies every active row, else None.

    Then it is the exact solution, with P = 0 (the QP is strictly convex). OSQP (1.x)
    prints "Polishing not needed - no active set detected at optimal point" through
    ``sys.stdout`` whenever polishing finds no active row, whatever ``verbose`` says; the
    OSQP backends use this test to switch polishing off for such a solve (polishing would
    not change the answer). Redirecting ``sys.stdout`` or file descriptor 1 around each
    solve instead is process-global state and breaks under threads. What remains: a solve
    whose true impulses are nonzero but below OSQP's detection threshold can still print
    that line (measured: 1 in ~6 000 piston solves); it changes no result.

    ``factor`` is a Cholesky factor of a constant M (``scipy.linalg.cho_factor``), or None.
    """
    try:
        if factor is not None:
            import scipy.linalg as sla

            v = sla.cho_solve(factor, b)
        else:
            v = np.linalg.solve(M, b)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(v)) or not np.all(G[rows] @ v >= c[rows]):
        return None
    return v


class OSQPSolver(ContactSolver):
    """OSQP, set up once and updated every step.

    Parameters
    ----------
    eps : float
        Absolute and relative tolerance (``eps_abs = eps_rel``). The default 1e-9 with
        polishing matches an exact solve; at eps >= 1e-5 impact counts change.
    polish : bool
        Polish the solution (solve the reduced KKT system on the detected active set).
    max_iter : int
        Iteration limit.
    refine : bool
        Make the answer exact on the active set OSQP found (default True): the KKT
        check measures velocities per coordinate, and ADMM alone leaves errors of
        1e-6 … 1e-4 in light coordinates of ill-scaled mass matrices.
    name : str, optional
        Name in results (default ``"osqp"`` or ``"osqp(eps=...)"``).
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

    def setup(self, ndof, nrows, mass=None):
        import osqp
        import scipy.sparse as sp

        n, m = ndof, nrows
        self._n, self._m = n, m
        # Dense patterns, kept fixed: upper triangle of P (CSC order), all of A.
        Ppat = sp.csc_matrix(np.triu(np.ones((n, n))))
        triu = [(i, j) for j in range(n) for i in range(j + 1)]
        self._p_rows = np.array([i for i, _ in triu])
        self._p_cols = np.array([j for _, j in triu])
        Ppat.data = (np.eye(n) if mass is None else mass)[self._p_rows, self._p_cols].astype(float)
        Apat = sp.csc_matrix(np.ones((m, n)))
        self._l = np.full(m, -np.inf)
        self._u = np.full(m, np.inf)
        self._constant_mass = mass is not None
        self._last_A = None
        self._factor = None
        if mass is not None:
            import scipy.linalg as sla

            try:
                self._factor = sla.cho_factor(np.asarray(mass, dtype=float))
            except (np.linalg.LinAlgError, ValueError):
                self._factor = None
        s = osqp.OSQP()
        s.setup(
            Ppat, np.zeros(n), Apat, self._l, self._u,
            verbose=False, eps_abs=self.eps, eps_rel=self.eps, polishing=self.polish,
            warm_starting=True, max_iter=self.max_iter, eps_prim_inf=1e-12, eps_dual_inf=1e-12,
        )
        self._solver = s
        self._solved_status = osqp.SolverStatus.OSQP_SOLVED

    def solve(self, M, b, G, c, rows):
        if self._solver is None:
            raise SolveFailed("OSQPSolver.solve called before setup()")
        # the QP is homogeneous in (b, c): solve small data in units where they are O(1)
        # and scale (v, P) back. OSQP's absolute tolerance would otherwise swamp the 1e-10 m
        # corrections of a drift-control projection (b = 0, c = −g).
        scale = min(1.0, max(float(np.abs(c[rows]).max()) if rows.size else 0.0,
                             float(np.abs(b).max()) / float(np.abs(np.diag(M)).max())
                             * float(np.abs(G[rows]).max()) if rows.size else 0.0, 1e-300))
        l = self._l
        l.fill(-np.inf)
        l[rows] = c[rows] / scale
        kw = {"q": -b / scale, "l": l}
        if not self._constant_mass:
            kw["Px"] = M[self._p_rows, self._p_cols]
        if G is not self._last_A:
            kw["Ax"] = G.ravel(order="F")
            self._last_A = G
        # polishing would find no active row: skip it, it would only print that (see
        # _unconstrained_if_feasible); the answer is the same
        quiet = self.polish and _unconstrained_if_feasible(M, b, G, c, rows, self._factor) is not None
        self._solver.update(**kw)
        if quiet:
            self._solver.update_settings(polishing=False)
            res = self._solver.solve(raise_error=False)
            self._solver.update_settings(polishing=True)
        else:
            res = self._solver.solve(raise_error=False)
        import osqp

        st = res.info.status_val  # an IntEnum: compares with the int
        nearly = st in (osqp.SolverStatus.OSQP_SOLVED_INACCURATE, osqp.SolverStatus.OSQP_MAX_ITER_REACHED)
        if st != self._solved_status and not (self.refine and nearly):
            raise SolveFailed(f"OSQP status {res.info.status!r} after {res.info.iter} iterations")
        # OSQP: l <= Ax <= u with y < 0 on active lower bounds; P = -y.
        v, P = scale * res.x, -scale * res.y[rows]
        if self.refine:
            # also from an iterate ADMM stopped short of its tolerance (ill-scaled M): the
            # active set it found is usually right, and the KKT check judges the result
            v, P = _refine_on_active_set(M, b, G[rows], c[rows], v, P)
        return v, P

    def describe(self):
        return {"name": self.name, "eps": self.eps, "polish": self.polish}


def _refine_on_active_set(M, b, GA, cA, v, P):
    """OSQP's answer made exact on the active set it found (rows with P > 0, possibly none): solve the
    equality-constrained KKT system there, ``W_SS P_S = c_S − G_S M⁻¹ b``, and keep the
    result when its impulses are non-negative and every row is feasible (to round-off);
    otherwise OSQP's own answer (the KKT check then judges it). ADMM converges slowly in
    a light coordinate of an ill-scaled M; this step does not depend on the scaling."""
    S = np.flatnonzero(P > 0.0)
    if S.size > M.shape[0]:
        return v, P
    try:
        sol = np.linalg.solve(M, np.column_stack([b, GA[S].T]))
        GS = GA[S]
        PS = np.linalg.solve(GS @ sol[:, 1:], cA[S] - GS @ sol[:, 0]) if S.size else np.zeros(0)
    except np.linalg.LinAlgError:
        return v, P
    if S.size and PS.min() < 0.0:
        return v, P
    v2 = sol[:, 0] + sol[:, 1:] @ PS
    slack = GA @ v2 - cA
    if slack.min() < -1e-12 * max(1e-300, float(np.abs(cA).max()), float(np.abs(GA @ v2).max())):
        return v, P
    P2 = np.zeros_like(P)
    P2[S] = PS
    return v2, P2


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
