"""Lemke's complementary pivoting for a general LCP: :func:`lcp_lemke`.

Finds z with ``w = A z + q``, ``0 <= z ⟂ w >= 0`` for the leading k x k block of A, A not
necessarily symmetric nor positive (semi-)definite — the planar friction LCP of
:mod:`moreau.contact.friction` is neither. The method (Lemke 1965; Cottle, Pang & Stone,
*The Linear Complementarity Problem*, 1992, §4.4) adds an artificial variable z0 with
covering vector 1, ``w − A z − 1 z0 = q``, starts from the almost complementary basis with
z0 at the most negative q_i, and pivots: the complement of the variable that left the basis
enters, the ratio test picks the row that leaves. It ends either with z0 leaving (a
solution) or on a column without a positive entry — a *secondary ray*: no solution was
found, which for the matrices of friction problems can mean that none exists. That is a
status (``RAY``), never an answer — unless z0 is already at round-off when the ray is met
(a degenerate problem: the basic point solves it but for z0's round-off): that point is
kept when it passes the answer's check below.

Degenerate problems (ties in the ratio test, frequent in contact problems: a sticking
contact with zero slip, a contact that closes with zero normal velocity) are handled by
the lexicographic ratio test on the rows of ``B⁻¹`` (the columns of the w variables in the
tableau), which excludes cycling; ratios within their round-off of each other (1e-12 of
the ratios' scale) count as ties, so round-off does not decide a tie and cycle. The basic
solution is refined once against the original data with the tableau's ``B⁻¹`` and checked
(z >= 0, w >= 0, z ⟂ w to 1e-9 of their scales): an answer that fails its own check is
``FAILED``, not returned.

Plain loops on small dense arrays: compiled once, called from the compiled time loop and
from Python (:class:`~moreau.contact.exact.ExactSolver`) alike.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from moreau.contact.active_set import _inline

__all__ = ["lcp_lemke", "lemke_workspace_shape", "OK", "FAILED", "RAY"]

OK, FAILED, RAY = 0, 1, 2


def lemke_workspace_shape(k: int) -> tuple[int, int]:
    """Shape of the tableau :func:`lcp_lemke` needs for k rows: ``(k, 2 k + 2)``."""
    return max(k, 1), 2 * max(k, 1) + 2


@_inline
def _pivot(T, k, ncol, r, c):
    """Gauss–Jordan pivot of the tableau's first k rows and ``ncol`` columns on (r, c)."""
    p = T[r, c]
    for j in range(ncol):
        T[r, j] /= p
    for i in range(k):
        if i != r:
            f = T[i, c]
            if f != 0.0:
                for j in range(ncol):
                    T[i, j] -= f * T[r, j]
            T[i, c] = 0.0
    T[r, c] = 1.0


@_inline
def _lex_less(T, k, i, ci, r, cr):
    """True when row i of ``B⁻¹`` divided by ci is lexicographically smaller than row r
    divided by cr (the tie-break of the ratio test)."""
    for j in range(k):
        a = T[i, j] / ci
        b = T[r, j] / cr
        if a < b:
            return True
        if a > b:
            return False
    return i < r


@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # a call: compiled once, not re-optimized inline
def lcp_lemke(A, q, z, k, T, basis, xb, piv=1e-9):
    """Solve ``w = A z + q, 0 <= z ⟂ w >= 0`` on the leading k x k block by Lemke's method.

    Parameters
    ----------
    A : ndarray, shape (>= k, >= k)
        The LCP matrix (any sign pattern); not modified.
    q : ndarray, shape (>= k,)
    z : ndarray, shape (>= k,)
        Out: the solution (zero when q >= 0).
    k : int
        Number of rows.
    T : ndarray, shape (>= k, >= 2 k + 2)
        Work: the tableau ``[B⁻¹ | −B⁻¹A | −B⁻¹1 | B⁻¹q]``.
    basis : ndarray of int64, shape (>= k,)
        Work, then the final basis: variable j < k is w_j, k <= j < 2k is z_{j−k}.
    xb : ndarray, shape (>= k,)
        Work.
    piv : float
        A column entry is a pivot candidate when above ``piv`` times the column's
        largest magnitude (smaller entries are round-off of zeros in a degenerate or
        singular tableau: pivoting on them ends on a spurious ray).

    Returns
    -------
    int
        ``OK``, ``RAY`` (secondary ray: no solution found) or ``FAILED``
        (pivot limit, 50 (k + 1) pivots, reached: cycling by round-off).
    """
    qmin = 0.0
    r: int | np.int64 = np.int64(-1)  # not the literal -1, here and below: numba would compile the pivot twice
    for i in range(k):
        z[i] = 0.0
        if q[i] < qmin or (q[i] == qmin and r >= 0):  # ties: the last index (lexicographic)
            qmin = q[i]
            r = i
    if r < 0:  # q >= 0: z = 0 solves it
        return OK
    nv = 2 * k + 1  # w, z, z0
    rhs = nv
    z0 = 2 * k
    for i in range(k):
        for j in range(k):
            T[i, j] = 1.0 if i == j else 0.0
            T[i, k + j] = -A[i, j]
        T[i, z0] = -1.0
        T[i, rhs] = q[i]
        basis[i] = i
    entering = z0
    status = FAILED
    at_ray = False
    for _ in range(50 * (k + 1)):
        leaving = basis[r]
        _pivot(T, k, nv + 1, r, entering)
        basis[r] = entering
        if leaving == z0:
            status = OK
            break
        entering = leaving + k if leaving < k else leaving - k  # the complement enters
        cmax = 0.0
        rscale = 0.0
        for i in range(k):
            cmax = max(cmax, abs(T[i, entering]))
            rscale = max(rscale, abs(T[i, rhs]))
        r = np.int64(-1)
        best = 0.0
        tie = 1e-12 * rscale / cmax if cmax > 0.0 else 0.0  # ratios closer than their round-off tie
        for i in range(k):
            ci = T[i, entering]
            if ci <= piv * cmax:
                continue
            ri = T[i, rhs]
            th = 0.0 if abs(ri) <= 1e-14 * rscale else ri / ci  # round-off of a zero is zero
            tol = max(1e-12 * abs(best), tie)
            if r < 0 or th < best - tol:
                r, best = i, th
            elif th <= best + tol:  # a tie: z0 leaves if it can, else the lexicographic rule
                if basis[i] == z0 or (basis[r] != z0 and _lex_less(T, k, i, ci, r, T[r, entering])):
                    r = i
                    best = min(best, th)
        if r < 0:
            status = RAY
            # a ray met with z0 already at round-off: the basic point is a solution but for
            # z0's round-off; kept when it passes the answer's check (a ray otherwise)
            for i in range(k):
                if basis[i] == z0 and abs(T[i, rhs]) <= 1e-12 * rscale:
                    T[i, rhs] = 0.0
                    status, at_ray = OK, True
            break
    if status != OK:
        return status
    checked = _refined_and_checked(A, q, z, k, T, basis, xb)  # one call site: inlined once
    return RAY if at_ray and checked != OK else checked


@_inline
def _refined_and_checked(A, q, z, k, T, basis, xb):
    """The basic solution of Lemke's final tableau into z, refined and checked; returns
    ``OK`` or ``FAILED`` (see :func:`lcp_lemke`)."""
    rhs = 2 * k + 1
    # the basic solution, refined against the original data: x_B += B⁻¹ (q − B x_B)
    # with the tableau's B⁻¹ (Gauss–Jordan accumulates round-off), while the residual halves
    for i in range(k):
        xb[i] = T[i, rhs]
    best = math.inf
    for _ in range(4):
        rn = 0.0
        for i in range(k):  # residual of w − A z = q on row i, into z (free until the end)
            t = q[i]
            for a in range(k):
                var = basis[a]
                if var < k:
                    if var == i:
                        t -= xb[a]
                elif var < 2 * k:  # z0, basic at round-off after a ray, counts as 0
                    t += A[i, var - k] * xb[a]
            z[i] = t
            rn = max(rn, abs(t))
        if not rn < 0.5 * best:
            break
        best = rn
        for a in range(k):
            t = 0.0
            for i in range(k):
                t += T[a, i] * z[i]
            T[a, rhs] = t  # the correction (the rhs column is not needed any more)
        for a in range(k):
            xb[a] = max(xb[a] + T[a, rhs], 0.0) if basis[a] < 2 * k else 0.0
    for i in range(k):
        z[i] = 0.0
    for a in range(k):
        if k <= basis[a] < 2 * k:
            z[basis[a] - k] = xb[a]
    # the answer's own check: z >= 0, w = A z + q >= 0, z ⟂ w, to 1e-9 of their scales
    # (pivots through a nearly singular tableau can end with z0 out of the basis and an
    # answer that is round-off; that is a failure, not a solution)
    zs = 0.0
    ws = 0.0
    for i in range(k):
        zs = max(zs, abs(z[i]))
        t = abs(q[i])
        for j in range(k):
            t += abs(A[i, j] * z[j])
        ws = max(ws, t)
    for i in range(k):
        t = q[i]
        for j in range(k):
            t += A[i, j] * z[j]
        if t < -1e-9 * ws or z[i] * t > 1e-9 * zs * ws:
            return FAILED
    return OK
