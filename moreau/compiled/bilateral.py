"""Bilateral rows in the compiled step: the velocity update in the null space of the
equality rows, their impulses and work, and the projection that holds positions on
g_E(q) = 0, with the kernels of
:mod:`moreau.contact.equality`. Called only by scenes with constraints (``ints[SC_ME] > 0``).

These parts are calls, compiled once each, not inlined into the loop: inlined (numba's IR
inlining, as the loop's other parts), they doubled the loop's own cold compile (59 s
against 33 s, 993 MB peak) and slowed the piston's step by about 5 % (more code in the
loop); as calls they cost a few tens of ns per step of a scene with constraints. They take
arrays, not the work tuple: a tuple typed at a call boundary costs compile time in the
caller."""

from __future__ import annotations

import numpy as np

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import (
    A_EQRES,
    C_EQROW,
    C_FAILKIND,
    C_USER,
    CONSTRAINTS_INCONSISTENT,
    CONSTRAINTS_NOT_HELD,
    DONE,
    SC_M,
    SC_ME,
    SC_MF,
    SC_N,
    SC_TRIG,
    USER_FAILED,
    EqualityWork,
)
from moreau.compiled.layout import call as _part  # calls from the loop, not inlined
from moreau.contact.equality import (
    MAX_HOLD_ITERATIONS,
    eq_basis,
    eq_free,
    eq_impulses,
    eq_particular,
    eq_project,
    eq_reduce_rows,
    eq_velocity,
)
from moreau.core import kernels as _k

__all__ = ["equality_work", "bilateral_parts"]



def equality_work(n: int, me: int, mc: int = 0) -> tuple:
    """The bilateral rows' work arrays (``layout.EqualityWork``); R, piv, cE and S (the rows
    of the velocity projection: the bilateral rows, then the tangent rows of the step's
    sticking contacts) have room for the me bilateral and mc more rows (numpy: allocating
    compiles nothing)."""
    k = max(me, 1)
    ks = me + mc if me else 1
    return EqualityWork(np.empty((n, n)), np.empty((n, ks)), np.zeros(ks, dtype=np.int64), np.empty(n),
                        np.zeros(n), np.empty(n), np.zeros(k), np.empty(n), np.eye(n), np.zeros(n), np.zeros(k),
                        np.zeros(ks), np.zeros(1, dtype=np.int64), np.empty((ks, n)))


@_part
def _eq_prepare(n, m0, me, L, G, v, b, Q, R, piv, x, y, by, cE, keep, cnt):
    """The basis of the bilateral rows (rows m0 .. m0+me of G at the midpoint), y₁ from
    ``c_E = −G_E v``, and ``b_y`` of the reduced problem (from ``b`` = M v + h f); returns
    the rank, or −1 when the rows are inconsistent (the row in ``cnt[C_EQROW]``)."""
    rank = eq_basis(L, G, m0, me, Q, R, piv, x)
    keep[0] = rank
    for j in range(me):
        t = 0.0
        for i in range(n):
            t -= G[m0 + j, i] * v[i]
        cE[j] = t
    bad = eq_particular(R, piv, rank, me, cE, y)
    if bad >= 0:
        cnt[C_EQROW] = bad
        cnt[C_FAILKIND] = CONSTRAINTS_INCONSISTENT
        return -1
    eq_free(L, Q, rank, b, y, by, x)
    return rank


@_part
def _eq_reduce(L, Q, y, x, rank, X, k0, k1, c):
    """Rows k0 .. k1 of X and their bounds c into the reduced problem
    (:func:`moreau.contact.equality.eq_reduce_rows`)."""
    eq_reduce_rows(L, Q, rank, X, k0, k1, c, y, x)


@_part
def _eq_finish(n, m, me, rank, M, L, b, G, P, v_new, Q, R, piv, x, PE, F, yv, friction, fr):
    """``v⁺ = L⁻ᵀ Q y`` (y: the reduced problem's answer, in ``v_new``) and the bilateral
    rows' impulses from ``G_Eᵀ P_E = M v⁺ − b − Gᵀ P − Tᵀ P_T`` (the contact rows' P per
    row; with ``friction``, the tangential impulses ``fr.PT`` per row on the rows
    ``fr.tangent_row``; ``fr`` None in a scene without friction)."""
    for i in range(n):
        yv[i] = v_new[i]
    eq_velocity(L, Q, yv, v_new)
    for i in range(n):
        t = -b[i]
        for j in range(n):
            t += M[i, j] * v_new[j]
        F[i] = t
    for r in range(m):
        if P[r] != 0.0:
            for i in range(n):
                F[i] -= P[r] * G[r, i]
        if fr is not None and friction and fr.PT[r] != 0.0:
            t = fr.tangent_row[r]
            for i in range(n):
                F[i] -= fr.PT[r] * G[t, i]
    eq_impulses(L, Q, R, piv, rank, me, F, PE, x)


@_part
def _eq_alone(n, m, m0, me, M, L, b, v, G, P, v_new, Q, R, piv, x, y, by, PE, F, yv, cE, keep, cnt, fr):
    """A step with bilateral rows and no contact row: v⁺ = L⁻ᵀ Q b_y; returns 0, or −1
    when the rows are inconsistent. ``fr``: the step's (unread here; passed so that
    :func:`_eq_finish` compiles once)."""
    rank = _eq_prepare(n, m0, me, L, G, v, b, Q, R, piv, x, y, by, cE, keep, cnt)
    if rank < 0:
        return -1
    for i in range(n):
        v_new[i] = by[i]
    _eq_finish(n, m, me, rank, M, L, b, G, P, v_new, Q, R, piv, x, PE, F, yv, rank < 0, fr)  # no friction
    return 0


@_part
def _eq_records(n, m0, me, v, v_new, G, PE, PE_acc):
    """The step's bilateral impulses into their sum since the last record; returns their
    work ½ P_Eᵀ G_E (v_k + v⁺) (0 up to round-off)."""
    w = 0.0
    for j in range(me):
        PE_acc[j] += PE[j]
        u = 0.0
        for i in range(n):
            u += G[m0 + j, i] * (v[i] + v_new[i])
        w += 0.5 * PE[j] * u
    return w


@_part
def _eq_hold(ints, bkind, boff, brow, bnrows, pool, tol, user, q, cq, sq, g, G, L, Q, R, piv, x, y, F, yv, cE, keep,
             cnt, acc):
    """q moved onto g_E(q) = 0 by Gauss–Newton steps in the metric of the step's M (as
    ``EqualityRows.hold``: the first with the step's basis at q_m, which leaves an error
    of O(h) times the correction, the next ones with the Jacobian at q); returns DONE,
    USER_FAILED or CONSTRAINTS_NOT_HELD (the row in ``cnt[C_EQROW]``). ``tol``: the
    lowered scene's activation_tol, whose rows m ... are the bilateral rows' tolerances."""
    n, m = ints[SC_N], ints[SC_M]
    m0 = m + ints[SC_MF]
    me = ints[SC_ME]
    rank = keep[0]  # the first correction with the step's basis (at q_m), then Newton's
    worst = 0.0
    bad = 0
    for it in range(MAX_HOLD_ITERATIONS + 1):
        st = ev.gaps(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, g)
        if st != 0:
            cnt[C_FAILKIND] = USER_FAILED
            cnt[C_USER] = st
            return USER_FAILED
        worst = 0.0
        for j in range(me):
            a = abs(g[m0 + j]) / tol[m + j]
            if not a <= worst:  # also NaN
                worst = a
                bad = j
        if worst <= 1.0 or it == MAX_HOLD_ITERATIONS:
            break
        if it > 0:
            st = ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, G)
            if st != 0:
                cnt[C_FAILKIND] = USER_FAILED
                cnt[C_USER] = st
                return USER_FAILED
            rank = eq_basis(L, G, m0, me, Q, R, piv, x)
        for j in range(me):
            cE[j] = -g[m0 + j]
        eq_particular(R, piv, rank, me, cE, y)  # redundant rows follow
        for i in range(n):
            yv[i] = y[i] if i < rank else 0.0
        eq_velocity(L, Q, yv, F)
        for i in range(n):
            q[i] += F[i]
        if ints[SC_TRIG]:
            _k.trig(q, cq, sq)
    if not worst <= 100.0:
        cnt[C_EQROW] = bad
        cnt[C_FAILKIND] = CONSTRAINTS_NOT_HELD
        return CONSTRAINTS_NOT_HELD
    for j in range(me):
        acc[A_EQRES] = max(acc[A_EQRES], abs(g[m0 + j]))
    return DONE


@_part
def _eq_project_velocity(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, v, G, M, L, Q, R, piv, x, y, yv, dv,
                         cE, S, contact, P, fr, cnt):
    """v projected onto ``G_E(q) v = 0`` in the metric of the step's M, keeping the slip
    of the step's sticking contacts at 0 (``contact``: a contact step; a row with
    ``P > 0``, ``mu > 0`` and ``|P_T| < mu P``: its tangent row is held; ``fr`` the friction
    arrays, None without friction), as
    ``EqualityRows.project_velocity`` (the same rows in the same order,
    :func:`moreau.contact.equality.eq_project`); returns the kinetic
    energy that removes (<= 0), or NaN when a user callable failed (the status in ``cnt``)."""
    n, m = ints[SC_N], ints[SC_M]
    m0 = m + ints[SC_MF]
    me = ints[SC_ME]
    st = ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, cq, sq, G)
    if st != 0:
        cnt[C_FAILKIND] = USER_FAILED
        cnt[C_USER] = st
        return np.nan
    for j in range(me):
        t = 0.0
        for i in range(n):
            S[j, i] = G[m0 + j, i]
            t -= G[m0 + j, i] * v[i]
        cE[j] = t
    k = me
    if fr is not None and contact and ints[SC_MF] > 0:
        mu, PT = fr.mu, fr.PT
        for r in range(m):
            if P[r] > 0.0 and mu[r] > 0.0 and abs(PT[r]) < mu[r] * P[r]:  # sticking: slip held at 0
                for i in range(n):
                    S[k, i] = G[fr.tangent_row[r], i]
                cE[k] = 0.0
                k += 1
    eq_project(L, S, k, me, cE, Q, R, piv, x, y, yv, dv)
    w = 0.0
    for i in range(n):
        t = 0.0
        for j in range(n):
            t += M[i, j] * (v[j] + 0.5 * dv[j])
        w += dv[i] * t
    for i in range(n):
        v[i] += dv[i]
    return w


@_part
def _eq_contact_rows(L, G, m0, me, Q, R, piv, x, y, keep, GA, na, cA):
    """Drift control's rows ``GA`` (na) and bounds ``cA`` written in the null space of the
    bilateral rows (rows m0 .. m0+me of G, at the current q; M = I there), as
    ``EqualityRows.project_contacts`` does. A call, not inlined: the QR inlined into the
    loop's drift control made its cold compile 110 s against 98 s (one run each)."""
    rank = eq_basis(L, G, m0, me, Q, R, piv, x)
    keep[0] = rank
    for i in range(L.shape[0]):
        y[i] = 0.0
    _eq_reduce(L, Q, y, x, rank, GA, np.int64(0), na, cA)  # not the literal 0 (compiled apart)


@_part
def _eq_back(L, Q, yv, dq):
    """dq = L⁻ᵀ Q dq: the reduced problem's answer back in coordinates (``yv`` is work)."""
    for i in range(L.shape[0]):
        yv[i] = dq[i]
    eq_velocity(L, Q, yv, dq)


bilateral_parts = (_eq_prepare, _eq_reduce, _eq_finish, _eq_alone, _eq_records, _eq_hold, _eq_project_velocity,
                   _eq_contact_rows, _eq_back)
