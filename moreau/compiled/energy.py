"""The energy check of the loop (the rule is :mod:`moreau.model.stability`'s)."""

import math

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import (  # the loop's layout
    A_DU,
    A_DU_WARN,
    A_KE0,
    A_KEMAX,
    A_KEMAX_WARN,
    A_RUNAWAY,
    A_T_EWARN,
    A_WORK_B,
    A_WORK_F,
    C_ELEVEL,
    C_EOK,
    C_EWARN,
    C_KLAST,
    C_RUNAWAY,
    DONE,
    ENERGY_GROWTH,
    F_ESTOP,
    F_EWARN,
    F_H,
    F_T0,
    RUNAWAY_RATE,
    SC_MASS_KIND,
    SC_N,
    USER_FAILED,
)
from moreau.compiled.layout import call as _call
from moreau.compiled.layout import part as _part
from moreau.compiled.step import _user_failed
from moreau.core import kernels as _k


@_part
def _step_work(n, h, f, fb, v, v_new, bias_work, acc):
    """The smooth forces' work over a step, h fᵀ (v + v⁺)/2, into ``acc[A_WORK_F]``; with
    ``bias_work`` the bias terms' share of it (fb: the bias of the last force evaluation)
    into ``acc[A_WORK_B]``."""
    wf = 0.0
    for i in range(n):
        wf += f[i] * (v[i] + v_new[i])
    acc[A_WORK_F] += 0.5 * h * wf
    if bias_work:
        wb = 0.0
        for i in range(n):
            wb += fb[i] * (v[i] + v_new[i])
        acc[A_WORK_B] += 0.5 * h * wb


@_part
def _kinetic_energy(model, user, q, v, cq, sq, M, cnt):
    """``(status, T)``: T = ½ vᵀ M(q) v with M(q) evaluated into ``M``; status DONE, or
    USER_FAILED when a user mass matrix failed."""
    ints = model.ints
    n = ints[SC_N]
    if _user_failed(ev.mass_apart(ints, model.pool, user, q, cq, sq, M), cnt):
        return USER_FAILED, 0.0
    ke = 0.0
    for i in range(n):
        for l in range(n):
            ke += v[i] * M[i, l] * v[l]
    return DONE, 0.5 * ke


@_call
def _energy_check(model, user, iset, fset, k, q, v, cq, sq, M, cnt, acc, q_warn, v_warn):
    """The energy ledger's check (see :mod:`moreau.model.stability`): the kinetic energy
    T(q, v) against T₀ plus the work of the applied forces (the bias terms do none:
    vᵀ f_bias = −½ vᵀ Ṁ v is part of dT/dt) and of the contacts. Unaccounted energy above ``F_EWARN``
    times the largest T so far is noted (``C_EWARN``); above ``F_ESTOP`` at two checks in a
    row the run stops (ENERGY_GROWTH; ``C_EOK``: the last check below both bounds); the state
    of the first warning into ``q_warn, v_warn`` (n,). Returns
    DONE, ENERGY_GROWTH or USER_FAILED. A
    chain's T from its O(n) product M v (:func:`moreau.compiled.evaluate.chain_kinetic`,
    into ``M[0]``: no reader expects M(q) in ``M`` after the step, a chain's M being formed
    where a step needs it), for chains of ``CHAIN_STRUCTURED_MIN`` (8) links or more (the 3-link chain's and the
    piston's steps were 13-15 % slower with it, measured interleaved)."""
    if model.ints[SC_MASS_KIND] == _k.MASS_CHAIN and model.ints[SC_N] >= _k.CHAIN_STRUCTURED_MIN:
        status, ke = DONE, ev.chain_kinetic(model.ints, model.pool, cq, sq, v, M[0])
    else:
        status, ke = _kinetic_energy(model, user, q, v, cq, sq, M, cnt)
    if status != DONE:
        return status
    kemax = acc[A_KEMAX]  # before this check (the runaway test's floor)
    if ke > acc[A_KEMAX]:
        acc[A_KEMAX] = ke
    du = ke - acc[A_KE0] - (acc[A_WORK_F] - acc[A_WORK_B])
    acc[A_DU] = du
    level = 0
    if du > 1e-12 * (1.0 + acc[A_KEMAX]):
        if du > fset[F_ESTOP] * acc[A_KEMAX]:
            level = 2
        elif du > fset[F_EWARN] * acc[A_KEMAX]:
            level = 1
    prev = cnt[C_ELEVEL]
    cnt[C_ELEVEL] = level
    # the runaway test: the ledger balances an explicit step's runaway exactly (constant M: the
    # kinetic energy change is the work of the forces applied); T rising above its largest so
    # far at a rate no resolved motion has shows it
    dk = k - cnt[C_KLAST]
    fast = dk > 0 and kemax > 0.0 and ke > kemax * math.exp(RUNAWAY_RATE * dk)
    cnt[C_RUNAWAY] = cnt[C_RUNAWAY] + 1 if fast else 0
    if cnt[C_RUNAWAY] >= 2:
        acc[A_RUNAWAY] = (ke / kemax) ** (1.0 / dk)  # the growth factor a step
        return ENERGY_GROWTH
    cnt[C_KLAST] = k
    if level == 0 and not fast:
        cnt[C_EOK] = k
    # the stop bound counts when two checks in a row find it passed: a coarse step's
    # transient at an impact (one step) warns, but is not a growth
    if level == 2 and prev == 2:
        return ENERGY_GROWTH
    if cnt[C_EWARN] == 0 and level >= 1:
        cnt[C_EWARN] = k
        acc[A_DU_WARN] = du
        acc[A_KEMAX_WARN] = acc[A_KEMAX]
        acc[A_T_EWARN] = fset[F_T0] + k * fset[F_H]
        for i in range(q.shape[0]):  # the state the warning's step advice is for
            q_warn[i] = q[i]
            v_warn[i] = v[i]
    return DONE
