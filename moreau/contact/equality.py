"""Equality rows (bilateral constraints) in the one-step problem: the step's velocity is
sought in the null space of the equality rows, in the metric of M, and the contact and
friction rows are solved there by the same solvers as without constraints.

With ``M = L Lᵀ`` (Cholesky) and ``u = Lᵀ v``, the step's QP ``min ½ vᵀMv − bᵀv`` becomes
``min ½ |u|² − (L⁻¹b)ᵀ u``; the equality rows ``G_E v = c_E`` become ``A u = c_E`` with
``A = G_E L⁻ᵀ``. A Householder QR of ``Aᵀ`` with column pivoting,

.. code-block:: text

    Aᵀ Π = Q R,   Q orthogonal (n x n),  R upper triangular,  rank r,

splits ``y = Qᵀ u`` into ``y₁ = y[:r]``, fixed by the rows (``R₁ᵀ y₁ = (Πᵀ c_E)[:r]``),
and ``y[r:]``, free. The *reduced problem* has the same size n and the same form as the
original: mass matrix I, ``b_y = [y₁; (Qᵀ L⁻¹ b)[r:]]``, each contact row
``G_y = G L⁻ᵀ Q`` with its first r columns moved into its bound
(``c_y = c − G_y[:, :r] y₁``) and zeroed. Its first r components are decoupled and
come out as y₁ exactly, so every contact solver (exact, enumeration, OSQP, qpsolvers)
solves it unchanged, and ``v = L⁻ᵀ Q y``. Redundant rows (rank r < k_E: a planar
four-bar written with one row too many) leave v unique; they must be consistent
(``Rᵀ`` of the redundant columns times y₁ equal to their c_E, else infeasible). The
impulses of the equality rows follow from ``G_Eᵀ P_E = M v⁺ − b − Gᵀ P``: ``R₁ (Πᵀ P_E)[:r]
= (Qᵀ L⁻¹ (M v⁺ − b − Gᵀ P))[:r]``, zero on redundant rows.

The same kernels hold positions on the constraint manifold after a step (a Gauss–Newton
step in the metric of M: ``Δq = −M⁻¹ G_Eᵀ (G_E M⁻¹ G_Eᵀ)⁺ g_E``, by :func:`eq_basis` and
:func:`eq_particular` with ``c = −g_E``). All allocation-free; both paths call them.
"""

from __future__ import annotations

import math

import numpy as np

from moreau.core.kernels import lt_solve
from moreau.core.kernels.jit import jit as _jit

__all__ = ["RANK_TOL", "MAX_HOLD_ITERATIONS", "eq_basis", "eq_particular", "eq_reduce_rows", "eq_free",
           "eq_velocity", "eq_impulses", "eq_project"]

#: a pivot of the QR below this fraction of the first one ends the rank (a redundant row)
RANK_TOL = 1e-9
#: Gauss–Newton iterations of the position projection before it gives up
MAX_HOLD_ITERATIONS = 10
#: a redundant row is consistent when its bound is met to this fraction of its scale
CONSISTENCY_TOL = 1e-8


@_jit
def _forward(L, x, n):
    """x = L⁻¹ x in place (L lower triangular)."""
    for i in range(n):
        t = x[i]
        for l in range(i):
            t -= L[i, l] * x[l]
        x[i] = t / L[i, i]


@_jit
def eq_basis(L, G, r0, me, Q, R, piv, x):
    """QR with column pivoting of ``Aᵀ = L⁻¹ G_Eᵀ`` (G_E: rows r0 .. r0+me of G): Q (n x n)
    and R (n x me, upper triangular in its first rank rows) in place, ``piv`` (me,) the
    original row of each column; ``x`` (n,) is work. Returns the rank."""
    n = L.shape[0]
    for j in range(me):
        for i in range(n):
            x[i] = G[r0 + j, i]
        _forward(L, x, n)
        for i in range(n):
            R[i, j] = x[i]
        piv[j] = j
    for i in range(n):
        for j in range(n):
            Q[i, j] = 1.0 if i == j else 0.0
    top = 0.0
    rank = 0
    for kk in range(min(n, me)):
        best = kk
        bn = -1.0
        for j in range(kk, me):
            s = 0.0
            for i in range(kk, n):
                s += R[i, j] * R[i, j]
            if s > bn:
                bn = s
                best = j
        nrm = math.sqrt(bn)
        if kk == 0:
            top = nrm
        if not nrm > RANK_TOL * top:  # also a zero first column
            break
        if best != kk:
            for i in range(n):
                t = R[i, kk]
                R[i, kk] = R[i, best]
                R[i, best] = t
            p = piv[kk]
            piv[kk] = piv[best]
            piv[best] = p
        alpha = -nrm if R[kk, kk] >= 0.0 else nrm
        for i in range(kk, n):
            x[i] = R[i, kk]
        x[kk] -= alpha
        uu = 0.0
        for i in range(kk, n):
            uu += x[i] * x[i]
        if uu > 0.0:
            for j in range(kk, me):
                s = 0.0
                for i in range(kk, n):
                    s += x[i] * R[i, j]
                f = 2.0 * s / uu
                for i in range(kk, n):
                    R[i, j] -= f * x[i]
            for i in range(n):
                s = 0.0
                for l in range(kk, n):
                    s += Q[i, l] * x[l]
                f = 2.0 * s / uu
                for l in range(kk, n):
                    Q[i, l] -= f * x[l]
        R[kk, kk] = alpha
        for i in range(kk + 1, n):
            R[i, kk] = 0.0
        rank += 1
    return rank


@_jit
def eq_particular(R, piv, rank, me, c, y):
    """y[:rank] from ``R₁ᵀ y₁ = (Πᵀ c)[:rank]`` (forward substitution); the redundant
    columns checked against their bounds. Returns −1, or the original index of the first
    redundant row whose bound is missed (the rows are inconsistent)."""
    for i in range(rank):
        t = c[piv[i]]
        for j in range(i):
            t -= R[j, i] * y[j]
        y[i] = t / R[i, i]
    for i in range(rank, me):
        t = -c[piv[i]]
        s = abs(c[piv[i]])
        for j in range(rank):
            t += R[j, i] * y[j]
            s += abs(R[j, i] * y[j])
        if abs(t) > CONSISTENCY_TOL * s + 1e-300:
            return piv[i]
    return -1


@_jit
def eq_reduce_rows(L, Q, rank, X, k0, k1, c, y, x):
    """Rows k0 .. k1 of X (and their bounds c) into the reduced problem: ``X_i ← X_i L⁻ᵀ Q``
    with its first ``rank`` entries moved into the bound (``c_i −= Σ_{j<rank} X_ij y_j``)
    and zeroed; ``x`` (n,) is work."""
    n = L.shape[0]
    for r in range(k0, k1):
        for i in range(n):
            x[i] = X[r, i]
        _forward(L, x, n)
        off = 0.0
        for j in range(n):
            t = 0.0
            for l in range(n):
                t += x[l] * Q[l, j]
            if j < rank:
                off += t * y[j]
                X[r, j] = 0.0
            else:
                X[r, j] = t
        c[r] -= off


@_jit
def eq_free(L, Q, rank, b, y, out, x):
    """The reduced problem's ``b_y`` into ``out``: ``Qᵀ L⁻¹ b`` with its first ``rank``
    entries replaced by y₁; ``x`` (n,) is work."""
    n = L.shape[0]
    for i in range(n):
        x[i] = b[i]
    _forward(L, x, n)
    for j in range(n):
        if j < rank:
            out[j] = y[j]
        else:
            t = 0.0
            for l in range(n):
                t += Q[l, j] * x[l]
            out[j] = t


@_jit
def eq_velocity(L, Q, yv, v):
    """v = L⁻ᵀ Q yv (the answer of the reduced problem back in coordinates)."""
    n = L.shape[0]
    for i in range(n):
        t = 0.0
        for j in range(n):
            t += Q[i, j] * yv[j]
        v[i] = t
    lt_solve(L, v, n)


@_jit
def eq_impulses(L, Q, R, piv, rank, me, F, PE, x):
    """The equality rows' impulses from the constraint impulse ``F = G_Eᵀ P_E`` (n,)
    (``M v⁺ − b − Gᵀ P``): ``R₁ (Πᵀ P_E)[:rank] = (Qᵀ L⁻¹ F)[:rank]``, zero on redundant
    rows; ``x`` (n,) is work (F is not changed)."""
    n = L.shape[0]
    for i in range(n):
        x[i] = F[i]
    _forward(L, x, n)
    for j in range(me):
        PE[j] = 0.0
    for i in range(rank - 1, -1, -1):
        t = 0.0
        for l in range(n):
            t += Q[l, i] * x[l]
        for j in range(i + 1, rank):
            t -= R[i, j] * PE[piv[j]]
        PE[piv[i]] = t / R[i, i]


@_jit
def eq_project(L, S, k, me, c, Q, R, piv, x, y, yv, dv):
    """The smallest change ``dv`` in the metric of ``M = L Lᵀ`` with ``S[:me] dv = c[:me]``
    and ``S[me:k] dv = 0``: the velocity projected onto the equality rows (the first me
    rows of ``S``, ``c = −G_E v``) keeping the velocities of the held rows ``S[me:k]``
    (the tangent rows of the step's sticking contacts). Held rows redundant with the equality rows and in
    conflict with them are dropped (the projection onto the equality rows alone).
    ``R`` (n, k), ``piv`` (k,), ``c`` (k,) with ``c[me:k] = 0``; ``Q``, ``x``, ``y``,
    ``yv`` work; returns the rank."""
    n = L.shape[0]
    first = np.int64(0)  # not the literal 0: numba would compile eq_basis twice
    rank = eq_basis(L, S, first, k, Q, R, piv, x)
    if eq_particular(R, piv, rank, k, c, y) >= 0 and k > me:
        rank = eq_basis(L, S, first, me, Q, R, piv, x)
        eq_particular(R, piv, rank, me, c, y)
    for i in range(n):
        yv[i] = y[i] if i < rank else 0.0
    eq_velocity(L, Q, yv, dv)
    return rank
