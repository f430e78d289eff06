"""The one-step problem with planar Coulomb friction, solved exactly by Lemke's method.

Rows of one step (all at the midpoint): k normal rows ``U_N = G_N v`` with lower bounds
c (Newton's law), then kf tangential rows ``U_T = G_T v``, one per normal row j with
``mu_j > 0`` (``fidx[f] = j``). With ``W = G M⁻¹ Gᵀ`` and ``w = G v_free − [c; 0]`` for the
stacked ``G = [G_N; G_T]`` the post-step velocities are ``U = W P + w`` and the law is::

    0 <= P_N ⟂ U_N >= 0,    |P_T| <= mu P_N,    U_T ≠ 0  ⇒  P_T = −mu P_N sign(U_T).

The law is an LCP in one of two classical forms, tried in this order:

*Glocker & Pfeiffer* (Pfeiffer & Glocker 1996; Acary & Brogliato 2008, §13.4): with
``σ_R = mu P_N + P_T`` and the negative part U_T⁻ of the slip velocity,
``0 <= σ_R ⟂ U_T + U_T⁻ >= 0`` and ``0 <= U_T⁻ ⟂ 2 mu P_N − σ_R >= 0``, so that
``z = (P_N, σ_R, U_T⁻)`` solves an LCP of size k + 2 kf:

    [ W_NN − W_NT μ   W_NT   0 ]          [ w_N ]
    [ W_TN − W_TT μ   W_TT   D ]  z   +   [ w_T ]
    [ 2 D μ           −D     0 ]          [  0  ]

*Stewart & Trinkle* (1996) / *Anitescu & Potra* (1997): ``P_T = β⁺ − β⁻`` with
``β± >= 0`` and the slip speed λ >= 0, ``0 <= β± ⟂ λ ± U_T >= 0``,
``0 <= λ ⟂ mu P_N − β⁺ − β⁻ >= 0``, an LCP of size k + 3 kf in ``z = (P_N, β⁺, β⁻, λ)``:

    [ W_NN    W_NT   −W_NT   0 ]          [  w_N ]
    [ W_TN    W_TT   −W_TT   D ]  z   +   [  w_T ]
    [ −W_TN  −W_TT    W_TT   D ]          [ −w_T ]
    [ D μ     −D      −D     0 ]          [   0  ]

whose matrix is copositive (a PSD Delassus block, a skew-symmetric λ coupling, a
non-negative μ block), for which Lemke's method finds a solution when one exists in exact
arithmetic (Anitescu & Potra, Nonlinear Dynamics 14, 231–247, 1997).

μ is the kf x k matrix with ``μ[f, fidx[f]] = mu_fidx[f]``: each contact's own
coefficient multiplies its own normal impulse (with one mu for all contacts a mix-up of
contacts here would be invisible). The velocity unknowns (U_T⁻, λ) and their rows are
scaled by ``D = diag(W_TT)`` so that every row is a velocity and every unknown an impulse
(the solution does not change).

Redundant rows (two corners of one body on one wall; a 3-link chain on a floor at three
points) make the Delassus block singular: either form can then end on a ray of round-off,
so :func:`solve_friction_step` tries the Glocker form, then the Anitescu–Potra form, each
with pivot tolerances 1e-9, 1e-7 and 1e-11, takes the first answer that passes the check
of :func:`friction_residuals_kernel` (the full law), and with at most five contacts
enumerates their states (:mod:`moreau.contact.friction_states`). Only when nothing is
found is the status ``RAY``, never an answer. From ``PGS_MIN_CONTACTS`` contacts on it
first relaxes the problem (:mod:`moreau.contact.pgs`), below it does when Lemke's method
fails (an 80-link chain on a rough floor: a ray at 38 contacts), checked the same way.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from moreau.contact import pgs as _pgs
from moreau.contact.active_set import _inline, _jit
from moreau.contact.friction_states import enumerate_states
from moreau.contact.friction_work import FrictionWorkspace, friction_workspace
from moreau.contact.kkt import kkt_residuals_rows
from moreau.contact.lemke import FAILED, OK, RAY, lcp_lemke
from moreau.core.kernels import cho_solve, delassus

__all__ = ["FrictionWorkspace", "friction_workspace", "solve_friction_step", "friction_residuals_kernel",
           "friction_one_step", "friction_residuals", "FRICTION_RESIDUALS", "FRICTION_METHODS",
           "PGS_MIN_CONTACTS"]

#: the pivot tolerances Lemke's method tries in turn (see :func:`solve_friction_step`)
PIVOT_TOLERANCES = (1e-9, 1e-7, 1e-11)

#: an answer with every law residual at most this is taken without trying another
GOOD = 1e-9

#: how :func:`solve_friction_step` solves: by size (see there), by Lemke's method only, or
#: by projected Gauss–Seidel and a polish (:mod:`moreau.contact.pgs`) only
FRICTION_AUTO, FRICTION_LEMKE, FRICTION_PGS = 0, 1, 2
FRICTION_METHODS = {"auto": FRICTION_AUTO, "lemke": FRICTION_LEMKE, "pgs": FRICTION_PGS}
#: from this many closed contacts on "auto" relaxes first (0.2-0.5x Lemke's time at 30-50)
PGS_MIN_CONTACTS = 32

#: the names of the six residuals of :func:`friction_residuals_kernel`, in order
FRICTION_RESIDUALS = ("primal", "dual", "complementarity", "stationarity", "cone", "slip")


@_inline
def _assemble(W, w, mu, fidx, k, kf, form, A, qv):
    """The friction LCP ``(A, qv)`` of the module docstring from the Delassus matrix W and
    free velocities w of the stacked rows: ``form`` 0 the Glocker–Pfeiffer form in
    ``(P_N, σ_R, U_T⁻)`` (size k + 2 kf), 1 the Anitescu–Potra form in ``(P_N, β⁺, β⁻, λ)``
    (size k + 3 kf); returns the size. The velocity-unknowns (U_T⁻, λ) are scaled by
    ``D = diag(W_TT)`` to impulses, their rows to velocities."""
    R = k + kf
    p = R + kf if form == 0 else R + 2 * kf
    for i in range(p):
        for j in range(p):
            A[i, j] = 0.0
    if form == 0:
        for i in range(R):  # U = W P + w with P_T = σ_R − μ P_N
            for j in range(k):
                A[i, j] = W[i, j]
            for f in range(kf):
                j = fidx[f]
                A[i, j] -= mu[j] * W[i, k + f]
                A[i, k + f] = W[i, k + f]
            qv[i] = w[i]
        for f in range(kf):
            d = max(W[k + f, k + f], 1e-300)
            A[k + f, R + f] = d  # + U_T⁻
            A[R + f, fidx[f]] = 2.0 * mu[fidx[f]] * d  # the left edge: 2 μ P_N − σ_R >= 0
            A[R + f, k + f] = -d
            qv[R + f] = 0.0
        return p
    # P_N at 0, β⁺ at k, β⁻ at R, λ at R + kf: the Delassus matrix of [G_N; G_T; −G_T]
    for a in range(R + kf):
        ia = a if a < R else a - kf
        sa = -1.0 if a >= R else 1.0
        for bb in range(R + kf):
            ib = bb if bb < R else bb - kf
            sb = -1.0 if bb >= R else 1.0
            A[a, bb] = sa * sb * W[ia, ib]
        qv[a] = sa * w[ia]
    for f in range(kf):
        d = max(W[k + f, k + f], 1e-300)
        lam = R + kf + f
        A[k + f, lam] = d
        A[R + f, lam] = d
        A[lam, fidx[f]] = d * mu[fidx[f]]
        A[lam, k + f] = -d
        A[lam, R + f] = -d
        qv[lam] = 0.0
    return p


@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # a call: compiled once, not re-optimized inline
def solve_friction_step(M, L, b, G, c, mu, fidx, k, kf, P, v, tol, res, ws, method=FRICTION_AUTO):
    """v and ``P = [P_N (k); P_T (kf)]`` of the one-step problem with friction (module
    docstring) on the first k normal rows of G and the kf tangential rows after them, and
    the six residuals of the full law (:func:`friction_residuals_kernel`) into ``res``.

    ``L`` = chol(M); ``c`` (>= k + kf) the normal rows' lower bounds, then per tangential
    row the offset of its slip velocity ``U_T = G_i v − c_i`` (zero, except in the
    reduced problem of a scene with bilateral rows, :mod:`moreau.contact.equality`);
    ``mu`` (>= k) their
    friction coefficients; ``fidx`` (>= kf) the normal row of each tangential row;
    ``ws`` from :func:`friction_workspace`; ``method`` one of ``FRICTION_METHODS``
    (auto: :mod:`moreau.contact.pgs` first from ``PGS_MIN_CONTACTS`` contacts on; below,
    after Lemke's method when that fails). Returns
    ``OK`` (every residual at most
    ``tol``), ``FAILED`` (the best answer found misses ``tol``; it is in P, v) or ``RAY``
    (no attempt found one; ``res`` infinite). The compiled loop's friction solve and a
    ContactSolver's (``tol = inf``: the caller checks) are this one compiled function.
    """
    n = M.shape[0]
    R = k + kf
    MinvGt, vfree, W, w, A, qv, z, T, basis, xb = ws.MinvGt, ws.vfree, ws.W, ws.w, ws.A, ws.qv, ws.z, ws.T, \
        ws.basis, ws.xb
    delassus(L, G, ws.Xt, MinvGt, W, R, n)
    cho_solve(L, b, vfree, n)
    for i in range(R):
        t = -c[i]  # a tangential row's c: the slip velocity's offset (0 but with bilateral rows)
        for j in range(n):
            t += G[i, j] * vfree[j]
        w[i] = t
    # the attempts of the module docstring, each answer checked against the full law: the
    # first below GOOD is taken, else the best one (the caller's check decides on it)
    cand, rb, Pb, vb = ws.cand, ws.rb, ws.Pb, ws.vb
    best = math.inf
    if method == FRICTION_PGS or (method == FRICTION_AUTO and k >= PGS_MIN_CONTACTS):
        best = _relaxed(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, W, w, cand, rb, Pb, vb, ws, best)
    for form in range(2 if best > GOOD and method != FRICTION_PGS else 0):
        p = _assemble(W, w, mu, fidx, k, kf, form, A, qv)
        for piv in PIVOT_TOLERANCES:
            if lcp_lemke(A, qv, z, p, T, basis, xb, piv) != OK:
                continue
            for j in range(k):
                P[j] = z[j]
            for f in range(kf):  # Glocker: P_T = σ_R − μ P_N; Anitescu–Potra: P_T = β⁺ − β⁻
                P[k + f] = z[k + f] - (mu[fidx[f]] * z[fidx[f]] if form == 0 else z[R + f])
            best = _keep_best(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, cand, rb, Pb, vb, best, ws)
            if best <= GOOD:
                break
        if best <= GOOD:
            break
    if best > GOOD and method != FRICTION_PGS and enumerate_states(W, w, mu, fidx, k, kf, P, A, qv, z, basis):
        best = _keep_best(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, cand, rb, Pb, vb, best, ws)
    if best > GOOD and method == FRICTION_AUTO and k < PGS_MIN_CONTACTS:  # Lemke failed: relax
        best = _relaxed(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, W, w, cand, rb, Pb, vb, ws, best)
    if best == math.inf:
        for i in range(6):
            res[i] = math.inf
        return RAY
    for j in range(R):
        P[j] = Pb[j]
    for i in range(n):
        v[i] = vb[i]
    for i in range(6):
        res[i] = rb[i]
    return OK if best <= tol else FAILED


@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # a call: compiled once
def _relaxed(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, W, w, cand, rb, Pb, vb, ws, best):
    """The problem by projected Gauss–Seidel sweeps, polished on the states they find once
    these settle (looked at after 25, 50, 100, ... sweeps; :mod:`moreau.contact.pgs`); each
    polished answer is checked against ``best`` so far (:func:`_keep_best`), the first
    passing ``GOOD`` ends it. Returns the best worst residual (answer in Pb, vb, rb)."""
    R = k + kf
    U, Q, st, sgn, rows, A, Lr, r, x, tf, Pp = (ws.U, ws.Q, ws.states, ws.signs, ws.rows, ws.AA, ws.Lr, ws.rr, ws.xr,
                                                ws.tf, ws.Pp)  # the relaxation's
    for j in range(k):
        tf[j] = -1
    for f in range(kf):
        tf[fidx[f]] = k + f
    for i in range(R):
        Pp[i] = 0.0
        U[i] = w[i]
    done, upto = 0, _pgs.PGS_FIRST_SWEEPS
    while done < _pgs.PGS_MAX_SWEEPS:
        _pgs.pgs_sweeps(W, w, mu, tf, k, R, Pp, U, upto - done)
        done, upto = upto, 2 * upto
        changed = _pgs.classify(mu, tf, k, Pp, st, sgn)
        if changed > max(2.0, _pgs.PGS_SETTLED * k) and done < _pgs.PGS_MAX_SWEEPS:
            continue
        for _ in range(_pgs.PGS_CORRECTIONS):
            _pgs.polish(W, w, mu, tf, k, R, Pp, Q, st, rows, sgn, A, Lr, r, x, 8)
            for i in range(R):
                P[i] = Q[i]
            best = _keep_best(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, cand, rb, Pb, vb, best, ws)
            if best <= GOOD:
                return best
            if _pgs.correct(W, w, mu, tf, k, R, Q, st, sgn) == 0:
                break
    for i in range(R):  # the relaxed answer itself, for the record
        P[i] = Pp[i]
    return _keep_best(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, cand, rb, Pb, vb, best, ws)


@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # a call, not inlined: three call sites
def _keep_best(M, L, b, G, c, mu, fidx, k, kf, P, v, vfree, MinvGt, res, rb, Pb, vb, best, ws):
    """v = v_free + M⁻¹ Gᵀ P for a candidate P, its law residuals; kept (in Pb, vb, rb)
    when better than ``best``; returns the best worst residual so far."""
    n = M.shape[0]
    R = k + kf
    for i in range(n):
        t = vfree[i]
        for j in range(R):
            t += MinvGt[j, i] * P[j]
        v[i] = t
    friction_residuals_kernel(M, L, b, G, c, mu, fidx, v, P, k, kf, res, ws)
    worst = 0.0
    for i in range(6):
        worst = max(worst, res[i])
    if not worst < best:  # also NaN
        return best
    for j in range(R):
        Pb[j] = P[j]
    for i in range(n):
        vb[i] = v[i]
    for i in range(6):
        rb[i] = res[i]
    return worst


@_jit
def friction_residuals_kernel(M, L, b, G, c, mu, fidx, v, P, k, kf, out, ws):
    """Scaled residuals of ``(v, P)`` against the full law, into ``out`` (6,): primal,
    dual, complementarity of the normal rows and stationarity (as
    :func:`~moreau.contact.kkt.kkt_residuals_rows`), then the cone,
    ``max (|P_T| − mu P_N) w_T / vel``, and stick/slip,
    ``max ((mu P_N + P_T) U_T⁺ + (mu P_N − P_T) U_T⁻) w_T / vel²`` (``w_T = Σ_j G_Tj² / M_jj``
    turns an impulse into the velocity it makes; ``vel`` the velocity scale of the KKT
    check). All dimensionless; ``ws`` from :func:`friction_workspace`."""
    R = k + kf
    Gv = ws.Gv
    no = k < 0  # False, as a variable: the literal would compile the residuals a second time
    vel = kkt_residuals_rows(M, L, b, G, c, v, P, R, k, out, Gv, ws.GtP, ws.rv, ws.d, ws.x, ws.X, ws.rd,
                             no, ws.d, np.int64(0), ws.d, ws.d, ws.X, no)  # no chain: its arrays unread
    cone = 0.0
    slip = 0.0
    for f in range(kf):
        i = k + f
        j = fidx[f]
        wi = 0.0
        for l in range(M.shape[0]):
            wi += G[i, l] * G[i, l] / M[l, l]
        pn = mu[j] * P[j]
        pt = P[i]
        cone = max(cone, (abs(pt) - pn) * wi / vel)
        u = Gv[i] - c[i]  # the slip velocity (c_i: its offset, see solve_friction_step)
        slip = max(slip, ((pn + pt) * max(u, 0.0) + (pn - pt) * max(-u, 0.0)) * wi / (vel * vel))
    out[4] = cone
    out[5] = slip


def _frictional(TA: np.ndarray, muA: np.ndarray, GA: np.ndarray, cA: np.ndarray,
                cT: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(G stacked [G_N; G_T of the rows with mu > 0], c stacked [c_N; c_T of those rows],
    fidx)``."""
    fidx = np.flatnonzero(muA > 0.0).astype(np.int64)
    cT = np.zeros(GA.shape[0]) if cT is None else np.asarray(cT, dtype=float)
    return (np.ascontiguousarray(np.vstack([GA, TA[fidx]]), dtype=float),
            np.ascontiguousarray(np.concatenate([cA, cT[fidx]]), dtype=float), fidx)


def friction_one_step(M: np.ndarray, b: np.ndarray, GA: np.ndarray, cA: np.ndarray, TA: np.ndarray,
                      muA: np.ndarray, L: np.ndarray | None = None, cT: np.ndarray | None = None,
                      method: str = "auto") -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """Solve the one-step problem with friction on k active rows (Lemke's method; for many
    contacts projected Gauss–Seidel and an exact polish first).

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Mass matrix (symmetric positive definite).
    b : ndarray, shape (n,)
        ``M v_k + h f``.
    GA, TA : ndarray, shape (k, n)
        Normal and tangent rows of the active contacts.
    cA, muA : ndarray, shape (k,)
        Lower bounds of the normal velocities; friction coefficients (0: no tangent row).
    L : ndarray, shape (n, n), optional
        Cholesky factor of M.
    cT : ndarray, shape (k,), optional
        Offsets of the slip velocities, ``U_T = T v − cT`` (default 0).
    method : {"auto", "lemke", "pgs"}
        "auto": the relaxation first from ``PGS_MIN_CONTACTS`` contacts on, Lemke's
        method when it fails; below, Lemke's method, then the relaxation when that fails;
        "lemke" or "pgs" alone.

    Returns
    -------
    status : int
        0 (solved), 2 (a secondary ray: no solution found), 1 (failed).
    v : ndarray, shape (n,)
    PN, PT : ndarray, shape (k,)
        Normal and tangential impulses (PT zero where mu = 0).
    """
    from moreau.core.kernels import cholesky

    if method not in FRICTION_METHODS:
        raise ValueError(f"method must be one of {list(FRICTION_METHODS)}, got {method!r}")
    M = np.ascontiguousarray(M, dtype=float)
    n, k = M.shape[0], GA.shape[0]
    if L is None:
        L = np.empty((n, n))
        if cholesky(M, L, n) >= 0:
            raise np.linalg.LinAlgError("the mass matrix is not positive definite")
    G, c, fidx = _frictional(TA, muA, GA, cA, cT)
    kf = fidx.shape[0]
    P = np.zeros(k + kf)
    v = np.empty(n)
    # the compiled loop's entry point, with no tolerance: one compiled function serves both paths
    status = solve_friction_step(M, np.ascontiguousarray(L, dtype=float), np.ascontiguousarray(b, dtype=float),
                                 G, c, np.ascontiguousarray(muA, dtype=float),
                                 fidx, k, kf, P, v, np.inf, np.empty(6),
                                 friction_workspace(n, k, kf),
                                 FRICTION_METHODS[method])
    PT = np.zeros(k)
    PT[fidx] = P[k:]
    return int(status), v, P[:k].copy(), PT


def friction_residuals(M: np.ndarray, b: np.ndarray, GA: np.ndarray, cA: np.ndarray, TA: np.ndarray,
                       muA: np.ndarray, v: np.ndarray, PN: np.ndarray, PT: np.ndarray,
                       L: np.ndarray | None = None, cT: np.ndarray | None = None) -> np.ndarray:
    """The six scaled residuals of :func:`friction_residuals_kernel` (primal, dual,
    complementarity, stationarity, cone, stick/slip) of an answer ``(v, PN, PT)``; shapes
    as in :func:`friction_one_step` (``cT``: the slip velocities' offsets). A mass matrix
    that is not positive definite gives infinite residuals."""
    from moreau.core.kernels import cholesky

    M = np.ascontiguousarray(M, dtype=float)
    n, k = M.shape[0], GA.shape[0]
    if L is None:
        L = np.empty((n, n))
        if cholesky(M, L, n) >= 0:
            return np.full(6, np.inf)
    G, c, fidx = _frictional(TA, muA, GA, cA, cT)
    kf = fidx.shape[0]
    P = np.concatenate([PN, PT[fidx]]).astype(float)
    out = np.empty(6)
    friction_residuals_kernel(M, np.ascontiguousarray(L, dtype=float), np.ascontiguousarray(b, dtype=float), G,
                              c, np.ascontiguousarray(muA, dtype=float), fidx,
                              np.ascontiguousarray(v, dtype=float), P, k, kf, out, friction_workspace(n, k, kf))
    return out
