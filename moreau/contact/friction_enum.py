"""An independent solver of the one-step problem with friction: enumeration of contact
states, :func:`friction_enumerate`.

Each active contact is open, closed without friction, sticking, or slipping to one side
(``P_T = ∓ mu P_N``); each combination fixes a linear system for the impulses, whose
answer is kept when it satisfies the whole law. Up to 4^k combinations, so for a handful
of contacts only: the check of :mod:`moreau.contact.friction`'s LCP in the tests (it
builds no LCP matrix, so an index mix-up in that matrix cannot repeat here) and the
``"enum"`` backend's friction solve.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["friction_enumerate", "MAX_CONTACTS"]

#: the most active contacts :func:`friction_enumerate` accepts (4^6 = 4096 systems)
MAX_CONTACTS = 6

_OPEN, _CLOSED, _STICK, _SLIP_POS, _SLIP_NEG = range(5)


def friction_enumerate(W: np.ndarray, w: np.ndarray, mu: np.ndarray, fidx: np.ndarray,
                       tol: float = 1e-10) -> np.ndarray | None:
    """Impulses ``P = [P_N (k); P_T (kf)]`` with ``U = W P + w`` satisfying the law of
    :mod:`moreau.contact.friction`, or None when no state combination does.

    Parameters
    ----------
    W : ndarray, shape (k + kf, k + kf)
        Delassus matrix of the stacked normal and tangential rows.
    w : ndarray, shape (k + kf,)
        Free velocities (normal rows less their bounds).
    mu : ndarray, shape (k,)
        Friction coefficient per normal row.
    fidx : ndarray of int, shape (kf,)
        Normal row of each tangential row.
    tol : float
        Tolerance of the law's inequalities, relative to the problem's velocity and
        impulse scales.

    Raises
    ------
    ValueError
        For more than ``MAX_CONTACTS`` normal rows.
    """
    k, kf = len(mu), len(fidx)
    R = k + kf
    if k > MAX_CONTACTS:
        raise ValueError(f"friction_enumerate accepts at most {MAX_CONTACTS} contacts, got {k}")
    tan = {int(j): k + f for f, j in enumerate(fidx)}
    vscale = max(float(np.max(np.abs(w), initial=0.0)), 1e-300)
    pscale = vscale / max(float(np.max(np.abs(np.diag(W)), initial=0.0)), 1e-300)
    choices = [(_OPEN, _STICK, _SLIP_POS, _SLIP_NEG) if j in tan else (_OPEN, _CLOSED) for j in range(k)]
    combos = sorted(itertools.product(*choices), key=lambda s: sum(x != _OPEN for x in s))
    for states in combos:
        A = np.zeros((R, R))
        rhs = np.zeros(R)
        for j, s in enumerate(states):
            i = tan.get(j)
            if s == _OPEN:
                A[j, j] = 1.0
                if i is not None:
                    A[i, i] = 1.0
                continue
            A[j], rhs[j] = W[j], -w[j]  # U_N = 0
            if i is None:
                continue
            if s == _STICK:
                A[i], rhs[i] = W[i], -w[i]  # U_T = 0
            else:  # P_T = −mu P_N (slip to +) or +mu P_N (slip to −)
                A[i, i] = 1.0
                A[i, j] = mu[j] if s == _SLIP_POS else -mu[j]
        try:
            P = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            continue
        if not np.all(np.isfinite(P)) or np.linalg.norm(A @ P - rhs) > 1e-9 * (np.linalg.norm(rhs) + vscale):
            continue
        U = W @ P + w
        if _admissible(states, tan, mu, P, U, tol * vscale, tol * pscale):
            return P
    return None


def _admissible(states, tan, mu, P, U, tv: float, tp: float) -> bool:
    """True when ``(P, U)`` satisfies every contact's law in its state."""
    for j, s in enumerate(states):
        i = tan.get(j)
        if s == _OPEN:
            if U[j] < -tv:
                return False
            continue
        if P[j] < -tp:
            return False
        if i is None:
            continue
        if abs(P[i]) > mu[j] * P[j] + tp:
            return False
        if (s == _SLIP_POS and U[i] < -tv) or (s == _SLIP_NEG and U[i] > tv):
            return False
    return True
