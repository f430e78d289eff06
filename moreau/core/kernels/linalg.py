"""Dense linear algebra for small SPD systems (leading k x k blocks, no views), and the
matrix exponential of a small step matrix (the tangent dynamics, ``expm_taylor``)."""

from __future__ import annotations

import math

from moreau.core.kernels.jit import jit as _jit

__all__ = ["cholesky", "lt_solve", "cho_solve", "cho_solve_pair", "sym_product", "delassus", "delassus_product",
           "symmetry_defect", "expm_taylor"]


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
def cho_solve_pair(L, b1, out1, b2, out2, k):
    """:func:`cho_solve` of two right-hand sides at once, each bit for bit as alone (two
    independent sums per row instead of one: the substitutions are bound by latency)."""
    for i in range(k):
        t1 = b1[i]
        t2 = b2[i]
        for l in range(i):
            t1 -= L[i, l] * out1[l]
            t2 -= L[i, l] * out2[l]
        out1[i] = t1 / L[i, i]
        out2[i] = t2 / L[i, i]
    for i in range(k - 1, -1, -1):
        t1 = out1[i]
        t2 = out2[i]
        for l in range(i + 1, k):
            t1 -= L[l, i] * out1[l]
            t2 -= L[l, i] * out2[l]
        out1[i] = t1 / L[i, i]
        out2[i] = t2 / L[i, i]


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
def delassus(L, G, X, MinvGt, W, k, n):
    """W[:k, :k] = G M⁻¹ Gᵀ (exactly symmetric) and MinvGt[j] = M⁻¹ G[j] for the first k
    rows of G (M = L Lᵀ, n x n): each column of X is :func:`cho_solve` of a row of G and W
    :func:`sym_product` of G and M⁻¹ Gᵀ, bit for bit (each entry summed in the same
    order), with the k right-hand sides side by side in ``X`` (work, (n, >= k)): the inner
    loops run over them, contiguous and independent, so they vectorize (4x faster than a
    row at a time at n = k = 40). L's zeros are skipped (a pile of bodies has a block
    diagonal M: its factor has almost none but them)."""
    for i in range(n):
        for j in range(k):
            X[i, j] = G[j, i]
    for i in range(n):  # L Y = Gᵀ
        for l in range(i):
            a = L[i, l]
            if a == 0.0:
                continue
            for j in range(k):
                X[i, j] -= a * X[l, j]
        a = L[i, i]
        for j in range(k):
            X[i, j] = X[i, j] / a
    for i in range(n - 1, -1, -1):  # Lᵀ X = Y
        for l in range(i + 1, n):
            a = L[l, i]
            if a == 0.0:
                continue
            for j in range(k):
                X[i, j] -= a * X[l, j]
        a = L[i, i]
        for j in range(k):
            X[i, j] = X[i, j] / a
    delassus_product(G, X, W, k, n)
    for j in range(k):
        for i in range(n):
            MinvGt[j, i] = X[i, j]


@_jit
def delassus_product(G, X, W, k, n):
    """W[:k, :k] = G X for X = M⁻¹ Gᵀ (n x >= k), exactly symmetric: W_ij = Σ_l G_il X_lj
    for j <= i, mirrored; the k sums of a row side by side (contiguous, they vectorize),
    skipping G's zeros (a chain's rows touch the links up to their own)."""
    for i in range(k):
        for j in range(i + 1):
            W[i, j] = 0.0
        for l in range(n):
            a = G[i, l]
            if a == 0.0:
                continue
            for j in range(i + 1):
                W[i, j] += a * X[l, j]
        for j in range(i):
            W[j, i] = W[i, j]


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


@_jit
def expm_taylor(B, E, W, V):
    """E = exp(B) (d x d) by scaling and squaring of a degree-6 Taylor polynomial: B is
    scaled by 2⁻ˢ to a 1-norm of at most 1/4 (truncation below 1e-8 relative, round-off for
    the small steps of the tangent dynamics), the polynomial evaluated by Horner's rule,
    then squared s times. ``W``, ``V``: work arrays of B's shape. Returns s."""
    d = B.shape[0]
    nrm = 0.0
    for j in range(d):
        col = 0.0
        for i in range(d):
            col += abs(B[i, j])
        nrm = max(nrm, col)
    s = 0
    if nrm > 0.25:
        s = max(0, int(math.ceil(math.log2(nrm / 0.25))))
    scale = 1.0 / 2.0 ** s
    for i in range(d):
        for j in range(d):
            W[i, j] = B[i, j] * scale
            E[i, j] = W[i, j] / 6.0
        E[i, i] += 1.0
    for p in (5, 4, 3, 2, 1):  # E = I + W E / p
        for i in range(d):
            for j in range(d):
                t = 0.0
                for l in range(d):
                    t += W[i, l] * E[l, j]
                V[i, j] = t / p
        for i in range(d):
            for j in range(d):
                E[i, j] = V[i, j]
            E[i, i] += 1.0
    for _ in range(s):
        for i in range(d):
            for j in range(d):
                t = 0.0
                for l in range(d):
                    t += E[i, l] * E[l, j]
                V[i, j] = t
        for i in range(d):
            for j in range(d):
                E[i, j] = V[i, j]
    return s
