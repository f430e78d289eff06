"""The one-step QP through its LCP: :func:`solve_one_step` forms ``W = G M⁻¹ Gᵀ`` and
``w = G M⁻¹ b − c``, calls an LCP method of :mod:`~moreau.contact.active_set`, and refines
the answer (:func:`_refine`); :func:`workspace` allocates its work arrays once per run.
Re-exported by :mod:`moreau.contact.lcp`."""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from moreau.contact.active_set import OK, _inline, _jit, _solve_active, lcp_dual_active_set, lcp_enumerate
from moreau.core.kernels import cho_solve, delassus

__all__ = ["OneStepWork", "solve_one_step", "workspace"]


#: the one-step problem's work arrays (:func:`workspace`): M⁻¹ Gᵀ by rows, M⁻¹ b, the
#: Delassus matrix W and w = G M⁻¹ b − c; the LCP methods' (s, A, inA, rhs, r, sub, fac:
#: the active set, its flags and the factor of its W_AA among them); the KKT check's (Gv,
#: GtP, rv, d, x, its residuals res (4,), X (n, n), and rd (n + 1,): √(M⁻¹)_jj and whether
#: they are kept); Xt (n, m): M⁻¹ Gᵀ by columns; ids (m + 1,): the rows whose W_AA factor
#: is kept for the next step (:mod:`moreau.compiled.warm_start`)
OneStepWork = namedtuple("OneStepWork", "MinvGt vfree W w s A inA rhs r sub fac Gv GtP rv d x res Xt X rd ids")


def workspace(n: int, m: int) -> OneStepWork:
    """Work arrays for problems of up to m rows on n coordinates (allocated once per run;
    the LCP methods, the solve and the KKT check work on leading blocks of them, creating
    no array views). Plain numpy: allocating compiles nothing."""
    mm = max(m, 1)
    return OneStepWork(np.empty((mm, n)), np.empty(n), np.empty((mm, mm)), np.empty(mm), np.empty(mm),
            np.empty(mm, dtype=np.int64), np.zeros(mm, dtype=np.bool_), np.empty(mm), np.empty(mm),
            np.empty((mm, mm)), np.empty((mm, mm)), np.empty(mm), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n), np.empty(4), np.empty((n, mm)), np.empty((n, n)), np.zeros(n + 1),
            np.full(mm + 1, -1, dtype=np.int64))


@_jit
def solve_one_step(M, L, b, G, c, P, v, k, method, tol, ws, fresh=True, vready=False):
    """v, P of the one-step QP on the first k rows of G with the LCP solver ``method``
    (0: dual active set, 1: enumeration); returns its status. ``L`` = chol(M), ``ws``
    from :func:`workspace`. ``fresh=False``: ``ws`` holds W = G M⁻¹ Gᵀ and M⁻¹ Gᵀ of
    this very M and G from the last call (a compiled step's later passes: only b
    changes), and they are not formed again. ``vready``: ``ws.vfree`` holds M⁻¹ b (a
    chain's, from its O(n) solve)."""
    n = M.shape[0]
    MinvGt = ws.MinvGt  # row j: M⁻¹ G_jᵀ
    W = ws.W
    if fresh:
        delassus(L, G, ws.Xt, MinvGt, W, k, n)  # W = G M⁻¹ Gᵀ, exactly symmetric
    vfree = ws.vfree
    if not vready:
        cho_solve(L, b, vfree, n)
    w = ws.w
    scale = 1e-300
    for i in range(k):
        w[i] = -c[i]
    for j in range(n):  # w = G v_f − c by columns: k independent sums, not one long one at a time
        x = vfree[j]
        for i in range(k):
            w[i] += G[i, j] * x
    for i in range(k):
        scale = max(scale, abs(w[i]), abs(c[i]))
    if method == 0:
        status = lcp_dual_active_set(W, w, P, k, tol * scale, ws.s, ws.A, ws.inA, ws.rhs, ws.r, ws.sub, ws.fac)
    else:
        status = lcp_enumerate(W, w, P, k, tol * scale, ws.s, ws.A, ws.rhs, ws.r, ws.sub, ws.fac)
    for i in range(n):
        v[i] = vfree[i]
    for j in range(k):  # v = v_f + M⁻¹ Gᵀ P by rows of M⁻¹ Gᵀ (contiguous: they vectorize)
        if P[j] != 0.0:
            for i in range(n):
                v[i] += MinvGt[j, i] * P[j]
    if status == OK:
        # iterative refinement; repeated (twice at most) while the residual it corrected was
        # above the round-off of G v − c: nearly dependent active rows (cond(W_AA) ~ 1e12)
        # take two or three steps, a well-conditioned set none more; one call site, so its
        # code is in the solve once
        kept, last = method == 0, math.inf
        for _ in range(3):
            applied, residual, scale = _refine(G, c, P, v, k, W, MinvGt, ws, kept, last)
            if not applied or residual <= 64.0 * 2.220446049250313e-16 * scale:
                break
            kept, last = applied, residual / scale  # (True: the rows refined keep their factor)
    return status


@_inline
def _refine(G, c, P, v, k, W, MinvGt, ws, kept, last):
    """One step of iterative refinement on the rows with P > 0: v⁺ = v_free + M⁻¹GᵀP
    cancels large free velocities (an impulse that stops a driven joint), leaving G v⁺
    off its bound c by round-off of the large terms; correct P and v by the residual.
    Returns ``(applied, max |G_i v − c_i| before the correction, max (|c_i| + |G_i||v|))``
    over those rows; nothing is applied when the residual is already at the round-off
    of G v − c (64 ε of that scale), nor when the residual relative to its scale has
    not halved since the ``last`` one (a contact holding a body at rest: v shrinks with
    each step, G v stays at a few % of ``|G||v|``). ``kept``: the rows flagged in ``ws.inA`` are listed in
    ``ws.A`` with the Cholesky factor of their W_AA in ``ws.fac`` (the dual active-set
    method leaves them so, and so does a refinement); when they are the rows with P > 0,
    that factor is used instead of factoring W_AA again."""
    A = ws.A
    inA = ws.inA
    res = ws.s
    rhs = ws.rhs
    dP = ws.r
    na = np.int64(0)  # not the literal 0: numba would compile the solve it is given twice
    worst = 0.0
    scale = 0.0
    same = kept
    for i in range(k):
        if P[i] > 0.0:
            t = -c[i]
            s = abs(c[i])
            for j in range(v.shape[0]):
                t += G[i, j] * v[j]
                s += abs(G[i, j] * v[j])
            res[i] = t
            na += 1
            worst = max(worst, abs(t))
            scale = max(scale, s)
            same = same and inA[i]
        elif inA[i]:
            same = False
    if na == 0 or worst <= 64.0 * 2.220446049250313e-16 * scale or worst > 0.5 * last * scale:  # nothing to do
        return False, worst, scale
    if same:  # unless W_AA is ill-conditioned (pivots spread by 1e4, cond >= 1e8): factored
        # afresh in the rows' order, as it was before the factor was kept; at cond ~ 1e13 the
        # factor of the order the rows were added in left complementarity residuals of 3e-9
        lo = math.inf
        hi = 0.0
        for a in range(na):
            lo = min(lo, ws.fac[a, a])
            hi = max(hi, ws.fac[a, a])
        same = hi <= 1e4 * lo
    if same:  # A[:na] holds these rows, ws.fac the factor of their W_AA
        for a in range(na):
            rhs[a] = -res[A[a]]
        cho_solve(ws.fac, rhs, dP, na)
    else:
        na = np.int64(0)
        for i in range(k):
            inA[i] = P[i] > 0.0
            if inA[i]:
                A[na] = i
                rhs[na] = -res[i]
                na += 1
        if not _solve_active(W, A, na, rhs, dP, ws.sub, ws.fac):
            for i in range(k):
                inA[i] = False
            return False, worst, scale
    for a in range(na):
        if P[A[a]] + dP[a] < 0.0:
            return False, worst, scale
    for a in range(na):
        P[A[a]] += dP[a]
        for j in range(v.shape[0]):
            v[j] += MinvGt[A[a], j] * dP[a]
    return True, worst, scale
