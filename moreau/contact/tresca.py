"""Friction by a fixed point over Tresca problems: the QP route to Coulomb's law.

With the friction bound s given, the one-step problem with friction is a convex QP in
the impulses (Tresca's law, a bound independent of the normal impulse):

    minimize ½ Pᵀ W P + wᵀ P   subject to   P_N >= 0,   −s <= P_T <= s,

(``W``, ``w``, the stacked rows and ``fidx`` as in :mod:`moreau.contact.friction`).
Coulomb's law is its fixed point ``s = mu P_N``: :func:`tresca_fixed_point` solves the QP
with ``s = 0``, sets ``s ← mu P_N`` and repeats until s stops changing — a second route,
independent of Lemke's, that the tests compare with it. It converges for the moderate mu
of engineering contacts (a contraction when mu times the coupling of normal and tangential
rows is small) and is reported as not converged otherwise; its answer is checked against
the full law by the integrator like every other.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from moreau.contact.base import SolveFailed

__all__ = ["tresca_fixed_point", "delassus", "solve_by_tresca"]

#: a box-constrained QP: (W, w, lower, upper) -> P minimizing ½ PᵀWP + wᵀP on lower <= P <= upper
BoxQP = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def delassus(M: np.ndarray, b: np.ndarray, G: np.ndarray, c: np.ndarray, T: np.ndarray, mu: np.ndarray,
             rows: np.ndarray, cT: np.ndarray | None = None,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(W, w, Gs, MinvGt, vfree)`` of the active rows: the stacked rows
    ``Gs = [G[rows]; T[rows with mu > 0]]``, ``W = Gs M⁻¹ Gsᵀ``, ``w = Gs v_free − [c; c_T]``
    (``cT`` (m,): the slip velocities' offsets, default 0)."""
    fidx = np.flatnonzero(mu[rows] > 0.0)
    Gs = np.vstack([G[rows], T[rows][fidx]])
    sol = np.linalg.solve(M, np.column_stack([b, Gs.T]))
    vfree, MinvGt = sol[:, 0], sol[:, 1:]
    W = Gs @ MinvGt
    W = 0.5 * (W + W.T)
    w = Gs @ vfree - np.concatenate([c[rows], np.zeros(fidx.shape[0]) if cT is None else cT[rows][fidx]])
    return W, w, Gs, MinvGt, vfree


def tresca_fixed_point(W: np.ndarray, w: np.ndarray, mu: np.ndarray, fidx: np.ndarray, box_qp: BoxQP,
                       tol: float = 1e-10, max_iter: int = 200) -> tuple[np.ndarray, int]:
    """Impulses ``P = [P_N (k); P_T (kf)]`` of the fixed point ``s = mu P_N`` and the number
    of QPs solved.

    Parameters
    ----------
    W, w : the problem of :mod:`moreau.contact.friction` on the stacked rows.
    mu : ndarray, shape (k,)
        Friction coefficients of the normal rows.
    fidx : ndarray of int, shape (kf,)
        Normal row of each tangential row.
    box_qp : callable
        The QP solver (OSQP, an active-set QP through qpsolvers, ...).
    tol : float
        Converged when ``max |s − mu P_N|`` is at most ``tol`` times the impulse scale.
    max_iter : int
        QPs solved at most.

    Raises
    ------
    SolveFailed
        When the bound has not converged after ``max_iter`` QPs (naming the change left).
    """
    k, kf = mu.shape[0], fidx.shape[0]
    lower = np.concatenate([np.zeros(k), np.zeros(kf)])
    upper = np.concatenate([np.full(k, np.inf), np.zeros(kf)])
    s = np.zeros(kf)
    change = np.inf
    for it in range(1, max_iter + 1):
        lower[k:], upper[k:] = -s, s
        P = box_qp(W, w, lower, upper)
        s_new = mu[fidx] * P[fidx]
        scale = max(float(np.max(np.abs(P), initial=0.0)), 1e-300)
        change = float(np.max(np.abs(s_new - s), initial=0.0))
        s = s_new
        if change <= tol * scale:
            return P, it
    raise SolveFailed(f"the Tresca fixed point did not converge in {max_iter} QPs "
                      f"(the friction bound still changed by {change:.3g})")


def solve_by_tresca(M: np.ndarray, b: np.ndarray, G: np.ndarray, c: np.ndarray, T: np.ndarray, mu: np.ndarray,
                    rows: np.ndarray, box_qp: BoxQP, cT: np.ndarray | None = None,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(v, P_N (k,), P_T (k,))`` of the one-step problem with friction on the active
    ``rows`` (the full-size arguments of :meth:`ContactSolver.solve_friction
    <moreau.contact.base.ContactSolver.solve_friction>`) by :func:`tresca_fixed_point`;
    the QPs are solved in units where W has a unit diagonal."""
    W, w, _, MinvGt, vfree = delassus(M, b, G, c, T, mu, rows, cT)
    muA = mu[rows]
    fidx = np.flatnonzero(muA > 0.0)
    d = 1.0 / np.sqrt(np.maximum(np.diag(W), 1e-300))  # P = d p: unit diagonal
    Ws, ws = W * np.outer(d, d), w * d  # the same arrays at every QP of the fixed point

    def scaled(Wu, wu, lower, upper):  # the same QP in the scaled impulses p = P / d
        return d * box_qp(Ws, ws, lower / d, upper / d)

    P, _ = tresca_fixed_point(W, w, muA, fidx, scaled)
    k = rows.shape[0]
    PT = np.zeros(k)
    PT[fidx] = P[k:]
    return vfree + MinvGt @ P, P[:k].copy(), PT
