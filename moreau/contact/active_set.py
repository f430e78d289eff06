"""The LCP methods of the exact contact solver: :func:`lcp_dual_active_set` (Goldfarb–Idnani
on W) and :func:`lcp_enumerate`, on the leading k x k block of the work arrays.

Described in :mod:`moreau.contact.lcp`, which re-exports them; :mod:`~moreau.contact.one_step`
builds their W and w from the one-step problem.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from moreau.core.kernels import cho_solve, cholesky, lt_solve

__all__ = ["lcp_dual_active_set", "lcp_enumerate", "OK", "FAILED"]

OK, FAILED = 0, 1
# allocation-free, so without reference counting; inlined by LLVM (see moreau.core.kernels.jit)
_jit = njit(cache=True, nogil=True, forceinline=True, _nrt=False)  # type: ignore[call-overload]
# internal helpers: no CPython or C entry points to build
_inline = njit(cache=True, nogil=True, forceinline=True, _nrt=False,  # type: ignore[call-overload]
               no_cpython_wrapper=True, no_cfunc_wrapper=True)


@_inline
def _solve_active(W, A, na, rhs, out, sub, fac):
    """out[:na] = W[A, A]⁻¹ rhs[:na] by Cholesky; False when W[A, A] is not PD."""
    for i in range(na):
        for j in range(na):
            sub[i, j] = W[A[i], A[j]]
    if cholesky(sub, fac, na) >= 0:
        return False
    cho_solve(fac, rhs, out, na)
    return True


@_inline
def _slacks(W, w, P, s, k):
    """s = w + W P on the first k rows; returns min s."""
    smin = math.inf
    for i in range(k):
        t = w[i]
        for j in range(k):
            t += W[i, j] * P[j]
        s[i] = t
        smin = min(smin, t)
    return smin


@_inline
def _direction(W, A, na, p, fac, y, r):
    """r = W_AA⁻¹ W_Ap (how the active impulses change per unit of P_p) with the factor
    ``fac`` of W_AA; y = L⁻¹ W_Ap is also the row that appends p to the factor, and the
    returned W_pp − yᵀy its pivot² (the Schur complement of W_AA)."""
    schur = W[p, p]
    for i in range(na):
        t = W[A[i], p]
        for j in range(i):
            t -= fac[i, j] * y[j]
        y[i] = t / fac[i, i]
        schur -= y[i] * y[i]
    for i in range(na):
        r[i] = y[i]
    lt_solve(fac, r, na)
    return schur


#: problems of at least this many rows try block principal pivoting first (a chain lying on a
#: floor closes all its rows at once: one factorization instead of one append per row)
BLOCK_MIN = 8
#: block pivoting gives up after this many factorizations, at most about the dual
#: method's work (k³/2) lost when it does
BLOCK_ITER = 3


@_inline
def _block_pivoting(W, w, P, k, tol, s, A, inA, rhs, r, sub, fac):
    """Block principal pivoting (Júdice & Pires, Optim. Methods Softw. 1994) on ``0 <= P ⟂
    w + W P >= 0``, from the rows the free motion violates: solve W_AA P_A = −w_A and swap
    every row that is wrong (P < 0 inside, slack < −tol outside) while their number
    falls. True when solved, with ``A`` (the active rows in increasing order), ``inA``
    and ``fac`` (the factor of W_AA) as :func:`lcp_dual_active_set` leaves them; False
    when W_AA is not positive definite (dependent rows), when the number of wrong rows
    does not fall, or after ``BLOCK_ITER`` factorizations (the caller then runs the dual
    method, which always ends)."""
    for i in range(k):
        inA[i] = w[i] < -tol
    best = k + 1
    for _ in range(BLOCK_ITER):
        na = np.int64(0)  # here and below not the literal 0 (or -1), which numba would compile apart
        for i in range(k):
            if inA[i]:
                A[na] = i
                rhs[na] = -w[i]
                na += 1
        if not _solve_active(W, A, na, rhs, r, sub, fac):
            return False
        for i in range(k):
            P[i] = 0.0
        for a in range(na):
            P[A[a]] = r[a]
        wrong = 0
        for i in range(k):
            if inA[i]:
                bad = P[i] < 0.0
            else:
                t = w[i]
                for a in range(na):
                    t += W[i, A[a]] * P[A[a]]
                s[i] = t
                bad = t < -tol
            if bad:
                wrong += 1
        if wrong == 0:
            return True
        if wrong >= best:
            return False
        best = wrong
        for i in range(k):
            if inA[i]:
                if P[i] < 0.0:
                    inA[i] = False
            elif s[i] < -tol:
                inA[i] = True
    return False


@_jit
def lcp_dual_active_set(W, w, P, k, tol, s, A, inA, rhs, r, sub, fac):
    """Solve ``0 <= P ⟂ w + W P >= 0`` (W PSD, the leading k x k block) by the
    Goldfarb–Idnani dual method.

    Parameters
    ----------
    W : ndarray, shape (>= k, >= k)
    w : ndarray, shape (>= k,)
    P : ndarray, shape (>= k,)
        Output: the impulses P[:k].
    k : int
        Number of rows.
    tol : float
        Accept slacks >= −tol (velocity units).
    s, A, inA, rhs, r, sub, fac : ndarray
        Work arrays (from :func:`workspace`).

    Returns
    -------
    int
        ``OK`` or ``FAILED`` (infeasible problem, or no convergence in 10 (k + 1) steps).

    Problems of ``BLOCK_MIN`` rows or more try block principal pivoting first
    (``_block_pivoting``) and start the dual method only when it gives up.
    """
    if k >= BLOCK_MIN and _block_pivoting(W, w, P, k, tol, s, A, inA, rhs, r, sub, fac):
        return OK
    for i in range(k):
        P[i] = 0.0
        inA[i] = False  # (also for k = 1: the flags tell the refinement which rows have a factor)
    if k == 1:  # closed form
        if w[0] >= -tol:
            return OK
        if not W[0, 0] > 0.0:
            return FAILED
        P[0] = -w[0] / W[0, 0]
        return OK
    na = np.int64(0)  # fac holds the Cholesky factor of W[A, A] (na x na), rows in the order of A
    converged = False
    for _ in range(10 * (k + 1)):
        p: int | np.int64 = np.int64(-1)
        worst = 0.0
        for i in range(k):
            if inA[i]:
                continue
            si = w[i]  # the slack, summed over the active rows (P is 0 elsewhere)
            for a in range(na):
                si += W[i, A[a]] * P[A[a]]
            s[i] = si
            if si < -tol:
                d = W[i, i]
                score = si / math.sqrt(d) if d > 0.0 else si
                if score < worst:
                    worst, p = score, i
        if p < 0:
            converged = True
            break
        added = False
        for _inner in range(k + 1):
            schur = _direction(W, A, na, p, fac, rhs, r)
            sp = w[p] + W[p, p] * P[p]  # (P_p > 0 after a step that dropped a row)
            for a in range(na):
                sp += W[p, A[a]] * P[A[a]]
            t1 = math.inf
            if schur > 1e-13 * max(W[p, p], 1e-300):
                t1 = -sp / schur
            t2 = math.inf
            jblock = -1
            for i in range(na):
                if r[i] > 0.0:
                    ti = P[A[i]] / r[i]
                    if ti < t2:
                        t2, jblock = ti, i
            if t1 == math.inf and t2 == math.inf:
                return FAILED  # row p cannot be satisfied: infeasible
            t = min(t1, max(t2, 0.0))
            for i in range(na):
                P[A[i]] -= t * r[i]
            P[p] += t
            if t2 < t1:  # drop the blocking row (and refactor W_AA), keep adding p
                jb = A[jblock]
                P[jb] = 0.0
                inA[jb] = False
                for i in range(jblock, na - 1):
                    A[i] = A[i + 1]
                na -= 1
                for i in range(na):
                    for j in range(na):
                        sub[i, j] = W[A[i], A[j]]
                if cholesky(sub, fac, na) >= 0:
                    return FAILED
                continue
            for j in range(na):  # append p: W[A + p, A + p] = [L 0; yᵀ √schur] [..]ᵀ
                fac[na, j] = rhs[j]
                fac[j, na] = 0.0
            fac[na, na] = math.sqrt(schur)
            A[na] = p
            inA[p] = True
            na += 1
            added = True
            break
        if not added:
            return FAILED
    if not converged:
        return FAILED
    # refine on the final active set: W_AA P_A = −w_A exactly (with its factor, which the
    # appends built as a fresh factorization would: the same operations in the same order)
    if na > 0:
        for i in range(na):
            rhs[i] = -w[A[i]]
        cho_solve(fac, rhs, r, na)
        ok = True
        for i in range(na):
            if r[i] < 0.0:
                ok = False
        if ok:
            for i in range(na):
                P[A[i]] = r[i]
    return OK


@_jit
def lcp_enumerate(W, w, P, k, tol, s, A, rhs, x, sub, fac):
    """Solve the same LCP by enumerating active sets, smallest first (k <= 12).

    Returns ``OK`` or ``FAILED`` (more than 12 rows, or no active set passes).
    """
    for i in range(k):
        P[i] = 0.0
    if k > 12:
        return FAILED
    if _slacks(W, w, P, s, k) >= -tol:
        return OK
    for size in range(1, k + 1):
        for mask in range(1, 1 << k):
            na = np.int64(0)
            for i in range(k):
                if mask >> i & 1:
                    A[na] = i
                    na += 1
            if na != size:
                continue
            for i in range(na):
                rhs[i] = -w[A[i]]
            if not _solve_active(W, A, na, rhs, x, sub, fac):
                continue
            good = True
            for i in range(na):
                if x[i] < 0.0:
                    good = False
            if not good:
                continue
            for i in range(k):
                P[i] = 0.0
            for i in range(na):
                P[A[i]] = x[i]
            if _slacks(W, w, P, s, k) >= -tol:
                return OK
    for i in range(k):
        P[i] = 0.0
    return FAILED

