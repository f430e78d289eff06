"""The energy-consistent step's inertial correction
(:class:`moreau.step.integrator.MoreauJeanEnergyConsistent`; the loop iterates the velocity
update; these two parts add κ M_m Δq to the force of every iterate).

The two that evaluate M are calls, not inlined parts: they run once per iterate, evaluate M
at another configuration (their own copy of the mass evaluation), and keep that code out
of the loop's own optimization (see :mod:`moreau.compiled.layout`); the iterates'
bookkeeping is inlined.
"""

import numpy as np

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import (
    A_WORST,
    DONE,
    F_ITOL,
    F_TOL,
    S_ITER,
    S_STEP,
    SC_MASS_KIND,
    SC_MASS_OFF,
    SC_N,
    SC_TRIG,
    SC_VELOCITY_DEPENDENT,
    STEP_ENERGY,
    STEP_THETA,
    USER_FAILED,
)
from moreau.compiled.layout import call as _call
from moreau.compiled.layout import part as _part
from moreau.compiled.step import _user_failed
from moreau.contact.kkt import kkt_residuals_kernel
from moreau.core import kernels as _k


@_part
def velocity_passes(iset, ints):
    """``(passes, iterate, correct)``: the velocity update's passes in a step (the
    predictor-corrector's two, or the energy-consistent step's first pass and iterates),
    whether they iterate, and whether with the inertial correction (M depends on q)."""
    const_mass = ints[SC_MASS_KIND] == _k.MASS_CONST
    iterate = iset[S_STEP] == STEP_ENERGY and (ints[SC_VELOCITY_DEPENDENT] == 1 or not const_mass)
    theta = iset[S_STEP] == STEP_THETA and ints[SC_VELOCITY_DEPENDENT] == 1
    passes = 2 if theta else (iset[S_ITER] + 1 if iterate else 1)
    return passes, iterate, iterate and not const_mass


@_part
def energy_start(model, user, correct, q, v, cm, sm, M, ec, cnt):
    """``(status, s0)``: s0 = T(q_m, v_k) − T(q_k, v_k), the start's share of the step's
    kinetic-energy change (0 unless ``correct``: other steps make no call); ``M`` (n, n)
    holds M(q_m), ``cm, sm`` cos/sin of q_m; M(q_k) is evaluated into ``ec.Ms``, cos/sin
    of q_k into ``ec.c2``/``ec.s2`` (``ec``: the loop's work arrays of this step), and a
    chain's M_m v_k kept in ``ec.mv``. Status DONE or USER_FAILED."""
    if not correct:
        return DONE, 0.0
    return _energy_start(model, user, q, v, cm, sm, M, ec.Ms, ec.c2, ec.s2, ec.mv, cnt)


@_call
def _energy_start(model, user, q, v, cm, sm, M, Ms, c2, s2, mv, cnt):
    """:func:`energy_start`'s evaluation (a call, out of the loop's own code); the chain's
    from two O(n) products M v in one sweep (:func:`moreau.core.kernels.chain_product_pair`), not from M,
    M_m v_k kept in ``mv`` (n,)."""
    ints, pool = model.ints, model.pool
    n = ints[SC_N]
    if ints[SC_TRIG]:
        _k.trig(q, c2, s2)
    t = 0.0
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN:
        Mv = Ms[0]
        _k.chain_product_pair(pool, ints[SC_MASS_OFF], cm, sm, c2, s2, v, mv, Mv)
        for i in range(n):
            t += v[i] * mv[i]
        for i in range(n):
            t -= v[i] * Mv[i]
        return DONE, 0.5 * t
    if _user_failed(ev.mass(ints, pool, user, q, c2, s2, Ms), cnt):
        return USER_FAILED, 0.0
    for i in range(n):
        a = 0.0
        for j in range(n):
            a += (M[i, j] - Ms[i, j]) * v[j]
        t += v[i] * a
    return DONE, 0.5 * t


@_call
def energy_correction(model, user, h, q, v, v_new, s0, cm, sm, M, Ms, c2, s2, qp, dq, mv, f, fb, cnt):
    """Add κ M_m Δq to ``f`` and ``fb`` (n,), with Δq = h (v_k + v⁺)/2 for the iterate
    ``v_new`` and κ = (−s − Δqᵀ f_bias) / (Δqᵀ M_m Δq),
    s = T(q_k + Δq, v⁺) − T(q_m, v⁺) + s0 (nothing when Δq = 0). ``M`` holds M(q_m),
    ``cm, sm`` cos/sin of q_m; ``Ms``, ``c2``, ``s2``, ``qp``, ``dq`` are scratch. The
    chain's products are its O(n) ones, both in one sweep (:func:`moreau.core.kernels.chain_product_pair`), without
    M(q_k + Δq), and M_m Δq = h/2 (M_m v_k + M_m v⁺) with M_m v_k from the step's start
    (``mv``). Returns DONE or USER_FAILED."""
    ints, pool = model.ints, model.pool
    n = ints[SC_N]
    for i in range(n):
        dq[i] = 0.5 * h * (v[i] + v_new[i])
        qp[i] = q[i] + dq[i]
    if ints[SC_TRIG]:
        _k.trig(qp, c2, s2)
    s = s0
    den = 0.0
    along = 0.0
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN:
        Mv = Ms[0]
        _k.chain_product_pair(pool, ints[SC_MASS_OFF], c2, s2, cm, sm, v_new, Mv, qp)  # M(q⁺) v⁺, M_m v⁺
        for i in range(n):
            s += 0.5 * v_new[i] * (Mv[i] - qp[i])
            qp[i] = 0.5 * h * (mv[i] + qp[i])  # M_m Δq
            den += dq[i] * qp[i]
            along += dq[i] * fb[i]
    else:
        if _user_failed(ev.mass(ints, pool, user, qp, c2, s2, Ms), cnt):
            return USER_FAILED
        for i in range(n):
            a = 0.0
            b = 0.0
            for j in range(n):
                a += (Ms[i, j] - M[i, j]) * v_new[j]
                b += M[i, j] * dq[j]
            s += 0.5 * v_new[i] * a
            den += dq[i] * b
            along += dq[i] * fb[i]
            qp[i] = b  # M_m Δq (q⁺ is no longer needed)
    if den > 0.0:
        kappa = (-s - along) / den
        for i in range(n):
            f[i] += kappa * qp[i]
            fb[i] += kappa * qp[i]
    return DONE


@_part
def iterate_from(n, npass, v, v_new, x, vbar):
    """The velocity at which pass ``npass`` (>= 1) evaluates the forces, vbar = (v_k + x)/2;
    the first iterate x is the first pass's answer (the midpoint step's v⁺)."""
    for i in range(n):
        if npass == 1:
            x[i] = v_new[i]
        vbar[i] = 0.5 * (v[i] + x[i])


@_part
def next_iterate(n, y, x, ylast, rlast, mixed, tol):
    """True when the answer ``y`` of the iterate ``x`` is converged, |y − x|∞ <= tol (1 + |y|∞);
    else the next iterate into ``x``: y, or with ``mixed`` (a previous pair in ``ylast``,
    ``rlast``) Anderson's depth-1 mix y − γ (y − y_last), γ = Δrᵀ r / Δrᵀ Δr with r = y − x
    (Walker & Ni 2011)."""
    change = 0.0
    top = 0.0
    num = 0.0
    den = 0.0
    for i in range(n):
        r = y[i] - x[i]
        change = max(change, abs(r))
        top = max(top, abs(y[i]))
        dr = r - rlast[i]
        num += dr * r
        den += dr * dr
    if change <= tol * (1.0 + top):
        return True
    mix = mixed and den > 0.0
    gamma = num / den if mix else 0.0
    for i in range(n):
        rlast[i] = y[i] - x[i]
        # (not 0 · (y − y_last) unmixed: y_last holds the previous step's values, or none)
        x[i] = y[i] - gamma * (y[i] - ylast[i]) if mix else y[i]
        ylast[i] = y[i]
    return False


@_part
def pass_forces(model, user, npass, correct, t, h, q, v, qm, cm, sm, v_new, s0, M, ec, vbar, f, fb, cnt):
    """The forces of pass ``npass`` >= 1 into ``f`` (bias share ``fb``): f(t + h/2, q_m,
    (v_k + x)/2) at the iterate x (``ec.x``; the first is the first pass's answer
    ``v_new``), plus the inertial correction when ``correct``; the part that does not
    depend on v is the first pass's (``ec.fq``). Returns DONE or USER_FAILED."""
    ints, ekind, eoff = model.ints, model.ekind, model.eoff
    Ms, c2, s2, qp, dq, x = ec.Ms, ec.c2, ec.s2, ec.qp, ec.dq, ec.x
    iterate_from(ints[SC_N], npass, v, v_new, x, vbar)
    # the forces that do not depend on v are the first pass's (``ec.fq``, same t and q_m)
    if _user_failed(ev.velocity_forces(ints, ekind, eoff, model.pool, user, t + 0.5 * h, qm, cm, sm, vbar, ec.fq, f,
                                       fb), cnt):
        return USER_FAILED
    if correct:
        return energy_correction(model, user, h, q, v, x, s0, cm, sm, M, Ms, c2, s2, qp, dq, ec.mv, f, fb, cnt)
    return DONE


@_call
def checked(M, L, active, m, lw, ws, v_new, fset, acc):
    """The KKT check of the last pass's contact solve, which ran unchecked (``check=False``
    of :func:`moreau.compiled.step._velocity_update`): the step's iterates are checked in
    the one kept, the converged one (as ``OneStepIntegrator._check_deferred``). True when
    it passes (the worst residual kept in ``acc``); False: the loop solves that pass again,
    with the check and the fallback. A call: it runs once a contact step."""
    k = np.int64(0)  # not the literal 0: numba would compile the check twice
    for r in range(m):
        if active[r]:
            k += 1
    res = ws.res
    # √(M⁻¹)_jj: a chain's were formed with this M (step._chain_prepare), others flagged
    # stale; kept as a bool variable: the literal True would type (and compile) the check
    # a second time
    keep = k >= 0
    kkt_residuals_kernel(M, L, lw.b, lw.GA, lw.cA, v_new, lw.PA, k, res, ws.Gv, ws.GtP, ws.rv, ws.d, ws.x,
                         ws.X, ws.rd, keep, ws.d, np.int64(0), ws.d, ws.d, lw.gen, k < 0)  # dense M, no chain
    worst = max(res[0], res[1], res[2], res[3])
    if worst <= fset[F_TOL]:
        if worst > acc[A_WORST]:
            acc[A_WORST] = worst
        return True
    return False


@_part
def end_of_pass(n, m, code, defer, mixed, v_new, ec, M, L, active, lw, ws, fset, acc):
    """``(done, defer, mixed)`` after an iterate's pass: done when it converged
    (:func:`next_iterate`) and, if its contact solve ran unchecked (``defer`` and a contact
    pass), its answer passes the check (:func:`checked`); the iterates' plain contact solves
    (no friction, no bilateral rows) are checked only in the pass whose answer is kept. An
    answer that fails it: the same iterate again, with ``defer`` off (checked, with the
    fallback). ``mixed``: the next iterate is Anderson-mixed."""
    if next_iterate(n, v_new, ec.x, ec.ylast, ec.rlast, mixed, fset[F_ITOL]):
        if not (defer and code == 1) or checked(M, L, active, m, lw, ws, v_new, fset, acc):
            return True, defer, mixed
        return False, False, mixed
    return False, defer, True
