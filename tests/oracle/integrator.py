"""One-step integrators: the Moreau–Jean midpoint time-stepper.

An integrator holds the state (t, q, v) of one scene and advances it by one step with
:meth:`~OneStepIntegrator.step`; it has no loop (that is :func:`moreau.simulate`). It can
be used by hand::

    integ = MoreauJeanMidpoint(scene, h=1e-3)
    integ.init(0.0, q0, v0)
    for _ in range(1000):
        integ.step()
    integ.t, integ.q, integ.v
"""


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
    """The Moreau–Jean midpoint time-stepper.

    One step from (t_k, q_k, v_k) with step h:

    .. code-block:: text

        q_m = q_k + h/2 · v_k
        M   = M(q_m),   f = f(t_k + h/2, q_m, v_k)        (only the scene's effects)
        A   = { i : g_i(q_m) <= 0 }                      (no rows → no solver call)
        G   = G_A(q_m),   U_k = G v_k
        M (v⁺ − v_k) = h f + Gᵀ P,    0 <= P ⟂ G v⁺ + e ∘ U_k >= 0
        q⁺  = q_m + h/2 · v⁺

    The contact problem is solved in its QP form (see :mod:`moreau.contact.problem`): impacts and
    sliding are the same computation, with no event detection.

    Order of accuracy: 1 globally when impacts occur, and 1 in smooth phases with
    velocity-dependent forces (damping, the Coriolis/centrifugal terms of a
    configuration-dependent M). For a constant mass matrix and position-only forces the
    smooth phases are integrated to order 2 (the scheme is then Störmer–Verlet).
    :class:`MoreauJeanPredictorCorrector` restores order 2 with velocity-dependent forces.

    The velocity condition is imposed with the Jacobian at the midpoint, so a pressed
    contact on a curved barrier drifts into it by about h²/2 · vᵀ∇²g v per step; a
    :class:`~moreau.step.drift.PositionProjection` given as ``drift_control`` removes it.
    """

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
    """Moreau–Jean midpoint with a predictor–corrector (θ = ½) treatment of the
    velocity-dependent forces.

    Formerly ``MoreauJeanTheta`` (still importable under that name): renamed because in
    Siconos' ``MoreauJeanOSI`` θ weights the whole step, while here the step stays the
    midpoint one and only the velocity-dependent forces are corrected.

    The forces are evaluated at the mean of the start and end velocities instead of at
    v_k, by one predictor–corrector pass:

    .. code-block:: text

        q_m = q_k + h/2 · v_k,   M = M(q_m)
        v*  = midpoint velocity update with f(t_m, q_m, v_k)       (contacts included)
        v⁺  = velocity update with f(t_m, q_m, (v_k + v*)/2)        (contacts included)
        q⁺  = q_m + h/2 · v⁺

    Order 2 in smooth phases also with damping and Coriolis/centrifugal terms; order 1
    across impacts, like every time-stepper with Newton's law. A scene whose forces do
    not depend on v takes the plain midpoint step (the corrector would change nothing).
    Contact steps cost two contact solves.
    """

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
    """Moreau–Jean midpoint with the velocity-dependent forces implicit and the inertial
    terms energy-consistent (a discrete gradient of the kinetic energy, Gonzalez 1996):
    the stable choice for fast, light parts (a long chain's whipping tail).

    With M_m = M(q_m) (factorized once per step, as in the midpoint step) the velocity
    update is solved by fixed-point iteration, every iterate with the step's contact rows
    and the same contact solve:

    .. code-block:: text

        q_m = q_k + h/2 · v_k,   M_m = M(q_m),   v̄ = (v_k + v⁺)/2,   Δq = h v̄
        s   = T(q_k + Δq, v⁺) − T(q_m, v⁺) + T(q_m, v_k) − T(q_k, v_k)
        κ   = (−s − Δqᵀ f_bias(q_m, v̄)) / (Δqᵀ M_m Δq)
        M_m (v⁺ − v_k) = h [ f(t_m, q_m, v̄) + κ M_m Δq ] + Gᵀ P,   0 <= P ⟂ G v⁺ + e ∘ U_k >= 0
        q⁺  = q_k + Δq

    where G, e and U_k are the rows closed at q_m, or reaching the barrier by the end of
    the step, 2 g(q_m) − g(q_k) <= 0 (as :class:`~moreau.step.drift.CombinedProjection`
    closes them): a fast part is stopped at the barrier instead of h/2 · (−G v) into it.
    T(q, v) = ½ vᵀ M(q) v. The scalar κ corrects the bias (centrifugal, Coriolis) force
    along Δq so that, at convergence, the kinetic energy changes by exactly the work of
    the applied forces and the contact impulses:

        T(q⁺, v⁺) − T(q_k, v_k) = Δqᵀ f_applied + ½ Pᵀ G (v_k + v⁺)

    whatever h, so the scheme cannot gain energy the way the explicit treatment of the
    bias does (its error, not its stability, grows with h). κ M_m Δq is O(h²), so the
    step keeps order 2 in smooth phases; order 1 across impacts. The first iterate is
    the midpoint step; iterations stop when the largest change of v⁺ is below
    ``iteration_tol · (1 + |v⁺|∞)``, and a step that does not converge in
    ``max_iterations`` stops the run with a :class:`moreau.SimulationError` (a step too
    large for the motion) rather than returning an unconverged state. The iterates' contact
    solves are KKT-checked in the converged pass only, whose answer is the one kept (one
    that fails is solved again, checked, with the fallback). A scene with a
    constant mass matrix and forces that do not depend on v takes the plain midpoint step.
    Measured on the 40-link chain of ``tests/hard_cases`` at h = 1e-3: 7.6–8.3 velocity
    updates a step on average (``traj.stats.velocity_updates / traj.stats.steps``).
    """

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
