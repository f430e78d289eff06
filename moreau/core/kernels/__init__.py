"""Physics kernels: the one implementation of every built-in mass matrix, force and gap.

Each kernel is a small numba function on arrays, free of allocation where it writes into
``out``: the compiled time loop (:mod:`moreau.compiled.loop`) calls them step after step, and the
Python path calls the very same functions through the objects of :mod:`moreau.model.forces`,
:mod:`moreau.model.chain` and :mod:`moreau.model.barriers` (so the physics is written once). Kernels
that *add* into ``out`` accumulate a sum of effects without temporaries.

Parameters are read from one flat float array at an offset (the layout is stated per
kernel): a scene's parameters live in one pool, and the hot loop creates no array views.

Kinds (the codes a scene is lowered to, :mod:`moreau.compiled.lowering`):

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

from moreau.core.jitcache import ensure_fresh

ensure_fresh()  # before any cached machine code of moreau is loaded

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

# Each kernel is compiled once and inlined where it is called by LLVM (forceinline): as
# calls, the piston step costs a quarter more; inlined by numba (inline="always") at
# every level, the loop took minutes and gigabytes to compile (see moreau.compiled.loop).
# _nrt=False (numba's internal flag): kernels allocate nothing, so they need no reference
# counting, and the Python path and the loop (compiled without it) share one version.
_jit = njit(cache=True, nogil=True, forceinline=True, _nrt=False)  # type: ignore[call-overload]


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


# -- dense linear algebra for small SPD systems (leading k x k blocks, no views) -----------
@_jit
def cholesky(M, L, k):
    """Lower Cholesky factor of the leading k x k block of M into L; returns the index of
    the first non-positive pivot, or −1 when the block is positive definite."""
    for j in range(k):
        t = M[j, j]
        for i in range(j):
            t -= L[j, i] * L[j, i]
        if not t > 0.0:  # also NaN
            return j
        d = math.sqrt(t)
        L[j, j] = d
        for i in range(j + 1, k):
            u = M[i, j]
            for l in range(j):
                u -= L[i, l] * L[j, l]
            L[i, j] = u / d
        for i in range(j):
            L[i, j] = 0.0
    return -1


@_jit
def lt_solve(L, out, k):
    """out[:k] = L⁻ᵀ out[:k] in place, L lower triangular (back substitution)."""
    for i in range(k - 1, -1, -1):
        t = out[i]
        for l in range(i + 1, k):
            t -= L[l, i] * out[l]
        out[i] = t / L[i, i]


@_jit
def cho_solve(L, b, out, k):
    """out[:k] = M⁻¹ b[:k] with M = L Lᵀ on the leading k x k block (b, out may alias)."""
    for i in range(k):
        t = b[i]
        for l in range(i):
            t -= L[i, l] * out[l]
        out[i] = t / L[i, i]
    lt_solve(L, out, k)


@_jit
def sym_product(A, B, W, k, n):
    """W[:k, :k] = A[:k, :n] B[:k, :n]ᵀ for a product known to be symmetric: the lower
    triangle is summed and mirrored, so that W is exactly symmetric."""
    for i in range(k):
        for j in range(i + 1):
            u = 0.0
            for l in range(n):
                u += A[i, l] * B[j, l]
            W[i, j] = u
            W[j, i] = u


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


# -- Newton's law at an impact (CombinedProjection) ----------------------------------------
@_jit
def impact_instant(g0, u, an, h):
    """The first s in [0, h] (s) at which ``g0 + u s + an s²/2`` reaches 0: where in the
    step a row that starts at gap ``g0`` (m, or the gap's unit) with normal velocity
    ``u`` and free normal acceleration ``an`` meets its barrier. 0 when it starts inside
    (g0 <= 0), h when the parabola does not reach 0 within the step."""
    if g0 <= 0.0:
        return 0.0
    disc = u * u - 2.0 * an * g0
    if disc < 0.0:
        return h
    d = math.sqrt(disc) - u  # the smaller root as 2 g0 / d: no cancellation
    if d <= 0.0:
        return h
    return min(2.0 * g0 / d, h)


@_jit
def impact_law(e, u, an, g0, h, locate):
    """Newton's law for a row that closes in a step, under CombinedProjection.

    The row bounces when its approach is an impact: faster than the smooth forces change
    its normal velocity in one step. The impulse turns the normal velocity at the impact
    instant s, ``u_s = u + s an``, into ``−e u_s``, and the smooth forces act for the
    rest of the step: ``U⁺ >= −e u_s + (h − s) an``, at least 0 — except with ``locate``
    when that motion keeps the row off the barrier to the end of the step: it may then
    already fall back towards it, and the bound is the motion's own end velocity.

    Parameters
    ----------
    e : float
        Restitution coefficient of the row, > 0.
    u : float
        Normal velocity at the start of the step, ``G(q_m) v_k``.
    an : float
        Free normal acceleration, ``G(q_m) M⁻¹ f``.
    g0 : float
        Gap at the start of the step, ``g(q_k)``.
    h : float
        Step size (s).
    locate : bool
        False: s = h/2 (the step's midpoint, on average where a row that closes in the
        step meets its barrier) and the impact test on ``u``. True: s from
        :func:`impact_instant` and the impact test on ``u_s``.

    Returns
    -------
    c : float
        The lower bound of U⁺ (negative only with ``locate``); NaN when the approach is
        not an impact.
    s : float
        The impact instant (s into the step). The impulse acting at s instead of at the
        midpoint moves the end-of-step position by ``(h/2 − s) M⁻¹ Gᵀ P``, and the
        normal velocities just before and after it sum to ``U + U⁺ + (2 s − h) an``
        (the impact log's energy).
    """
    if locate:
        s = impact_instant(g0, u, an, h)
        us = u + s * an
        fast = -us > abs(h * an)
    else:
        s = 0.5 * h
        us = u + s * an
        fast = -u > abs(h * an)
    if not fast:
        return math.nan, s
    w = h - s
    c = -e * us + w * an
    if not (locate and w * (0.5 * w * an - e * us) > 0.0):  # (the end-of-step gap of that motion)
        c = max(c, 0.0)
    return c, s


# -- allocating wrappers for the Python path ------------------------------------------------
def force_of(kernel, n: int, *args) -> np.ndarray:
    """Call an accumulating force kernel on a fresh zero vector of size n."""
    out = np.zeros(n)
    kernel(*args, out)
    return out


def flat(*params) -> np.ndarray:
    """The parameters of one kernel as one flat float array (the kernel's layout)."""
    return np.ascontiguousarray(np.concatenate([np.ravel(np.asarray(x, dtype=float)) for x in params]))


def cos_sin(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cos q, sin q) through :func:`trig`, for the Python path."""
    c = np.empty(q.shape[0])
    s = np.empty(q.shape[0])
    trig(q, c, s)
    return c, s
