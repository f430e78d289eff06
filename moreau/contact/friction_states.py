"""The compiled fallback of the friction solve: enumeration of contact states,
:func:`enumerate_states`.

Each active contact is open, closed (frictionless rows), sticking, or slipping to one
side (``P_T = ∓ mu P_N``); each combination, fewest closed contacts first, fixes a
linear system for the impulses ``P = [P_N; P_T]`` with ``U = W P + w``, whose answer is
taken when it satisfies the whole law. Exact where Lemke's pivoting fails on the round-off
of a singular tableau (:mod:`moreau.contact.friction`), for a handful of contacts only
(``MAX_STATES_CONTACTS``: 4⁵ = 1024 systems at most). The same search as the Python
test oracle :func:`moreau.contact.friction_enum.friction_enumerate`, which stays
independent of this code.
"""

from __future__ import annotations

from numba import njit

from moreau.contact.active_set import _inline

__all__ = ["enumerate_states", "MAX_STATES_CONTACTS"]

#: the most active contacts :func:`enumerate_states` searches
MAX_STATES_CONTACTS = 5


@_inline
def _gauss(A, rhs, x, n, piv):
    """x = A⁻¹ rhs by Gaussian elimination with partial pivoting (A and rhs overwritten);
    False when a pivot is below ``piv`` (singular)."""
    for c in range(n):
        r = c
        for i in range(c + 1, n):
            if abs(A[i, c]) > abs(A[r, c]):
                r = i
        if abs(A[r, c]) <= piv:
            return False
        if r != c:
            for j in range(n):
                A[c, j], A[r, j] = A[r, j], A[c, j]
            rhs[c], rhs[r] = rhs[r], rhs[c]
        for i in range(c + 1, n):
            f = A[i, c] / A[c, c]
            if f != 0.0:
                for j in range(c, n):
                    A[i, j] -= f * A[c, j]
                rhs[i] -= f * rhs[c]
    for c in range(n - 1, -1, -1):
        t = rhs[c]
        for j in range(c + 1, n):
            t -= A[c, j] * x[j]
        x[c] = t / A[c, c]
    return True


@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # a call: compiled once, not re-optimized inline
def enumerate_states(W, w, mu, fidx, k, kf, P, A, rhs, U, tcol):
    """Impulses ``P = [P_N (k); P_T (kf)]`` satisfying the friction law for ``U = W P + w``
    (rows and ``fidx`` as in :func:`moreau.contact.friction.solve_friction_step`); returns
    True when found. ``A`` (>= R, >= R), ``rhs``, ``U`` (>= R) and ``tcol`` (>= k, int) are
    work arrays (R = k + kf); at most ``MAX_STATES_CONTACTS`` contacts."""
    R = k + kf
    if k > MAX_STATES_CONTACTS:
        return False
    for j in range(k):
        tcol[j] = -1
    for f in range(kf):
        tcol[fidx[f]] = k + f
    vs = 1e-300
    dmax = 1e-300
    for i in range(R):
        vs = max(vs, abs(w[i]))
        dmax = max(dmax, W[i, i])
    tv = 1e-10 * vs
    tp = 1e-10 * vs / dmax
    total = 1
    for _ in range(k):
        total *= 4
    for nclosed in range(k + 1):
        for code in range(total):
            c = code
            closed = 0
            valid = True
            for j in range(k):  # state of contact j: 0 open, 1 stick/closed, 2 slip +, 3 slip −
                s = c % 4
                c //= 4
                if s != 0:
                    closed += 1
                if s > 1 and tcol[j] < 0:
                    valid = False
            if not valid or closed != nclosed:
                continue
            for i in range(R):
                rhs[i] = 0.0
                for l in range(R):
                    A[i, l] = 0.0
            c = code
            for j in range(k):
                s = c % 4
                c //= 4
                i = tcol[j]
                if s == 0:
                    A[j, j] = 1.0
                    if i >= 0:
                        A[i, i] = 1.0
                    continue
                for l in range(R):
                    A[j, l] = W[j, l]
                rhs[j] = -w[j]
                if i < 0:
                    continue
                if s == 1:
                    for l in range(R):
                        A[i, l] = W[i, l]
                    rhs[i] = -w[i]
                else:
                    A[i, i] = 1.0
                    A[i, j] = mu[j] if s == 2 else -mu[j]
            if not _gauss(A, rhs, P, R, 1e-12 * dmax):
                continue
            for i in range(R):
                t = w[i]
                for l in range(R):
                    t += W[i, l] * P[l]
                U[i] = t
            ok = True
            c = code
            for j in range(k):
                s = c % 4
                c //= 4
                i = tcol[j]
                if s == 0:
                    ok = U[j] >= -tv
                else:
                    ok = P[j] >= -tp
                    if ok and i >= 0:
                        ok = abs(P[i]) <= mu[j] * P[j] + tp
                        if ok and s == 2:
                            ok = U[i] >= -tv
                        elif ok and s == 3:
                            ok = U[i] <= tv
                if not ok:
                    break
            if ok:
                return True
    return False
