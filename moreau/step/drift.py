"""Drift control: keep positions on the admissible side of curved barriers.

The midpoint scheme imposes the contact condition on velocities with the Jacobian at the
midpoint, so a contact pressed against a curved barrier drifts into it by about
h²/2 · vᵀ∇²g v per step, an O(h) penetration over a sliding phase (on the piston ≈ 10 % of
the clearance at h = 1e-4). Two corrections, given as ``simulate(..., drift_control=)`` and
run by the compiled loop (:mod:`moreau.compiled.drift`); the theory page's "Drift and drift
control" derives them and gives their measured effect:

- :class:`CombinedProjection` (the default of the bundled piston): every row, whatever its
  restitution, is projected back onto ``g >= 0``, and Newton's restitution acts only at
  impacts, so that a row in persistent contact gets no spurious bounce.
- :class:`PositionProjection`: positions only, plastic rows (e = 0) only by default.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["PositionProjection", "CombinedProjection"]


class PositionProjection:
    """Project q⁺ onto ``g(q) >= 0`` in the metric of the mass matrix after each step.

    With the rows that penetrate at q⁺ and the rows closed in the step, solve

        minimize ½ Δqᵀ M(q⁺) Δq   subject to   g(q⁺) + G(q⁺) Δq >= 0

    (the one-step QP with b = 0 and c = −g, so the same solver, checks and fallback) and set
    q⁺ ← q⁺ + Δq; repeat while a row still penetrates, up to ``max_iter`` times. Velocities
    are not changed. Only rows whose restitution is at most ``max_restitution`` are
    projected: moving a bouncing contact out of the barrier without touching its velocity
    keeps it bouncing at speeds ~h·g instead of letting it come to rest.

    Parameters
    ----------
    max_iter : int
        Projection passes per step (default 2).
    tol : float
        Accept a remaining penetration up to ``tol`` (gap units; default 0).
    max_restitution : float
        Project only rows with e <= this (default 0.0); 1.0 projects every row.
    velocity : bool
        Also make the velocity of the rows the projection held admissible at the projected
        q⁺: ``v⁺ ← argmin ‖v' − v⁺‖_M`` subject to ``G_A(q⁺) v' >= 0`` (an e = 0 impulse,
        counted with the step's contact impulses). Default False. Without it a contact
        sliding along a curved barrier keeps the O(h) normal velocity into the barrier
        that the midpoint Jacobian leaves, the projection holds it there, and it leaves
        the barrier late or hops off and on (docs/guide/accuracy.md, "Leaving a curved
        barrier"). Frictionless scenes without bilateral rows only (``ValueError``).
    """

    #: restitution acts at impacts only (see :class:`CombinedProjection`); False here
    impacts_only = False
    #: steps a row stays in persistent contact after its last impulse (CombinedProjection)
    memory = 0
    #: Newton's law at the impact instant located in the step (CombinedProjection)
    locate_impacts = False

    def __init__(self, max_iter: int = 2, tol: float = 0.0, max_restitution: float = 0.0,
                 velocity: bool = False) -> None:
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
            raise ValueError(f"{type(self).__name__}.max_iter must be a positive integer, got {max_iter!r}")
        if not (np.isfinite(tol) and tol >= 0):
            raise ValueError(f"{type(self).__name__}.tol must be finite and >= 0, got {tol!r}")
        if not (0.0 <= max_restitution <= 1.0):
            raise ValueError(f"PositionProjection.max_restitution must be in [0, 1], got {max_restitution!r}")
        if not isinstance(velocity, (bool, np.bool_)):
            raise ValueError(f"{type(self).__name__}.velocity must be True or False, got {velocity!r}")
        self.max_iter = int(max_iter)
        self.tol = float(tol)
        self.max_restitution = float(max_restitution)
        self.velocity = bool(velocity)

    def eligible_rows(self, scene) -> np.ndarray:
        """Rows this projection may move, shape (m,) of bool. Warns (``RuntimeWarning``)
        when a scene has contact rows but none is eligible: the projection then does
        nothing (use :class:`CombinedProjection` for rows with e > 0). ``ValueError`` when
        ``velocity=True`` meets a scene with friction or bilateral rows."""
        eligible = scene.restitution <= self.max_restitution
        self._check_velocity(scene)
        if scene.nrows and not eligible.any():
            warnings.warn(
                f"{type(self).__name__}(max_restitution={self.max_restitution:g}) projects no row of scene "
                f"{scene.name!r}: every row has e > {self.max_restitution:g}; use CombinedProjection() for "
                "drift control of bouncing rows", RuntimeWarning, stacklevel=4)
        return eligible

    def _check_velocity(self, scene) -> None:
        """``ValueError`` when ``velocity=True`` meets friction or bilateral rows."""
        if self.velocity and (scene.has_friction or scene.nconstraints):
            what = "friction" if scene.has_friction else "bilateral rows"
            raise ValueError(f"{type(self).__name__}(velocity=True) needs a frictionless scene without bilateral "
                             f"rows; scene {scene.name!r} has {what}")

    def describe(self) -> dict:
        return {"type": "PositionProjection", "max_iter": self.max_iter, "tol": self.tol,
                "max_restitution": self.max_restitution, "velocity": self.velocity}


class CombinedProjection(PositionProjection):
    """Drift control for every restitution: positions projected onto ``g >= 0`` and
    velocities kept consistent with the contacts that persist.

    After the projected Moreau–Jean schemes of Acary (2013), which Siconos implements as
    ``MoreauJeanDirectProjectionOSI`` and ``MoreauJeanCombinedProjectionOSI`` [1]_ [2]_:

    1. **Restitution at impacts only.** A closed row takes its Newton restitution only when
       it approaches faster than the smooth forces change its normal velocity in one step
       (``−U⁻ > h |G M⁻¹ f|``) and carried no impulse in the last ``memory`` steps; then at
       the step's midpoint, ``U⁺ >= −e U_m + h/2 a_n`` with ``U_m = U⁻ + h/2 a_n``. Every
       other closed row persists and takes e = 0.
    2. **Positions.** After every step the persistent contacts of the step (closed, no
       restitution applied) are projected back onto ``g >= 0`` in the metric of M (the QP
       of :class:`PositionProjection`), whatever their e.
    3. **Velocities consistent with the positions.** A row the projection held on ``g = 0``
       stays in the contact problem while it carries an impulse without bouncing and its
       gap does not grow beyond where the projection left it; a row that reaches the
       barrier by the end of a step (``2 g(q_m) − g(q_k) <= 0``) enters that step's problem.
    4. **Located impacts** (``locate_impacts=True``; not the default). The impact instant s
       is read off the step's own data, ``g(q_k) + U s + a_n s²/2 = 0``
       (``moreau.core.kernels.impact_law``); Newton's law acts at s and its impulse moves
       the end of the step as an impulse at s does.

    Parameters
    ----------
    max_iter : int
        Projection passes per step (default 2).
    tol : float
        Accept a remaining penetration up to ``tol`` (gap units; default 0).
    memory : int
        Steps after its last impulse during which a row counts as in persistent contact
        (default 2). 0 applies restitution at every fast approach.
    locate_impacts : bool
        Newton's law at the impact instant located inside the step (point 4; default
        False). Use with ``memory=0`` for bodies that bounce without persistent contacts.

    References
    ----------
    .. [1] V. Acary, "Projected event-capturing time-stepping schemes for nonsmooth
       mechanical systems with unilateral contact and Coulomb's friction", Computer
       Methods in Applied Mechanics and Engineering 256 (2013) 224–250.
    .. [2] V. Acary and B. Brogliato, *Numerical Methods for Nonsmooth Dynamical
       Systems*, Lecture Notes in Applied and Computational Mechanics 35, Springer (2008).
    """

    impacts_only = True

    def __init__(self, max_iter: int = 2, tol: float = 0.0, memory: int = 2, locate_impacts: bool = False) -> None:
        super().__init__(max_iter=max_iter, tol=tol, max_restitution=1.0)
        if isinstance(memory, bool) or not isinstance(memory, (int, np.integer)) or memory < 0:
            raise ValueError(f"CombinedProjection.memory must be an integer >= 0, got {memory!r}")
        if not isinstance(locate_impacts, (bool, np.bool_)):
            raise ValueError(f"CombinedProjection.locate_impacts must be True or False, got {locate_impacts!r}")
        self.memory = int(memory)
        self.locate_impacts = bool(locate_impacts)

    def eligible_rows(self, scene) -> np.ndarray:
        return np.ones(scene.nrows, dtype=bool)

    def describe(self) -> dict:
        return {"type": "CombinedProjection", "max_iter": self.max_iter, "tol": self.tol, "memory": self.memory,
                "locate_impacts": self.locate_impacts}
