"""Barrier kernels: gaps g(q) and Jacobians of the built-in barriers, written from row ``r0``."""

from __future__ import annotations

from moreau.core.kernels.jit import jit as _jit

__all__ = ["gaps_linear", "jacobian_linear", "gaps_trig", "jacobian_trig"]


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
