"""Barrier kernels: gaps g(q) and Jacobians of the built-in barriers, written from row ``r0``."""

from __future__ import annotations

from moreau.core.kernels.jit import jit as _jit

__all__ = ["gaps_linear", "jacobian_linear", "gaps_trig", "jacobian_trig", "gaps_chain_point",
           "jacobian_chain_point"]


# -- barriers ----------------------------------------------------------------------------
@_jit
def gaps_linear(p, o, mr, q, g, r0):
    """g[r0:r0+mr] = A q + b; p[o:] = A (mr x n), b (mr)."""
    n = q.shape[0]
    ob = o + mr * n
    for r in range(mr):
        t = 0.0
        for j in range(n):
            t += p[o + r * n + j] * q[j]
        g[r0 + r] = t + p[ob + r]  # A q first, then b: numpy's order of the reference path


@_jit
def jacobian_linear(p, o, mr, G, r0):
    """G[r0:r0+mr] = A; p[o:] = A (mr x n), b (mr)."""
    n = G.shape[1]
    for r in range(mr):
        for j in range(n):
            G[r0 + r, j] = p[o + r * n + j]


@_jit
def gaps_trig(p, o, mr, c, s, g, r0):
    """g[r0:r0+mr] = g0 + A cos q + B sin q (points of a chain against lines);
    p[o:] = g0 (mr), A (mr x n), B (mr x n); ``c, s`` = cos q, sin q."""
    n = c.shape[0]
    oa = o + mr
    ob = oa + mr * n
    for r in range(mr):
        ac = 0.0
        bs = 0.0
        for j in range(n):
            ac += p[oa + r * n + j] * c[j]
            bs += p[ob + r * n + j] * s[j]
        g[r0 + r] = p[o + r] + ac + bs  # the order of g0 + A cos q + B sin q


@_jit
def jacobian_trig(p, o, mr, c, s, G, r0):
    """G[r0:r0+mr] = B ∘ cos q − A ∘ sin q; layout of :func:`gaps_trig`."""
    n = c.shape[0]
    oa = o + mr
    ob = oa + mr * n
    for r in range(mr):
        for j in range(n):
            G[r0 + r, j] = p[ob + r * n + j] * c[j] - p[oa + r * n + j] * s[j]


# -- points of a pendulum chain against lines, from the chain's structure ------------------
# Row r, a point on link k_r: g_r = g0_r + du_r X_k + dw_r Y_k + a_r cos φ_k + b_r sin φ_k,
# with X_k = Σ_{j<k} l_j cos φ_j, Y_k = Σ_{j<k} l_j sin φ_j (the joint's position, summed
# once for all rows): O(n + m) against the O(m n) of gaps_trig. Layout p[o:]: g0, k, du,
# dw, a, b (mr each), the rows in order of k (mr), l (n).
@_jit
def gaps_chain_point(p, o, mr, c, s, g, r0):
    """g[r0:r0+mr] for points of a chain against lines (layout above); ``c, s`` = cos q,
    sin q (n,)."""
    ol = o + 7 * mr
    x = 0.0
    y = 0.0
    j = 0
    for t in range(mr):
        r = int(p[o + 6 * mr + t])
        k = int(p[o + mr + r])
        while j < k:
            x += p[ol + j] * c[j]
            y += p[ol + j] * s[j]
            j += 1
        g[r0 + r] = (p[o + r] + p[o + 2 * mr + r] * x + p[o + 3 * mr + r] * y
                     + p[o + 4 * mr + r] * c[k] + p[o + 5 * mr + r] * s[k])


@_jit
def jacobian_chain_point(p, o, mr, c, s, G, r0):
    """G[r0:r0+mr] of :func:`gaps_chain_point`: l_j (dw_r cos φ_j − du_r sin φ_j) for j < k_r,
    b_r cos φ_k − a_r sin φ_k at k_r, 0 beyond."""
    n = c.shape[0]
    ol = o + 7 * mr
    for r in range(mr):
        k = int(p[o + mr + r])
        du = p[o + 2 * mr + r]
        dw = p[o + 3 * mr + r]
        for j in range(k):
            G[r0 + r, j] = p[ol + j] * (dw * c[j] - du * s[j])
        G[r0 + r, k] = p[o + 5 * mr + r] * c[k] - p[o + 4 * mr + r] * s[k]
        for j in range(k + 1, n):
            G[r0 + r, j] = 0.0
