"""Step-size control in the compiled loop: each step taken once with H and twice with H/2
(step doubling, Studer, Leine & Glocker, IJNME 76(11), 2008), compared, and accepted or
taken again with a smaller H.

The steps are the loop's own: ``moreau.compiled.loop._run_chunk`` given a controller state
and a snapshot runs each attempt's three steps through its one step, with the parts here
inlined (``_attempt_step`` before each step, ``_swap`` to save and restore its start,
``_after_step`` after each step), and judges the attempt in ``judge_attempt``,
called through its address: a run without step-size control compiles none of the judge,
and an attempt costs one call (a call of the whole loop per step would pass some
thousand words of arguments and check the arrays' overlaps: its cost is in
docs/performance.md). The comparison of the two answers x_c (one step of H) and x_f (two of H/2),
x = (q, v), gives the local error of x_f, scaled
componentwise as ``err = max |x_f − x_c| / (c (atol_i + rtol |x_f|))``, where c depends on
the kind of step:

- *smooth*: no row closed in any of the three steps and none in contact at the start, or
  the same rows closed in all three and held at rest (the two answers differ only
  tangentially to them: ``local_error._tangential``): c = 2^p − 1 for a scheme of order p
  (2; 1 for the midpoint step with velocity-dependent forces), and the step is extrapolated
  (Richardson): x = x_f + (x_f − x_c)/(2^p − 1), one order higher (not with bilateral rows:
  the extrapolated q would leave them);
- *persistent contact*: the same rows closed in all three, otherwise: c = 1, order 1;
- *switching*: a row closes or opens, a closed row with friction sticks, slips or reverses,
  or an impact is logged: c = 1, and x_f − x_c ~ (jump of v) H, so the step shrinks until
  the switching time is resolved to the tolerance. Two switches no midpoint of the three
  steps sees count as velocity error (over v's tolerances): a barrier crossed inside the step (its
  impact is a step late: ``local_error._crossing``) and a closed row's force falling through
  zero, or its friction reaching the cone, in the step's last quarter (``local_error._pull``).

An attempt with err <= 1 is accepted, and the next H is H · min(4, 0.9 err^(−1/(order+1)))
(a smooth step's err not below what the error constant of the last one to two largest
steps predicts, ``local_error._remembered``; at most ``K_HMAX``); a rejected one is taken
again with H · max(0.1, min(0.9, 0.9 err^(−1/(order+1)))). Below ``K_HMIN`` an attempt is accepted anyway and counted
(``C_FORCED``). An error that does not grow with H is a floor (the round-off of the step
and its contact solve), not the step's: a step accepted within the tolerance at ``K_HMIN``,
or grown by more than 1.5 since the last accepted one of the same kind (not switching)
while its error grew by less than the square root of that, is followed by one at least
twice as long (``_at_floor``), so that a floor just under the tolerance cannot hold the
step at ``K_HMIN`` for good. The state of a rejected attempt is restored from
``layout.Snapshot``; the work it did is kept in the counters of solves and velocity
updates.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from moreau.compiled.layout import (
    C_ACCEPTED,
    C_EOK,
    C_FAILKIND,
    C_FALLBACKS,
    C_FORCED,
    C_K,
    C_NIMP,
    C_REC,
    C_REJECTED,
    C_SOLVES,
    C_UPDATES,
    C_USER,
    DONE,
    DRIFT_NONE,
    F_H,
    F_T0,
    I_STEP,
    IMPACTS_FULL,
    K_EACC,
    K_END,
    K_H,
    K_HACC,
    K_HMAX,
    K_HMIN,
    K_KACC,
    K_RTOL,
    K_T,
    K_TOK,
    R_GAP,
    R_UNPROJECTED,
    RECORDS_FULL,
    S_DRIFT,
    S_JUDGE,
    S_JUDGE_KEY,
    S_MASS_READY,
    S_RECORD,
    S_STEP,
    SC_M,
    SC_ME,
    SC_MF,
    SC_N,
    SC_TRIG,
    SC_VELOCITY_DEPENDENT,
    STEP_MIDPOINT,
    STEP_ON,
    USER_FAILED,
    Snapshot,
)
from moreau.compiled.layout import call as _call
from moreau.compiled.layout import part as _part
from moreau.compiled.local_error import _at_floor, _error, _remembered, _slip, _step_kind
from moreau.compiled.native import address_and_key, call_checked
from moreau.compiled.variants import variant_of
from moreau.core import kernels as _k
from moreau.core.jitcache import compile_lock

log = logging.getLogger(__name__)

# the variants whose judge this process has loaded: later runs take no file lock (a set's
# add is atomic; a race only takes the lock once more)
_judged: set[str] = set()

#: what ``judge_attempt`` returns when a user callable failed (the status in ``cnt[C_USER]``)
JUDGE_FAILED = -2

# the counters a rejected attempt keeps: the work it did
_KEPT = (C_SOLVES, C_FALLBACKS, C_UPDATES, C_ACCEPTED, C_REJECTED, C_FORCED)


def snapshot(n: int, m: int, mf: int, me: int) -> Snapshot:
    """The arrays of a ``layout.Snapshot`` for n coordinates, m rows (mf tangent
    rows, me bilateral rows); allocated once per run."""
    from moreau.compiled.layout import N_ACCUMULATORS, N_COUNTERS, N_ROWSTATE

    return Snapshot(np.empty(n), np.empty(n), np.zeros(m, dtype=np.bool_), np.zeros(m), np.zeros(m, dtype=np.bool_),
                    np.zeros(m, dtype=np.int64), np.zeros(m), np.zeros((m, N_ROWSTATE)), np.zeros((2, m)),
                    np.zeros(N_COUNTERS, dtype=np.int64), np.zeros(N_ACCUMULATORS), np.zeros(m if mf else 0),
                    np.zeros(me), np.empty(n), np.empty(n), np.zeros(m + mf + me), np.zeros(m, dtype=np.bool_),
                    np.zeros(m, dtype=np.bool_), np.zeros(m, dtype=np.bool_), np.full(m, np.nan),
                    np.zeros(m if mf else 0), np.zeros(m if mf else 0), np.zeros(m if mf else 0), np.zeros(m),
                    np.zeros(m if mf else 0), np.zeros(n), np.zeros(m), np.zeros(2 * n))


@_part
def _copy(save, a, b):
    """``a`` into ``b`` (``save``) or ``b`` into ``a``, element by element (1-D)."""
    for i in range(a.shape[0]):
        if save:
            b[i] = a[i]
        else:
            a[i] = b[i]


@_part
def _copy2(save, a, b):
    """As :func:`_copy`, for 2-D arrays."""
    for i in range(a.shape[0]):
        _copy(save, a[i], b[i])


@_part
def _swap(save, q, v, in_contact, P_acc, act_acc, last_imp, gmax, rs, pen, cnt, acc, fr, eqw, sn):
    """Copy the run state into the snapshot ``sn`` (``save``) or back from it; the counters
    of the work done (``_KEPT``) are not restored."""
    for a, b in ((q, sn.q), (v, sn.v), (P_acc, sn.P_acc), (gmax, sn.gmax), (acc, sn.acc)):
        _copy(save, a, b)
    for a, b in ((in_contact, sn.in_contact), (act_acc, sn.act_acc)):
        _copy(save, a, b)
    _copy(save, last_imp, sn.last_imp)
    _copy2(save, rs, sn.rs)
    _copy2(save, pen, sn.pen)
    if not save:
        for c in _KEPT:
            sn.cnt[c] = cnt[c]
    _copy(save, cnt, sn.cnt)
    if fr is not None:
        _copy(save, fr.PT_acc, sn.PT_acc)
    if eqw is not None:
        _copy(save, eqw.PE_acc, sn.PE_acc)


@_part
def _attempt_step(phase, H, last, ctl, sn, k_end, fset, active, T, IMP, m, q, v, in_contact, P_acc, act_acc,
                  last_imp, gmax, rs, pen, cnt, acc, fr, eqw):
    """Before step ``phase`` of an attempt: (``STEP_ON``, H, whether it ends the run). Before
    the step of H (phase 0) an attempt begins: its closed rows and start kept in ``sn`` and
    the step of H set in ``fset``; or (status, 0, False) when the chunk ends (DONE:
    ``cnt[C_ACCEPTED] == k_end`` or the end time reached; ``RECORDS_FULL``,
    ``IMPACTS_FULL``: grow the buffers and call again, nothing lost). Before the first step
    of H/2 the start is restored. (One call site of ``_swap``: its copies are compiled once.)"""
    if phase == 0:
        t, H, t_end = ctl[K_T], ctl[K_H], ctl[K_END]
        if cnt[C_ACCEPTED] >= k_end or t >= t_end:
            return DONE, 0.0, False
        if cnt[C_REC] + 1 >= T.shape[0]:
            return RECORDS_FULL, 0.0, False
        if cnt[C_NIMP] + 3 * m > IMP.shape[0]:  # room for three steps' impacts: an attempt is never cut
            return IMPACTS_FULL, 0.0, False
        last = H >= (t_end - t) * (1.0 - 1e-9)  # the end, not a sliver of a step after it
        if last:
            H = t_end - t
        for r in range(m):
            sn.closed0[r] = active[r]
        fset[F_H] = H  # one step of H
        fset[F_T0] = t - cnt[C_K] * H
    if phase <= 1:
        _swap(phase == 0, q, v, in_contact, P_acc, act_acc, last_imp, gmax, rs, pen, cnt, acc, fr, eqw, sn)
    return STEP_ON, H, last


@_part
def _after_step(phase, H, last, model, user, iset, fset, Minv, work, q, v, in_contact, P_acc, act_acc, last_imp, gmax,
                rs, pen, cnt, acc, fr, eqw, IMP, ctl, sn):
    """After step ``phase`` of an attempt (0 the step of H, 1 and 2 the two of H/2): the
    next phase, and 1 when the state is to be recorded (else 0; ``native.MISMATCH``: the
    judge's address was made for other types). After the step of H its end is kept (the
    loop then restores the start), after the first of H/2 its closed rows, slips and
    impulses are kept, after the second ``judge_attempt`` accepts or rejects the attempt."""
    ints = model.ints
    n, m = ints[SC_N], ints[SC_M]
    own = work[0]
    active, gq = own.active, own.gq
    end = R_UNPROJECTED if iset[S_DRIFT] != DRIFT_NONE else R_GAP  # the end gaps' column before drift control
    t, k0 = ctl[K_T], sn.cnt[C_K]  # (sn.cnt keeps the start's step, impacts and energy check)
    if phase == 0:
        iset[S_MASS_READY] = 1  # a constant M and its factor are formed: not again per call
        for i in range(n):
            sn.qc[i] = q[i]
            sn.vc[i] = v[i]
        for r in range(m + ints[SC_MF] + ints[SC_ME]):
            sn.gc[r] = gq[r]
        for r in range(m):
            sn.closed_c[r] = active[r]
            sn.gu[r] = rs[r, end]
        _slip(m, active, own.P, fr, sn.slip_c)
        fset[F_H] = 0.5 * H  # two steps of H/2
        fset[F_T0] = t - k0 * 0.5 * H
        return 1, np.int64(0)
    if phase == 1:
        for r in range(m):
            sn.closed_f[r] = active[r]
        _slip(m, active, own.P, fr, sn.slip_f)
        _copy(True, own.P, sn.p_f)
        if fr is not None:
            _copy(True, fr.PT, sn.pt_f)
        return 2, np.int64(0)
    # the attempt judged in its own compiled function, called through its address (S_JUDGE): only
    # a run with step-size control compiles it, and the loop's compile holds none of it
    return 0, call_checked(iset[S_JUDGE], iset[S_JUDGE_KEY], (H, last, model, user, iset, Minv, work, q, v,
                                                              in_contact, P_acc, act_acc, last_imp, gmax, rs, pen, cnt,
                                                              acc, fr, eqw, IMP, ctl, sn))


@_call
def judge_attempt(H, last, model, user, iset, Minv, work, q, v, in_contact, P_acc, act_acc, last_imp, gmax, rs, pen,
                  cnt, acc, fr, eqw, IMP, ctl, sn):
    """The attempt of step ``H`` after its second step of H/2: accepted (extrapolated where
    smooth; 1 when the state is to be recorded, else 0) or rejected (the start restored, 0),
    and the next H chosen (``ctl[K_H]``)."""
    ints = model.ints
    n, m = ints[SC_N], ints[SC_M]
    own = work[0]
    active, gq = own.active, own.gq
    end = R_UNPROJECTED if iset[S_DRIFT] != DRIFT_NONE else R_GAP  # the end gaps' column before drift control
    t = ctl[K_T]
    nimp0, eok0, mg = sn.cnt[C_NIMP], sn.cnt[C_EOK], m + ints[SC_MF] + ints[SC_ME]
    p = 1 if iset[S_STEP] == STEP_MIDPOINT and ints[SC_VELOCITY_DEPENDENT] != 0 else 2
    kind, unseen, status = _step_kind(model, user, Minv, work, m, n, H, q, v, gq, rs, end, sn, fr, nimp0,
                                      cnt[C_NIMP])
    c = (2.0 ** p - 1.0) if kind == 0 else 1.0
    order = p if kind == 0 else (1 if kind == 1 else 0)
    err = max(_error(q, v, sn, ctl[K_RTOL], c), unseen)
    hmax, hmin = ctl[K_HMAX], ctl[K_HMIN]
    if status != 0 or (err > 1.0 and 0.5 * H > hmin):  # back to the start (one copy of _swap's code)
        _swap(False, q, v, in_contact, P_acc, act_acc, last_imp, gmax, rs, pen, cnt, acc, fr, eqw, sn)
        for r in range(m):
            active[r] = sn.closed0[r]
        if status != 0:  # a user's Jacobian failed at the step's midpoint: the run stops here, naming it
            cnt[C_FAILKIND], cnt[C_USER] = USER_FAILED, status
            return JUDGE_FAILED
        cnt[C_REJECTED] += 1  # rejected: a smaller step
        ctl[K_H] = max(hmin, H * max(0.1, min(0.9, 0.9 * err ** (-1.0 / (order + 1)))))
        return np.int64(0)
    if err > 1.0:
        cnt[C_FORCED] += 1
    _slip(m, active, own.P, fr, sn.slip0)
    # Richardson: one order more (the gaps alike, to second order in the change); not
    # with bilateral rows, whose g_E(q) = 0 the extrapolated q would leave
    if kind == 0 and ints[SC_ME] == 0:
        for i in range(n):
            q[i] += (q[i] - sn.qc[i]) / c
            v[i] += (v[i] - sn.vc[i]) / c
        for r in range(mg):
            gq[r] += (gq[r] - sn.gc[r]) / c
        for r in range(m):
            rs[r, R_GAP] = gq[r]
        if ints[SC_TRIG]:  # cos q, sin q of the extrapolated q (the record's energies)
            _k.trig(q, own.cq, own.sq)
    for j in range(nimp0, cnt[C_NIMP]):  # the log's step: the accepted step's index
        IMP[j, I_STEP] = cnt[C_ACCEPTED]
    for r in range(m):
        if pen[0, r] > sn.pen[0, r]:
            sn.pen_t[r] = t + H
    if cnt[C_EOK] != eok0:
        ctl[K_TOK] = t
    cnt[C_ACCEPTED] += 1
    ctl[K_T] = ctl[K_END] if last else t + H
    e = _remembered(ctl, kind, order, err, H, t)
    grow = 4.0 if e == 0.0 else min(4.0, 0.9 * e ** (-1.0 / (order + 1)))
    same = kind != 2 and ctl[K_KACC] == kind  # (errors of one kind scale alike with H)
    if err <= 1.0 and _at_floor(H, err, hmin, ctl[K_HACC] if same else 0.0, ctl[K_EACC]):
        grow = max(grow, 2.0)
    ctl[K_HACC], ctl[K_EACC], ctl[K_KACC] = H, err, kind
    ctl[K_H] = min(hmax, max(hmin, H * max(grow, 0.1)))
    return np.int64(1) if cnt[C_ACCEPTED] % iset[S_RECORD] == 0 or last else np.int64(0)


def judge_address(model: tuple, user: np.ndarray, settings, state, records, tally, work: tuple, control: np.ndarray,
                  snap: Snapshot) -> tuple[int, int]:
    """The address of ``judge_attempt``'s machine code for a run's arrays (those of
    :func:`moreau.compiled.loop.run_chunk`) and the key of its argument types, as
    ``_after_step`` calls it (the ``S_JUDGE`` settings): loaded, or compiled (once per
    machine, by one process at a time; logged) when the run is the first with step-size
    control for its variant of the loop."""
    st = state
    args = (0.0, False, model, user, settings.iset, settings.Minv, work[:3], st.q, st.v, st.in_contact, st.P_acc,
            st.act_acc, st.last_imp, st.gmax, st.rs, st.pen, tally.cnt, tally.acc, work[3], work[4], records.IMP,
            control, snap)
    variant = variant_of(work)
    if variant in _judged:
        return address_and_key(judge_attempt, args)
    known, t0 = len(judge_attempt.overloads), time.perf_counter()
    with compile_lock(".judge." + variant):
        found = address_and_key(judge_attempt, args)
    _judged.add(variant)
    if len(judge_attempt.overloads) > known and time.perf_counter() - t0 > 2.0:  # compiled, not loaded
        log.info("moreau: step-size control compiled in %.0f s, once for this machine", time.perf_counter() - t0)
    return found
