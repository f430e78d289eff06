"""Compiled exact contact solvers and the KKT check shared by every backend.

The one-step problem (see :mod:`moreau.onestep`) on its k active rows,

    minimize ½ vᵀ M v − vᵀ b   subject to   G v >= c,

is solved through its LCP ``0 <= P ⟂ s = w + W P >= 0`` with ``W = G M⁻¹ Gᵀ`` (k x k,
symmetric positive semi-definite, singular for redundant rows) and
``w = G M⁻¹ b − c``; then ``v = M⁻¹ (b + Gᵀ P)``.

:func:`lcp_dual_active_set` is the dual active-set method of Goldfarb & Idnani (1983,
"A numerically stable dual method for solving strictly convex quadratic programs",
Math. Programming 27, 1–33; the algorithm of quadprog) written on W: starting from the
unconstrained minimum (P = 0), it adds the most violated row, moves the impulses of the
active rows along the direction that keeps their slacks zero, and drops a row whose
impulse reaches zero before the new one is satisfied. The active rows stay linearly
independent (a dependent row is satisfied by the others or the problem is infeasible),
so redundant contacts are handled exactly; every step is a solve with the Cholesky
factor of W on the active rows. It terminates in a finite number of steps for any k.
:func:`lcp_enumerate` (active sets smallest first, k <= 12) is the independent fallback.
Both are plain loops on small dense arrays: they run inside the compiled time loop and,
called from Python, as the ``"exact"`` backend (:class:`moreau.solvers.ExactSolver`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernels import cho_solve, cholesky

__all__ = ["lcp_dual_active_set", "lcp_enumerate", "kkt_residuals_kernel", "OK", "FAILED"]

OK, FAILED = 0, 1
_jit = njit(cache=True, nogil=True)


@_jit
def _solve_active(W, A, na, rhs, out, L):
    """out[:na] = W[A, A]⁻¹ rhs[:na] by Cholesky; False when W[A, A] is not PD."""
    for i in range(na):
        for j in range(na):
            L[i, j] = W[A[i], A[j]]
    sub = L[:na, :na]
    fac = np.empty((na, na))
    if cholesky(sub, fac) >= 0:
        return False
    cho_solve(fac, rhs[:na], out[:na])
    return True


@_jit
def _slacks(W, w, P, s):
    k = w.shape[0]
    for i in range(k):
        t = w[i]
        for j in range(k):
            t += W[i, j] * P[j]
        s[i] = t


@_jit
def lcp_dual_active_set(W, w, P, tol):
    """Solve ``0 <= P ⟂ w + W P >= 0`` (W PSD) by the Goldfarb–Idnani dual method.

    Parameters
    ----------
    W : ndarray, shape (k, k)
    w : ndarray, shape (k,)
    P : ndarray, shape (k,)
        Output: the impulses.
    tol : float
        Accept slacks >= −tol (velocity units).

    Returns
    -------
    int
        ``OK`` or ``FAILED`` (infeasible problem, or no convergence in 10 (k + 1) steps).
    """
    k = w.shape[0]
    P[:] = 0.0
    s = np.empty(k)
    A = np.empty(k, dtype=np.int64)
    inA = np.zeros(k, dtype=np.bool_)
    na = 0
    rhs = np.empty(k)
    r = np.empty(k)
    Lw = np.empty((k, k))
    for _ in range(10 * (k + 1)):
        _slacks(W, w, P, s)
        p = -1
        worst = 0.0
        for i in range(k):
            if not inA[i] and s[i] < -tol:
                d = W[i, i]
                score = s[i] / math.sqrt(d) if d > 0.0 else s[i]
                if score < worst:
                    worst, p = score, i
        if p < 0:
            break
        added = False
        for _inner in range(k + 1):
            # r = W_AA⁻¹ W_Ap: how the active impulses change per unit of P_p
            if na > 0:
                for i in range(na):
                    rhs[i] = W[A[i], p]
                if not _solve_active(W, A, na, rhs, r, Lw):
                    return FAILED
            schur = W[p, p]
            for i in range(na):
                schur -= W[p, A[i]] * r[i]
            sp = w[p]
            for j in range(k):
                sp += W[p, j] * P[j]
            t1 = math.inf
            if schur > 1e-13 * max(W[p, p], 1e-300):
                t1 = -sp / schur
            t2 = math.inf
            jblock = -1
            for i in range(na):
                if r[i] > 0.0:
                    ti = P[A[i]] / r[i]
                    if ti < t2:
                        t2, jblock = ti, i
            if t1 == math.inf and t2 == math.inf:
                return FAILED  # row p cannot be satisfied: infeasible
            t = min(t1, max(t2, 0.0))
            for i in range(na):
                P[A[i]] -= t * r[i]
            P[p] += t
            if t2 < t1:  # drop the blocking row, keep adding p
                jb = A[jblock]
                P[jb] = 0.0
                inA[jb] = False
                for i in range(jblock, na - 1):
                    A[i] = A[i + 1]
                na -= 1
                continue
            A[na] = p
            inA[p] = True
            na += 1
            added = True
            break
        if not added:
            return FAILED
    else:
        return FAILED
    # refine on the final active set: W_AA P_A = −w_A exactly
    if na > 0:
        for i in range(na):
            rhs[i] = -w[A[i]]
        if _solve_active(W, A, na, rhs, r, Lw):
            ok = True
            for i in range(na):
                if r[i] < 0.0:
                    ok = False
            if ok:
                for i in range(na):
                    P[A[i]] = r[i]
    return OK


@_jit
def lcp_enumerate(W, w, P, tol):
    """Solve the same LCP by enumerating active sets, smallest first (k <= 12).

    Returns ``OK`` or ``FAILED`` (more than 12 rows, or no active set passes).
    """
    k = w.shape[0]
    P[:] = 0.0
    if k > 12:
        return FAILED
    s = np.empty(k)
    _slacks(W, w, P, s)
    if s.min() >= -tol:
        return OK
    A = np.empty(k, dtype=np.int64)
    rhs = np.empty(k)
    x = np.empty(k)
    Lw = np.empty((k, k))
    for size in range(1, k + 1):
        for mask in range(1, 1 << k):
            na = 0
            for i in range(k):
                if mask >> i & 1:
                    A[na] = i
                    na += 1
            if na != size:
                continue
            for i in range(na):
                rhs[i] = -w[A[i]]
            if not _solve_active(W, A, na, rhs, x, Lw):
                continue
            good = True
            for i in range(na):
                if x[i] < 0.0:
                    good = False
            if not good:
                continue
            P[:] = 0.0
            for i in range(na):
                P[A[i]] = x[i]
            _slacks(W, w, P, s)
            if s.min() >= -tol:
                return OK
    P[:] = 0.0
    return FAILED


@_jit
def kkt_residuals_kernel(M, L, b, G, c, v, P, out):
    """Scaled KKT residuals of ``(v, P)`` for the one-step QP, written to ``out`` (4,):
    primal, dual, complementarity, stationarity (each dimensionless).

    Contact rows are measured as normal velocities against the contact's own velocity
    scale (the largest of |c|, |G v|, the normal velocity the impulses make, and
    1e-9 |G||v|); an impulse counts through the velocity it makes, ``P_i Σ_j G_ij²/M_jj``.
    Stationarity is measured per coordinate as a velocity error: ``δ = M⁻¹ (M v − b − Gᵀ P)``
    against ``max(|v_i|, |(M⁻¹ b)_i|, 1e-9 (‖v‖_M + ‖M⁻¹b‖_M)/√M_ii)``. Every measure is
    invariant under a rescaling of any single coordinate (a change of units), so a light
    coordinate's velocity error is not hidden behind a heavy one's momentum.
    ``L`` is the Cholesky factor of M.
    """
    k, n = G.shape
    Gv = np.empty(k)
    GtP = np.zeros(n)
    for i in range(k):
        t = 0.0
        for j in range(n):
            t += G[i, j] * v[j]
            GtP[j] += G[i, j] * P[i]
        Gv[i] = t
    vel = 1e-300
    for i in range(k):
        vel = max(vel, abs(c[i]), abs(Gv[i]))
        a = 0.0
        f = 0.0
        for j in range(n):
            a += abs(G[i, j]) * abs(GtP[j]) / M[j, j]
            f += abs(G[i, j]) * abs(v[j])
        vel = max(vel, a, 1e-9 * f)
    primal = 0.0
    dual = 0.0
    comp = 0.0
    for i in range(k):
        slack = Gv[i] - c[i]
        wi = 0.0
        for j in range(n):
            wi += G[i, j] * G[i, j] / M[j, j]
        pw = P[i] * wi
        primal = max(primal, -slack / vel)
        dual = max(dual, -pw / vel)
        comp = max(comp, abs(pw * slack) / (vel * vel))
    r = np.empty(n)
    for i in range(n):
        t = -b[i] - GtP[i]
        for j in range(n):
            t += M[i, j] * v[j]
        r[i] = t
    d = np.empty(n)
    cho_solve(L, r, d)
    x = np.empty(n)
    cho_solve(L, b, x)
    ev = 0.0
    ex = 0.0
    for i in range(n):
        for j in range(n):
            ev += v[i] * M[i, j] * v[j]
            ex += x[i] * M[i, j] * x[j]
    energy = math.sqrt(max(ev, 0.0)) + math.sqrt(max(ex, 0.0))
    stat = 0.0
    for i in range(n):
        sc = max(abs(v[i]), abs(x[i]), 1e-9 * energy / math.sqrt(M[i, i]), 1e-300)
        stat = max(stat, abs(d[i]) / sc)
    out[0] = primal
    out[1] = dual
    out[2] = comp
    out[3] = stat


@_jit
def solve_one_step(M, L, b, G, c, P, v, method, tol):
    """v, P of the one-step QP on all rows of G (k x n) with the LCP solver ``method``
    (0: dual active set, 1: enumeration); returns its status. ``L`` = chol(M)."""
    k, n = G.shape
    MinvGt = np.empty((n, k))
    col = np.empty(n)
    for j in range(k):
        cho_solve(L, G[j], col)
        MinvGt[:, j] = col
    vfree = np.empty(n)
    cho_solve(L, b, vfree)
    W = np.empty((k, k))
    w = np.empty(k)
    scale = 1e-300
    for i in range(k):
        t = -c[i]
        for j in range(n):
            t += G[i, j] * vfree[j]
        w[i] = t
        scale = max(scale, abs(t), abs(c[i]))
        for j in range(k):
            u = 0.0
            for l in range(n):
                u += G[i, l] * MinvGt[l, j]
            W[i, j] = u
    for i in range(k):  # exactly symmetric
        for j in range(i + 1, k):
            a = 0.5 * (W[i, j] + W[j, i])
            W[i, j] = a
            W[j, i] = a
    if method == 0:
        status = lcp_dual_active_set(W, w, P, tol * scale)
    else:
        status = lcp_enumerate(W, w, P, tol * scale)
    for i in range(n):
        t = vfree[i]
        for j in range(k):
            t += MinvGt[i, j] * P[j]
        v[i] = t
    return status
