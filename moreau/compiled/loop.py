"""The compiled time loop: Moreau–Jean midpoint steps, contact solves, drift control,
recording, impact log and run statistics, all in machine code.

:func:`run_chunk` advances a run from step ``k`` to ``k_end`` (or until the impact
buffer is full, a solve fails or the state breaks) and returns a status code; the
Python driver (:mod:`moreau.compiled.runner`) calls it chunk after chunk, advancing the
progress bar and honouring Ctrl-C between chunks, and turns the codes into the
documented exceptions. The step is the one of :class:`moreau.MoreauJeanMidpoint` (and,
with ``STEP_THETA``, of :class:`moreau.MoreauJeanPredictorCorrector`, with ``STEP_ENERGY`` of
:class:`moreau.MoreauJeanEnergyConsistent`), evaluated with the same kernels.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

from moreau.compiled import evaluate as ev
from moreau.compiled.adaptive import JUDGE_FAILED, _after_step, _attempt_step, snapshot
from moreau.compiled.bilateral import _eq_hold, _eq_project_velocity, _eq_records
from moreau.compiled.drift import _project
from moreau.compiled.energy import _energy_check, _kinetic_energy, _step_work
from moreau.compiled.implicit import end_of_pass, energy_start, pass_forces, velocity_passes
from moreau.compiled.layout import (  # the loop's layout
    A_WORK_E,
    A_WORK_EV,
    C_FAILKIND,
    C_K,
    C_NIMP,
    C_PROJ,
    C_REC,
    C_UPDATES,
    DONE,
    DRIFT_COMBINED,
    DRIFT_NONE,
    F_H,
    F_PE0,
    F_T0,
    IMPACTS_FULL,
    K_T,
    NATIVE_MISMATCH,
    NONFINITE,
    NONFINITE_GAP,
    NOT_CONVERGED,
    NOT_SPD,
    R_BOUNCED,
    R_DELAY,
    R_GAP,
    R_UNPROJECTED,
    S_DRIFT,
    S_ECHECK,
    S_ENERGY,
    S_LOCATE,
    S_MASS_READY,
    S_NSTEPS,
    S_STRIDE,
    SC_HAS_BIAS,
    SC_M,
    SC_MASS_KIND,
    SC_MASS_OFF,
    SC_ME,
    SC_MF,
    SC_N,
    SC_TRIG,
    STEP_ON,
    USER_FAILED,
    Records,
    RunState,
    Settings,
    Snapshot,
    Tally,
    chunk_arguments,
)
from moreau.compiled.layout import part as _part
from moreau.compiled.records import _contact_records
from moreau.compiled.step import _user_failed, _velocity_update
from moreau.core import kernels as _k


@_part
def _midpoint_model(model, user, t, h, const_mass, q, v, qm, cm, sm, M, L, gen, f, fb, ec, gm, cnt):
    """The midpoint q_m = q + h/2 v and the model there: M(q_m) factorized (unless
    constant; a chain's only as the O(n) generators ``gen`` of its factor, M and L are
    formed by the velocity update when a row closes), f(t + h/2, q_m, v) (a step with
    later passes, ``ec`` not None: its part that does not depend on v also into ``ec.fq``) and
    the gaps g(q_m); returns DONE or why not."""
    ints, ekind, eoff, bkind, boff, brow, bnrows, pool = (model.ints, model.ekind, model.eoff, model.bkind,
                                                          model.boff, model.brow, model.bnrows, model.pool)
    n, m = ints[SC_N], ints[SC_M]
    for i in range(n):
        qm[i] = q[i] + 0.5 * h * v[i]
    if ints[SC_TRIG]:
        _k.trig(qm, cm, sm)
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN:
        if _k.chain_generators(pool, ints[SC_MASS_OFF], cm, sm, gen) >= 0:
            return NOT_SPD
    elif not const_mass:
        if _user_failed(ev.mass(ints, pool, user, qm, cm, sm, M), cnt):
            return USER_FAILED
        if _k.symmetry_defect(M) > 1e-10:
            return NOT_SPD
        if _k.cholesky(M, L, n) >= 0:
            return NOT_SPD
    if _user_failed(ev.force(ints, ekind, eoff, pool, user, t + 0.5 * h, qm, cm, sm, v, f, fb), cnt):
        return USER_FAILED
    if ec is not None:
        ev.position_forces(ints, ekind, eoff, pool, t + 0.5 * h, qm, cm, sm, v, ec.fq)
    if m > 0:
        if _user_failed(ev.gaps(ints, bkind, boff, brow, bnrows, pool, user, qm, cm, sm, gm), cnt):
            return USER_FAILED
        s = 0.0
        for r in range(m):
            s += gm[r]
        if not math.isfinite(s):
            return NONFINITE_GAP
    return DONE


@_part
def _end_position(n, m, h, contact, iset, qm, v_new, L, P, G, rs, vbar, vfree, q_new):
    """q⁺ = q_m + h/2 v⁺; with located impacts, the impulses of the rows that bounced act
    at their instants s, not at the midpoint: q⁺ += M⁻¹ Σ (h/2 − s_r) G_rᵀ P_r (see
    MoreauJeanMidpoint._impulse_timing). Returns False when q⁺ or v⁺ is not finite."""
    for i in range(n):
        q_new[i] = qm[i] + 0.5 * h * v_new[i]
    if contact and iset[S_DRIFT] == DRIFT_COMBINED and iset[S_LOCATE] == 1:
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
    s = 0.0
    for i in range(n):
        s += q_new[i] + v_new[i]
    return math.isfinite(s)


@_part
def _end_gaps(model, user, iset, fset, q_new, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw, rs,
              in_contact, pen, gmax, eqw, v_new, P_acc, act_acc, last_imp, onset):
    """The gaps at q⁺, drift control (v⁺ of the rows it held; a landing it catches logged with ``onset`` = (t, h,
    f, fgap, IMP)), the deepest penetration, each row's largest gap since its last contact; DONE or why not."""
    ints, bkind, boff, brow, bnrows, pool = model.ints, model.bkind, model.boff, model.brow, model.bnrows, model.pool
    m = ints[SC_M]
    if _user_failed(ev.gaps(ints, bkind, boff, brow, bnrows, pool, user, q_new, cq, sq, gq), cnt):
        return USER_FAILED
    if iset[S_DRIFT] != DRIFT_NONE:
        for r in range(m):  # (step-size control's crossing rule reads the depth before drift control)
            rs[r, R_UNPROJECTED] = gq[r]
        nproj = cnt[C_PROJ]
        if not _project(model, user, iset, fset, q_new, cq, sq, active, gq, M, L, cnt, acc,
                        fail, eligible, ws, lw, rs, in_contact, eqw, v_new, P_acc, act_acc, last_imp, gmax, onset):
            return cnt[C_FAILKIND]
        if eqw is not None and ints[SC_ME] > 0 and cnt[C_PROJ] > nproj:  # moved along the bilateral rows: restore
            status = _eq_hold(ints, bkind, boff, brow, bnrows, pool, model.atol, user, q_new, cq, sq, gq, lw.G, L,
                              eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.y, eqw.F, eqw.yv, eqw.cE, eqw.rank, cnt, acc)
            if status != DONE:
                return status
    for r in range(m):
        if -gq[r] > pen[0, r]:  # the deepest penetration, and the step that ends there
            pen[0, r] = -gq[r]
            pen[1, r] = cnt[C_K] + 1
        if in_contact[r]:
            gmax[r] = -math.inf
        elif gq[r] > gmax[r]:
            gmax[r] = gq[r]
        rs[r, R_GAP] = gq[r]
    return DONE


@_part
def _record(model, user, iset, fset, t, q, v, cq, sq, M, P_acc, act_acc, gq, T, Q, V, PS, ACT, GP, KE, PE, cnt,
            fr, PTS, eqw):
    """Record the state at time t (and the impulses and activity summed since the last
    record, the gaps and, when asked, the energies); returns DONE or USER_FAILED."""
    ints, ekind, eoff, pool = model.ints, model.ekind, model.eoff, model.pool
    n, m = ints[SC_N], ints[SC_M]
    rec = cnt[C_REC]
    T[rec] = t
    for i in range(n):
        Q[rec, i] = q[i]
        V[rec, i] = v[i]
    for r in range(m):
        PS[rec, r] = P_acc[r]
        ACT[rec, r] = act_acc[r]
        GP[rec, r] = gq[r]
        P_acc[r] = 0.0
        act_acc[r] = False
    if fr is not None and ints[SC_MF] > 0:
        for r in range(m):
            PTS[rec, r] = fr.PT_acc[r]
            fr.PT_acc[r] = 0.0
    if eqw is not None:  # bilateral rows: impulses and residuals after the contact rows
        m0 = m + ints[SC_MF]
        for j in range(ints[SC_ME]):
            PS[rec, m + j] = eqw.PE_acc[j]
            GP[rec, m + j] = gq[m0 + j]
            eqw.PE_acc[j] = 0.0
    if iset[S_ENERGY] == 1:
        status, ke = _kinetic_energy(model, user, q, v, cq, sq, M, cnt)
        if status != DONE:
            return status
        KE[rec] = ke
        PE[rec] = ev.potential(ints, ekind, eoff, pool, q, cq, sq) + fset[F_PE0]
    cnt[C_REC] = rec + 1
    return DONE


def run_chunk(model: tuple, user: np.ndarray, settings: Settings, state: RunState, records: Records, tally: Tally,
              work: tuple, k_end: int, control: np.ndarray | None = None, snap: Snapshot | None = None) -> int:
    """Advance the run to step ``k_end`` (see the module docstring); returns a status.

    ``state`` (``layout.RunState``; with the step ``cnt[C_K]``) is
    updated in place, so a chunk resumes where the previous one stopped; ``settings``,
    ``records`` and ``tally`` are the layout's named tuples of the same names. ``user`` (5,)
    holds the addresses of the scene's user slots (:mod:`moreau.compiled.usercalls`; zeros
    for a built-in scene); ``work`` comes from :func:`~moreau.compiled.variants.loop_workspace`: its None entries
    choose the loop compiled without friction, bilateral rows or later passes.

    One step: the model at the midpoint, the velocity update (twice with θ: a predictor
    pass with f(v_k), then f((v_k + v*)/2); the energy-consistent step's iterates until v⁺
    stops changing), the contact records, the end position, the gaps and drift control
    there, and a record every ``stride`` steps.

    With step-size control (:mod:`moreau.compiled.adaptive`): its state ``control`` (``layout.K_*``) and
    snapshot ``snap`` (``adaptive.snapshot``); ``k_end`` then counts accepted steps, and the run also stops
    at the end time. The same compiled loop runs both (a run without control passes empty arrays).
    """
    return _run_chunk(*chunk_arguments(model, user, settings, state, records, tally, work, k_end),
                      *control_arguments(control, snap))


def control_arguments(control: np.ndarray | None, snap: Snapshot | None) -> tuple[np.ndarray, Snapshot]:
    """The loop's last two arguments: step-size control's state and snapshot, or (no
    control) arrays of their types and no elements."""
    if control is None or snap is None:
        return _no_control()
    return control, snap


@functools.cache
def _no_control() -> tuple[np.ndarray, Snapshot]:
    """An empty control state and a snapshot of no rows, made once: the loop reads and writes
    them only when the state has elements, so every fixed-step run (any thread) shares them."""
    return np.zeros(0), snapshot(0, 0, 0, 0)


# Compiled without reference counting (numba's internal ``_nrt`` flag): every array it touches is owned by the
# caller and nothing is allocated, so the counts (an atomic increment and decrement per array per use, measured
# at two thirds of a contact step's time) would be pure overhead. User callables run in their own wrappers.
# Called from Python only: no C entry point is built.
@njit(cache=True, nogil=True, _nrt=False, no_cfunc_wrapper=True)  # type: ignore[call-overload]  # numba's flag
def _run_chunk(model, user, iset, fset, Minv, eligible, q, v, k_end, in_contact, P_acc, act_acc,
               T, Q, V, PS, ACT, GP, KE, PE, IMP, pen, cnt, acc, fail, last_imp, gmax, fgap, rs, work, PTS,
               fr, eqw, ec, ctl, sn):
    """The steps of :func:`run_chunk`, on the fields of its named tuples; ``fr``, ``eqw``,
    ``ec``: friction's, the bilateral rows' and the later passes' arrays, or None (their
    code pruned at compile time: one compiled variant per feature set); ``ctl``, ``sn``:
    step-size control's state and snapshot, empty without it."""
    ints, pool = model.ints, model.pool
    n, m = ints[SC_N], ints[SC_M]
    h, t0 = fset[F_H], fset[F_T0]
    stride, nsteps = iset[S_STRIDE], iset[S_NSTEPS]
    const_mass = ints[SC_MASS_KIND] == _k.MASS_CONST
    passes, iterate, correct = 1, False, False
    if ec is not None:
        passes, iterate, correct = velocity_passes(iset, ints)
    own, ws, lw = work
    me, friction = ints[SC_ME], ints[SC_MF] > 0
    M, L, cm, sm, cq, sq, qm, f, v_new, vbar, q_new, gm, gq, P, active, G, vfree, fb = own
    bias_work = iset[S_ECHECK] > 0 and ints[SC_HAS_BIAS] != 0
    if const_mass and iset[S_MASS_READY] == 0:
        if _user_failed(ev.mass_apart(ints, pool, user, q, cq, sq, M), cnt):
            return USER_FAILED
        if _k.cholesky(M, L, n) >= 0:
            return NOT_SPD
    cap = IMP.shape[0]
    controlled = ctl.shape[0] > 0
    phase, H, last = 0, 0.0, False  # step-size control: the attempt's step of H (0), its two of H/2 (1, 2)
    while True:
        if controlled:  # an attempt begun (its start saved), or its first step of H/2 (the start restored)
            status, H, last = _attempt_step(phase, H, last, ctl, sn, k_end, fset, own.active, T, IMP, m, q, v,
                                            in_contact, P_acc, act_acc, last_imp, gmax, rs, pen, cnt, acc, fr, eqw)
            if status != STEP_ON:
                return status
            h, t0 = fset[F_H], fset[F_T0]
        elif cnt[C_K] >= k_end:
            break
        if m > 0 and cnt[C_NIMP] + m > cap:
            return IMPACTS_FULL
        k = cnt[C_K]
        t = t0 + k * h
        nimp = cnt[C_NIMP]
        status = _midpoint_model(model, user, t, h, const_mass, q, v, qm, cm, sm, M, L, lw.gen, f, fb, ec, gm, cnt)
        if status != DONE:
            return status
        s0 = 0.0
        if ec is not None:
            status, s0 = energy_start(model, user, correct, q, v, cm, sm, M, ec, cnt)
            if status != DONE:
                return status
        # one call site of the velocity update, so the contact solve is compiled (inlined) once;
        # its later passes see the forces at (v_k + x)/2 for an iterate x (implicit.pass_forces)
        code, mixed, defer = 0, False, iterate and not friction and me == 0  # (implicit.end_of_pass)
        for npass in range(passes):
            if ec is not None and npass >= 1:
                status = pass_forces(model, user, npass, correct, t, h, q, v, qm, cm, sm, v_new, s0, M, ec, vbar,
                                     f, fb, cnt)
                if status != DONE:
                    return status
            code = _velocity_update(model, user, iset, fset, qm, cm, sm, M, L, Minv, f, v, gm, v_new, P,
                                    active, G, cnt, acc, fail, ws, lw, last_imp, rs, fr, eqw, npass >= 1, not defer)
            cnt[C_UPDATES] += 1
            if code < 0:
                return cnt[C_FAILKIND]
            if ec is not None and iterate and npass >= 1:
                done, defer, mixed = end_of_pass(n, m, code, defer, mixed, v_new, ec, M, L, active, lw, ws, fset, acc)
                if done:
                    break
                if npass == passes - 1:
                    return NOT_CONVERGED
        if eqw is not None and me > 0:
            acc[A_WORK_E] += _eq_records(n, m + ints[SC_MF], me, v, v_new, G, eqw.PE, eqw.PE_acc)
        _step_work(n, h, f, fb, v, v_new, bias_work, acc)
        _contact_records(n, m, t, k, h, code == 1, v, v_new, f, L, P, active, G, vfree, P_acc, act_acc,
                         in_contact, last_imp, gmax, fgap, rs, IMP, cnt, acc, friction, fr, me, eqw)
        if not _end_position(n, m, h, code == 1, iset, qm, v_new, L, P, G, rs, vbar, vfree, q_new):
            return NONFINITE
        # the energy check: every S_ECHECK steps, and after a step with a logged impact
        echeck = iset[S_ECHECK] > 0 and ((k + 1) % iset[S_ECHECK] == 0 or cnt[C_NIMP] > nimp)
        if ints[SC_TRIG] and (m > 0 or me > 0 or iset[S_ENERGY] == 1 or echeck):
            _k.trig(q_new, cq, sq)
        if eqw is not None and me > 0:  # positions held on the bilateral rows (before the contacts' drift control)
            status = _eq_hold(ints, model.bkind, model.boff, model.brow, model.bnrows, pool, model.atol, user, q_new,
                              cq, sq, gq, G, L, eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.y, eqw.F, eqw.yv, eqw.cE, eqw.rank,
                              cnt, acc)
            if status != DONE:
                return status
        if m > 0:
            status = _end_gaps(model, user, iset, fset, q_new, cq, sq, active, gq, M, L, cnt, acc, fail, eligible,
                               ws, lw, rs, in_contact, pen, gmax, eqw, v_new, P_acc, act_acc, last_imp,
                               (t, h, f, fgap, IMP))
            if status != DONE:
                return status
        if eqw is not None and me > 0:  # v onto the bilateral rows at q⁺ (work['constraint_projection'])
            w = _eq_project_velocity(ints, model.bkind, model.boff, model.brow, model.bnrows, pool, user, q_new, cq,
                                     sq, v_new, G, M, L, eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.y, eqw.yv, eqw.F, eqw.cE,
                                     eqw.S, code == 1, P, fr, cnt)
            if w != w:
                return cnt[C_FAILKIND]
            acc[A_WORK_EV] += w
        for i in range(n):  # element loops: a slice copy would allocate a temporary
            q[i] = q_new[i]
            v[i] = v_new[i]
        k += 1
        cnt[C_K] = k
        if echeck:
            status = _energy_check(model, user, iset, fset, k, q, v, cq, sq, M, cnt, acc, lw.q_warn, lw.v_warn)
            if status != DONE:
                return status
        record = k % stride == 0 or k == nsteps
        if controlled:  # the attempt's next step, or its end (accepted or rejected; 1: record it)
            phase, code = _after_step(phase, H, last, model, user, iset, fset, Minv, work, q, v, in_contact, P_acc,
                                      act_acc, last_imp, gmax, rs, pen, cnt, acc, fr, eqw, IMP, ctl, sn)
            h, t0 = fset[F_H], fset[F_T0]
            if code < 0:
                return USER_FAILED if code == JUDGE_FAILED else NATIVE_MISMATCH
            record = code == 1
        if record and _record(model, user, iset, fset, ctl[K_T] if controlled else t0 + k * h, q, v, cq, sq, M, P_acc,
                              act_acc, gq, T, Q, V, PS, ACT, GP, KE, PE, cnt, fr, PTS, eqw) != DONE:
            return USER_FAILED  # (with step-size control: at an accepted attempt's end)
    return DONE
