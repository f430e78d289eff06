"""The pendulum chain's mass matrix and centrifugal (bias) terms.

A serial chain's M(q) has rank-2 semiseparable off-diagonal blocks: for i < j,

    M_ij = M_ji = u_i · w_j,   u_i = l_i e(φ_i),   w_j = R(φ_j) (β_j, γ_j),

with l_i the link's length, β_j = l_j Σ_{k>j} m_k + m_j a_j and γ_j = m_j b_j (a_j, b_j the
centre of mass along and across link j), R(φ) the rotation by φ and e(φ) = (cos φ, sin φ).
So M x, the centrifugal terms and the Cholesky factor of M need O(n) work from these
generators, against O(n²) (O(n³) for the factor) from the dense matrix: at n = 40 they
cost a tenth of the dense kernels.

Layout ``p[o:]`` of every kernel here: ν (n x n), ν^s (n x n), then the generators
diag ν (n), l (n), β (n), γ (n) (``PendulumChain`` builds it).
"""

from __future__ import annotations

import math

from moreau.core.kernels.jit import jit as _jit

__all__ = ["chain_mass", "add_chain_bias", "chain_product", "chain_product_pair", "chain_generators", "chain_fill",
           "chain_factor", "chain_solve", "chain_solve_columns", "chain_inverse_diagonal_sqrt", "CHAIN_STRUCTURED_MIN"]

#: Chains of at least this many links take the O(n) forms where a step could also use
#: dense ones (the contact problem from the chain's solve, points against lines, the energy
#: check's kinetic energy); shorter chains keep the dense forms, cheaper at that size
#: (docs/performance.md, "The chain in O(n)"). One number for both paths and every such choice.
CHAIN_STRUCTURED_MIN = 8


# -- the pendulum chain's mass matrix and centrifugal terms ------------------------------
@_jit
def chain_mass(p, o, c, s, M):
    """M = ν ∘ cos(q_i − q_j) + ν^s ∘ sin(q_i − q_j) (n x n); ``c, s`` = cos q, sin q
    (cos(q_i − q_j) = c_i c_j + s_i s_j, sin = s_i c_j − c_i s_j)."""
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
    """out += Σ_j ∂M_ij/∂q_i v_j² = Σ_j (ν^s_ij cos d_ij − ν_ij sin d_ij) v_j², d_ij = q_i − q_j
    (the centrifugal terms −N(q) φ̇², N m), in O(n): u_i⊥ · Σ_{j>i} w_j v_j² +
    w_i⊥ · Σ_{j<i} u_j v_j² (x⊥ = x turned by +90°)."""
    n = c.shape[0]
    g = o + 2 * n * n
    ax = 0.0
    ay = 0.0
    for i in range(n - 1, -1, -1):  # the links beyond i
        li = p[g + n + i]
        out[i] += li * (c[i] * ay - s[i] * ax)
        v2 = v[i] * v[i]
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        ax += (be * c[i] - ga * s[i]) * v2
        ay += (be * s[i] + ga * c[i]) * v2
    bx = 0.0
    by = 0.0
    for i in range(n):  # the links before i
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        out[i] += (be * c[i] - ga * s[i]) * by - (be * s[i] + ga * c[i]) * bx
        v2 = p[g + n + i] * v[i] * v[i]
        bx += c[i] * v2
        by += s[i] * v2


@_jit
def chain_product(p, o, c, s, x, out):
    """out = M(q) x (n,) in O(n); ``c, s`` = cos q, sin q; ``x`` and ``out`` must not alias."""
    n = c.shape[0]
    g = o + 2 * n * n
    ax = 0.0
    ay = 0.0
    for i in range(n - 1, -1, -1):
        out[i] = p[g + i] * x[i] + p[g + n + i] * (c[i] * ax + s[i] * ay)
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        ax += (be * c[i] - ga * s[i]) * x[i]
        ay += (be * s[i] + ga * c[i]) * x[i]
    bx = 0.0
    by = 0.0
    for i in range(n):
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        out[i] += (be * c[i] - ga * s[i]) * bx + (be * s[i] + ga * c[i]) * by
        lx = p[g + n + i] * x[i]
        bx += c[i] * lx
        by += s[i] * lx


@_jit
def chain_product_pair(p, o, c, s, c2, s2, x, out, out2):
    """out = M(q) x and out2 = M(q₂) x (n,) in one sweep, each exactly as
    :func:`chain_product` computes it (``c, s``, ``c2, s2``: cos/sin of q and q₂; ``x``
    must alias neither output). The two running sums are independent, so the sweep costs
    little more than one product (the energy-consistent step's T(q⁺, v⁺) − T(q_m, v⁺))."""
    n = c.shape[0]
    g = o + 2 * n * n
    ax = 0.0
    ay = 0.0
    ax2 = 0.0
    ay2 = 0.0
    for i in range(n - 1, -1, -1):
        di, li, xi = p[g + i], p[g + n + i], x[i]
        out[i] = di * xi + li * (c[i] * ax + s[i] * ay)
        out2[i] = di * xi + li * (c2[i] * ax2 + s2[i] * ay2)
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        ax += (be * c[i] - ga * s[i]) * xi
        ay += (be * s[i] + ga * c[i]) * xi
        ax2 += (be * c2[i] - ga * s2[i]) * xi
        ay2 += (be * s2[i] + ga * c2[i]) * xi
    bx = 0.0
    by = 0.0
    bx2 = 0.0
    by2 = 0.0
    for i in range(n):
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        out[i] += (be * c[i] - ga * s[i]) * bx + (be * s[i] + ga * c[i]) * by
        out2[i] += (be * c2[i] - ga * s2[i]) * bx2 + (be * s2[i] + ga * c2[i]) * by2
        lx = p[g + n + i] * x[i]
        bx += c[i] * lx
        by += s[i] * lx
        bx2 += c2[i] * lx
        by2 += s2[i] * lx


@_jit
def chain_generators(p, o, c, s, gen):
    """The O(n) generators of M(q)'s lower Cholesky factor into ``gen`` (4, n): the pivots
    d_j, p_j = (u_j − S_j w_j) / d_j (two rows) and 1 / d_j, with d_j² = M_jj − w_jᵀ S_j w_j
    and S_j = Σ_{k<j} p_k p_kᵀ (2 x 2), so that L_jj = d_j and L_ij = w_i · p_j (i > j).
    Returns the index of the first non-positive pivot, or −1 (as ``cholesky``)."""
    n = c.shape[0]
    g = o + 2 * n * n
    sxx = 0.0
    sxy = 0.0
    syy = 0.0
    for j in range(n):
        be, ga = p[g + 2 * n + j], p[g + 3 * n + j]
        wx = be * c[j] - ga * s[j]
        wy = be * s[j] + ga * c[j]
        tx = sxx * wx + sxy * wy
        ty = sxy * wx + syy * wy
        t = p[g + j] - (wx * tx + wy * ty)
        if not t > 0.0:  # also NaN
            return j
        d = math.sqrt(t)
        inv = 1.0 / d
        lj = p[g + n + j]
        px = (lj * c[j] - tx) * inv
        py = (lj * s[j] - ty) * inv
        sxx += px * px
        sxy += px * py
        syy += py * py
        gen[0, j] = d
        gen[1, j] = px
        gen[2, j] = py
        gen[3, j] = inv
    return -1


@_jit
def chain_fill(p, o, c, s, gen, L):
    """The dense factor L (n x n, upper triangle zeroed) from :func:`chain_generators`,
    row by row: L_ij = w_i · p_j (O(n²))."""
    n = c.shape[0]
    g = o + 2 * n * n
    for i in range(n):
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        wx = be * c[i] - ga * s[i]
        wy = be * s[i] + ga * c[i]
        for j in range(i):
            L[i, j] = wx * gen[1, j] + wy * gen[2, j]
        L[i, i] = gen[0, i]
        for j in range(i + 1, n):
            L[i, j] = 0.0


@_jit
def chain_factor(p, o, c, s, gen, L):
    """The lower Cholesky factor of M(q) into ``L`` (n x n) in O(n²), its generators into
    ``gen`` (4, n); returns the index of the first non-positive pivot, or −1."""
    st = chain_generators(p, o, c, s, gen)
    if st < 0:
        chain_fill(p, o, c, s, gen, L)
    return st


@_jit
def chain_solve(p, o, c, s, gen, b, out):
    """out = M(q)⁻¹ b (n,) in O(n) from :func:`chain_generators`: L y = b, then Lᵀ x = y,
    with L_ij = w_i · p_j carried as 2-vector sums (``b`` and ``out`` may alias)."""
    n = c.shape[0]
    g = o + 2 * n * n
    zx = 0.0
    zy = 0.0
    for i in range(n):
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        y = (b[i] - ((be * c[i] - ga * s[i]) * zx + (be * s[i] + ga * c[i]) * zy)) * gen[3, i]
        out[i] = y
        zx += gen[1, i] * y
        zy += gen[2, i] * y
    zx = 0.0
    zy = 0.0
    for j in range(n - 1, -1, -1):
        x = (out[j] - (gen[1, j] * zx + gen[2, j] * zy)) * gen[3, j]
        out[j] = x
        be, ga = p[g + 2 * n + j], p[g + 3 * n + j]
        zx += (be * c[j] - ga * s[j]) * x
        zy += (be * s[j] + ga * c[j]) * x


@_jit
def chain_solve_columns(p, o, c, s, gen, X, k, zx, zy):
    """X[:, :k] = M(q)⁻¹ X[:, :k] in place: :func:`chain_solve` of k right-hand sides side
    by side, each column bit for bit as alone (the inner loops run over the columns,
    contiguous and independent, so they vectorize); ``zx, zy`` (>= k) are work."""
    n = c.shape[0]
    g = o + 2 * n * n
    for j in range(k):
        zx[j] = 0.0
        zy[j] = 0.0
    for i in range(n):
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        wx = be * c[i] - ga * s[i]
        wy = be * s[i] + ga * c[i]
        gx, gy, d = gen[1, i], gen[2, i], gen[3, i]
        for j in range(k):
            y = (X[i, j] - (wx * zx[j] + wy * zy[j])) * d
            X[i, j] = y
            zx[j] += gx * y
            zy[j] += gy * y
    for j in range(k):
        zx[j] = 0.0
        zy[j] = 0.0
    for i in range(n - 1, -1, -1):
        be, ga = p[g + 2 * n + i], p[g + 3 * n + i]
        wx = be * c[i] - ga * s[i]
        wy = be * s[i] + ga * c[i]
        gx, gy, d = gen[1, i], gen[2, i], gen[3, i]
        for j in range(k):
            x = (X[i, j] - (gx * zx[j] + gy * zy[j])) * d
            X[i, j] = x
            zx[j] += wx * x
            zy[j] += wy * x


@_jit
def chain_inverse_diagonal_sqrt(p, o, c, s, gen, out):
    """out[j] = √(M⁻¹)_jj (n,) in O(n) from :func:`chain_generators` (the dense way, O(n³):
    :func:`moreau.contact.kkt.inverse_diagonal_sqrt`). Column j of L⁻¹ is 1/d_j at j and
    −w_i · Z_i / d_i below, with Z_{j+1} = a_j = p_j / d_j and Z_{i+1} = T_i Z_i,
    T_i = I − a_i w_iᵀ; so (M⁻¹)_jj = 1/d_j² + a_jᵀ Q_{j+1} a_j with the 2 x 2 sums
    Q_j = w_j w_jᵀ / d_j² + T_jᵀ Q_{j+1} T_j, Q_n = 0, summed from the tip."""
    n = c.shape[0]
    g = o + 2 * n * n
    qxx = 0.0
    qxy = 0.0
    qyy = 0.0
    for j in range(n - 1, -1, -1):
        di = gen[3, j]
        ax = gen[1, j] * di
        ay = gen[2, j] * di
        out[j] = math.sqrt(di * di + ax * (qxx * ax + qxy * ay) + ay * (qxy * ax + qyy * ay))
        be, ga = p[g + 2 * n + j], p[g + 3 * n + j]
        wx = be * c[j] - ga * s[j]
        wy = be * s[j] + ga * c[j]
        t00 = 1.0 - ax * wx
        t01 = -ax * wy
        t10 = -ay * wx
        t11 = 1.0 - ay * wy
        m00 = qxx * t00 + qxy * t10
        m01 = qxx * t01 + qxy * t11
        m10 = qxy * t00 + qyy * t10
        m11 = qxy * t01 + qyy * t11
        dd = di * di
        qxx = t00 * m00 + t10 * m10 + wx * wx * dd
        qxy = t00 * m01 + t10 * m11 + wx * wy * dd
        qyy = t01 * m01 + t11 * m11 + wy * wy * dd
