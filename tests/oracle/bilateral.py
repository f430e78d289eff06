"""The step's equality rows on the Python path (the twin of :mod:`moreau.compiled.bilateral`):
the velocity update in the null space of the bilateral rows, their impulses, and the
projection that holds positions on g_E(q) = 0 after every step. The kernels are those
of :mod:`moreau.contact.equality`.

The velocity condition of a bilateral row is ``G_E(q_m) (v_k + v⁺) = 0``: the midpoint
rule for the hidden constraint ``d/dt g_E = G_E v = 0``. It keeps ``g_E(q⁺) − g_E(q_k)``
at O(h³) per step, and the constraint impulses do no work: ``½ P_Eᵀ G_E (v_k + v⁺) = 0``
(the energy ledger's ``work["constraints"]`` checks it).
"""

from __future__ import annotations

import logging

import numpy as np

from moreau.contact.equality import (
    MAX_HOLD_ITERATIONS,
    eq_basis,
    eq_free,
    eq_impulses,
    eq_particular,
    eq_project,
    eq_reduce_rows,
    eq_velocity,
)
from moreau.core.errors import SolverError
from moreau.run.trust import constraint_rank

__all__ = ["EqualityRows", "MAX_HOLD_ITERATIONS", "constraint_rank"]

log = logging.getLogger(__name__)


class EqualityRows:
    """Work arrays and the last step's results of a scene's bilateral rows.

    Attributes
    ----------
    PE : ndarray, shape (k_E,)
        The equality rows' impulses of the last step (N s).
    rank : int
        The rank of the equality rows at the last step (k_E less the redundant rows).
    residual : float
        The largest |g_E| left by the position projection so far.
    """

    def __init__(self, scene) -> None:
        n, me = scene.ndof, scene.nconstraints
        self.scene = scene
        self.n, self.me = n, me
        self.Q = np.empty((n, n))
        self.R = np.empty((n, me))
        self.piv = np.zeros(me, dtype=np.int64)
        self.x = np.empty(n)
        self.y = np.zeros(n)
        self.yv = np.zeros(n)
        self.eye = np.eye(n)
        self.PE = np.zeros(me)
        self.GE: np.ndarray | None = None
        self.L: np.ndarray | None = None
        self.M: np.ndarray | None = None
        self.rank = 0
        self.residual = 0.0
        self.hold_tol = np.asarray(scene.constraint_hold_tol, dtype=float)

    def _basis(self, L, GE) -> int:
        self.rank = eq_basis(L, GE, 0, self.me, self.Q, self.R, self.piv, self.x)
        return self.rank

    def velocity(self, integ, qm, M, L, b, v, G, c, rows, T=None):
        """``(v⁺, P[rows])`` of the step with the bilateral rows held (their impulses in
        :attr:`PE`); ``G, c`` the contact rows (None without active rows), ``T`` their
        tangent rows when a row has friction (the reduced tangent rows then carry the slip
        velocity's offset, ``c_T``)."""
        scene = self.scene
        GE = np.ascontiguousarray(integ._evaluate(scene.constraint_jacobian, (qm,), (self.me, self.n),
                                                  "constraint_jacobian", integ.t, qm, v), dtype=float)
        L = np.ascontiguousarray(L)
        rank = self._basis(L, GE)
        bad = eq_particular(self.R, self.piv, rank, self.me, -(GE @ v), self.y)
        if bad >= 0:
            name = scene.constraint_names[bad]
            raise SolverError(
                f"the bilateral constraints are inconsistent at step {integ.k} (t = {integ.t:.9g}): row {name!r} "
                f"cannot be held together with the others (rank {rank} of {self.me} rows)",
                step=integ.k, t=integ.t, rows=[name], residuals={})
        b = np.ascontiguousarray(b, dtype=float)
        by = np.empty(self.n)
        eq_free(L, self.Q, rank, b, self.y, by, self.x)
        #: the free velocity with the joints held (no contact impulse): what the impact
        #: log's velocity test compares with
        self.v_free = np.empty(self.n)
        eq_velocity(L, self.Q, by, self.v_free)
        if rows is not None and rows.size:
            Gy = np.array(G, dtype=float)
            cy = np.array(c, dtype=float)
            eq_reduce_rows(L, self.Q, rank, Gy, 0, Gy.shape[0], cy, self.y, self.x)
            Ty = cT = None
            if T is not None:
                Ty, cT = np.array(T, dtype=float), np.zeros(T.shape[0])
                eq_reduce_rows(L, self.Q, rank, Ty, 0, Ty.shape[0], cT, self.y, self.x)
            ysol, PA = integ._solve_contact(self.eye, by, Gy, cy, rows, L=self.eye, T=Ty, cT=cT)
        else:
            ysol, PA = by, np.zeros(0)
        v_new = np.empty(self.n)
        eq_velocity(L, self.Q, np.ascontiguousarray(ysol, dtype=float), v_new)
        F = M @ v_new - b
        if PA.size:
            F -= G[rows].T @ PA
            if T is not None:  # and the friction impulses
                F -= T[rows].T @ integ._PT_active
        eq_impulses(L, self.Q, self.R, self.piv, rank, self.me, F, self.PE, self.x)
        self.GE, self.L, self.M = GE, L, np.ascontiguousarray(M, dtype=float)
        return v_new, PA

    def project_contacts(self, integ, q, M, G, c, rows):
        """``(dq, P[rows])`` of drift control's projection QP (``min ½ dqᵀ M dq``,
        ``G[rows] dq >= c[rows]``) solved in the null space of the bilateral rows at the
        current q (``G_E dq = 0``): the contact rows are projected along the constraints,
        which they then break only to second order (the hold after it restores them)."""
        scene = self.scene
        GE = np.ascontiguousarray(scene.constraint_jacobian(q), dtype=float)
        L = np.ascontiguousarray(np.linalg.cholesky(M))
        rank = self._basis(L, GE)
        self.y[:] = 0.0
        Gy, cy = np.array(G, dtype=float), np.array(c, dtype=float)
        eq_reduce_rows(L, self.Q, rank, Gy, 0, Gy.shape[0], cy, self.y, self.x)
        ysol, PA = integ._solve_contact(self.eye, np.zeros(self.n), Gy, cy, rows, kind="projection", L=self.eye)
        dq = np.empty(self.n)
        eq_velocity(L, self.Q, np.ascontiguousarray(ysol, dtype=float), dq)
        self.L, self.M = L, np.ascontiguousarray(M, dtype=float)
        return dq, PA

    def project_velocity(self, integ, q, v):
        """``(v', work)``: v projected onto ``G_E(q) v' = 0`` in the metric of the step's M
        (the velocity condition holds the rows at the midpoint; this keeps the constraint
        velocity at q⁺ from persisting, flipping sign from step to step), keeping the slip
        of the step's sticking contacts at 0 (``P > 0``, ``mu > 0``, ``|P_T| < mu P``: their
        tangent rows are held, so a rolling contact stays rolling), and the kinetic energy
        that removes, ``v̄ᵀ M Δv`` (<= 0 up to the held rows' velocity at q⁺; O(h⁴) per
        step). The rows are stacked in the compiled step's order for the shared kernel
        :func:`moreau.contact.equality.eq_project`."""
        scene = self.scene
        stack = [np.asarray(scene.constraint_jacobian(q), dtype=float)]
        if integ.contact_step and scene.has_friction:  # sticking rows: their slip held at 0
            mu, P = integ._mu, integ.P
            held = np.flatnonzero((P > 0.0) & (mu > 0.0) & (np.abs(integ.PT) < mu * P))
            if held.size:
                stack.append(np.asarray(scene.tangent_jacobian(q), dtype=float)[held])
        S = np.ascontiguousarray(np.vstack(stack))
        k, n = S.shape
        c = np.zeros(k)
        c[:self.me] = -(S[:self.me] @ v)
        dv = np.empty(n)
        eq_project(self.L, S, k, self.me, c, np.empty((n, n)), np.empty((n, k)), np.zeros(k, dtype=np.int64),
                   self.x, self.y, self.yv, dv)
        return v + dv, float(dv @ (self.M @ (v + 0.5 * dv)))

    def work(self, v, v_new) -> float:
        """½ P_Eᵀ G_E (v_k + v⁺) of the last step (0 up to round-off)."""
        assert self.GE is not None
        return 0.5 * float(self.PE @ (self.GE @ (v + v_new)))

    def hold(self, integ, q):
        """q moved onto g_E(q) = 0 (Gauss–Newton steps in the metric of the step's M, the
        first with the step's own basis at q_m: its error is O(h) times the correction);
        ``SolverError`` when |g_E| stays above 100 times its tolerance."""
        scene = self.scene
        L = self.L
        g = np.asarray(scene.constraint_gaps(q), dtype=float)
        rank = self.rank  # the first correction with the step's basis (at q_m), then Newton's
        for it in range(MAX_HOLD_ITERATIONS):
            if np.all(np.abs(g) <= self.hold_tol):
                break
            if it > 0:
                GE = np.ascontiguousarray(scene.constraint_jacobian(q), dtype=float)
                rank = self._basis(L, GE)
            eq_particular(self.R, self.piv, rank, self.me, -g, self.y)  # redundant rows follow
            self.yv[:] = 0.0
            self.yv[:rank] = self.y[:rank]
            dq = np.empty(self.n)
            eq_velocity(L, self.Q, self.yv, dq)
            q = q + dq
            g = np.asarray(scene.constraint_gaps(q), dtype=float)
        worst = float(np.max(np.abs(g) / self.hold_tol))
        if not worst <= 100.0:
            i = int(np.argmax(np.abs(g) / self.hold_tol))
            raise SolverError(
                f"the bilateral constraints could not be held at step {integ.k} (t = {integ.t:.9g}): "
                f"|g| = {abs(g[i]):.3g} on row {scene.constraint_names[i]!r} after {MAX_HOLD_ITERATIONS} "
                "projection steps (a singular configuration, or a step too large for the motion)",
                step=integ.k, t=integ.t, rows=[scene.constraint_names[i]], residuals={})
        self.residual = max(self.residual, float(np.max(np.abs(g))))
        return q
