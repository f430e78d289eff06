"""The pendulum chain's mass matrix and centrifugal (bias) terms."""

from __future__ import annotations

from moreau.core.kernels.jit import jit as _jit

__all__ = ["chain_mass", "add_chain_bias"]


# -- the pendulum chain's mass matrix and centrifugal terms ------------------------------
@_jit
def chain_mass(p, o, c, s, M):
    """M = ν ∘ cos(q_i − q_j) + ν^s ∘ sin(q_i − q_j) (n x n); p[o:] = ν, ν^s (n x n each);
    ``c, s`` = cos q, sin q (cos(q_i − q_j) = c_i c_j + s_i s_j, sin = s_i c_j − c_i s_j)."""
    n = c.shape[0]
    os_ = o + n * n
    for i in range(n):
        M[i, i] = p[o + i * n + i]
        for j in range(i + 1, n):
            cd = c[i] * c[j] + s[i] * s[j]
            sd = s[i] * c[j] - c[i] * s[j]
            M[i, j] = p[o + i * n + j] * cd + p[os_ + i * n + j] * sd
            M[j, i] = p[o + j * n + i] * cd - p[os_ + j * n + i] * sd


@_jit
def add_chain_bias(p, o, c, s, v, out):
    """out += Σ_j (ν^s_ij cos d_ij − ν_ij sin d_ij) v_j², d_ij = q_i − q_j (−N(q) φ̇²);
    layout of :func:`chain_mass`."""
    n = c.shape[0]
    os_ = o + n * n
    for i in range(n):
        t = 0.0
        for j in range(n):
            if j != i:
                cd = c[i] * c[j] + s[i] * s[j]
                sd = s[i] * c[j] - c[i] * s[j]
                t += (p[os_ + i * n + j] * cd - p[o + i * n + j] * sd) * v[j] * v[j]
        out[i] += t
