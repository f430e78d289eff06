"""The one-step integrators: which Moreau–Jean step the compiled loop takes.

Each class names a scheme and documents it; :func:`moreau.simulate` takes the class
(``integrator=MoreauJeanMidpoint``) and the loop runs that step (:mod:`moreau.compiled.step`,
:mod:`moreau.compiled.implicit`). A subclass may change a scheme's settings (the
energy-consistent step's ``max_iterations`` and ``iteration_tol``), not its step: every
phase of the step has one implementation, in the loop.
"""

from __future__ import annotations

from typing import Any

__all__ = ["OneStepIntegrator", "MoreauJeanMidpoint", "MoreauJeanPredictorCorrector", "MoreauJeanEnergyConsistent"]


class OneStepIntegrator:
    """The base of the schemes :func:`moreau.simulate` accepts as ``integrator``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError(f"{type(self).__name__} names a scheme: pass the class, "
                        f"simulate(scene, t_span, q0, v0, h, integrator={type(self).__name__}); "
                        "to take single steps, simulate over one step h")


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


class MoreauJeanPredictorCorrector(MoreauJeanMidpoint):
    """Moreau–Jean midpoint with a predictor–corrector (θ = ½) treatment of the
    velocity-dependent forces (formerly ``MoreauJeanTheta``, still importable).

    The forces are evaluated at the mean of the start and end velocities instead of at
    v_k, by one predictor–corrector pass:

    .. code-block:: text

        q_m = q_k + h/2 · v_k,   M = M(q_m)
        v*  = midpoint velocity update with f(t_m, q_m, v_k)       (contacts included)
        v⁺  = velocity update with f(t_m, q_m, (v_k + v*)/2)        (contacts included)
        q⁺  = q_m + h/2 · v⁺

    Order 2 in smooth phases also with damping and Coriolis/centrifugal terms; order 1
    across impacts, like every time-stepper with Newton's law. A scene whose forces do
    not depend on v takes the plain midpoint step. Contact steps cost two contact solves.
    """


class MoreauJeanEnergyConsistent(MoreauJeanMidpoint):
    """Moreau–Jean midpoint with the velocity-dependent forces implicit and the inertial
    terms energy-consistent (a discrete gradient of the kinetic energy, Gonzalez 1996):
    the stable choice for fast, light parts (a long chain's whipping tail).

    With M_m = M(q_m) the velocity update is solved by fixed-point iteration (Anderson
    mixing of depth 1 from the third iterate), every iterate with the step's contact rows:

    .. code-block:: text

        q_m = q_k + h/2 · v_k,   M_m = M(q_m),   v̄ = (v_k + v⁺)/2,   Δq = h v̄
        s   = T(q_k + Δq, v⁺) − T(q_m, v⁺) + T(q_m, v_k) − T(q_k, v_k)
        κ   = (−s − Δqᵀ f_bias(q_m, v̄)) / (Δqᵀ M_m Δq)
        M_m (v⁺ − v_k) = h [ f(t_m, q_m, v̄) + κ M_m Δq ] + Gᵀ P,   0 <= P ⟂ G v⁺ + e ∘ U_k >= 0
        q⁺  = q_k + Δq

    where G, e and U_k are the rows closed at q_m, or reaching the barrier by the end of
    the step, 2 g(q_m) − g(q_k) <= 0: a fast part is stopped at the barrier instead of
    h/2 · (−G v) into it. T(q, v) = ½ vᵀ M(q) v. At convergence the kinetic energy changes
    by exactly the work of the applied forces and the contact impulses,

        T(q⁺, v⁺) − T(q_k, v_k) = Δqᵀ f_applied + ½ Pᵀ G (v_k + v⁺)

    whatever h. κ M_m Δq is O(h²), so the step keeps order 2 in smooth phases; order 1
    across impacts. Iterations stop when the largest change of v⁺ is below
    ``iteration_tol · (1 + |v⁺|∞)``; a step that does not converge in ``max_iterations``
    stops the run with a :class:`moreau.SimulationError`. Only the kept pass's contact
    solve is KKT-checked. A scene with a constant mass matrix and forces that do not
    depend on v takes the plain midpoint step.
    """

    #: largest change of v⁺ between iterates (max norm), relative to 1 + max(abs(v⁺)), that ends
    #: the iteration
    iteration_tol = 1e-10
    #: iterates allowed per step before the run stops
    max_iterations = 60


#: The former name of :class:`MoreauJeanPredictorCorrector` (kept for existing scripts).
MoreauJeanTheta = MoreauJeanPredictorCorrector
