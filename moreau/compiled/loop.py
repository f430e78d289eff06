"""The compiled time loop: Moreau–Jean midpoint steps, contact solves, drift control,
recording, impact log and run statistics, all in machine code.

:func:`run_chunk` advances a run from step ``k`` to ``k_end`` (or until the impact
buffer is full, a solve fails or the state breaks) and returns a status code; the
Python driver (:mod:`moreau.compiled.runner`) calls it chunk after chunk, advancing the
progress bar and honouring Ctrl-C between chunks, and turns the codes into the
documented exceptions. The step is the one of :class:`moreau.MoreauJeanMidpoint` (and,
with ``THETA``, of :class:`moreau.MoreauJeanPredictorCorrector`), evaluated with the same kernels.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from moreau.compiled import evaluate as ev
from moreau.contact.lcp import kkt_residuals_kernel, solve_one_step, workspace
from moreau.core import kernels as _k

# status codes
DONE, IMPACTS_FULL, SOLVER_FAILED, NONFINITE, NOT_SPD, NONFINITE_GAP, USER_FAILED = 0, 1, 2, 3, 4, 5, 6
# settings (int array)
S_THETA, S_DRIFT, S_DRIFT_ITER, S_STRIDE, S_NSTEPS, S_METHOD, S_FALLBACK, S_ENERGY, S_MEMORY, S_LOCATE = range(10)
# drift control modes (S_DRIFT)
DRIFT_NONE, DRIFT_POSITION, DRIFT_COMBINED = 0, 1, 2
# per-row state of CombinedProjection (float array (m, 6)): gap at q_k, the gap where the
# projection last held the row, held (pinned), restitution applied in this step, and for
# a row that bounced at s into the step h/2 − s and (2 s − h) a_n (kernels.impact_law)
R_GAP, R_PINGAP, R_PINNED, R_BOUNCED, R_DELAY, R_SHIFT = range(6)
# impact-log columns
I_T, I_STEP, I_ROW, I_UB, I_UA, I_P, I_LOST, I_FLIGHT, I_FAST = range(9)
# settings (float array)
F_H, F_T0, F_TOL, F_DRIFT_TOL, F_PE0 = range(5)
# counters (int array)
# (C_USER: the status of a user callable that failed, see moreau.compiled.usercalls.decode)
C_REC, C_NIMP, C_SOLVES, C_FALLBACKS, C_CONTACT, C_PROJ, C_K, C_FAILKIND, C_USER = range(9)
N_COUNTERS = 9
# accumulators (float array)
A_WORST, A_WORK_F, A_WORK_C = range(3)

_jit = njit(cache=True, nogil=True)
# The step's parts are inlined into the loop by numba (IR level), as are the evaluation
# functions (moreau.compiled.evaluate); the kernels and LCP routines they call are inlined by LLVM
# (forceinline) and compiled once each. Measured (benchmarks/compile_cost.py, and the
# piston at e = 0.9 against the former build, best of 3-4 interleaved runs): numba
# inlining at every level compiled for 7-10 min in 10.8 GB; LLVM inlining at every level
# compiles in ~30 s but the step costs 8 % more; the kernels as plain calls 26 % more, and
# the parts too (their tuples of arrays passed at every call) 38 % more. No CPython or C
# entry points are built for what only the loop calls.
_part = njit(cache=True, nogil=True, _nrt=False, inline="always",  # type: ignore[call-overload]
             no_cpython_wrapper=True, no_cfunc_wrapper=True)


@_part
def _contact_solve(M, L, b, GA, cA, na, v_out, P_out, iset, fset, cnt, acc, fail, ws):
    """Main LCP method, KKT check, fallback; False when both fail (residuals in ``fail``)."""
    res = ws[16]
    tol = fset[F_TOL]
    # np.int64: numba would type the count as the literal 0 at one of the inlined call
    # sites and compile the solver and the check a second time
    k = np.int64(na)
    for attempt in range(2):
        method = iset[S_METHOD] if attempt == 0 else iset[S_FALLBACK]
        if method < 0:
            break
        if attempt == 1:
            cnt[C_FALLBACKS] += 1
        st = solve_one_step(M, L, b, GA, cA, P_out, v_out, k, method, 1e-12, ws)
        if st == 0:
            kkt_residuals_kernel(M, L, b, GA, cA, v_out, P_out, k, res, ws[11], ws[12], ws[13], ws[14], ws[15],
                                 ws[1])
            worst = max(res[0], res[1], res[2], res[3])
            if worst <= tol:
                if worst > acc[A_WORST]:
                    acc[A_WORST] = worst
                return True
            for i in range(4):
                fail[attempt, i] = res[i]
        else:
            for i in range(4):
                fail[attempt, i] = math.inf
    return False


@_part
def _free_acceleration(n, const_mass, Minv, L, f, out):
    """M⁻¹ f into ``out`` (with the inverse of a constant M, as the reference path)."""
    if const_mass:
        for i in range(n):
            t = 0.0
            for j in range(n):
                t += Minv[i, j] * f[j]
            out[i] = t
    else:
        _k.cho_solve(L, f, out, n)


@_part
def _velocity_update(model, user, iset, fset, qm, cm, sm, M, L, Minv, f, v, gm, v_new, P, active,
                     GA_all, cnt, acc, fail, ws, lw, last_imp, rs):
    """v⁺ with the contacts closed at qm (gaps ``gm``); returns 1 (contact), 0 (free) or
    −1 (failed: the solve, or a user callable; the status is in ``cnt[C_FAILKIND]``).
    ``P`` (m,) and ``active`` (m,) are set for the step.

    With combined drift control, a row's restitution acts only at an impact (see
    :class:`moreau.step.drift.CombinedProjection`): it approaches faster than the smooth forces
    change its normal velocity in one step, and it carried no impulse in the last
    ``S_MEMORY`` steps; other closed rows take e = 0 (a persistent contact). A row is
    then also closed when the projection holds it, or when it reaches the barrier by the
    end of the step (2 g(q_m) − g(q_k) <= 0; with ``S_LOCATE`` the free step's end gap,
    2 g(q_m) − g(q_k) + h²/2 G M⁻¹ f <= 0). Newton's law is :func:`moreau.core.kernels.impact_law`.
    ``rs`` (m, 6) holds per row the gap at q_k, the gap the projection left it at, the
    pinned and bounced flags, and a bounced row's h/2 − s and (2 s − h) a_n (columns
    ``R_GAP`` ... ``R_SHIFT``)."""
    ints, ekind, eoff, bkind, boff, brow, bnrows, pool, e, atol = model
    n, m = ints[0], ints[1]
    h = fset[F_H]
    combined = iset[S_DRIFT] == DRIFT_COMBINED
    locate = combined and iset[S_LOCATE] == 1
    rhs = lw[2]
    if locate:  # the free step's end gap, + h²/2 G M⁻¹ f, decides which rows close
        _free_acceleration(n, ints[2] == _k.MASS_CONST, Minv, L, f, rhs)
        if _user_failed(ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, qm, cm, sm, GA_all), cnt):
            return -1
    for r in range(m):
        active[r] = gm[r] <= atol[r]
        if combined:
            reach = 2.0 * gm[r] - rs[r, R_GAP]
            if locate:
                du = 0.0
                for i in range(n):
                    du += GA_all[r, i] * rhs[i]
                reach += 0.5 * h * h * du
            active[r] = active[r] or rs[r, R_PINNED] != 0.0 or reach <= 0.0
            rs[r, R_BOUNCED] = 0.0
            rs[r, R_DELAY] = 0.0
            rs[r, R_SHIFT] = 0.0
        P[r] = 0.0
    na = _count(active, m)
    if na == 0:
        if not locate:
            _free_acceleration(n, ints[2] == _k.MASS_CONST, Minv, L, f, rhs)
        for i in range(n):
            v_new[i] = v[i] + h * rhs[i]
        return 0
    if combined:
        if not locate:
            _free_acceleration(n, ints[2] == _k.MASS_CONST, Minv, L, f, rhs)
        k_now = cnt[C_K]
        memory = iset[S_MEMORY]
    cnt[C_SOLVES] += 1
    if not locate:
        if _user_failed(ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, qm, cm, sm, GA_all), cnt):
            return -1
    GA = lw[0]
    cA = lw[1]
    j = 0
    for r in range(m):
        if active[r]:
            u = 0.0
            for i in range(n):
                GA[j, i] = GA_all[r, i]
                u += GA_all[r, i] * v[i]
            er = e[r]
            c = -er * u
            if combined and er != 0.0:
                c = 0.0
                if k_now - last_imp[r] > memory:
                    du = 0.0
                    for i in range(n):
                        du += GA_all[r, i] * rhs[i]
                    cr, s_imp = _k.impact_law(er, u, du, rs[r, R_GAP], h, locate)
                    if cr == cr:  # an impact: Newton's law where it happens
                        rs[r, R_BOUNCED] = 1.0
                        rs[r, R_DELAY] = 0.5 * h - s_imp
                        rs[r, R_SHIFT] = (2.0 * s_imp - h) * du
                        c = cr
            cA[j] = c
            j += 1
    b = lw[3]
    for i in range(n):
        s = h * f[i]
        for l in range(n):
            s += M[i, l] * v[l]
        b[i] = s
    PA = lw[4]
    if not _contact_solve(M, L, b, GA, cA, na, v_new, PA, iset, fset, cnt, acc, fail, ws):
        cnt[C_FAILKIND] = SOLVER_FAILED
        return -1
    j = 0
    for r in range(m):
        if active[r]:
            P[r] = PA[j]
            j += 1
    return 1


@_part
def _project(model, user, iset, fset, q, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw, rs,
             in_contact):
    """Drift control: move q onto g >= 0 (see PositionProjection and CombinedProjection).

    The rows of the projection QP: with PositionProjection the eligible rows that
    penetrate or were closed; with CombinedProjection the persistent contacts of the
    step (closed, no restitution applied). Those held on g = 0 are marked pinned, and
    stay pinned while they carry an impulse without bouncing and their gap does not grow
    beyond where the projection left them."""
    ints, ekind, eoff, bkind, boff, brow, bnrows, pool, e, atol = model
    n, m = ints[0], ints[1]
    dtol = fset[F_DRIFT_TOL]
    combined = iset[S_DRIFT] == DRIFT_COMBINED
    sel = lw[8]
    need = False
    for r in range(m):
        if combined:
            if not (in_contact[r] and rs[r, R_BOUNCED] == 0.0 and gq[r] <= rs[r, R_PINGAP]):
                rs[r, R_PINNED] = 0.0
            sel[r] = active[r] and rs[r, R_BOUNCED] == 0.0
        else:
            sel[r] = eligible[r] and (gq[r] < 0.0 or active[r])
        if sel[r] and gq[r] < -dtol:
            need = True
    if not need:
        return True
    G = lw[5]
    dq = lw[6]
    zero = lw[7]
    for _ in range(iset[S_DRIFT_ITER]):
        if not combined:
            for r in range(m):
                sel[r] = eligible[r] and (gq[r] < 0.0 or active[r])
        na = _count(sel, m)
        if _user_failed(ev.mass(ints, pool, user, q, cq, sq, M), cnt):
            return False
        if _k.cholesky(M, L, n) >= 0:
            cnt[C_FAILKIND] = NOT_SPD
            return False
        if _user_failed(ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, G), cnt):
            return False
        GA = lw[0]
        cA = lw[1]
        j = 0
        for r in range(m):
            if sel[r]:
                for i in range(n):
                    GA[j, i] = G[r, i]
                cA[j] = -gq[r]
                j += 1
        PA = lw[4]
        if not _contact_solve(M, L, zero, GA, cA, na, dq, PA, iset, fset, cnt, acc, fail, ws):
            cnt[C_FAILKIND] = SOLVER_FAILED
            return False
        for i in range(n):
            q[i] += dq[i]
        if ints[8]:
            _k.trig(q, cq, sq)
        if _user_failed(ev.gaps(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, gq), cnt):
            return False
        if combined:
            j = 0
            for r in range(m):
                if sel[r]:
                    if PA[j] > 0.0:
                        rs[r, R_PINNED] = 1.0
                        rs[r, R_PINGAP] = max(gq[r], 0.0)
                    j += 1
        done = True
        for r in range(m):
            if not combined:
                sel[r] = eligible[r] and (gq[r] < 0.0 or active[r])
            if sel[r] and gq[r] < -dtol:
                done = False
        if done:
            break
    cnt[C_PROJ] += 1
    return True


@_part
def _user_failed(status, cnt):
    """True (and the status kept in ``cnt``) when a user callable failed."""
    if status == 0:
        return False
    cnt[C_FAILKIND] = USER_FAILED
    cnt[C_USER] = status
    return True


@_part
def _count(flags, m):
    """The number of True entries among the first m of ``flags``."""
    k = 0
    for r in range(m):
        if flags[r]:
            k += 1
    return k


@_jit
def loop_workspace(n, m):
    """The work arrays of :func:`run_chunk` for n coordinates and m rows (allocated once
    per run, outside the loop: the loop itself allocates nothing)."""
    mm = max(m, 1)
    own = (np.empty((n, n)), np.empty((n, n)), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n),
           np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(m), np.empty(m),
           np.zeros(m), np.zeros(m, dtype=np.bool_), np.empty((m, n)), np.empty(n))
    lw = (np.empty((mm, n)), np.empty(mm), np.empty(n), np.empty(n), np.empty(mm),
          np.empty((mm, n)), np.empty(n), np.zeros(n), np.zeros(mm, dtype=np.bool_))
    return own, workspace(n, m), lw


# Compiled without reference counting (numba's internal ``_nrt`` flag): every array it
# touches is owned by the caller and nothing is allocated, so the counts (an atomic
# increment and decrement per array per use, measured at two thirds of a contact step's
# time) would be pure overhead. User callables run in their own wrappers (usercalls).
@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # numba's internal flag
def run_chunk(model, user, iset, fset, Minv, eligible, q, v, k_end, in_contact, P_acc, act_acc,
              T, Q, V, PS, ACT, GP, KE, PE, IMP, pen, cnt, acc, fail, last_imp, gmax, fgap, rs, work):
    """Advance the run to step ``k_end`` (see the module docstring); returns a status.

    State (q, v, step ``cnt[C_K]``, contact flags, impulse accumulators, per row the
    step of its last impulse ``last_imp`` and its largest gap since then ``gmax``) is
    updated in place, so a chunk resumes where the previous one stopped. ``user`` (5,)
    holds the addresses of the scene's user slots (:mod:`moreau.compiled.usercalls`; zeros for a
    built-in scene). ``fgap`` (m,) is each row's flight gap: a contact onset after the
    gap exceeded it is an impact. ``rs`` (m, 6) is the per-row state of
    CombinedProjection (see ``_velocity_update``); ``work`` comes from
    :func:`loop_workspace`.
    """
    ints, ekind, eoff, bkind, boff, brow, bnrows, pool, e, atol = model
    n, m = ints[0], ints[1]
    h, t0 = fset[F_H], fset[F_T0]
    stride, nsteps = iset[S_STRIDE], iset[S_NSTEPS]
    theta = iset[S_THETA] == 1 and ints[7] == 1
    const_mass = ints[2] == _k.MASS_CONST
    own, ws, lw = work
    M, L, cm, sm, cq, sq, qm, f, v_new, vbar, q_new, gm, gq, P, active, G, vfree = own
    if const_mass:
        if _user_failed(ev.mass(ints, pool, user, q, cq, sq, M), cnt):
            return USER_FAILED
        if _k.cholesky(M, L, n) >= 0:
            return NOT_SPD
    cap = IMP.shape[0]
    while cnt[C_K] < k_end:
        if m > 0 and cnt[C_NIMP] + m > cap:
            return IMPACTS_FULL
        k = cnt[C_K]
        t = t0 + k * h
        for i in range(n):
            qm[i] = q[i] + 0.5 * h * v[i]
        if ints[8]:
            _k.trig(qm, cm, sm)
        if not const_mass:
            if _user_failed(ev.mass(ints, pool, user, qm, cm, sm, M), cnt):
                return USER_FAILED
            if ints[2] != _k.MASS_CHAIN and _k.symmetry_defect(M) > 1e-10:
                return NOT_SPD
            if _k.cholesky(M, L, n) >= 0:
                return NOT_SPD
        if _user_failed(ev.force(ints, ekind, eoff, pool, user, t + 0.5 * h, qm, cm, sm, v, f), cnt):
            return USER_FAILED
        if m > 0:
            if _user_failed(ev.gaps(ints, bkind, boff, brow, bnrows, pool, user, qm, cm, sm, gm), cnt):
                return USER_FAILED
            s = 0.0
            for r in range(m):
                s += gm[r]
            if not math.isfinite(s):
                return NONFINITE_GAP
        # θ: a predictor pass with f(v_k), then the step with f((v_k + v*)/2); one call
        # site, so the contact solve is compiled (inlined) once
        code = 0
        for npass in range(2 if theta else 1):
            if npass == 1:
                for i in range(n):
                    vbar[i] = 0.5 * (v[i] + v_new[i])
                if _user_failed(ev.force(ints, ekind, eoff, pool, user, t + 0.5 * h, qm, cm, sm, vbar, f), cnt):
                    return USER_FAILED
            code = _velocity_update(model, user, iset, fset, qm, cm, sm, M, L, Minv, f, v, gm, v_new, P,
                                    active, G, cnt, acc, fail, ws, lw, last_imp, rs)
            if code < 0:
                return cnt[C_FAILKIND]
        # smooth-force work of the step, h fᵀ (v + v⁺)/2
        wf = 0.0
        for i in range(n):
            wf += f[i] * (v[i] + v_new[i])
        acc[A_WORK_F] += 0.5 * h * wf
        if code == 1:
            cnt[C_CONTACT] += 1
            onset = False
            for r in range(m):
                if P[r] != 0.0:
                    P_acc[r] += P[r]
                if active[r]:
                    act_acc[r] = True
                    ub = 0.0
                    ua = 0.0
                    for i in range(n):
                        ub += G[r, i] * v[i]
                        ua += G[r, i] * v_new[i]
                    acc[A_WORK_C] += 0.5 * P[r] * (ub + ua)
                    if P[r] > 0.0 and not in_contact[r]:
                        onset = True
            if onset:
                _k.cho_solve(L, f, vfree, n)
                for i in range(n):
                    vfree[i] = v[i] + h * vfree[i]
                for r in range(m):
                    if P[r] > 0.0 and not in_contact[r]:
                        ub = 0.0
                        ua = 0.0
                        uf = 0.0
                        for i in range(n):
                            ub += G[r, i] * v[i]
                            ua += G[r, i] * v_new[i]
                            uf += G[r, i] * vfree[i]
                        fast = -ub > abs(uf - ub)  # faster than the smooth forces alone
                        flight = gmax[r] > fgap[r]  # after the gap opened by more than fgap
                        if fast or flight:
                            j = cnt[C_NIMP]
                            IMP[j, I_T] = t
                            IMP[j, I_STEP] = k
                            IMP[j, I_ROW] = r
                            IMP[j, I_UB] = ub
                            IMP[j, I_UA] = ua
                            IMP[j, I_P] = P[r]
                            IMP[j, I_LOST] = -0.5 * P[r] * (ua + ub + rs[r, R_SHIFT])  # (see impact_law)
                            IMP[j, I_FLIGHT] = 1.0 if flight else 0.0
                            IMP[j, I_FAST] = 1.0 if fast else 0.0
                            cnt[C_NIMP] = j + 1
            for r in range(m):
                in_contact[r] = P[r] > 0.0
                if P[r] > 0.0:
                    last_imp[r] = k
        else:
            for r in range(m):
                in_contact[r] = False
                active[r] = False
        s = 0.0
        for i in range(n):
            q_new[i] = qm[i] + 0.5 * h * v_new[i]
        if code == 1 and iset[S_DRIFT] == DRIFT_COMBINED and iset[S_LOCATE] == 1:
            # the impulses of the rows that bounced act at their instants s, not at the
            # midpoint: q⁺ += M⁻¹ Σ (h/2 − s_r) G_rᵀ P_r (see MoreauJeanMidpoint._impulse_timing)
            shifted = False
            for i in range(n):
                vbar[i] = 0.0
            for r in range(m):
                if rs[r, R_BOUNCED] != 0.0 and P[r] > 0.0:
                    shifted = True
                    for i in range(n):
                        vbar[i] += rs[r, R_DELAY] * P[r] * G[r, i]
            if shifted:
                _k.cho_solve(L, vbar, vfree, n)
                for i in range(n):
                    q_new[i] += vfree[i]
        for i in range(n):
            s += q_new[i] + v_new[i]
        if not math.isfinite(s):
            return NONFINITE
        if ints[8] and (m > 0 or iset[S_ENERGY] == 1):
            _k.trig(q_new, cq, sq)
        if m > 0:
            if _user_failed(ev.gaps(ints, bkind, boff, brow, bnrows, pool, user, q_new, cq, sq, gq), cnt):
                return USER_FAILED
            if iset[S_DRIFT] != DRIFT_NONE:
                if not _project(model, user, iset, fset, q_new, cq, sq, active, gq, M, L, cnt, acc,
                                fail, eligible, ws, lw, rs, in_contact):
                    return cnt[C_FAILKIND]
            for r in range(m):
                if -gq[r] > pen[r]:
                    pen[r] = -gq[r]
                if in_contact[r]:
                    gmax[r] = -math.inf
                elif gq[r] > gmax[r]:
                    gmax[r] = gq[r]
                rs[r, R_GAP] = gq[r]
        for i in range(n):  # element loops: a slice copy would allocate a temporary
            q[i] = q_new[i]
            v[i] = v_new[i]
        k += 1
        cnt[C_K] = k
        if k % stride == 0 or k == nsteps:
            rec = cnt[C_REC]
            T[rec] = t0 + k * h
            for i in range(n):
                Q[rec, i] = q[i]
                V[rec, i] = v[i]
            for r in range(m):
                PS[rec, r] = P_acc[r]
                ACT[rec, r] = act_acc[r]
                GP[rec, r] = gq[r]
                P_acc[r] = 0.0
                act_acc[r] = False
            if iset[S_ENERGY] == 1:
                if _user_failed(ev.mass(ints, pool, user, q, cq, sq, M), cnt):
                    return USER_FAILED
                ke = 0.0
                for i in range(n):
                    for l in range(n):
                        ke += v[i] * M[i, l] * v[l]
                KE[rec] = 0.5 * ke
                PE[rec] = ev.potential(ints, ekind, eoff, pool, q, cq, sq) + fset[F_PE0]
            cnt[C_REC] = rec + 1
    return DONE
