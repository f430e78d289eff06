"""Compiled exact contact solvers and the KKT check shared by every backend.

The one-step problem (see :mod:`moreau.contact.problem`) on its k active rows,

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
called from Python, as the ``"exact"`` backend (:class:`moreau.contact.solvers.ExactSolver`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from moreau.core.kernels import cho_solve, cholesky, sym_product

__all__ = ["lcp_dual_active_set", "lcp_enumerate", "kkt_residuals_kernel", "solve_one_step", "workspace",
           "OK", "FAILED"]

OK, FAILED = 0, 1
# allocation-free, so without reference counting; inlined by LLVM (see moreau.core.kernels.jit)
_jit = njit(cache=True, nogil=True, forceinline=True, _nrt=False)  # type: ignore[call-overload]
# internal helpers: no CPython or C entry points to build
_inline = njit(cache=True, nogil=True, forceinline=True, _nrt=False,  # type: ignore[call-overload]
               no_cpython_wrapper=True, no_cfunc_wrapper=True)


@njit(cache=True, nogil=True)
def workspace(n, m):
    """Work arrays for problems of up to m rows on n coordinates (allocated once per run;
    every routine below works on leading blocks of them, creating no array views)."""
    mm = max(m, 1)
    return (np.empty((mm, n)), np.empty(n), np.empty((mm, mm)), np.empty(mm), np.empty(mm),
            np.empty(mm, dtype=np.int64), np.zeros(mm, dtype=np.bool_), np.empty(mm), np.empty(mm),
            np.empty((mm, mm)), np.empty((mm, mm)), np.empty(mm), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n), np.empty(4))


@_inline
def _solve_active(W, A, na, rhs, out, sub, fac):
    """out[:na] = W[A, A]⁻¹ rhs[:na] by Cholesky; False when W[A, A] is not PD."""
    for i in range(na):
        for j in range(na):
            sub[i, j] = W[A[i], A[j]]
    if cholesky(sub, fac, na) >= 0:
        return False
    cho_solve(fac, rhs, out, na)
    return True


@_inline
def _slacks(W, w, P, s, k):
    """s = w + W P on the first k rows; returns min s."""
    smin = math.inf
    for i in range(k):
        t = w[i]
        for j in range(k):
            t += W[i, j] * P[j]
        s[i] = t
        smin = min(smin, t)
    return smin


@_jit
def lcp_dual_active_set(W, w, P, k, tol, s, A, inA, rhs, r, sub, fac):
    """Solve ``0 <= P ⟂ w + W P >= 0`` (W PSD, the leading k x k block) by the
    Goldfarb–Idnani dual method.

    Parameters
    ----------
    W : ndarray, shape (>= k, >= k)
    w : ndarray, shape (>= k,)
    P : ndarray, shape (>= k,)
        Output: the impulses P[:k].
    k : int
        Number of rows.
    tol : float
        Accept slacks >= −tol (velocity units).
    s, A, inA, rhs, r, sub, fac : ndarray
        Work arrays (from :func:`workspace`).

    Returns
    -------
    int
        ``OK`` or ``FAILED`` (infeasible problem, or no convergence in 10 (k + 1) steps).
    """
    for i in range(k):
        P[i] = 0.0
    if k == 1:  # closed form
        if w[0] >= -tol:
            return OK
        if not W[0, 0] > 0.0:
            return FAILED
        P[0] = -w[0] / W[0, 0]
        return OK
    for i in range(k):
        inA[i] = False
    na = 0
    converged = False
    for _ in range(10 * (k + 1)):
        _slacks(W, w, P, s, k)
        p = -1
        worst = 0.0
        for i in range(k):
            if not inA[i] and s[i] < -tol:
                d = W[i, i]
                score = s[i] / math.sqrt(d) if d > 0.0 else s[i]
                if score < worst:
                    worst, p = score, i
        if p < 0:
            converged = True
            break
        added = False
        for _inner in range(k + 1):
            # r = W_AA⁻¹ W_Ap: how the active impulses change per unit of P_p
            if na > 0:
                for i in range(na):
                    rhs[i] = W[A[i], p]
                if not _solve_active(W, A, na, rhs, r, sub, fac):
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
    if not converged:
        return FAILED
    # refine on the final active set: W_AA P_A = −w_A exactly
    if na > 0:
        for i in range(na):
            rhs[i] = -w[A[i]]
        if _solve_active(W, A, na, rhs, r, sub, fac):
            ok = True
            for i in range(na):
                if r[i] < 0.0:
                    ok = False
            if ok:
                for i in range(na):
                    P[A[i]] = r[i]
    return OK


@_jit
def lcp_enumerate(W, w, P, k, tol, s, A, rhs, x, sub, fac):
    """Solve the same LCP by enumerating active sets, smallest first (k <= 12).

    Returns ``OK`` or ``FAILED`` (more than 12 rows, or no active set passes).
    """
    for i in range(k):
        P[i] = 0.0
    if k > 12:
        return FAILED
    if _slacks(W, w, P, s, k) >= -tol:
        return OK
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
            if not _solve_active(W, A, na, rhs, x, sub, fac):
                continue
            good = True
            for i in range(na):
                if x[i] < 0.0:
                    good = False
            if not good:
                continue
            for i in range(k):
                P[i] = 0.0
            for i in range(na):
                P[A[i]] = x[i]
            if _slacks(W, w, P, s, k) >= -tol:
                return OK
    for i in range(k):
        P[i] = 0.0
    return FAILED


@_jit
def kkt_residuals_kernel(M, L, b, G, c, v, P, k, out, Gv, GtP, r, d, x, y):
    """Scaled KKT residuals of ``(v, P)`` for the one-step QP on the first k rows of G,
    written to ``out`` (4,): primal, dual, complementarity, stationarity (dimensionless).

    Contact rows are measured as normal velocities against the contact's own velocity
    scale (the largest of ``|c|``, ``|G v|``, the normal velocity the impulses make, and
    ``1e-9 |G||v|``); an impulse counts through the velocity it makes, ``P_i Σ_j G_ij²/M_jj``.
    Stationarity is measured per coordinate as a velocity error: ``δ = M⁻¹ (M v − b − Gᵀ P)``
    against ``max(|v_i|, |(M⁻¹ b)_i|, 1e-9 (‖v‖_M + ‖M⁻¹b‖_M)/√M_ii)``, less the round-off
    floor of that reconstruction, ``16 ε √(M⁻¹)_ii Σ_j √(M⁻¹)_jj (|M||v| + |b| + |Gᵀ||P|)_j``
    (an impulse that stops a heavy motion leaves a residual that cancels large momenta;
    a chain of 24 links stopped flat on a floor is exact only to 3e-6 by this measure,
    the piston to 1e-13). When ``max |δ_i| / max(|v_i|, |(M⁻¹ b)_i|)`` is at most 1e-12,
    that bound of the measure is returned and the floor (O(n³)) is not computed. Every
    measure is invariant under a rescaling of any single coordinate (a change of units),
    so a light coordinate's velocity error is not hidden behind a heavy one's momentum.
    ``L`` is the Cholesky factor of M; Gv (>= k), GtP, r, d, x (n) are work arrays.
    """
    n = M.shape[0]
    for j in range(n):
        GtP[j] = 0.0
    for i in range(k):
        t = 0.0
        for j in range(n):
            t += G[i, j] * v[j]
            GtP[j] += G[i, j] * P[i]
        Gv[i] = t
    # the floor keeps vel² representable: a row whose Jacobian vanishes (a pendulum tip
    # touching a floor at the bottom of its swing) has every velocity scale 0, and
    # 1e-300² underflowed to 0 (a ZeroDivisionError in the complementarity residual)
    vel = 1e-150
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
    for i in range(n):
        t = -b[i] - GtP[i]
        for j in range(n):
            t += M[i, j] * v[j]
        r[i] = t
    cho_solve(L, r, d, n)
    cho_solve(L, b, x, n)
    out[0] = primal
    out[1] = dual
    out[2] = comp
    # a velocity error below 1e-12 of its scale needs no round-off floor (the check
    # passes whatever the floor): the O(n³) bound below is computed only above it
    raw = 0.0
    for i in range(n):
        sc = max(abs(v[i]), abs(x[i]), 1e-300)
        raw = max(raw, abs(d[i]) / sc)
    if raw <= 1e-12:
        out[3] = raw
        return
    ev = 0.0
    ex = 0.0
    for i in range(n):
        for j in range(n):
            ev += v[i] * M[i, j] * v[j]
            ex += x[i] * M[i, j] * x[j]
    energy = math.sqrt(max(ev, 0.0)) + math.sqrt(max(ex, 0.0))
    # round-off floor of δ: |M⁻¹| (|M||v| + |b| + |Gᵀ||P|) ε, with |M⁻¹_ij| <= √(M⁻¹_ii M⁻¹_jj)
    # (r cancels large momenta when an impulse stops a motion: the answer is then exact
    # to this floor, not better); √(M⁻¹)_jj = ‖L⁻¹ e_j‖ by forward substitution into y
    total = 0.0
    for j in range(n):
        nrm = 0.0
        for i in range(j, n):
            t = 1.0 if i == j else 0.0
            for l in range(j, i):
                t -= L[i, l] * y[l]
            y[i] = t / L[i, i]
            nrm += y[i] * y[i]
        sj = abs(b[j])
        for l in range(n):
            sj += abs(M[j, l] * v[l])
        for l in range(k):
            sj += abs(G[l, j] * P[l])
        r[j] = math.sqrt(nrm)  # r is free now: √(M⁻¹)_jj
        total += r[j] * sj
    stat = 0.0
    for i in range(n):
        sc = max(abs(v[i]), abs(x[i]), 1e-9 * energy / math.sqrt(M[i, i]), 1e-300)
        floor = 16.0 * 2.220446049250313e-16 * r[i] * total
        stat = max(stat, max(0.0, abs(d[i]) - floor) / sc)
    out[3] = stat


@_jit
def solve_one_step(M, L, b, G, c, P, v, k, method, tol, ws):
    """v, P of the one-step QP on the first k rows of G with the LCP solver ``method``
    (0: dual active set, 1: enumeration); returns its status. ``L`` = chol(M), ``ws``
    from :func:`workspace`."""
    n = M.shape[0]
    MinvGt = ws[0]  # row j: M⁻¹ G_jᵀ
    row = ws[13]
    for j in range(k):
        for i in range(n):
            row[i] = G[j, i]
        cho_solve(L, row, row, n)
        for i in range(n):
            MinvGt[j, i] = row[i]
    vfree = ws[1]
    cho_solve(L, b, vfree, n)
    W = ws[2]
    w = ws[3]
    scale = 1e-300
    for i in range(k):
        t = -c[i]
        for j in range(n):
            t += G[i, j] * vfree[j]
        w[i] = t
        scale = max(scale, abs(t), abs(c[i]))
    sym_product(G, MinvGt, W, k, n)  # W = G M⁻¹ Gᵀ, exactly symmetric
    if method == 0:
        status = lcp_dual_active_set(W, w, P, k, tol * scale, ws[4], ws[5], ws[6], ws[7], ws[8], ws[9], ws[10])
    else:
        status = lcp_enumerate(W, w, P, k, tol * scale, ws[4], ws[5], ws[7], ws[8], ws[9], ws[10])
    for i in range(n):
        t = vfree[i]
        for j in range(k):
            t += MinvGt[j, i] * P[j]
        v[i] = t
    if status == OK:
        # iterative refinement; repeated (twice at most) while the residual it corrected was
        # above the round-off of G v − c: nearly dependent active rows (cond(W_AA) ~ 1e12)
        # take two or three steps, a well-conditioned set none more
        applied, residual, scale = _refine(G, c, P, v, k, W, MinvGt, ws)
        for _ in range(2):
            if not applied or residual <= 64.0 * 2.220446049250313e-16 * scale:
                break
            applied, residual, scale = _refine(G, c, P, v, k, W, MinvGt, ws)
    return status


@_inline
def _refine(G, c, P, v, k, W, MinvGt, ws):
    """One step of iterative refinement on the rows with P > 0: v⁺ = v_free + M⁻¹GᵀP
    cancels large free velocities (an impulse that stops a driven joint), leaving G v⁺
    off its bound c by round-off of the large terms; correct P and v by the residual.
    Returns ``(applied, max |G_i v − c_i| before the correction, max (|c_i| + |G_i||v|))``
    over those rows; nothing is applied when the residual is already at the round-off
    of G v − c (64 ε of that scale)."""
    A = ws[5]
    rhs = ws[7]
    dP = ws[8]
    na = 0
    worst = 0.0
    scale = 0.0
    for i in range(k):
        if P[i] > 0.0:
            t = -c[i]
            s = abs(c[i])
            for j in range(v.shape[0]):
                t += G[i, j] * v[j]
                s += abs(G[i, j] * v[j])
            A[na] = i
            rhs[na] = -t
            na += 1
            worst = max(worst, abs(t))
            scale = max(scale, s)
    if na == 0 or worst <= 64.0 * 2.220446049250313e-16 * scale:  # nothing to refine
        return False, worst, scale
    if not _solve_active(W, A, na, rhs, dP, ws[9], ws[10]):
        return False, worst, scale
    for a in range(na):
        if P[A[a]] + dP[a] < 0.0:
            return False, worst, scale
    for a in range(na):
        P[A[a]] += dP[a]
        for j in range(v.shape[0]):
            v[j] += MinvGt[A[a], j] * dP[a]
    return True, worst, scale
