"""Physics kernels: the one implementation of every built-in mass matrix, force and gap.

Each kernel is a small numba function on arrays, free of allocation where it writes into
``out``: the compiled time loop (:mod:`moreau.loop`) calls them step after step, and the
Python path calls the very same functions through the objects of :mod:`moreau.forces`,
:mod:`moreau.chain` and :mod:`moreau.barriers` (so the physics is written once). Kernels
that *add* into ``out`` accumulate a sum of effects without temporaries.

Kinds (the codes a scene is lowered to, :mod:`moreau.lowering`):

========== ===================================================== ========================
code       generalized force added                               built from
========== ===================================================== ========================
CONST      ``c``                                                 ConstantForce, LinkTorque
LINEAR_V   ``−C v``                                              LinearDamping, JointDamping
AFFINE_Q   ``−K q + b``                                          LinearSpring, JointSprings
TRIG       ``B ∘ cos q − A ∘ sin q``                             ChainGravity, PointForce
HARMONIC   ``a sin(ω t + φ)``                                    HarmonicForce
FOURIER_PT ``cos q ∘ (X F) + sin q ∘ (Y F)``, F = d·s(q_j)       PointForce(FourierLoad)
========== ===================================================== ========================

Barriers: LINEAR ``g = A q + b`` (LinearBarrier, JointStop) and TRIG
``g = g0 + A cos q + B sin q`` (PointLineBarrier). Masses: constant, or the pendulum
chain's ``ν ∘ cos(φ_i − φ_j) + ν^s ∘ sin(φ_i − φ_j)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "CONST", "LINEAR_V", "AFFINE_Q", "TRIG", "HARMONIC", "FOURIER_PT", "USER",
    "BAR_LINEAR", "BAR_TRIG", "BAR_USER", "MASS_CONST", "MASS_CHAIN", "MASS_USER",
]

# effect kinds
CONST, LINEAR_V, AFFINE_Q, TRIG, HARMONIC, FOURIER_PT, USER = 0, 1, 2, 3, 4, 5, 99
# barrier kinds
BAR_LINEAR, BAR_TRIG, BAR_USER = 0, 1, 99
# mass kinds
MASS_CONST, MASS_CHAIN, MASS_USER = 0, 1, 99

_jit = njit(cache=True, nogil=True)


# -- forces ------------------------------------------------------------------------------
@_jit
def add_constant(c, out):
    """out += c."""
    for i in range(out.shape[0]):
        out[i] += c[i]


@_jit
def add_linear_v(C, v, out):
    """out += −C v (damping)."""
    n = out.shape[0]
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += C[i, j] * v[j]
        out[i] -= s


@_jit
def add_affine_q(K, b, q, out):
    """out += −K q + b (springs)."""
    n = out.shape[0]
    for i in range(n):
        s = b[i]
        for j in range(n):
            s -= K[i, j] * q[j]
        out[i] += s


@_jit
def add_trig(A, B, q, out):
    """out += B ∘ cos q − A ∘ sin q (gravity on a chain, a constant force at a point)."""
    for i in range(out.shape[0]):
        out[i] += B[i] * math.cos(q[i]) - A[i] * math.sin(q[i])


@_jit
def add_harmonic(a, omega, phase, t, out):
    """out += a sin(ω t + φ)."""
    s = math.sin(omega * t + phase)
    for i in range(out.shape[0]):
        out[i] += a[i] * s


@_jit
def fourier_series(a0, a, b, w, x):
    """s(x) = a0 + Σ_k a_k cos(k w x) + b_k sin(k w x), k = 1..K (Clenshaw-free
    recurrence on the rotation e^{i w x}: one sin/cos pair per call)."""
    c1 = math.cos(w * x)
    s1 = math.sin(w * x)
    ck, sk = c1, s1
    out = a0
    for k in range(a.shape[0]):
        out += a[k] * ck + b[k] * sk
        ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
    return out


@_jit
def add_point_fourier(X, Y, d, a0, a, b, w, j, q, out):
    """A force F = d · s(q_j) (s a Fourier series) at a point of a chain:
    out += cos q ∘ (X F) + sin q ∘ (Y F)."""
    s = fourier_series(a0, a, b, w, q[j])
    F0 = d[0] * s
    F1 = d[1] * s
    for i in range(out.shape[0]):
        out[i] += math.cos(q[i]) * (X[i, 0] * F0 + X[i, 1] * F1) + math.sin(q[i]) * (
            Y[i, 0] * F0 + Y[i, 1] * F1)


# -- barriers ----------------------------------------------------------------------------
@_jit
def gaps_linear(A, b, q, out):
    """out = A q + b, shape (m,)."""
    m, n = A.shape
    for r in range(m):
        s = b[r]
        for j in range(n):
            s += A[r, j] * q[j]
        out[r] = s


@_jit
def jacobian_linear(A, out):
    """out = A, shape (m, n)."""
    out[:, :] = A


@_jit
def gaps_trig(g0, A, B, q, out):
    """out = g0 + A cos q + B sin q, shape (m,) (points of a chain against lines)."""
    m, n = A.shape
    for r in range(m):
        s = g0[r]
        for j in range(n):
            s += A[r, j] * math.cos(q[j]) + B[r, j] * math.sin(q[j])
        out[r] = s


@_jit
def jacobian_trig(A, B, q, out):
    """out = B ∘ cos q − A ∘ sin q, shape (m, n)."""
    m, n = A.shape
    for j in range(n):
        c = math.cos(q[j])
        s = math.sin(q[j])
        for r in range(m):
            out[r, j] = B[r, j] * c - A[r, j] * s


# -- the pendulum chain's mass matrix and centrifugal terms ------------------------------
@_jit
def chain_mass(nu_c, nu_s, q, out):
    """out = ν ∘ cos(q_i − q_j) + ν^s ∘ sin(q_i − q_j), shape (n, n)."""
    n = q.shape[0]
    for i in range(n):
        out[i, i] = nu_c[i, i]
        for j in range(i + 1, n):
            d = q[i] - q[j]
            c = math.cos(d)
            s = math.sin(d)
            out[i, j] = nu_c[i, j] * c + nu_s[i, j] * s
            out[j, i] = nu_c[j, i] * c - nu_s[j, i] * s


@_jit
def add_chain_bias(nu_c, nu_s, q, v, out):
    """out += Σ_j (ν^s_ij cos d_ij − ν_ij sin d_ij) v_j², d_ij = q_i − q_j (−N(q) φ̇²)."""
    n = q.shape[0]
    for i in range(n):
        s = 0.0
        for j in range(n):
            if j != i:
                d = q[i] - q[j]
                s += (nu_s[i, j] * math.cos(d) - nu_c[i, j] * math.sin(d)) * v[j] * v[j]
        out[i] += s


# -- dense linear algebra for small SPD systems --------------------------------------------
@_jit
def cholesky(M, L):
    """Lower Cholesky factor L of M (n x n) into ``L``; returns the index of the first
    non-positive pivot, or −1 when M is positive definite (within round-off)."""
    n = M.shape[0]
    for j in range(n):
        s = M[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:  # also NaN
            return j
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = M[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d
        for i in range(j):
            L[i, j] = 0.0
    return -1


@_jit
def cho_solve(L, b, out):
    """out = M⁻¹ b with M = L Lᵀ (b and out of shape (n,); they may be the same array)."""
    n = L.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * out[k]
        out[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= L[k, i] * out[k]
        out[i] = s / L[i, i]


@_jit
def symmetry_defect(M):
    """max |M − Mᵀ| relative to max |M| (0 for a symmetric matrix)."""
    n = M.shape[0]
    big = 0.0
    asym = 0.0
    for i in range(n):
        for j in range(n):
            a = abs(M[i, j])
            if a > big:
                big = a
            d = abs(M[i, j] - M[j, i])
            if d > asym:
                asym = d
    if big == 0.0:
        return 0.0
    return asym / big


# -- allocating wrappers for the Python path ------------------------------------------------
def force_of(kernel, n: int, *args) -> np.ndarray:
    """Call an accumulating force kernel on a fresh zero vector of size n."""
    out = np.zeros(n)
    kernel(*args, out)
    return out
