"""The smooth steps of the tangent dynamics (:func:`moreau.dynamics.lyapunov_spectrum_tangent`)
in compiled code, on a lowered scene (the QR of ``_reorthonormalized`` of
:mod:`moreau.dynamics.tangent`; its numpy reference is in the tests).

Between impacts the frame Q (2n x k) of the tangent dynamics is carried over a step by
``exp(h A)``, A = ∂F/∂x of the vector field F(t, x) = (v, M(q)⁻¹ f(t, q, v)) at the step's
midpoint state, by forward differences (the rule of ``moreau.dynamics.saltation._Flow``),
and re-orthonormalized by QR, in compiled code instead of the interpreter's
work (2n + 1 evaluations of f and n + 1 of M a step; docs/studies.md has the cost).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import SC_N, SC_TRIG, call
from moreau.core import kernels as _k

# the run's entry point (called from Python): NRT on, for numpy's QR
_entry = njit(cache=True, nogil=True)


@call
def _accel(ints, ekind, eoff, pool, user, t, q, v, c, s, M, L, f, fb, a):
    """a = M(q)⁻¹ f(t, q, v); returns 0, a user status (> 0) or −1 (M not positive definite)."""
    n = ints[SC_N]
    if ints[SC_TRIG]:
        _k.trig(q, c, s)
    st = ev.mass(ints, pool, user, q, c, s, M)
    if st != 0:
        return st
    if _k.cholesky(M, L, n) >= 0:
        return -1
    st = ev.force(ints, ekind, eoff, pool, user, t, q, c, s, v, f, fb)
    if st != 0:
        return st
    _k.cho_solve(L, f, a, n)
    return 0


@_entry
def smooth_steps(ints, ekind, eoff, pool, user, t0, h, X, first, last, eps, Q, logd, trace):
    """Carry the frame over the smooth steps ``first .. last − 1`` of a recorded trajectory.

    Parameters
    ----------
    ints, ekind, eoff, pool, user
        The lowered scene (:class:`moreau.compiled.lowering.CompiledScene`; ``user`` its
        slot addresses).
    t0 : float
        Time of ``X[0]`` (time units); step s runs from ``t0 + s h`` to ``t0 + (s + 1) h``.
    h : float
        Step size.
    X : ndarray, shape (steps + 1, 2n)
        The recorded states.
    first, last : int
        The steps to take (none with an impact).
    eps : float
        Relative forward-difference step of ``A``.
    Q : ndarray, shape (2n, k)
        The orthonormal frame, updated in place.
    logd : ndarray, shape (last − first, k)
        Out: ``ln |diag R|`` of each step's QR.
    trace : ndarray, shape (last − first,)
        Out: ``h trace A`` of each step.

    Returns
    -------
    int
        0, or the step that failed and why (:func:`decode_status`).
    """
    n = ints[SC_N]
    dim = 2 * n
    k = Q.shape[1]
    q, v, y = np.empty(n), np.empty(n), np.empty(n)
    c, s_, M, L = np.empty(n), np.empty(n), np.empty((n, n)), np.empty((n, n))
    f, fb, a0, a1 = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    f0 = np.empty(n)
    A = np.zeros((dim, dim))
    B, E, W, V = np.empty((dim, dim)), np.empty((dim, dim)), np.empty((dim, dim)), np.empty((dim, dim))
    for i in range(n):
        A[i, n + i] = 1.0
    for st in range(first, last):
        t = t0 + (st + 0.5) * h
        for i in range(n):
            q[i] = 0.5 * (X[st, i] + X[st + 1, i])
            v[i] = 0.5 * (X[st, n + i] + X[st + 1, n + i])
        code = _accel(ints, ekind, eoff, pool, user, t, q, v, c, s_, M, L, f0, fb, a0)
        if code != 0:
            return _failure(st, code)
        # f0 holds f(t, q, v) and L the factor of M(q) at the unperturbed state
        for j in range(n):
            d = eps * max(1.0, abs(v[j]))
            for i in range(n):
                y[i] = v[i]
            y[j] += d
            st_f = ev.force(ints, ekind, eoff, pool, user, t, q, c, s_, y, f, fb)
            if st_f != 0:
                return _failure(st, st_f)
            for i in range(n):
                f[i] -= f0[i]
            _k.cho_solve(L, f, a1, n)
            for i in range(n):
                A[n + i, n + j] = a1[i] / d
        # the columns of q last: they refactor M at perturbed configurations
        for j in range(n):
            d = eps * max(1.0, abs(q[j]))
            for i in range(n):
                y[i] = q[i]
            y[j] += d
            code = _accel(ints, ekind, eoff, pool, user, t, y, v, c, s_, M, L, f, fb, a1)
            if code != 0:
                return _failure(st, code)
            for i in range(n):
                A[n + i, j] = (a1[i] - a0[i]) / d
        tr = 0.0
        for i in range(dim):
            tr += A[i, i]
            for j in range(dim):
                B[i, j] = h * A[i, j]
        _k.expm_taylor(B, E, W, V)
        Qr, R = np.linalg.qr(E @ Q)
        for j in range(k):
            dj = R[j, j]
            if dj == 0.0 or not math.isfinite(dj):
                return _failure(st, np.int64(-2))  # not the literal (compiled apart)
            sg = 1.0 if dj > 0.0 else -1.0
            for i in range(dim):
                Q[i, j] = Qr[i, j] * sg
            logd[st - first, j] = math.log(abs(dj))
        trace[st - first] = h * tr
    return 0


@njit(cache=True, nogil=True)
def _failure(step, code):
    """The status of a failed step: ``step * 1024 + (code mod 1024)`` + 1 (> 0); see
    :func:`decode_status`."""
    return step * 1024 + (code % 1024) + 1


def decode_status(status: int) -> tuple[int, int]:
    """``(step, code)`` of a non-zero :func:`smooth_steps` status: code −2 a degenerate frame
    (zero or non-finite diagonal of R), −1 a mass matrix not positive definite (mod 1024),
    else a user callable's status (:func:`moreau.compiled.usercalls.decode`)."""
    step, code = divmod(int(status) - 1, 1024)
    if code >= 1022:
        code -= 1024
    return step, code
