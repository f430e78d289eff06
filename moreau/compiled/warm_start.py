"""A persistent contact's one-step problem solved from the last step's factor: a chain
lying on a floor closes the same rows step after step, and its W = G M⁻¹ Gᵀ hardly
changes, so the Cholesky factor of the last W_AA is kept and the new problem is solved by
refinement on it, matrix-free (G and the chain's O(n) solve), without forming W.

What is kept (``OneStepWork.ids``): ``ids[0]`` is the number of closed rows the factor
``fac`` (rows ``A[:count(inA)]``) was formed for and ``ids[1:]`` their row indices; −1 when
nothing is kept, −2 right after the dual active-set method succeeded (the step then
records which rows it solved). Every other solve that uses the work arrays drops it.
"""

from __future__ import annotations

import math

from numba import njit

from moreau.core.kernels import chain_solve

__all__ = ["WARM_ITER", "keep_rows", "same_rows", "warm_solve"]

#: corrections on the kept factor before the warm start gives up (a factor of the right
#: W_AA needs one, and one more to confirm; a factor that has aged needs a few)
WARM_ITER = 4

_jit = njit(cache=True, nogil=True, forceinline=True, _nrt=False)  # type: ignore[call-overload]
# a call, not inlined: only a chain's persistent contacts run it, other scenes' loops carry
# no copy of its body (the loop's compile); its sums may be reassociated (vectorized, not
# latency-bound): its answer is accepted by its residual and owes no other computation equal bits
_call = njit(cache=True, nogil=True, _nrt=False, fastmath={"reassoc"})  # type: ignore[call-overload]
_sum = njit(cache=True, nogil=True, forceinline=True, _nrt=False, fastmath={"reassoc"})  # type: ignore[call-overload]


@_sum
def _slack(G, cA, v, i, n):
    """Row i's slack G_i v − cA_i, and the sum of its terms' magnitudes (its round-off scale)."""
    t = -cA[i]
    u = abs(cA[i])
    for j in range(n):
        g = G[i, j] * v[j]
        t += g
        u += abs(g)
    return t, u


@_call
def warm_solve(p, o, c, s, gen, G, cA, k, ws, v, P):
    """v, P of the one-step LCP ``0 <= P ⟂ G v − cA >= 0``, ``v = M⁻¹ (b + Gᵀ P)``, on
    the first k rows of G (n coordinates of a chain: :func:`~moreau.core.kernels.chain_solve`
    from ``p, o, c, s, gen``), with ``ws.vfree`` = M⁻¹ b, taking as active the rows kept
    in ``ws.A`` / ``ws.inA`` and refining on their kept factor ``ws.fac``. True when the
    answer meets the LCP to ``1e-12`` of the problem's velocity scale (as
    :func:`~moreau.contact.one_step.solve_one_step`'s): every active row's slack and
    every other row's violation below it, every active impulse >= 0. False otherwise
    (v and P are then scratch); the caller checks a True answer like any other."""
    n = c.shape[0]
    A, inA, fac, vfree, rhs, dP, gt, y, w, wu = ws.A, ws.inA, ws.fac, ws.vfree, ws.rhs, ws.r, ws.GtP, ws.x, ws.w, ws.s
    eps = 2.220446049250313e-16
    na = 0
    wscale = 1e-300
    for j in range(n):
        v[j] = vfree[j]
    for i in range(k):  # the free motion's slacks w (|terms| summed in wu): the problem's scale
        P[i] = 0.0
        if inA[i]:
            na += 1
        t, u = _slack(G, cA, v, i, n)
        w[i] = t
        wu[i] = u
        wscale = max(wscale, abs(t), abs(cA[i]))
    tol = 1e-12 * wscale
    last = math.inf
    worst = 0.0
    for it in range(WARM_ITER + 1):
        worst = 0.0
        scale = 0.0
        for a in range(na):  # the active rows' slacks at the current v (the free ones first)
            i = A[a]
            t, u = (w[i], wu[i]) if it == 0 else _slack(G, cA, v, i, n)
            rhs[a] = -t
            worst = max(worst, abs(t))
            scale = max(scale, u)
        # done at the round-off of G v − c or of the free motion's slacks (a body at rest:
        # v, and with it the first, vanishes), or when a correction no longer halves it
        if worst <= 64.0 * eps * max(scale, wscale) or worst > 0.5 * last or it == WARM_ITER:
            break
        last = worst
        for a in range(na):  # dP = fac⁻ᵀ fac⁻¹ rhs
            t = rhs[a]
            for l in range(a):
                t -= fac[a, l] * dP[l]
            dP[a] = t / fac[a, a]
        for a in range(na - 1, -1, -1):  # by rows of fac (contiguous)
            d = dP[a] / fac[a, a]
            dP[a] = d
            for l in range(a):
                dP[l] -= fac[a, l] * d
        for j in range(n):
            gt[j] = 0.0
        for a in range(na):
            d = dP[a]
            P[A[a]] += d
            for j in range(n):
                gt[j] += G[A[a], j] * d
        chain_solve(p, o, c, s, gen, gt, y)
        for j in range(n):
            v[j] += y[j]
    if worst > tol:
        return False
    for i in range(k):
        if inA[i]:
            if P[i] < 0.0:
                return False
            continue
        if _slack(G, cA, v, i, n)[0] < -tol:
            return False
    return True


@_jit
def same_rows(ids, active, m, na):
    """True when the na rows closed (flags ``active``, (m,)) are those of the kept factor:
    the same rows closed as at the last solve, whose factor may then serve."""
    if ids[0] != na:
        return False
    j = 0
    for r in range(m):
        if active[r]:
            if ids[1 + j] != r:
                return False
            j += 1
    return True


@_jit
def keep_rows(ids, active, m, na, chain):
    """Record the na closed rows as the kept factor's, after the dual method solved them
    (a ``chain``'s: other scenes keep nothing)."""
    if ids[0] != -2 or not chain:
        return
    j = 0
    for r in range(m):
        if active[r]:
            ids[1 + j] = r
            j += 1
    ids[0] = na
