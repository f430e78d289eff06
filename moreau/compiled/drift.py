"""Drift control: the projection of the end position onto g >= 0, and of the velocity of
the rows it held onto G(q⁺) v >= 0 (:mod:`moreau.step.drift`: PositionProjection,
CombinedProjection)."""

from __future__ import annotations

import numpy as np

from moreau.compiled import evaluate as ev
from moreau.compiled.bilateral import _eq_back, _eq_contact_rows
from moreau.compiled.layout import (  # the loop's layout
    A_WORK_C,
    C_FAILKIND,
    C_K,
    C_PROJ,
    DRIFT_COMBINED,
    F_DRIFT_TOL,
    NATIVE_MISMATCH,
    NOT_SPD,
    PROJECTION_FAILED,
    R_BOUNCED,
    R_GAP,
    R_PINGAP,
    R_PINNED,
    R_UNPROJECTED,
    S_DRIFT,
    S_DRIFT_ITER,
    S_DRIFT_VELOCITY,
    S_PROJECT,
    S_PROJECT_KEY,
    SC_M,
    SC_MASS_OFF,
    SC_ME,
    SC_MF,
    SC_N,
    SC_TRIG,
)
from moreau.compiled.layout import call as _call
from moreau.compiled.layout import part as _part
from moreau.compiled.native import address_and_key, call_checked
from moreau.compiled.records import _log_if_impact
from moreau.compiled.step import _contact_solve, _user_failed
from moreau.core import kernels as _k


@_part
def _project(model, user, iset, fset, q, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw, rs,
             in_contact, eqw, v, P_acc, act_acc, last_imp, gmax, onset):
    """Drift control: move q onto g >= 0 (see PositionProjection and CombinedProjection).

    The rows of the projection QP: with PositionProjection the eligible rows that
    penetrate or were closed; with CombinedProjection the persistent contacts of the
    step (closed, no restitution applied). Those held on g = 0 are marked pinned, and
    stay pinned while they carry an impulse without bouncing and their gap does not grow
    beyond where the projection left them.

    With bilateral rows the QP is solved in their null space at q (``G_E dq = 0``,
    :mod:`moreau.contact.equality`; ``eqw`` their work arrays, None without them), as
    ``EqualityRows.project_contacts`` does: the contacts are projected along the
    constraints, and the hold after it restores them to second order."""
    m = model.ints[SC_M]
    dtol = fset[F_DRIFT_TOL]
    combined = iset[S_DRIFT] == DRIFT_COMBINED
    sel = lw.sel
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
    # through its address (S_PROJECT), so that the loop's compile neither compiles the projection
    # nor waits for it (the second process of a cold compile does it)
    done = call_checked(iset[S_PROJECT], iset[S_PROJECT_KEY], (model, user, iset, fset, q, cq, sq, active, gq,
                        M, L, cnt, acc, fail, eligible, ws, lw, in_contact, eqw, rs, combined, dtol, v, P_acc,
                        act_acc, last_imp, gmax, onset))
    if done < 0:
        cnt[C_FAILKIND] = NATIVE_MISMATCH
    return done == 1


def projection_address(model: tuple, user, settings, state, records, tally, work: tuple) -> tuple[int, int]:
    """The address of :func:`project_rows`'s machine code for a run's arrays (those of
    :func:`moreau.compiled.loop.run_chunk`, the plain variant's) and the key of its argument
    types, as :func:`_project` calls it (the ``S_PROJECT`` settings): loaded or compiled here."""
    own, ws, lw, fr, eqw, ec = work
    st = state
    return address_and_key(project_rows, (
        model, user, settings.iset, settings.fset, own.q_new, own.cq, own.sq, own.active, own.gq, own.M, own.L,
        tally.cnt, tally.acc, tally.fail, settings.eligible, ws, lw, st.in_contact, eqw, st.rs, True, 0.0, own.v_new,
        st.P_acc, st.act_acc, st.last_imp, st.gmax, (0.0, 0.0, own.f, settings.fgap, records.IMP)))


@_call
def project_rows(model, user, iset, fset, q, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw, in_contact,
                 eqw, rs, combined, dtol, v, P_acc, act_acc, last_imp, gmax, onset):
    """:func:`_project_rows` as the loop calls it, through its address (compiled once per
    variant, apart from the loop, its body inlined here): 1 when it held the rows, 0 when
    it failed."""
    held = _project_rows(model, user, iset, fset, q, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw,
                         in_contact, eqw, rs, combined, dtol, v, P_acc, act_acc, last_imp, gmax, onset)
    return np.int64(1) if held else np.int64(0)


@_part
def _project_rows(model, user, iset, fset, q, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw, in_contact,
                  eqw, rs, combined, dtol, v, P_acc, act_acc, last_imp, gmax, onset):
    """The projection itself, when a selected row penetrates beyond the tolerance: the body
    of :func:`project_rows`, which the loop calls through its address (it runs in few
    steps; its contact solve and model evaluations stay out of the loop's compile and
    module).

    With ``S_DRIFT_VELOCITY`` a last pass makes the velocity ``v`` of the rows the
    projection held (``lw.held``: a positive multiplier) admissible at the projected q:
    v ← argmin ‖v' − v‖_M subject to G_A(q) v' >= 0, an e = 0 impulse counted with the
    step's contact impulses and work, and in the impact log where it catches a landing
    (``gmax``, ``onset`` = (t, h, f, fgap, IMP): what the log's tests read). Frictionless
    scenes without bilateral rows (the drift control's ``eligible_rows`` checks). One call
    site of the contact solve serves both passes: each inlined copy costs the compile seconds."""
    ints, bkind, boff, brow, bnrows, pool = model.ints, model.bkind, model.boff, model.brow, model.bnrows, model.pool
    n, m = ints[SC_N], ints[SC_M]
    sel, held, G, GA, cA, PA = lw.sel, lw.held, lw.G, lw.GA, lw.cA, lw.PA
    dq = lw.dq
    npass = iset[S_DRIFT_ITER]
    for r in range(m):
        held[r] = False
    it = 0
    while True:
        last = it == npass  # the velocity pass
        if not (combined or last):
            for r in range(m):
                sel[r] = eligible[r] and (gq[r] < 0.0 or active[r])
        if _user_failed(ev.jacobian_apart(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, G), cnt):
            return False
        j = np.int64(0)  # np.int64: a literal 0 would compile its callees again
        for r in range(m):
            if held[r] if last else sel[r]:
                for i in range(n):
                    GA[j, i] = G[r, i]
                cA[j] = 0.0 if last else -gq[r]
                j += 1
        if last and not _approaching(GA, v, j, n):
            return True
        if _user_failed(ev.mass_apart(ints, pool, user, q, cq, sq, M), cnt):
            return False
        if ev.factor(ints, pool, M, cq, sq, L, lw.gen) >= 0:
            cnt[C_FAILKIND] = NOT_SPD
            return False
        rhs = lw.zero
        if last:  # the momentum M v
            rhs = lw.b
            for i in range(n):
                rhs[i] = 0.0
                for k in range(n):
                    rhs[i] += M[i, k] * v[k]
        Ms, Ls = M, L
        if eqw is not None and ints[SC_ME] > 0:  # the QP in the bilateral rows' null space (M = I there)
            _eq_contact_rows(L, G, m + ints[SC_MF], ints[SC_ME], eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.y, eqw.rank, GA,
                             j, cA)
            Ms, Ls = eqw.eye, eqw.eye
        if not _contact_solve(Ms, Ls, rhs, GA, cA, j, dq, PA, iset, fset, cnt, acc, fail, ws,
                              (pool, ints[SC_MASS_OFF], cq, sq, lw.gen)):
            cnt[C_FAILKIND] = PROJECTION_FAILED  # its rows: ``sel`` (lw.sel), the error message's
            if last:
                for r in range(m):
                    sel[r] = held[r]
            return False
        if last:
            _held_impulses(n, m, cnt, held, GA, PA, v, dq, P_acc, act_acc, in_contact, last_imp, acc, L, lw.b, gmax,
                           rs, onset)
            return True
        if eqw is not None and ints[SC_ME] > 0:
            _eq_back(L, eqw.Q, eqw.yv, dq)
        for i in range(n):
            q[i] += dq[i]
        if ints[SC_TRIG]:
            _k.trig(q, cq, sq)
        if _user_failed(ev.gaps_apart(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, gq), cnt):
            return False
        j = np.int64(0)
        for r in range(m):  # the rows it held (pushed out: a positive multiplier)
            if sel[r]:
                if PA[j] > 0.0:
                    held[r] = True
                    if combined:
                        rs[r, R_PINNED] = 1.0
                        rs[r, R_PINGAP] = max(gq[r], 0.0)
                j += 1
        done = True
        for r in range(m):
            if not combined:
                sel[r] = eligible[r] and (gq[r] < 0.0 or active[r])
            if sel[r] and gq[r] < -dtol:
                done = False
        it += 1
        if done or it == npass:
            cnt[C_PROJ] += 1
            if iset[S_DRIFT_VELOCITY] != 1:
                return True
            it = npass


@_part
def _approaching(GA, v, k, n):
    """True when one of the k rows of ``GA`` has a normal velocity G_j v < 0."""
    for j in range(k):
        u = 0.0
        for i in range(n):
            u += GA[j, i] * v[i]
        if u < 0.0:
            return True
    return False


@_part
def _held_impulses(n, m, cnt, held, GA, PA, v, v_new, P_acc, act_acc, in_contact, last_imp, acc, L, tmp, gmax, rs,
                   onset):
    """The velocity pass's impulses, counted with the step's (records, contact work, and an
    onset in the impact log for a row not in contact before: a landing the projection
    caught, by the step's rule (records._log_if_impact), with ``L`` the factor of M(q⁺)
    and ``tmp`` (n,) for M⁻¹ f; its crossing time between the gaps at q_k and at q⁺ before
    the projection, ``rs``), and its velocity ``v_new`` into ``v``."""
    t, h, f, fgap, IMP = onset
    k = cnt[C_K]
    solved = False
    j = 0
    for r in range(m):
        if held[r]:
            if PA[j] > 0.0:
                ub = 0.0
                ua = 0.0
                for i in range(n):
                    ub += GA[j, i] * v[i]
                    ua += GA[j, i] * v_new[i]
                acc[A_WORK_C] += 0.5 * PA[j] * (ub + ua)
                if not in_contact[r]:
                    if not solved:
                        _k.cho_solve(L, f, tmp, n)
                        solved = True
                    us = 0.0
                    for i in range(n):
                        us += GA[j, i] * tmp[i]
                    g0, g1 = rs[r, R_GAP], rs[r, R_UNPROJECTED]  # (linear between them)
                    cross = t + (h * g0 / (g0 - g1) if g0 > 0.0 and g1 < 0.0 else 0.0)
                    _log_if_impact(IMP, cnt, t, k, r, ub, ua, h * us, PA[j], -0.5 * PA[j] * (ua + ub),
                                   gmax[r] > fgap[r], cross)
                P_acc[r] += PA[j]
                act_acc[r] = True
                in_contact[r] = True
                last_imp[r] = k
            j += 1
    for i in range(n):
        v[i] = v_new[i]
