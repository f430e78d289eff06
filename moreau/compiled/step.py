"""The compiled Moreau–Jean step: the free acceleration, the velocity update with the
contacts closed at the midpoint, and the contact solve with its check and fallback
(:class:`moreau.step.integrator.MoreauJeanMidpoint`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from moreau.compiled import evaluate as ev
from moreau.compiled.bilateral import _eq_alone, _eq_finish, _eq_prepare, _eq_reduce
from moreau.compiled.friction import _friction_solve
from moreau.compiled.layout import (  # the loop's layout
    A_WORST,
    C_FAILKIND,
    C_FALLBACKS,
    C_K,
    C_SOLVES,
    C_USER,
    DRIFT_COMBINED,
    F_H,
    F_TOL,
    METHOD_EXACT,
    METHOD_EXTERNAL,
    NATIVE_MISMATCH,
    R_BOUNCED,
    R_DELAY,
    R_GAP,
    R_PINNED,
    R_SHIFT,
    S_DELASSUS,
    S_DELASSUS_KEY,
    S_DRIFT,
    S_EXTERNAL,
    S_FALLBACK,
    S_LOCATE,
    S_MEMORY,
    S_METHOD,
    S_STEP,
    S_WARM,
    S_WARM_KEY,
    SC_M,
    SC_MASS_KIND,
    SC_MASS_OFF,
    SC_ME,
    SC_MF,
    SC_N,
    SOLVER_FAILED,
    STEP_ENERGY,
    USER_FAILED,
)
from moreau.compiled.layout import call as _call
from moreau.compiled.layout import part as _part
from moreau.compiled.native import MISMATCH, address_and_key, call_checked
from moreau.compiled.usercalls import call_solver
from moreau.compiled.warm_start import keep_rows, same_rows, warm_solve
from moreau.contact.lcp import kkt_residuals_kernel, solve_one_step
from moreau.core import kernels as _k


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
    k = np.int64(0)  # not the literal 0: numba would compile the callees given the count twice
    for r in range(m):
        if flags[r]:
            k += 1
    return k


@_part
def _contact_solve(M, L, b, GA, cA, na, v_out, P_out, iset, fset, cnt, acc, fail, ws, mass, fresh=True, check=True,
                   prepared=False, warm=False, cd=None):
    """Main LCP method, KKT check, fallback; False when both fail (residuals in ``fail``).
    ``check=False``: an answer the method reports solved is taken unchecked (the
    energy-consistent step's passes; the loop checks the one it keeps,
    :func:`moreau.compiled.implicit.checked`). ``prepared``: ``ws`` holds the Delassus
    matrix and M⁻¹ b already (:func:`_chain_prepare`).
    ``fresh=False``: ``ws`` holds the Delassus matrix of this M and GA (see
    :func:`~moreau.contact.one_step.solve_one_step`) and the KKT check's √(M⁻¹)_jj of
    this M; the fallback reuses the main's. A
    step's later passes pass it, except with bilateral rows or friction (which solve other
    problems) and with ``S_LOCATE`` (whose closed rows depend on f). ``mass``: the chain's
    ``(pool, offset, cm, sm, gen)`` (read when ``prepared``; every scene passes arrays of
    these types). ``warm`` (a chain's fresh pass, W not yet formed; ``cd`` = ``mass``, None
    compiles none of it): first the kept factor's answer
    (:func:`moreau.compiled.warm_start.warm_solve`), checked; W is formed only when it fails.
    ``ws.ids[0]`` is left −2 when the dual active-set method solved, −1 after any other
    solve (:mod:`~moreau.compiled.warm_start`)."""
    res = ws.res
    tol = fset[F_TOL]
    # np.int64: numba would type the count as the literal 0 at one of the inlined call
    # sites and compile the solver and the check a second time
    k = np.int64(na)
    # a called-back main solver forms no Delassus matrix: the fallback forms its own
    external = iset[S_METHOD] == METHOD_EXTERNAL
    # ``prepared`` as a bool variable (k >= 0): drift's literal False would type (and
    # compile) the check and the solver a second time
    by_chain = prepared or k < 0
    first = 0  # attempt -1: the kept factor's answer (a chain's fresh pass); W is formed only when it fails
    if cd is not None and warm:
        first = -1
    for attempt in range(first, 2):  # one call site of the check: its code is in the loop once
        st = 1
        if attempt < 0:
            if cd is not None:  # through its address (warm_start_addresses): not in the loop's compile
                got = call_checked(iset[S_WARM], iset[S_WARM_KEY], (cd[0], cd[1], cd[2], cd[3], cd[4], GA, cA, k, ws,
                                                                    v_out, P_out))
                if got == MISMATCH:
                    cnt[C_FAILKIND] = NATIVE_MISMATCH
                    return False
                st = 0 if got == 1 else 1
        else:
            method = iset[S_METHOD] if attempt == 0 else iset[S_FALLBACK]
            if method < 0:
                break
            if cd is not None and prepared and fresh and attempt == 0:  # a chain's W, formed here once
                if call_checked(iset[S_DELASSUS], iset[S_DELASSUS_KEY], (cd[0], cd[1], cd[2], cd[3], cd[4], GA, k,
                                                                          ws)) == MISMATCH:
                    cnt[C_FAILKIND] = NATIVE_MISMATCH
                    return False
            if attempt == 1:
                cnt[C_FALLBACKS] += 1
            ws.ids[0] = -1
            if method == METHOD_EXTERNAL:
                st = call_solver(iset[S_EXTERNAL + attempt], M, b, GA, cA, v_out, P_out, M.shape[0], k)
                if st == 2:  # interrupted (Ctrl-C): no fallback, the runner raises it
                    return False
            else:
                st = solve_one_step(M, L, b, GA, cA, P_out, v_out, k, method, 1e-12, ws,
                                    (external or fresh and attempt == 0) and not prepared, by_chain)
                if st == 0 and method == METHOD_EXACT:
                    ws.ids[0] = -2
            if st == 0 and not check:
                return True
        if st == 0:
            # a later pass checks against the same M: the check's round-off floor keeps its
            # √(M⁻¹)_jj (O(n³)); not the fallback of a fresh pass (the main may have failed
            # before any check of this M), unless _chain_prepare formed them (as for the kept answer)
            kkt_residuals_kernel(M, L, b, GA, cA, v_out, P_out, k, res, ws.Gv, ws.GtP, ws.rv, ws.d, ws.x,
                                 ws.X, ws.rd, not fresh or prepared, mass[0], mass[1], mass[2], mass[3], mass[4],
                                 by_chain)
            worst = max(res[0], res[1], res[2], res[3])
            if worst <= tol:
                if worst > acc[A_WORST]:
                    acc[A_WORST] = worst
                return True
            if attempt >= 0:
                for i in range(4):
                    fail[attempt, i] = res[i]
        elif attempt >= 0:
            for i in range(4):
                fail[attempt, i] = math.inf
    return False


@_part
def _chain_prepare(ints, pool, cm, sm, gen, b, ws, fresh):
    """A chain's contact problem (without friction or bilateral rows; True when prepared)
    with its O(n) solve (:func:`moreau.core.kernels.chain_solve`, from the generators
    ``gen`` of M's factor at q_m, cos/sin ``cm, sm``) instead of the dense factor's: M⁻¹ b
    into ``ws.vfree`` and, when ``fresh``, the KKT check's √(M⁻¹)_jj (``ws.rd``, flagged
    kept; O(n) against O(n³)). Other scenes: a
    fresh pass flags the check's kept √(M⁻¹)_jj stale (``implicit.checked`` keeps them), and
    so do chains under ``CHAIN_STRUCTURED_MIN`` (8) links: the dense solves cost as little there, and the dense floor,
    formed only when a check needs it, less (the 3-link chain's step on a floor was 5-7 %
    slower with these). W itself is formed by :func:`_contact_solve` (:func:`chain_delassus`),
    unless the kept factor serves."""
    n = ints[SC_N]
    if ints[SC_MASS_KIND] != _k.MASS_CHAIN or ints[SC_MF] > 0 or ints[SC_ME] > 0 or n < _k.CHAIN_STRUCTURED_MIN:
        if fresh:
            ws.rd[n] = 0.0
        return False
    _k.chain_solve(pool, ints[SC_MASS_OFF], cm, sm, gen, b, ws.vfree)
    if not fresh:
        return True
    _k.chain_inverse_diagonal_sqrt(pool, ints[SC_MASS_OFF], cm, sm, gen, ws.rd)
    ws.rd[n] = 1.0
    return True


@_call  # once a step at most, and only a chain's: called through its address (warm_start_addresses)
def chain_delassus(pool, off, cm, sm, gen, GA, k, ws):
    """A chain's M⁻¹ G_jᵀ (rows of ``ws.MinvGt``) and W = G M⁻¹ Gᵀ (``ws.W``) for the first
    k rows of ``GA``, by its O(n) solve from its mass at ``pool[off:]`` (:func:`_chain_prepare`)."""
    n = cm.shape[0]
    MinvGt, W, X = ws.MinvGt, ws.W, ws.Xt
    for i in range(n):  # the k right-hand sides side by side (their solves vectorize)
        for j in range(k):
            X[i, j] = GA[j, i]
    _k.chain_solve_columns(pool, off, cm, sm, gen, X, k, ws.s, ws.r)
    for j in range(k):
        for i in range(n):
            MinvGt[j, i] = X[i, j]
    _k.delassus_product(GA, X, W, k, n)
    return np.int64(0)


@_call
def warm_answer(p, o, c, s, gen, G, cA, k, ws, v, P):
    """:func:`~moreau.compiled.warm_start.warm_solve` as the loop calls it, through its
    address: 1 when the kept factor's answer is in ``v, P``, else 0."""
    return np.int64(1) if warm_solve(p, o, c, s, gen, G, cA, k, ws, v, P) else np.int64(0)


def warm_start_addresses(model: Any, work: tuple) -> tuple[int, int, int, int]:
    """The addresses of :func:`warm_answer`'s and :func:`chain_delassus`'s machine code for a
    run's arrays (``model``, ``work`` of :func:`moreau.compiled.loop.run_chunk`), as
    :func:`_contact_solve` calls them, each with the key of its argument types (the
    ``S_WARM`` and ``S_DELASSUS`` settings): loaded or compiled here. Only a chain's
    persistent contact runs them, once a step at most; as calls through an address the
    loop's compile neither compiles them nor links their code."""
    own, ws, lw = work[:3]
    p, o, k = model.pool, np.int64(model.ints[SC_MASS_OFF]), np.int64(0)
    warm, warm_key = address_and_key(warm_answer, (p, o, own.cm, own.sm, lw.gen, lw.GA, lw.cA, k, ws, own.v_new, lw.PA))
    rows, rows_key = address_and_key(chain_delassus, (p, o, own.cm, own.sm, lw.gen, lw.GA, k, ws))
    return warm, warm_key, rows, rows_key


@_part
def _free_acceleration(ints, pool, Minv, L, gen, cm, sm, f, out):
    """M⁻¹ f into ``out`` (with the inverse of a constant M, as the reference path; a
    chain's from the generators ``gen`` of its factor, O(n), ``cm, sm``: cos/sin of q_m)."""
    n = ints[SC_N]
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN:
        _k.chain_solve(pool, ints[SC_MASS_OFF], cm, sm, gen, f, out)
    elif ints[SC_MASS_KIND] == _k.MASS_CONST:
        for i in range(n):
            t = 0.0
            for j in range(n):
                t += Minv[i, j] * f[j]
            out[i] = t
    else:
        _k.cho_solve(L, f, out, n)


@_part
def _momentum(ints, pool, h, M, cm, sm, v, f, b):
    """b = M v + h f, the right-hand side of the step's velocity update; a chain's M v
    in O(n) (``cm, sm``: cos/sin of the configuration of M)."""
    n = ints[SC_N]
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN:
        ev.chain_momentum(ints, pool, h, cm, sm, v, f, b)
        return
    for i in range(n):
        s = h * f[i]
        for l in range(n):
            s += M[i, l] * v[l]
        b[i] = s


@_part
def _closed_model(model, user, qm, cm, sm, M, L, gen, G, cnt, locate, again):
    """What a pass with closed rows (or bilateral rows) needs at q_m, once a step (later
    passes close the same rows): a chain's M and factor (from the generators ``gen``)
    and G(q_m) (again in every pass with bilateral rows or friction, whose solves work on
    G's rows; with ``locate`` it is already there). False when a user callable failed."""
    ints, bkind, boff, brow, bnrows, pool = model.ints, model.bkind, model.boff, model.brow, model.bnrows, model.pool
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN and not again:
        ev.chain_dense(ints, pool, cm, sm, gen, M, L)
    if locate or (again and ints[SC_ME] == 0 and ints[SC_MF] == 0):
        return True
    return not _user_failed(ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, qm, cm, sm, G), cnt)


@_part
def _velocity_update(model, user, iset, fset, qm, cm, sm, M, L, Minv, f, v, gm, v_new, P, active,
                     GA_all, cnt, acc, fail, ws, lw, last_imp, rs, fr, eqw, again, check):
    """v⁺ with the contacts closed at qm (gaps ``gm``); returns 1 (contact), 0 (free) or
    −1 (failed: the solve, or a user callable; the status is in ``cnt[C_FAILKIND]``).
    ``P`` (m,) and ``active`` (m,) are set for the step; ``again``: a later pass of it.

    With combined drift control, a row's restitution acts only at an impact (see
    :class:`moreau.step.drift.CombinedProjection`): it approaches faster than the smooth forces
    change its normal velocity in one step, and it carried no impulse in the last
    ``S_MEMORY`` steps; other closed rows take e = 0 (a persistent contact). A row is then
    also closed when the projection holds it, or when it reaches the barrier by the end of
    the step (2 g(q_m) − g(q_k) <= 0; with ``S_LOCATE`` the free step's end gap, + h²/2 G M⁻¹ f;
    the energy-consistent step too; Newton's law: :func:`moreau.core.kernels.impact_law`).
    ``rs`` (m, 6, columns ``R_GAP`` ... ``R_SHIFT``) holds per row the gap at q_k, the gap
    the projection left, the pinned and bounced flags, a bounced row's h/2 − s and (2 s − h) a_n.
    ``fr``, ``eqw``: the friction and bilateral work arrays (``layout.FrictionWork``,
    ``EqualityWork``), None in a scene without them (not compiled then; with bilateral rows
    every step solves in their null space). ``check=False``: unchecked (``implicit.checked``)."""
    ints, bkind, boff, brow, bnrows, pool, e, atol = (model.ints, model.bkind, model.boff, model.brow, model.bnrows,
                                                      model.pool, model.e, model.atol)
    n, m = ints[SC_N], ints[SC_M]
    h = fset[F_H]
    combined = iset[S_DRIFT] == DRIFT_COMBINED
    locate = combined and iset[S_LOCATE] == 1
    rhs = lw.rhs
    if locate:  # the free step's end gap, + h²/2 G M⁻¹ f, decides which rows close
        _free_acceleration(ints, pool, Minv, L, lw.gen, cm, sm, f, rhs)
        if _user_failed(ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, qm, cm, sm, GA_all), cnt):
            return -1
    ahead = iset[S_STEP] == STEP_ENERGY and not combined  # rows reaching the barrier by the step end
    for r in range(m):
        active[r] = gm[r] <= atol[r] or (ahead and 2.0 * gm[r] - rs[r, R_GAP] <= 0.0)
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
    me, mf = ints[SC_ME], ints[SC_MF]
    if na == 0 and me == 0:
        if not locate:
            _free_acceleration(ints, pool, Minv, L, lw.gen, cm, sm, f, rhs)
        for i in range(n):
            v_new[i] = v[i] + h * rhs[i]
        return 0
    if combined:
        if not locate:
            _free_acceleration(ints, pool, Minv, L, lw.gen, cm, sm, f, rhs)
        k_now, memory = cnt[C_K], iset[S_MEMORY]
    if na > 0:
        cnt[C_SOLVES] += 1
    if not _closed_model(model, user, qm, cm, sm, M, L, lw.gen, GA_all, cnt, locate, again):
        return -1
    b = lw.b
    _momentum(ints, pool, h, M, cm, sm, v, f, b)
    if eqw is not None and me > 0 and na == 0:  # no contact row: the bilateral rows alone
        return _eq_alone(n, m, m + mf, me, M, L, b, v, GA_all, P, v_new, eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.y,
                         eqw.by, eqw.PE, eqw.F, eqw.yv, eqw.cE, eqw.rank, cnt, fr)
    GA, cA = lw.GA, lw.cA
    j = 0
    for r in range(m):
        if active[r]:
            u = 0.0
            for i in range(n):
                GA[j, i] = GA_all[r, i]
                u += GA_all[r, i] * v[i]
            er = e[r]
            c = _k.newton_target(er, u)
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
    PA, solved = lw.PA, 0
    Ms, Ls, bs = M, L, b
    rank = -1
    if eqw is not None and me > 0:  # bilateral rows: the contact rows solved in their null space (M = I there)
        rank = _eq_prepare(n, m + mf, me, L, GA_all, v, b, eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.y, eqw.by, eqw.cE,
                           eqw.rank, cnt)
        if rank < 0:
            return -1
        _eq_reduce(L, eqw.Q, eqw.y, eqw.x, rank, GA, np.int64(0), na, cA)  # not the literal 0 (compiled apart)
        Ms, Ls, bs = eqw.eye, eqw.eye, eqw.by
    if fr is not None and mf > 0:  # friction: the tangent rows join (Lemke's method)
        solved = _friction_solve(n, m, Ms, Ls, bs, GA_all, GA, cA, active, na, v_new, PA, iset, fset, acc, fail, fr,
                                 cnt, L, eqw, rank)
    fresh = not again or locate or me > 0 or mf > 0  # else the last Delassus matrix stands
    warm = check and not again and iset[S_METHOD] == METHOD_EXACT and same_rows(ws.ids, active, m, na)
    chain, mass = _chain_prepare(ints, pool, cm, sm, lw.gen, b, ws, fresh), (pool, ints[SC_MASS_OFF], cm, sm, lw.gen)
    if solved < 0 or (solved == 0 and not _contact_solve(Ms, Ls, bs, GA, cA, na, v_new, PA, iset, fset, cnt, acc,
                                                          fail, ws, mass, fresh, check, chain, warm and chain, mass)):
        if cnt[C_FAILKIND] != NATIVE_MISMATCH:  # (set by _contact_solve: a warm start's address, other types)
            cnt[C_FAILKIND] = NATIVE_MISMATCH if solved == -2 else SOLVER_FAILED  # (-2: friction's address)
        return -1
    keep_rows(ws.ids, active, m, na, chain)  # the rows of the factor the dual method left
    j = 0
    for r in range(m):
        if active[r]:
            P[r] = PA[j]
            j += 1
    if eqw is not None and me > 0:
        _eq_finish(n, m, me, rank, M, L, b, GA_all, P, v_new, eqw.Q, eqw.R, eqw.piv, eqw.x, eqw.PE, eqw.F, eqw.yv,
                   solved == 1, fr)
    return 1
