"""Many contacts with friction: projected Gauss–Seidel on the one-step problem, and an
exact polish on the contact states it finds.

The Delassus form of :mod:`moreau.contact.friction` (``U = W P + w``, normal rows first,
then one tangent row per frictional contact). :func:`pgs_sweeps` relaxes one contact at a
time (the normal impulse projected on ``P_N >= 0``, then the tangential one on the cone
``|P_T| <= mu P_N``): each sweep costs O(R²) and the sweeps converge linearly, fast at first.
The answer is then made exact on the states they found (:func:`classify`: open,
sticking, slipping with the impulse's sign): :func:`polish` solves the equations of those
states (U_N = 0 closed, U_T = 0 sticking, P_T = ±mu P_N slipping) as a correction of the
relaxed impulses on a semidefinite Cholesky factor of W on the closed and sticking rows
(a redundant row — two corners of one body on one wall — keeps its relaxed share), and
:func:`correct` changes the states the polished answer violates, for another polish.
:func:`moreau.contact.friction.solve_friction_step` runs them for many contacts and
checks the answer against the full law, as it checks Lemke's. Projected Gauss–Seidel
on the Delassus form is the classical relaxation of contact problems (Jean's NSCD;
Acary & Brogliato 2008, "Numerical Methods for Nonsmooth Dynamical Systems", ch. 13);
the polish is an active-set step on the states it found, which makes the answer exact.
"""

from __future__ import annotations

import math

from moreau.contact.active_set import _jit

__all__ = ["pgs_sweeps", "classify", "polish", "correct", "OPEN", "STICK", "SLIP"]

#: contact states
OPEN, STICK, SLIP = 0, 1, 2
#: sweeps before the first look at the states (doubled before each next one), and at most
PGS_FIRST_SWEEPS, PGS_MAX_SWEEPS = 25, 3200
#: the states are polished once at most this fraction of them (or 2) changed since the last
#: look (a polish of 1000 contacts costs about as much as 1000 sweeps), and at the end
PGS_SETTLED = 0.02
#: polishes at one look, each on the states the last one violated
PGS_CORRECTIONS = 4


@_jit
def pgs_sweeps(W, w, mu, tf, k, R, P, U, sweeps):
    """``sweeps`` projected Gauss–Seidel sweeps on P (R,), keeping ``U = W P + w`` (W
    exactly symmetric, as ``moreau.core.kernels.delassus`` forms it); ``tf`` (k,) each
    contact's tangent row (−1: none)."""
    for _ in range(sweeps):
        for j in range(k):
            pn = max(0.0, P[j] - U[j] / W[j, j]) if W[j, j] > 0.0 else P[j]
            d = pn - P[j]
            if d != 0.0:
                P[j] = pn
                for i in range(R):
                    U[i] += W[j, i] * d  # W symmetric: its row, contiguous
            f = tf[j]
            if f >= 0:
                bound = mu[j] * P[j]
                pt = min(bound, max(-bound, P[f] - U[f] / W[f, f] if W[f, f] > 0.0 else P[f]))
                d = pt - P[f]
                if d != 0.0:
                    P[f] = pt
                    for i in range(R):
                        U[i] += W[f, i] * d


@_jit
def polish(W, w, mu, tf, k, R, P, Q, st, rows, sgn, A, Lr, r, x, iters):
    """Q (R,): P made exact on the contact states ``st`` (k,) (``sgn`` (R,): a slipping
    contact's impulse sign on its tangent row) — U_N = 0 closed, U_T = 0 sticking,
    P_T = sgn mu P_N slipping — by ``iters`` corrections from P on a semidefinite Cholesky
    factor of W on the closed and sticking rows (a pivot below 1e-11 of the largest drops
    its row, which keeps P's value), the slipping impulses following their normal ones.
    ``rows``, ``A``, ``Lr``, ``r``, ``x``: work (R,), (R, R). Returns the rows solved for."""
    for i in range(R):
        Q[i] = 0.0
    s = 0
    for j in range(k):
        if st[j] != OPEN:
            rows[s] = j
            s += 1
            Q[j] = max(P[j], 0.0)
            f = tf[j]
            if f >= 0:
                if st[j] == STICK:
                    rows[s] = f
                    s += 1
                    Q[f] = P[f]
                else:
                    Q[f] = sgn[f] * mu[j] * Q[j]
    for a in range(s):  # the upper triangle: the factor is formed in place, row by row
        for b in range(a, s):
            A[a, b] = W[rows[a], rows[b]]
    # semidefinite Cholesky, right-looking (Lr holds U = Lᵀ; its updates run along rows, so
    # they vectorize): a pivot below 1e-11 of the diagonal's largest drops its row
    dmax = 0.0
    for a in range(s):
        dmax = max(dmax, A[a, a])
    for a in range(s):
        t = A[a, a]
        if t <= 1e-11 * dmax:
            for b in range(a, s):
                Lr[a, b] = 0.0
            continue
        d = math.sqrt(t)
        Lr[a, a] = d
        for b in range(a + 1, s):
            Lr[a, b] = A[a, b] / d
        for b in range(a + 1, s):
            u = Lr[a, b]
            if u != 0.0:
                for c in range(b, s):
                    A[b, c] -= u * Lr[a, c]
    for _ in range(iters):
        worst, scale = 0.0, 1e-300
        for a in range(s):  # residual of the equations at Q
            i = rows[a]
            u = w[i]
            for c in range(R):
                u += W[i, c] * Q[c]
            r[a] = -u
            worst, scale = max(worst, abs(u)), max(scale, abs(w[i]))
        if worst <= 1e-15 * scale:
            break
        for a in range(s):  # Uᵀ y = r, column by column (dropped rows: 0)
            if Lr[a, a] == 0.0:
                x[a] = 0.0
                continue
            x[a] = r[a] / Lr[a, a]
            for c in range(a + 1, s):
                r[c] -= Lr[a, c] * x[a]
        for a in range(s - 1, -1, -1):  # U Δ = y
            if Lr[a, a] == 0.0:
                x[a] = 0.0
                continue
            t = x[a]
            for c in range(a + 1, s):
                t -= Lr[a, c] * x[c]
            x[a] = t / Lr[a, a]
        for a in range(s):
            Q[rows[a]] += x[a]
        for j in range(k):  # the slipping impulses follow their normal ones
            f = tf[j]
            if f >= 0 and st[j] == SLIP:
                Q[f] = sgn[f] * mu[j] * Q[j]
    return s


@_jit
def classify(mu, tf, k, P, st, sgn):
    """Contact states ``st`` (k,) from impulses P: OPEN (no normal impulse), STICK (inside
    the cone), SLIP (on its edge; ``sgn`` on the tangent row: the impulse's sign). Returns
    how many states changed."""
    big = 1e-300
    for j in range(k):
        big = max(big, P[j])
    changed = 0
    for j in range(k):
        f = tf[j]
        s = STICK
        if P[j] <= 1e-12 * big:
            s = OPEN
        elif f >= 0 and abs(P[f]) >= (1.0 - 1e-7) * mu[j] * P[j]:
            s = SLIP
            sgn[f] = 1.0 if P[f] > 0.0 else -1.0
        if s != st[j]:
            st[j] = s
            changed += 1
    return changed


@_jit
def correct(W, w, mu, tf, k, R, Q, st, sgn):
    """Change the states the polished Q violates: a closed row pulling (Q_N < 0) opens, an
    open row approaching (U_N < 0) closes, a sticking impulse outside its cone slips, a
    slip whose velocity agrees with its impulse sticks; returns the number changed."""
    changed = 0
    big, pbig = 1e-300, 1e-300
    for j in range(k):
        big, pbig = max(big, abs(w[j])), max(pbig, abs(Q[j]))
    for j in range(k):
        f = tf[j]
        u = w[j]
        for c in range(R):
            u += W[j, c] * Q[c]
        if st[j] != OPEN and Q[j] < -1e-12 * pbig:
            st[j] = OPEN
            changed += 1
        elif st[j] == OPEN and u < -1e-12 * big:
            st[j] = STICK
            changed += 1
        elif st[j] == STICK and f >= 0 and abs(Q[f]) > mu[j] * Q[j] * (1.0 + 1e-9) + 1e-14 * pbig:
            st[j] = SLIP
            sgn[f] = 1.0 if Q[f] > 0.0 else -1.0
            changed += 1
        elif st[j] == SLIP:
            ut = w[f]
            for c in range(R):
                ut += W[f, c] * Q[c]
            if ut * sgn[f] > 1e-12 * big:  # the slip goes the impulse's way: not Coulomb's
                st[j] = STICK
                changed += 1
    return changed
