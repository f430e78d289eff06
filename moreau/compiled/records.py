"""The compiled loop's contact records after each velocity update: impulses and activity
summed up to the next record, the contact work, and the impact log (what
:class:`moreau.results.impacts.ImpactLog` keeps)."""

from moreau.compiled.friction import _friction_records
from moreau.compiled.layout import (  # the loop's layout
    A_WORK_C,
    C_CONTACT,
    C_NIMP,
    I_CROSS,
    I_FAST,
    I_FLIGHT,
    I_LOST,
    I_P,
    I_ROW,
    I_STEP,
    I_T,
    I_UA,
    I_UB,
    R_GAP,
    R_SHIFT,
)
from moreau.compiled.layout import part as _part
from moreau.contact.equality import eq_velocity
from moreau.core import kernels as _k


@_part
def _log_onsets(n, m, t, k, h, v, v_new, f, L, P, G, vfree, in_contact, gmax, fgap, rs, IMP, cnt, me, eqw):
    """Log the contact onsets of step k that are impacts: faster than the smooth forces
    alone would change the normal velocity, or after the gap opened beyond its flight gap
    (the rule of :class:`moreau.results.impacts.ImpactLog`). With bilateral rows the free
    velocity is the one with the joints held, ``L⁻ᵀ Q b_y`` of the step's reduced problem."""
    if eqw is not None and me > 0:
        eq_velocity(L, eqw.Q, eqw.by, vfree)
    else:
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
            lost = -0.5 * P[r] * (ua + ub + rs[r, R_SHIFT])  # the energy lost: see impact_law
            # the gap at q_k closed at the approach speed (second order in h for a smooth
            # approach; before t when q_k had crossed already)
            g0 = rs[r, R_GAP]
            cross = t + (max(-h, min(h, g0 / -ub)) if ub < 0.0 else 0.0)
            _log_if_impact(IMP, cnt, t, k, r, ub, ua, uf - ub, P[r], lost, gmax[r] > fgap[r], cross)


@_part
def _log_if_impact(IMP, cnt, t, k, r, ub, ua, du_smooth, P, lost, flight, cross):
    """Log row ``r``'s onset in step ``k`` (starting at ``t``; its gap crossed zero at
    ``cross``, estimated) if it is an impact: the normal velocity ``ub`` faster than the
    smooth forces alone change it in the step (``du_smooth``), or ``flight``, after the gap
    opened beyond its flight gap."""
    fast = -ub > abs(du_smooth)
    if not (fast or flight):
        return
    j = cnt[C_NIMP]
    IMP[j, I_T] = t
    IMP[j, I_STEP] = k
    IMP[j, I_ROW] = r
    IMP[j, I_UB] = ub
    IMP[j, I_UA] = ua
    IMP[j, I_P] = P
    IMP[j, I_LOST] = lost
    IMP[j, I_FLIGHT] = 1.0 if flight else 0.0
    IMP[j, I_CROSS] = cross
    IMP[j, I_FAST] = 1.0 if fast else 0.0
    cnt[C_NIMP] = j + 1


@_part
def _contact_records(n, m, t, k, h, contact, v, v_new, f, L, P, active, G, vfree, P_acc, act_acc, in_contact,
                     last_imp, gmax, fgap, rs, IMP, cnt, acc, friction, fr, me, eqw):
    """After the velocity update: impulses and activity summed up to the next record, the
    contact work, the impact log, and which rows are in contact now."""
    if not contact:
        for r in range(m):
            in_contact[r] = False
            active[r] = False
        return
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
    if fr is not None and friction:
        _friction_records(n, m, v, v_new, G, active, fr, acc)
    if onset:
        _log_onsets(n, m, t, k, h, v, v_new, f, L, P, G, vfree, in_contact, gmax, fgap, rs, IMP, cnt, me, eqw)
    for r in range(m):
        in_contact[r] = P[r] > 0.0
        if P[r] > 0.0:
            last_imp[r] = k
