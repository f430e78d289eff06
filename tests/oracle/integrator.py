"""The numpy reference of the one-step integrators (:mod:`moreau.step.integrator`): each
class holds the state of one scene and advances it by :meth:`~oracle.base.OneStepIntegrator.step`."""


from __future__ import annotations

import logging

import numpy as np

from moreau.core.kernels import NEGLIGIBLE_VELOCITY
from moreau.core.kernels import impact_law as _impact_law
from moreau.model.stability import not_converged_message
from oracle.base import ContactDetails, OneStepIntegrator, _solve_with
from oracle.checks import BadModelOutput, NonFiniteState, NotConverged, check_initial_state

__all__ = ["OneStepIntegrator", "MoreauJeanMidpoint", "MoreauJeanPredictorCorrector", "MoreauJeanEnergyConsistent",
           "NonFiniteState", "NotConverged", "BadModelOutput", "ContactDetails", "check_initial_state"]

log = logging.getLogger(__name__)


class MoreauJeanMidpoint(OneStepIntegrator):
    """The numpy step of :class:`moreau.MoreauJeanMidpoint` (the scheme is documented there)."""

    #: close a row also when it reaches its barrier by the end of the step (2 g(q_m) − g(q_k) <= 0)
    closes_ahead = False

    def step(self) -> bool:
        h = self.h
        v = self.v
        qm = self.q + (0.5 * h) * v
        if self._M is not None and self._L is not None:  # a constant mass matrix
            M, L = self._M, self._L
        else:
            M, L = self._mass_at(qm, v)
        f = self.force_at(self.t + 0.5 * h, qm, v)
        v_new, contact = self._velocity_update(qm, M, L, f, v)
        return self._finish(qm, v_new, contact, f)

    # -- shared by the midpoint family ----------------------------------------------------
    def _velocity_update(self, qm, M, L, f, v):
        """v⁺ from ``M (v⁺ − v) = h f + Gᵀ P`` with the contacts closed at ``qm``; L is the
        Cholesky factor of M."""
        self.n_updates += 1
        self._unchecked = None
        h = self.h
        scene = self.scene
        if scene.gaps is not None:
            g = self.gaps_at(qm, v)
            gs = float(g.sum())
            if gs - gs != 0.0:  # NaN or inf: a NaN gap would otherwise count as open
                raise NonFiniteState(
                    f"gaps became non-finite at step {self.k} (t = {self.t:.9g}): g = {g.tolist()}",
                    self.k, self.t)
            active = g <= scene.activation_tol  # g <= 0 up to the gap's own round-off
            G = an = None
            if self.closes_ahead and not self._impacts_only:  # a row reaching the barrier by the
                # end of the step (linear in v_k) closes now
                active = active | (2.0 * g - self.gaps_at(self.q, v) <= 0.0)
            if self._impacts_only:  # CombinedProjection: a persistent contact stays in the problem,
                # and a row that reaches the barrier by the end of the step enters it now
                g_start = self.gaps_at(self.q, v)
                reach = 2.0 * g - g_start  # the end-of-step gap, linear in v_k
                if self._locate:  # ... or the free step's own: + h²/2 G M⁻¹ f
                    G = self.jacobian_at(qm, v)
                    an = G @ (self._Minv @ f if self._Minv is not None else _solve_with(L, f))
                    reach = reach + (0.5 * h * h) * an
                active = active | self.pinned | (reach <= 0.0)
            if active.any():
                rows = np.flatnonzero(active)
                if G is None:
                    G = self.jacobian_at(qm, v)
                U = G @ v
                if self._impacts_only:  # restitution at impacts only (CombinedProjection)
                    if an is None:  # the free normal accelerations
                        an = G @ (self._Minv @ f if self._Minv is not None else _solve_with(L, f))
                    self.bounced = np.zeros(scene.nrows, dtype=bool)
                    self.bounce_delay = np.zeros(scene.nrows)
                    self.bounce_shift = np.zeros(scene.nrows)
                    c = np.zeros(scene.nrows)
                    for r in rows:  # Newton's law where an impact happens (kernels.impact_law)
                        if self._e[r] > 0.0 and self.k - self.last_impulse_step[r] > self._memory:
                            cr, s = _impact_law(self._e[r], U[r], an[r], g_start[r], h, self._locate)
                            if cr == cr:  # not NaN: an impact
                                self.bounced[r], c[r] = True, cr
                                self.bounce_delay[r] = 0.5 * h - s
                                self.bounce_shift[r] = (2.0 * s - h) * an[r]
                else:
                    c = np.where(np.abs(U) >= NEGLIGIBLE_VELOCITY, -self._e * U, 0.0)  # kernels.newton_target
                b = M @ v + h * f
                # tangent rows only when an active row has friction (else the frictionless
                # solve, as the compiled step does)
                T = self.tangent_at(qm, v) if scene.has_friction and (self._mu[rows] > 0.0).any() else None
                if self._eq is not None:  # bilateral rows: the same solve in their null space
                    v_new, PA = self._eq.velocity(self, qm, M, L, b, v, G, c, rows, T)
                else:
                    v_new, PA = self._solve_contact(M, b, G, c, rows, L=L, T=T)
                P = np.zeros(scene.nrows)
                P[rows] = PA
                self.active, self.P = active, P
                if T is not None:
                    self.PT = np.zeros(scene.nrows)
                    self.PT[rows] = self._PT_active
                    self._T = T
                elif self._T is not None:  # a contact step without friction after one with it
                    self.PT = np.zeros(scene.nrows)
                    self._T = None
                self._last = (M, G, v, v_new, P)
                return v_new, True
        if self._eq is not None:  # bilateral rows: held in every step
            return self._eq.velocity(self, qm, M, L, M @ v + h * f, v, None, None, None)[0], False
        if self._Minv is not None:  # a constant mass matrix
            return v + h * (self._Minv @ f), False
        return v + h * _solve_with(L, f), False  # the step's one factorization

    def _finish(self, qm, v_new, contact: bool, f, v_arg=None, bias_extra=None) -> bool:
        """Move to q⁺ = q_m + h/2 v⁺ (then drift control), check, advance time; add the
        step's energy-ledger terms (smooth-force and contact work; with ``track_bias_work``
        the bias terms' share of the former, at the velocity ``v_arg`` f was evaluated at,
        plus ``bias_extra`` when f holds an inertial term besides the bias force)."""
        q_new = qm + (0.5 * self.h) * v_new
        if contact and self._locate and self.bounced.any():
            q_new = q_new + self._impulse_timing()
        self._check_finite(q_new, v_new)
        self.work_forces += 0.5 * self.h * float(f @ (self.v + v_new))
        if self.track_bias_work:
            fb = self.scene.system.bias_force(qm, self.v if v_arg is None else v_arg)
            if bias_extra is not None:
                fb = fb + bias_extra
            self.work_bias += 0.5 * self.h * float(np.asarray(fb) @ (self.v + v_new))
        if contact:
            self.n_contact_steps += 1
            assert self._last is not None  # set by the contact solve of this step
            _, G, v_old, _, P = self._last
            act = self.active
            self.work_contacts += 0.5 * float(P[act] @ (G[act] @ (v_old + v_new)))
            if self._T is not None:
                self.work_friction += 0.5 * float(self.PT[act] @ (self._T[act] @ (v_old + v_new)))
        elif self.active is not self._no_contact:
            # no contact in this step (also when only a θ predictor closed one): clear
            self.active = self._no_contact
            self.P = np.zeros(self.scene.nrows)
            if self._T is not None:
                self.PT = np.zeros(self.scene.nrows)
                self._T = None
        self.contact_step = contact
        if contact:
            self.last_impulse_step[self.P > 0.0] = self.k
        if self._eq is not None:  # the bilateral rows: their (zero) work, positions held on them
            self.work_constraints += self._eq.work(self.v, v_new)
            q_new = self._eq.hold(self, q_new)
        if self.drift_control is not None and self.scene.nrows:
            q_held = q_new
            q_new = self.drift_control.project(self, q_new)
            if self._eq is not None and q_new is not q_held:  # the projection moved along the rows:
                q_new = self._eq.hold(self, q_new)  # restore them to second order
        if self._eq is not None:  # and the velocity onto them at q⁺
            v_new, w = self._eq.project_velocity(self, q_new, v_new)
            self.work_constraint_projection += w
        self.q = q_new
        self.v = v_new
        self.k += 1
        self.t = self.t0 + self.k * self.h
        return contact


class MoreauJeanPredictorCorrector(MoreauJeanMidpoint):
    """The numpy step of :class:`moreau.MoreauJeanPredictorCorrector`."""

    def step(self) -> bool:
        if not self.scene.velocity_dependent:
            return super().step()
        h = self.h
        v = self.v
        qm = self.q + (0.5 * h) * v
        tm = self.t + 0.5 * h
        if self._M is not None and self._L is not None:  # a constant mass matrix
            M, L = self._M, self._L
        else:
            M, L = self._mass_at(qm, v)
        force = self.force_at
        v_pred, _ = self._velocity_update(qm, M, L, force(tm, qm, v), v)
        v_arg = 0.5 * (v + v_pred)
        f = force(tm, qm, v_arg)
        v_new, contact = self._velocity_update(qm, M, L, f, v)
        return self._finish(qm, v_new, contact, f, v_arg)


class MoreauJeanEnergyConsistent(MoreauJeanMidpoint):
    """The numpy step of :class:`moreau.MoreauJeanEnergyConsistent` (fixed-point iterates with
    Anderson mixing of depth 1; the scheme is documented there)."""

    closes_ahead = True
    #: largest change of v⁺ between iterates (max norm), relative to 1 + max(abs(v⁺)), that ends
    #: the iteration
    iteration_tol = 1e-10
    #: iterates allowed per step before the run stops
    max_iterations = 60

    def step(self) -> bool:
        scene = self.scene
        const = self._M is not None and self._L is not None
        if not scene.velocity_dependent and const:
            return super().step()
        h, q, v = self.h, self.q, self.v
        qm = q + (0.5 * h) * v
        tm = self.t + 0.5 * h
        if const:
            M, L = self._M, self._L
        else:
            M, L = self._mass_at(qm, v)
            # T(q_m, v_k) − T(q_k, v_k): the start's share of s
            s0 = 0.5 * float(v @ M @ v) - scene.kinetic_energy(q, v)
        # the iterates: x (whose mean with v_k the forces see) -> y, the velocity update's
        # answer; the first x is the midpoint step's v⁺, then x = y, accelerated from the
        # third on by Anderson mixing of depth 1 (a secant step along the last two residuals
        # y − x; Walker & Ni 2011), which the contact steps' slow linear convergence needs.
        # A plain contact solve (no friction, no bilateral rows) is checked only in the
        # pass whose answer is kept: the converged one (``_check_deferred``)
        self._defer_check = not scene.has_friction and self._eq is None
        try:
            x, contact = self._velocity_update(qm, M, L, self.force_at(tm, qm, v), v)
            y_last = r_last = None
            for _ in range(self.max_iterations):
                vbar = 0.5 * (v + x)
                f = self.force_at(tm, qm, vbar)
                corr = None
                if not const:
                    dq = h * vbar
                    Mdq = M @ dq
                    den = float(dq @ Mdq)
                    s = scene.kinetic_energy(q + dq, x) - 0.5 * float(x @ M @ x) + s0
                    fb = np.asarray(scene.system.bias_force(qm, vbar), dtype=float)
                    kappa = (-s - float(dq @ fb)) / den if den > 0.0 else 0.0
                    corr = kappa * Mdq
                    f = f + corr
                y, contact = self._velocity_update(qm, M, L, f, v)
                r = y - x
                change = float(np.max(np.abs(r)))
                if change <= self.iteration_tol * (1.0 + float(np.max(np.abs(y)))):
                    if self._check_deferred():
                        self._defer_check = False
                        return self._finish(qm, y, contact, f, vbar, corr)
                    self._defer_check = False  # failed its check: this x again, checked, with the fallback
                    continue
                x = y
                if r_last is not None:
                    dr = r - r_last
                    dd = float(dr @ dr)
                    if dd > 0.0:
                        x = y - (float(dr @ r) / dd) * (y - y_last)
                y_last, r_last = y, r
        finally:
            self._defer_check = False
        where = f"at step {self.k} (t = {self.t:.9g}, last change of v⁺ {change:.3g})"
        raise NotConverged(not_converged_message(scene, self.t, q, v, h, where, self.max_iterations), self.k, self.t)


#: The former name of :class:`MoreauJeanPredictorCorrector` (kept for existing scripts).
MoreauJeanTheta = MoreauJeanPredictorCorrector
