"""The exact refinement of an approximate answer (OSQP's): from the active set it
proposes to the exact solution of the one-step problem, in mass-normalized units.

:func:`_exact_from_proposed_set` and its pieces are numba-compiled: small dense loops,
called at every solve (LAPACK's triangular solves go through a threaded BLAS whose
start-up costs milliseconds here). :func:`_cholesky` and :func:`_normalized` bring the
problem to those units; :func:`_upper_solve` brings the answer back. :func:`ensure_loaded`
loads them (or compiles them, once per machine) before a run's first solve.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np
from numba import njit

from moreau.core.kernels import lt_solve, sym_product

_jit = njit(cache=True, nogil=True)
log = logging.getLogger(__name__)


def _cholesky(M):
    """Lower Cholesky factor of M, or None when M is not positive definite."""
    from moreau.core.kernels import cholesky

    M = np.ascontiguousarray(M, dtype=float)
    n = M.shape[0]
    L = np.empty((n, n))
    return None if cholesky(M, L, n) >= 0 else L


@_jit
def _normalized(L, b, G, A, r, uf):
    """``u_free = L⁻¹ b`` into uf and the rows of ``G L⁻ᵀ`` scaled to unit length into A,
    their scales ``1 / ‖(G L⁻ᵀ)_i‖`` into r (1 for a zero row)."""
    n = L.shape[0]
    for i in range(n):
        t = b[i]
        for j in range(i):
            t -= L[i, j] * uf[j]
        uf[i] = t / L[i, i]
    for row in range(G.shape[0]):
        nrm = 0.0
        for i in range(n):
            t = G[row, i]
            for j in range(i):
                t -= L[i, j] * A[row, j]
            A[row, i] = t / L[i, i]
            nrm += A[row, i] * A[row, i]
        s = 1.0 / math.sqrt(nrm) if nrm > 0.0 else 1.0
        r[row] = s
        for i in range(n):
            A[row, i] *= s


@_jit
def _upper_solve(L, x):
    """L⁻ᵀ x for a lower triangular L (a new array)."""
    y = x.copy()
    lt_solve(L, y, y.shape[0])
    return y


@_jit
def _solve_on(W, w, S, ns, kept, out, F):
    """``W_SS p_S = −w_S`` on the rows ``S[:ns]`` by Cholesky, taking them in order and
    leaving out a row whose pivot shows it dependent on those before it (below 1e-13 of its
    W_ii, the exact solver's test: a redundant contact gets no impulse). The rows kept go
    to ``kept``, their impulses to ``out``; returns how many were kept. F: work (>= ns)²."""
    nk = 0
    for a in range(ns):
        i = S[a]
        d = W[i, i]
        for r in range(nk):  # row nk of F: F[:nk, :nk]⁻¹ W[kept, i]
            t = W[i, kept[r]]
            for m in range(r):
                t -= F[nk, m] * F[r, m]
            F[nk, r] = t / F[r, r]
            d -= F[nk, r] * F[nk, r]
        if not d > 1e-13 * W[i, i]:
            continue
        F[nk, nk] = math.sqrt(d)
        kept[nk] = i
        nk += 1
    for r in range(nk):
        t = -w[kept[r]]
        for m in range(r):
            t -= F[r, m] * out[m]
        out[r] = t / F[r, r]
    for r in range(nk - 1, -1, -1):
        t = out[r]
        for m in range(r + 1, nk):
            t -= F[m, r] * out[m]
        out[r] = t / F[r, r]
    return nk


@_jit
def _nonnegative_on(W, w, S, ns, kept, out, F):
    """:func:`_solve_on` on ``S[:ns]``, dropping the most negative impulse and solving again
    until none is negative; S[:returned] holds the rows, ``out`` their impulses. Returns
    ``(rows, rows dropped)``."""
    dropped = 0
    while True:
        nk = _solve_on(W, w, S, ns, kept, out, F)
        for a in range(nk):
            S[a] = kept[a]
        ns = nk
        worst = -1
        for a in range(nk):
            if out[a] < 0.0 and (worst < 0 or out[a] < out[worst]):
                worst = a
        if worst < 0:
            return ns, dropped
        for a in range(worst, ns - 1):
            S[a] = S[a + 1]
        ns -= 1
        dropped += 1



@_jit
def _lcp_of(A, uf, c, u, W, w, s):
    """The LCP of the normalized problem into W (``A Aᵀ``) and w (``A u_free − c``), and
    the slacks of the proposed u into s (``A u − c``); returns the tolerance of the
    complementarity check, 1e-12 of the problem's velocity scale."""
    k, n = A.shape
    scale = 1e-300
    for j in range(n):
        scale = max(scale, abs(uf[j]))
    for i in range(k):
        t = -c[i]
        t0 = -c[i]
        for j in range(n):
            t += A[i, j] * uf[j]
            t0 += A[i, j] * u[j]
        w[i] = t
        s[i] = t0
        scale = max(scale, abs(t), abs(c[i]))
    sym_product(A, A, W, k, n)
    return 1e-12 * scale


@_jit
def _proposed_set(p, s, S):
    """The rows with ``p_i > s_i`` and ``p_i > 0`` into S, in decreasing ``p_i − s_i``;
    returns how many."""
    k = p.shape[0]
    found = np.empty(k, dtype=np.int64)
    key = np.empty(k)
    ns = 0
    for i in range(k):
        if p[i] > s[i] and p[i] > 0.0:
            found[ns] = i
            key[ns] = s[i] - p[i]
            ns += 1
    for a in range(ns):  # a stable insertion sort by key (numba's argsort compiles for seconds)
        i, kk, b = found[a], key[a], a
        while b > 0 and kk < key[b - 1]:
            found[b], key[b] = found[b - 1], key[b - 1]
            b -= 1
        found[b], key[b] = i, kk
    for a in range(ns):
        S[a] = found[a]
    return ns


@_jit
def _set_impulses(S, ns, out, q, inA):
    """q: the impulses ``out`` on the rows ``S[:ns]``, zero elsewhere; inA: those rows."""
    q[:] = 0.0
    inA[:] = False
    for a in range(ns):
        q[S[a]] = out[a]
        inA[S[a]] = True


@_jit
def _most_violated(W, w, q, inA, tol):
    """The row outside the set whose slack ``w + W q`` is most below ``−tol`` (less the
    round-off of ``W q``), or −1 (the rows in the set have zero slack)."""
    k = W.shape[0]
    eps = 2.220446049250313e-16
    j = -1
    worst = 0.0
    for i in range(k):
        if inA[i]:
            continue
        t = w[i]
        fl = 0.0
        for m in range(k):
            t += W[i, m] * q[m]
            fl += abs(W[i, m] * q[m])
        t += 8.0 * eps * fl
        if t < -tol and (j < 0 or t < worst):
            j, worst = i, t
    return j


@_jit
def _add_row(j, W, w, S, ns, kept, out, F, q, inA, dp):
    """Bring the violated row j to its bound (a Goldfarb–Idnani step): move the set's
    impulses q so that their slacks stay zero, dropping a row whose impulse reaches zero
    first, then add j and solve exactly on the new set (:func:`_nonnegative_on`).
    Returns ``(rows in the set, rows dropped there)``, or ``(-1, 0)`` when it fails (the
    set lost independence to round-off, or row j cannot be satisfied: infeasible)."""
    k = W.shape[0]
    slj = w[j]
    for m in range(k):
        slj += W[j, m] * q[m]
    for _inner in range(k + 1):
        ds = W[j, j]
        if ns > 0:
            if _solve_on(W, W[j], S, ns, kept, dp, F) != ns:  # dp = −W_AA⁻¹ W_Aj
                return -1, 0  # the set lost independence to round-off
            for a in range(ns):
                ds += W[j, S[a]] * dp[a]
        t_full = -slj / ds if ds > 1e-13 * W[j, j] else math.inf
        t_part = math.inf
        blocking = -1
        for a in range(ns):
            if dp[a] < 0.0:
                ratio = -q[S[a]] / dp[a]
                if ratio < t_part:
                    t_part, blocking = ratio, a
        t = min(t_full, t_part)
        if t == math.inf:
            return -1, 0  # row j cannot be satisfied: infeasible
        for a in range(ns):
            q[S[a]] += t * dp[a]
        q[j] += t
        slj += t * ds
        if t_full <= t_part:
            S[ns] = j
            ns += 1
            ns, dropped = _nonnegative_on(W, w, S, ns, kept, out, F)  # exactly on the new set
            _set_impulses(S, ns, out, q, inA)
            return ns, dropped
        q[S[blocking]] = 0.0
        inA[S[blocking]] = False
        for a in range(blocking, ns - 1):
            S[a] = S[a + 1]
        ns -= 1
    return -1, 0


@_jit
def _correct_set(W, w, tol, S, ns, kept, out, F, q, inA, dp):
    """While a row is violated (:func:`_most_violated`), add it (:func:`_add_row`).
    Returns ``(rows in the set, corrections made)``; the rows −1 when it does not settle."""
    k = W.shape[0]
    corrections = 0
    for _ in range(4 * k + 10):
        j = _most_violated(W, w, q, inA, tol)
        if j < 0:
            return ns, corrections
        corrections += 1
        ns, dropped = _add_row(j, W, w, S, ns, kept, out, F, q, inA, dp)
        if ns < 0:
            return -1, corrections
        corrections += dropped
    return -1, corrections


@_jit
def _refined_answer(L, GR, cRo, A, uf, rR, W, S, ns, kept, F, q, dp, v, P):
    """From the settled impulses q: ``u = u_free + Aᵀ q``, ``v = L⁻ᵀ u``, then iterative
    refinement in the original units (``G v − c`` on the set, back through W) while it
    reduces that residual, keeping the best answer; v and P (original units) into ``v``,
    ``P``."""
    k, n = A.shape
    ut = uf.copy()
    for i in range(k):
        if q[i] != 0.0:
            for j in range(n):
                ut[j] += A[i, j] * q[i]
    vv = _upper_solve(L, ut)
    # iterative refinement in the original units, keeping the best answer
    best = math.inf
    vbest = vv.copy()
    qbest = q.copy()
    t = np.zeros(k)
    for step in range(4 if ns > 0 else 0):
        err = 0.0
        for i in range(k):
            t[i] = 0.0
        for a in range(ns):
            i = S[a]
            g = -cRo[i]
            for j in range(n):
                g += GR[i, j] * vv[j]
            t[i] = rR[i] * g  # the set's slacks, in the normalized units
            err = max(err, abs(t[i]))
        if not err < best:
            break
        best = err
        for j in range(n):  # (element by element: a slice copy compiles numba's shape checks)
            vbest[j] = vv[j]
        for i in range(k):
            qbest[i] = q[i]
        if err == 0.0 or step == 3:
            break
        if _solve_on(W, t, S, ns, kept, dp, F) != ns:
            break
        ok = True
        for a in range(ns):
            if q[S[a]] + dp[a] < 0.0:
                ok = False
        if not ok:
            break
        du = np.zeros(n)
        for a in range(ns):
            q[S[a]] += dp[a]
            for j in range(n):
                du[j] += A[S[a], j] * dp[a]
        dv = _upper_solve(L, du)
        for j in range(n):
            vv[j] += dv[j]
    for j in range(n):
        v[j] = vbest[j]
    for i in range(k):
        P[i] = qbest[i] * rR[i]


@_jit
def _exact_from_proposed_set(L, GR, cRo, A, uf, c, rR, u, p, v, P, info):
    """The exact solution of the normalized one-step problem ``min ½|u|² − u_freeᵀu,
    A u >= c`` (rows of A of unit length) from the active set an approximate ``(u, p)``
    proposes: v (original units) and P into ``v``, ``P``; returns False when it does not
    settle (an infeasible problem, or active rows that lose independence to round-off).
    ``info[0]``: the corrections the proposed set needed.

    In the LCP form ``0 <= p ⟂ s = w + W p >= 0`` (``W = A Aᵀ``, unit diagonal;
    ``w = A u_free − c``) p and s are both velocities, and the proposed set is
    ``{i : p_i > s_i, p_i > 0}`` (the primal–dual active-set rule: for OSQP's polished
    answer, the rows it holds at their bound with an impulse), taken in decreasing
    ``p_i − s_i``. On that set solve ``W_SS p_S = −w_S`` (a row dependent on those before
    it, a redundant contact, gets no impulse) and drop the most negative impulse until
    none is negative: a dual-feasible start. Then check complementarity, and while a row is
    violated (slack below ``−tol``, 1e-12 of the problem's velocity scale as in the exact
    solver, less the round-off of ``W p``) correct the set as the dual active-set method of
    Goldfarb & Idnani does (the exact solver's, :mod:`moreau.contact.lcp`): add the most violated
    row, moving the impulses of the set so that their slacks stay zero, and drop a row
    whose impulse reaches zero first. From a right proposal this is one solve. Last,
    ``u = u_free + Aᵀ p``, ``v = L⁻ᵀ u`` and iterative refinement in the original units
    (``G v − c`` on the set, back through W) while it reduces that residual: large
    cancelling impulses (nearly opposed rows) leave it at round-off of the large terms.
    """
    k, n = A.shape
    W = np.empty((k, k))
    w = np.empty(k)
    s = np.empty(k)
    tol = _lcp_of(A, uf, c, u, W, w, s)
    S = np.empty(k, dtype=np.int64)
    ns = _proposed_set(p, s, S)
    kept = np.empty(k, dtype=np.int64)
    out = np.empty(k)
    F = np.empty((k, k))
    ns, corrections = _nonnegative_on(W, w, S, ns, kept, out, F)
    q = np.empty(k)
    inA = np.empty(k, dtype=np.bool_)
    _set_impulses(S, ns, out, q, inA)
    dp = np.empty(k)
    ns, corrected = _correct_set(W, w, tol, S, ns, kept, out, F, q, inA, dp)
    if ns < 0:
        return False
    info[0] = corrections + corrected
    _refined_answer(L, GR, cRo, A, uf, rR, W, S, ns, kept, F, q, dp, v, P)
    return True


def ensure_loaded() -> float:
    """Load the refinement's kernels from numba's cache, or compile them there (about 7 s,
    once per machine and version, said in one logged line); returns the seconds it took.
    Called by :meth:`moreau.OSQPSolver.setup` and ``moreau compile``, on a one-row problem
    with the argument types of a run's solves."""
    t0 = time.perf_counter()
    one, zero = np.ones(1), np.zeros(1)
    L, A = np.ones((1, 1)), np.empty((1, 1))
    uf, r = np.empty(1), np.empty(1)
    _normalized(L, one, L, A, r, uf)
    _exact_from_proposed_set(L, L, zero, A, uf, zero, r, one, zero, np.empty(1), np.empty(1),
                             np.zeros(2, dtype=np.int64))
    _upper_solve(L, one)
    spent = time.perf_counter() - t0
    if spent > 2.0:  # compiled, not loaded
        log.info("moreau: the exact refinement of OSQP's answers compiled in %.0f s, once for this machine", spent)
    return spent
