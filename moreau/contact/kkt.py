"""The KKT check shared by every backend: :func:`kkt_residuals_kernel`, the scaled residuals
of an answer ``(v, P)`` of the one-step QP (re-exported by :mod:`moreau.contact.lcp`)."""

from __future__ import annotations

import math

from numba import njit

from moreau.core.kernels import chain_product, chain_solve, cho_solve_pair

__all__ = ["kkt_residuals_kernel", "kkt_residuals_rows"]

# the check's sums may be reassociated (vectorized): they measure, nothing downstream owes
# them equal bits (docs/performance.md, "Many rows in contact"); the solves it calls keep their order
_jit = njit(cache=True, nogil=True, forceinline=True, _nrt=False, fastmath={"reassoc"})  # type: ignore[call-overload]


@_jit
def kkt_residuals_kernel(M, L, b, G, c, v, P, k, out, Gv, GtP, r, d, x, X, rd, keep, p, o, cq, sq, gen, chain):
    """Scaled KKT residuals of ``(v, P)`` for the one-step QP on the first k rows of G
    (all unilateral): :func:`~moreau.contact.kkt.kkt_residuals_rows` with ``kn = k``."""
    kkt_residuals_rows(M, L, b, G, c, v, P, k, k, out, Gv, GtP, r, d, x, X, rd, keep, p, o, cq, sq, gen, chain)


@_jit
def kkt_residuals_rows(M, L, b, G, c, v, P, k, kn, out, Gv, GtP, r, d, x, X, rd, keep, p, o, cq, sq, gen, chain):
    """Scaled KKT residuals of ``(v, P)`` for the one-step QP on the first k rows of G,
    written to ``out`` (4,): primal, dual, complementarity, stationarity (dimensionless).

    Contact rows are measured as normal velocities against the contact's own velocity
    scale (the largest of ``|c|``, ``|G v|``, the normal velocity the impulses make, and
    ``1e-9 |G||v|``); an impulse counts through the velocity it makes, ``P_i Σ_j G_ij²/M_jj``.
    Stationarity is measured per coordinate as a velocity error: ``δ = M⁻¹ (M v − b − Gᵀ P)``
    against ``max(|v_i|, |(M⁻¹ b)_i|, 1e-9 (‖v‖_M + ‖M⁻¹b‖_M)/√M_ii)``, less the round-off
    floor of that reconstruction, ``16 ε √(M⁻¹)_ii Σ_j √(M⁻¹)_jj (|M||v| + |b| + |Gᵀ||P|)_j``
    (an impulse that stops a heavy motion leaves a residual that cancels large momenta;
    a chain of 24 links stopped flat on a floor is exact only to 3e-6 by this measure,
    the piston to 1e-13). When ``max |δ_i| / max(|v_i|, |(M⁻¹ b)_i|)`` is at most 1e-12,
    that bound of the measure is returned and the floor (O(n³)) is not computed. Every
    measure is invariant under a rescaling of any single coordinate (a change of units),
    so a light coordinate's velocity error is not hidden behind a heavy one's momentum.
    ``L`` is the Cholesky factor of M; Gv (>= k), GtP, r, d, x (n) and X (n x n) are work
    arrays. The floor's √(M⁻¹)_jj are kept in ``rd`` (n + 1, ``rd[n]`` = 1 once they are):
    ``keep`` says M and L are those of the last call with this ``rd`` (a step's later
    passes), so they are reused, not formed again (O(n³)).

    ``chain``: M v and M⁻¹ in O(n) by the chain's kernels from ``p, o, cq, sq, gen``
    (unread otherwise; every caller passes arrays of these types: one compiled version).

    Only the first ``kn`` rows are unilateral (primal, dual and complementarity); rows
    kn..k−1 (tangential rows of friction, with their own law check in
    :mod:`moreau.contact.friction`, ``c`` their slip velocity's offset) enter
    stationarity and the velocity scale. Returns
    the velocity scale; ``Gv`` holds ``G v`` on return.
    """
    n = M.shape[0]
    if not keep:
        rd[n] = 0.0
    for j in range(n):
        GtP[j] = 0.0
        d[j] = 1.0 / M[j, j]  # (d is free until the stationarity solve below)
    # the floor keeps vel² representable: a row whose Jacobian vanishes (a pendulum tip
    # touching a floor at the bottom of its swing) has every velocity scale 0, and
    # 1e-300² underflowed to 0 (a ZeroDivisionError in the complementarity residual)
    vel = 1e-150
    for i in range(k):
        t = 0.0
        f = 0.0
        for j in range(n):
            t += G[i, j] * v[j]
            f += abs(G[i, j]) * abs(v[j])
            GtP[j] += G[i, j] * P[i]
        Gv[i] = t
        vel = max(vel, abs(c[i]), abs(t), 1e-9 * f)
    primal = 0.0  # the largest −slack, −P_i w_i and |P_i w_i slack|; scaled by vel once it is known
    dual = 0.0
    comp = 0.0
    for i in range(k):
        a = 0.0
        wi = 0.0
        for j in range(n):
            a += abs(G[i, j]) * abs(GtP[j]) * d[j]
            wi += G[i, j] * G[i, j] * d[j]
        vel = max(vel, a)
        if i < kn:
            slack = Gv[i] - c[i]
            pw = P[i] * wi
            primal = max(primal, -slack)
            dual = max(dual, -pw)
            comp = max(comp, abs(pw * slack))
    if chain:
        chain_product(p, o, cq, sq, v, x)  # (x: M v, for now)
        for i in range(n):
            r[i] = x[i] - b[i] - GtP[i]
        chain_solve(p, o, cq, sq, gen, r, d)
        chain_solve(p, o, cq, sq, gen, b, x)
    else:
        for i in range(n):
            r[i] = -b[i] - GtP[i]
        for j in range(n):  # r += M v by columns: independent updates, not one long sum
            vj = v[j]
            for i in range(n):
                r[i] += M[i, j] * vj
        cho_solve_pair(L, r, d, b, x, n)
    out[0] = primal / vel
    out[1] = dual / vel
    out[2] = comp / (vel * vel)
    # a velocity error below 1e-12 of its scale needs no round-off floor (the check
    # passes whatever the floor): the O(n³) bound below is computed only above it
    raw = 0.0
    for i in range(n):
        sc = max(abs(v[i]), abs(x[i]), 1e-300)
        raw = max(raw, abs(d[i]) / sc)
    if raw <= 1e-12:
        out[3] = raw
        return vel
    ev = 0.0
    ex = 0.0
    for i in range(n):
        for j in range(n):
            ev += v[i] * M[i, j] * v[j]
            ex += x[i] * M[i, j] * x[j]
    energy = math.sqrt(max(ev, 0.0)) + math.sqrt(max(ex, 0.0))
    # round-off floor of δ: |M⁻¹| (|M||v| + |b| + |Gᵀ||P|) ε, with |M⁻¹_ij| <= √(M⁻¹_ii M⁻¹_jj)
    # (r cancels large momenta when an impulse stops a motion: the answer is then exact
    # to this floor, not better)
    if not (keep and rd[n] == 1.0):
        inverse_diagonal_sqrt(L, n, X, rd)
        rd[n] = 1.0
    total = 0.0
    for j in range(n):
        sj = abs(b[j])
        for l in range(n):
            sj += abs(M[j, l] * v[l])
        for l in range(k):
            sj += abs(G[l, j] * P[l])
        total += rd[j] * sj
    stat = 0.0
    for i in range(n):
        sc = max(abs(v[i]), abs(x[i]), 1e-9 * energy / math.sqrt(M[i, i]), 1e-300)
        floor = 16.0 * 2.220446049250313e-16 * rd[i] * total
        stat = max(stat, max(0.0, abs(d[i]) - floor) / sc)
    out[3] = stat
    return vel


# a call, not inlined: it runs at most once per step, and inlined into every check it
# slowed the small problems' steps (the 3-link chain on a floor, the four-bar) by 1.5–2x
@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]
def inverse_diagonal_sqrt(L, n, X, out):
    """out[j] = √(M⁻¹)_jj = ‖L⁻¹ e_j‖ (j < n) for M = L Lᵀ: X = L⁻¹ (lower triangle) row by
    row, each row an update by the rows above it (contiguous), then its column norms."""
    for i in range(n):
        for j in range(i):
            X[i, j] = 0.0
        X[i, i] = 1.0
        for l in range(i):
            a = L[i, l]
            for j in range(l + 1):
                X[i, j] -= a * X[l, j]
        d = 1.0 / L[i, i]
        for j in range(i + 1):
            X[i, j] *= d
    for j in range(n):
        out[j] = 0.0
    for i in range(n):
        for j in range(i + 1):
            out[j] += X[i, j] * X[i, j]
    for j in range(n):
        out[j] = math.sqrt(out[j])
