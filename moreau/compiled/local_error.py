"""The local error of a step-doubling attempt (:mod:`moreau.compiled.adaptive`) and the
switching points it must resolve: from the one step of H and the two of H/2 taken from one
state, the kind of the step, its scaled error, and the error of a switch that no midpoint of
the three steps sees.

- ``_step_kind``: the attempt's kind and unseen switch; ``_kind``: smooth,
  persistent contact or switching (a row closes or opens, a closed row with friction
  sticks, slips or reverses, an impact); ``_tangential`` finds the persistent-contact
  steps that are as smooth as a free one (the rows held at rest);
- ``_error``: the scaled difference of the two answers;
- ``_crossing``: a barrier crossed inside the step, the impact a step late, as the state
  error it makes; ``_pull``: a closed row whose force falls through zero (or whose
  friction reaches the cone) in the last quarter of the step, likewise;
- ``_remembered``: the error that sizes the next smooth step, with a memory of the error
  constant; ``_at_floor``: an error that does not grow with H.

Each is a small part inlined into the loop's variant with step-size control (``layout.part``).
"""

from __future__ import annotations

import math

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import K_C0, K_C1, K_CB, K_HMAX, R_GAP
from moreau.compiled.layout import part as _part
from moreau.compiled.step import _free_acceleration

#: how many times its own error the remembered error constant may make a smooth step's
#: (:func:`_remembered`): the damped pendulum's error over tol stays within 0.29–0.87 for
#: tol = 1e-3 … 1e-8 (without memory 0.45 … 11.7)
MEMORY_CAP = 8.0


@_part
def _error(q, v, sn, rtol, c):
    """The scaled local error max |x_f − x_c| / (c (atol_i + rtol |x_f|)) of the fine answer
    (q, v) against the coarse one kept in ``sn`` (atol_i: ``sn.atol``, q's then v's)."""
    err = 0.0
    n = q.shape[0]
    for a, b, k in ((q, sn.qc, 0), (v, sn.vc, n)):
        for i in range(n):
            e = abs(a[i] - b[i]) / (c * (sn.atol[k + i] + rtol * abs(a[i])))
            if e > err or e != e:
                err = e if e == e else math.inf
    return err


@_part
def _at_floor(H, err, hmin, hl, el):
    """True when the error of a step of H accepted within the tolerance is a floor (the
    round-off of the step and of its contact solve), not the step's: at the smallest step,
    or not grown with H since the last accepted step (of hl, error el) as an error of
    order >= 1 would (H^2). Such a step is grown, not shrunk towards h_min for good."""
    return H <= hmin * (1.0 + 1e-9) or (hl > 0.0 and H > 1.5 * hl and err < el * math.sqrt(H / hl))


@_part
def _slip_of(r, active, P, fr):
    """Row r's slip at the end of the step just taken: ±1 the sign of its tangential impulse
    where it lies on the friction cone (|P_T| = mu P_N, the law check's test), else 0
    (sticking or open)."""
    pt, bound = fr.PT[r], fr.mu[r] * P[r]
    if active[r] and bound > 0.0 and abs(pt) >= (1.0 - 1e-9) * bound:
        return 1.0 if pt > 0.0 else -1.0
    return 0.0


@_part
def _slip(m, active, P, fr, out):
    """Each row's slip (:func:`_slip_of`) into ``out``; nothing without friction."""
    if fr is not None:
        for r in range(m):
            out[r] = _slip_of(r, active, P, fr)


@_part
def _kind(m, active, sn, nimp0, nimp, P, fr):
    """0 smooth, 1 persistent contact, 2 switching (see the module docstring), from the
    rows in contact at the start, the closed rows of the step before and of the three
    steps, the impacts logged and, with friction, the rows' slip (stick to slip or back, a
    reversal: the switching points of a closed row)."""
    closed, changed = False, nimp > nimp0
    for r in range(m):
        a = active[r]
        if a or sn.closed_c[r] or sn.closed_f[r] or sn.closed0[r] or sn.in_contact[r]:
            closed = True
        if a != sn.closed_c[r] or a != sn.closed_f[r] or a != sn.closed0[r]:
            changed = True
    if fr is not None:
        for r in range(m):
            s = _slip_of(r, active, P, fr)
            if s != sn.slip0[r] or s != sn.slip_c[r] or s != sn.slip_f[r]:
                changed = True
    return 2 if changed else (1 if closed else 0)


@_part
def _tangential(m, n, active, G, q, v, gq, sn):
    """True when the fine and the coarse answers differ along the closed rows only
    tangentially: G_r (v_f − v_c) and g_r(q_f) − g_r(q_c) zero to 1e-6 of |G_r| |x_f − x_c|
    for every closed row r (a row held at rest, as on a straight guide). The difference then
    has no part in the rows' normal directions (in the metric of M), the step is as smooth as
    a free one, and its extrapolation leaves the rows' gaps and normal velocities as they
    are; a contact that rebounds a little each step (a resting ball's e h g) does not pass."""
    dq, dv = 0.0, 0.0
    for i in range(n):
        dq += (q[i] - sn.qc[i]) ** 2
        dv += (v[i] - sn.vc[i]) ** 2
    dq, dv = math.sqrt(dq), math.sqrt(dv)
    for r in range(m):
        if active[r]:
            gn, u = 0.0, 0.0
            for i in range(n):
                gn += G[r, i] ** 2
                u += G[r, i] * (v[i] - sn.vc[i])
            gn = math.sqrt(gn)
            if abs(u) > 1e-6 * gn * dv or abs(gq[r] - sn.gc[r]) > 1e-6 * gn * dq:
                return False
    return True


@_part
def _response(model, Minv, work, row, sn):
    """M⁻¹ G_rowᵀ into ``sn.x`` (the velocity change of a unit impulse on the row), its
    largest component scaled by the velocities' tolerances, max |x_i| / atol_(n+i), and
    W = G_row M⁻¹ G_rowᵀ."""
    own, lw = work[0], work[2]
    G, x = own.G, sn.x
    n = x.shape[0]
    _free_acceleration(model.ints, model.pool, Minv, own.L, lw.gen, own.cm, own.sm, G[row], x)
    w, big = 0.0, 0.0
    for i in range(n):
        w += G[row, i] * x[i]
        big = max(big, abs(x[i]) / sn.atol[n + i])
    return big, w


@_part
def _excess(a1, a2, H):
    """The impulse a row's force (or its friction's margin) a(t), taken linear through
    a1 = a(t + H/4) and a2 = a(t + 3H/4) (impulses over H/2), would exert beyond its zero
    in the last quarter of the step: > 0 where a changes sign there, unseen by any
    midpoint of the three steps."""
    end = 1.5 * a2 - 0.5 * a1
    if a2 <= 0.0 or end >= 0.0:
        return 0.0
    d = 0.25 * H * (-end) / (a2 - end)  # the time from the zero to the step's end
    return 0.5 * (-end) / (0.5 * H) * d


@_part
def _pull(model, Minv, work, m, H, active, sn, fr):
    """The largest velocity change (over the velocities' tolerances) of the impulse a closed
    row would exert past a switching point inside the last quarter of the step: its contact
    force falling through zero (the row opens) or its friction force reaching mu times it (it
    slips). The step's midpoints do not see these points, so the three steps agree; the
    impulse through M⁻¹ Gᵀ is the error of taking the switch a step late (0 if none)."""
    P = work[0].P
    worst = 0.0
    for r in range(m):
        if not (active[r] and sn.closed_f[r] and sn.closed_c[r]):
            continue
        a, row = _excess(sn.p_f[r], P[r], H), r
        if fr is not None and fr.mu[r] > 0.0 and a == 0.0:
            mu = fr.mu[r]
            a, row = _excess(mu * sn.p_f[r] - abs(sn.pt_f[r]), mu * P[r] - abs(fr.PT[r]), H), fr.tangent_row[r]
        if a > 0.0:
            worst = max(worst, a * _response(model, Minv, work, row, sn)[0])
    return worst


@_part
def _least(atol, n):
    """The smallest of the velocities' tolerances, ``atol[n:]``."""
    least = math.inf
    for i in range(n, atol.shape[0]):
        least = min(least, atol[i])
    return least


@_part
def _crossing(model, user, Minv, work, m, sn, rs, end):
    """The state error (over the velocities' tolerances) of a barrier crossed inside the
    step: a row neither closed nor in contact at the start that ends the coarse and the fine steps a
    depth p deeper than at the start (gap ``sn.rs[r, R_GAP]``; the end gaps before drift
    control put the row back on its barrier, ``rs[:, end]``) has its impact late by
    p / |ġ|, and the impact's velocity jump, (1 + e) ġ M⁻¹ G_rᵀ / W_rr (W_rr = G_r M⁻¹ G_rᵀ),
    that long in the state makes p (1 + e) max_i |(M⁻¹ G_rᵀ)_i| / (atol_(n+i) W_rr) (0 if none),
    and the status of the evaluation of G, at the last step's midpoint (a user callable's,
    0 when it did not fail): a step that closes no row leaves the Jacobian of an earlier one
    (or, before the run's first contact, none) in ``work``."""
    worst, fresh = 0.0, False
    for r in range(m):
        if not (sn.in_contact[r] or sn.closed0[r]):
            p = min(-rs[r, end], -sn.gu[r]) - max(0.0, -sn.rs[r, R_GAP])
            if p > 0.0:
                if not fresh:
                    own = work[0]
                    status = ev.jacobian_apart(model.ints, model.bkind, model.boff, model.brow, model.bnrows,
                                               model.pool, user, own.qm, own.cm, own.sm, own.G)
                    if status != 0:
                        return worst, status
                    fresh = True
                big, w = _response(model, Minv, work, r, sn)
                worst = max(worst, p * (1.0 + model.e[r]) * big / w if w > 0.0 else p / _least(sn.atol, sn.q.shape[0]))
    return worst, 0


@_part
def _remembered(ctl, kind, order, err, H, t):
    """The error that sizes the next step: for a smooth step, not less than the largest error
    constant C = err / H^(order+1) of the smooth steps in the last one to two largest steps of
    time predicts (``ctl[K_C0]``, ``ctl[K_C1]``; a switching step forgets them). Where the error's
    leading term changes sign, the error alone lets the step grow, and the run's error, made
    at D H^(order+2) a step against an estimate C H^(order+1) = tol, sums ∫ D/C dt, which
    grows as log(1/tol) at each zero of C; the constant over a fixed time keeps it bounded.
    The memory makes the error at most ``MEMORY_CAP`` times the step's own: an error floor
    (round-off, H-independent) read as a constant would hold the step at the floor's H for the
    whole window (the e = 0 piston at tol = 2e-11: 670 000 steps for 50 000)."""
    if kind == 2:
        ctl[K_C0] = ctl[K_C1] = 0.0
        ctl[K_CB] = t + H
        return err
    if kind == 1:
        return err
    if t + H - ctl[K_CB] > ctl[K_HMAX]:  # a new window
        ctl[K_C1] = ctl[K_C0] if t + H - ctl[K_CB] <= 2.0 * ctl[K_HMAX] else 0.0
        ctl[K_C0] = 0.0
        ctl[K_CB] = t + H
    ctl[K_C0] = max(ctl[K_C0], err / H ** (order + 1))
    return max(err, min(MEMORY_CAP * err, max(ctl[K_C0], ctl[K_C1]) * H ** (order + 1)))


@_part
def _step_kind(model, user, Minv, work, m, n, H, q, v, gq, rs, end, sn, fr, nimp0, nimp):
    """The kind of the attempt (0 smooth, 1 persistent contact, 2 switching), the scaled
    error of a switch its midpoints do not see (:func:`_crossing`, :func:`_pull`) and the
    status of a user callable that failed there (0: none); a persistent-contact step whose
    rows are held at rest counts as smooth."""
    active = work[0].active
    kind = _kind(m, active, sn, nimp0, nimp, work[0].P, fr)
    unseen, status = _crossing(model, user, Minv, work, m, sn, rs, end)
    if status != 0:
        return kind, unseen, status
    if unseen > 0.0:
        kind = 2
    if kind == 1:  # (not with an impact: its impulse is no force to extrapolate)
        unseen = _pull(model, Minv, work, m, H, active, sn, fr)
        if unseen > 0.0:
            kind = 2
    if kind == 1 and _tangential(m, n, active, work[0].G, q, v, gq, sn):
        kind = 0
    return kind, unseen, 0
