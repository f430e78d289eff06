"""Coulomb friction in the compiled step: the tangent rows of the active contacts join
the step's problem, solved by Lemke's method with the law check
(:func:`moreau.contact.friction.solve_friction_step`). Compiled only into the loop's
variants with friction (``moreau.compiled.variants.VARIANTS``). The solve is called through
the address of its machine code (:func:`friction_address`, looked up by the run, as the
drift projection is): the loop's compile neither compiles it nor waits for the second
process that does, and LLVM does not optimize its 21 000 instructions again in the
loop's module. The two parts here are inlined: as calls of their own, passing the
friction arrays' tuple, they compiled 5 s slower."""

from __future__ import annotations

import numpy as np

from moreau.compiled.bilateral import _eq_reduce
from moreau.compiled.layout import (
    A_T_PAINLEVE,
    A_WORK_T,
    A_WORST,
    C_K,
    C_PAINLEVE,
    C_PAINLEVE_ROW,
    C_PAINLEVE_STEP,
    F_H,
    F_T0,
    F_TOL,
    S_FRICTION,
    S_FRICTION_KEY,
    FrictionWork,
)
from moreau.compiled.layout import part as _part
from moreau.compiled.native import address_and_key, call_checked
from moreau.contact.friction import FRICTION_AUTO, friction_workspace, solve_friction_step
from moreau.contact.painleve import PAINLEVE_MARGIN

__all__ = ["friction_address", "friction_work", "friction_parts"]


def friction_work(n: int, m: int, mf: int, mu: np.ndarray, tangent_row: np.ndarray) -> tuple:
    """The friction arrays of the loop's workspace (``layout.FrictionWork``) — per active
    row its index among the normal rows and its mu, the step's tangential impulses per row
    and their sum since the last record, the law residuals, Lemke's work arrays, and per row
    its mu and tangent row (numpy: allocating compiles nothing)."""
    mm = max(m, 1)
    return FrictionWork(np.zeros(mm, dtype=np.int64), np.zeros(mm), np.zeros(m), np.zeros(m),
                        np.zeros(6), friction_workspace(n, m, mf), np.ascontiguousarray(mu, dtype=np.float64),
                        np.ascontiguousarray(tangent_row, dtype=np.int64))


def friction_address(settings, work: tuple) -> tuple[int, int]:
    """The address of :func:`~moreau.contact.friction.solve_friction_step`'s machine code
    for a run's arrays (``settings``, ``work`` of :func:`moreau.compiled.loop.run_chunk`),
    as :func:`_friction_solve` calls it, and the key of its argument types (the
    ``S_FRICTION`` settings): loaded or compiled here."""
    own, _, lw, fr = work[:4]
    return address_and_key(solve_friction_step, (
        own.M, own.L, lw.b, lw.GA, lw.cA, fr.muA, fr.fidx, np.int64(0), np.int64(0), lw.PA, own.v_new,
        float(settings.fset[F_TOL]), fr.res, fr.lemke, np.int64(FRICTION_AUTO)))


@_part
def _friction_solve(n, m, M, L, b, G, GA, cA, active, na, v_new, PA, iset, fset, acc, fail, fr, cnt, Lo, eqw, rank):
    """The step's contact problem with friction: the tangent rows of the active rows with
    mu > 0 stacked under the normal rows ``GA`` (na rows), solved and checked. Returns 1
    (solved; ``PA`` = [P_N; P_T], ``fr``'s PT per row), 0 (no active row has friction: the
    caller solves the frictionless problem), −1 (no answer passed the law check; the
    residuals in ``fail[0]``) or −2 (the solve's address was made for other argument types:
    never called). A sliding contact in Painlevé's region (as
    :func:`moreau.contact.painleve.painleve_rows` finds them) is counted in ``cnt``.

    With bilateral rows (``rank`` >= 0: M, L, b are the reduced problem's, ``Lo`` the
    step's own Cholesky factor, ``eqw`` the bilateral work arrays) the tangent rows are
    reduced likewise, their slip offsets into ``cA[na:]`` (see
    :mod:`moreau.contact.equality`); else ``rank`` is −1 and the offsets are 0."""
    fidx, muA, PT, _, res, fws, mu, trow = fr
    kf = 0
    j = 0
    for r in range(m):
        PT[r] = 0.0
        if active[r]:
            muA[j] = mu[r]
            if mu[r] > 0.0:
                t = trow[r]
                for i in range(n):
                    GA[na + kf, i] = G[t, i]
                cA[na + kf] = 0.0
                fidx[kf] = j
                kf += 1
            j += 1
    if kf == 0:
        return 0
    if eqw is not None and rank >= 0:
        _eq_reduce(Lo, eqw.Q, eqw.y, eqw.x, rank, GA, na, na + kf, cA)
    # through its address (S_FRICTION); ``method`` given, as friction_one_step gives it: one
    # compiled signature serves both
    st = call_checked(iset[S_FRICTION], iset[S_FRICTION_KEY], (M, L, b, GA, cA, muA, fidx, np.int64(na),
                      np.int64(kf), PA, v_new, fset[F_TOL], res, fws, np.int64(FRICTION_AUTO)))
    if st < 0:  # never called: the caller says NATIVE_MISMATCH
        return -2
    if st != 0:
        for i in range(6):
            fail[0, i] = res[i]
        return -1
    worst = 0.0
    for i in range(6):
        worst = max(worst, res[i])
    if worst > acc[A_WORST]:
        acc[A_WORST] = worst
    W = fws.W  # the step's Delassus matrix: normal rows, then tangent rows
    painleve = -1
    f = 0
    j = 0
    for r in range(m):
        if active[r]:
            if f < kf and fidx[f] == j:
                pt = PA[na + f]
                PT[r] = pt
                pn = PA[j]
                ut = -cA[na + f]
                for i in range(n):
                    ut += GA[na + f, i] * v_new[i]
                if abs(pt) >= (1.0 - 1e-9) * mu[r] * pn and not (pn == 0.0 and ut == 0.0):
                    s = (-1.0 if pt > 0.0 else 1.0) if pn > 0.0 else (1.0 if ut > 0.0 else -1.0)
                    wnn = W[j, j]  # at round-off of W_TT: a row held by the bilateral ones, not Painlevé's
                    if wnn - mu[r] * s * W[j, na + f] <= PAINLEVE_MARGIN * wnn and wnn > 1e-9 * W[na + f, na + f] \
                            and painleve < 0:
                        painleve = r
                f += 1
            j += 1
    if painleve >= 0:
        cnt[C_PAINLEVE] += 1
        if cnt[C_PAINLEVE_STEP] == 0:
            cnt[C_PAINLEVE_STEP] = cnt[C_K] + 1
            cnt[C_PAINLEVE_ROW] = painleve
            acc[A_T_PAINLEVE] = fset[F_T0] + cnt[C_K] * fset[F_H]
    return 1


@_part
def _friction_records(n, m, v, v_new, G, active, fr, acc):
    """The step's tangential impulses into their sum since the last record, and their
    work ½ P_Tᵀ (U_T⁻ + U_T⁺) into the ledger."""
    _, _, PT, PT_acc, _, _, _, trow = fr
    for r in range(m):
        if active[r] and PT[r] != 0.0:
            PT_acc[r] += PT[r]
            t = trow[r]
            u = 0.0
            for i in range(n):
                u += G[t, i] * (v[i] + v_new[i])
            acc[A_WORK_T] += 0.5 * PT[r] * u


friction_parts = (_friction_solve, _friction_records)
