"""Force kernels: each adds one built-in effect's generalized force into ``out``."""

from __future__ import annotations

import math

from moreau.core.kernels.jit import jit as _jit

__all__ = [
    "add_constant", "add_linear_v", "add_affine_q", "trig", "add_trig", "add_harmonic",
    "fourier_series", "add_point_fourier",
]


# -- forces ------------------------------------------------------------------------------
# Parameters come as one flat float array ``p`` read from offset ``o`` (no array views in
# the hot loop: each would cost a reference count); the layout is given per kernel.
@_jit
def add_constant(p, o, out):
    """out += c; p[o:] = c (n)."""
    for i in range(out.shape[0]):
        out[i] += p[o + i]


@_jit
def add_linear_v(p, o, v, out):
    """out += −C v (damping); p[o:] = C (n x n, row-major)."""
    n = out.shape[0]
    for i in range(n):
        t = 0.0
        for j in range(n):
            t += p[o + i * n + j] * v[j]
        out[i] -= t


@_jit
def add_affine_q(p, o, q, out):
    """out += −K q + b (springs); p[o:] = K (n x n), b (n)."""
    n = out.shape[0]
    ob = o + n * n
    for i in range(n):
        t = p[ob + i]
        for j in range(n):
            t -= p[o + i * n + j] * q[j]
        out[i] += t


@_jit
def trig(q, c, s):
    """c = cos q, s = sin q: evaluated once per configuration, shared by every kernel."""
    for i in range(q.shape[0]):
        c[i] = math.cos(q[i])
        s[i] = math.sin(q[i])


@_jit
def add_trig(p, o, c, s, out):
    """out += B ∘ cos q − A ∘ sin q (gravity on a chain, a constant force at a point);
    p[o:] = A (n), B (n); ``c, s`` = cos q, sin q."""
    n = out.shape[0]
    for i in range(n):
        out[i] += p[o + n + i] * c[i] - p[o + i] * s[i]


@_jit
def add_harmonic(p, o, t, out):
    """out += a sin(ω t + φ); p[o:] = a (n), ω, φ."""
    n = out.shape[0]
    sn = math.sin(p[o + n] * t + p[o + n + 1])
    for i in range(n):
        out[i] += p[o + i] * sn


@_jit
def fourier_series(a0, p, oa, ob, K, w, x):
    """σ(x) = a0 + Σ_k a_k cos(k w x) + b_k sin(k w x), k = 1..K, with a = p[oa:oa+K],
    b = p[ob:ob+K] (one sin/cos pair per call: the harmonics by rotation)."""
    c1 = math.cos(w * x)
    s1 = math.sin(w * x)
    ck, sk = c1, s1
    out = a0
    for k in range(K):
        out += p[oa + k] * ck + p[ob + k] * sk
        ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
    return out


@_jit
def add_point_fourier(p, o, q, c, s, out):
    """A force F = d · σ(q_j) (σ a Fourier series) at a point of a chain:
    out += cos q ∘ (X F) + sin q ∘ (Y F).

    p[o:] = X (n x 2), Y (n x 2), d (2), a0, ω, j, K, a (K), b (K)."""
    n = out.shape[0]
    h = o + 4 * n
    K = int(p[h + 5])
    sig = fourier_series(p[h + 2], p, h + 6, h + 6 + K, K, p[h + 3], q[int(p[h + 4])])
    F0 = p[h] * sig
    F1 = p[h + 1] * sig
    oy = o + 2 * n
    for i in range(n):
        out[i] += c[i] * (p[o + 2 * i] * F0 + p[o + 2 * i + 1] * F1) + s[i] * (
            p[oy + 2 * i] * F0 + p[oy + 2 * i + 1] * F1)
