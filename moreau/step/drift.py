"""Drift control: keep positions on the admissible side of curved barriers.

The midpoint scheme imposes the contact condition on velocities with the Jacobian at
the midpoint, so a contact pressed against a curved barrier drifts into it by about
h²/2 · vᵀ∇²g v per step, an O(h) penetration over a sliding phase (on the piston ≈ 10 %
of the clearance at h = 1e-4). Two corrections:

- :class:`CombinedProjection` (the default of the bundled piston): every row, whatever
  its restitution, is projected back onto ``g >= 0``, and Newton's restitution acts only
  at impacts, so that a row in persistent contact gets no spurious bounce.
- :class:`PositionProjection`: positions only, plastic rows (e = 0) only by default.
"""

from __future__ import annotations

import logging
import warnings

import numpy as np

__all__ = ["PositionProjection", "CombinedProjection"]

log = logging.getLogger(__name__)


class PositionProjection:
    """Project q⁺ onto ``g(q) >= 0`` in the metric of the mass matrix after each step.

    With the rows that penetrate at q⁺ and the rows closed in the step, solve

        minimize ½ Δqᵀ M(q⁺) Δq   subject to   g(q⁺) + G(q⁺) Δq >= 0

    (the one-step QP with b = 0 and c = −g, so the same solver, checks and fallback) and
    set q⁺ ← q⁺ + Δq, after every step; repeat while a row still penetrates, up to ``max_iter`` times (the
    linearization leaves ``O(|Δq|²)`` behind, far below the drift it removes). Velocities are
    not changed. One more small solve per step in which something penetrates.

    Only rows whose restitution is at most ``max_restitution`` (default 0: plastic
    contacts) are projected. Moving a bouncing contact (e > 0) out of the barrier without
    touching its velocity keeps it bouncing at speeds ~h·g instead of letting it come to
    rest (measured: a ball with e = 0.8 logs 656 impacts in 6 s instead of 25, the
    e = 0.9 piston 5–25× more impacts per cycle), so those rows are left to the scheme,
    whose drift is small where contacts bounce (≈ 0.5 % of the piston's clearance at
    h = 1e-4 for e = 0.9).

    Parameters
    ----------
    max_iter : int
        Projection passes per step (default 2).
    tol : float
        Accept a remaining penetration up to ``tol`` (gap units; default 0).
    max_restitution : float
        Project only rows with e <= this (default 0.0); 1.0 projects every row.
    """

    def __init__(self, max_iter: int = 2, tol: float = 0.0, max_restitution: float = 0.0) -> None:
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
            raise ValueError(f"PositionProjection.max_iter must be a positive integer, got {max_iter!r}")
        if not (np.isfinite(tol) and tol >= 0):
            raise ValueError(f"PositionProjection.tol must be finite and >= 0, got {tol!r}")
        if not (0.0 <= max_restitution <= 1.0):
            raise ValueError(f"PositionProjection.max_restitution must be in [0, 1], got {max_restitution!r}")
        self.max_iter = int(max_iter)
        self.tol = float(tol)
        self.max_restitution = float(max_restitution)
        self._scene: object | None = None  # the scene _eligible was computed for
        self._eligible = np.zeros(0, dtype=bool)

    #: restitution acts at impacts only (see :class:`CombinedProjection`); False here
    impacts_only = False
    #: steps a row stays in persistent contact after its last impulse (CombinedProjection)
    memory = 0

    def eligible_rows(self, scene) -> np.ndarray:
        """Rows this projection may move, shape (m,) of bool. Warns (``RuntimeWarning``)
        when a scene has contact rows but none is eligible: the projection then does
        nothing (use :class:`CombinedProjection` for rows with e > 0)."""
        eligible = scene.restitution <= self.max_restitution
        if scene.nrows and not eligible.any():
            warnings.warn(
                f"{type(self).__name__}(max_restitution={self.max_restitution:g}) projects no row of scene "
                f"{scene.name!r}: every row has e > {self.max_restitution:g}; use CombinedProjection() for "
                "drift control of bouncing rows", RuntimeWarning, stacklevel=4)
        return eligible

    def project(self, integ, q: np.ndarray) -> np.ndarray:
        """The projected q⁺ for the integrator ``integ`` (its scene, solver and last step)."""
        scene = integ.scene
        if self._scene is not scene:  # rows this projection may move, once per scene
            self._scene, self._eligible = scene, self.eligible_rows(scene)
        eligible = self._eligible
        if not eligible.any():
            return q
        g = scene.gaps(q)
        # a held row stays held while it carries an impulse without bouncing and its gap has
        # not grown beyond where the projection left it (see CombinedProjection)
        integ.pinned &= (integ.P > 0.0) & ~integ.bounced & (g <= integ.pin_gap)
        if not (self._rows(integ, g, eligible) & (g < -self.tol)).any():
            return q
        zero = np.zeros(scene.ndof)
        for _ in range(self.max_iter):
            rows = np.flatnonzero(self._rows(integ, g, eligible))
            M = integ._M if integ._constant_mass else scene.system.mass_matrix(q)
            if integ._eq is not None:  # along the bilateral rows (moreau.step.bilateral)
                dq, mu = integ._eq.project_contacts(integ, q, M, scene.jacobian(q), -g, rows)
            else:
                dq, mu = integ._solve_contact(M, zero, scene.jacobian(q), -g, rows, kind="projection")
            q = q + dq
            g = scene.gaps(q)
            held = rows[mu > 0.0]
            integ.pinned[held] = True
            integ.pin_gap[held] = np.maximum(g[held], 0.0)
            if not (self._rows(integ, g, eligible) & (g < -self.tol)).any():
                break
        integ.n_projections += 1
        return q

    @staticmethod
    def _rows(integ, g: np.ndarray, eligible: np.ndarray) -> np.ndarray:
        """Rows of the projection QP: eligible rows that penetrate or were closed."""
        return ((g < 0.0) | integ.active) & eligible

    def describe(self) -> dict:
        return {"type": "PositionProjection", "max_iter": self.max_iter, "tol": self.tol,
                "max_restitution": self.max_restitution}


class CombinedProjection(PositionProjection):
    """Drift control for every restitution: positions projected onto ``g >= 0`` and
    velocities kept consistent with the contacts that persist.

    After the ideas of the projected Moreau–Jean schemes of Acary (2013), which Siconos
    implements as ``MoreauJeanDirectProjectionOSI`` and
    ``MoreauJeanCombinedProjectionOSI`` [1]_ [2]_, with the velocity level made
    consistent with the projection:

    1. **Restitution at impacts only.** A closed row takes its Newton restitution only
       when it approaches faster than the smooth forces change its normal velocity in one
       step (``−U⁻ > h |G M⁻¹ f|``, the velocity test of the impact log) and carried no
       impulse in the last ``memory`` steps. Every other closed row is a contact that
       persists (pressed, sliding, or re-closing after the drift opened it for a step)
       and takes e = 0, i.e. ``U⁺ >= 0``: no approach velocity is left for the next step
       and none is turned into a bounce. This is the limit of Newton's law as the approach
       velocity goes to 0 relative to ``h |a_n|``; the difference to the plain law is O(h).
       A row that bounces takes Newton's law at the step's midpoint: with the free normal
       velocity there, ``U_m = U⁻ + h/2 a_n``, the impulse turns ``U_m`` into ``−e U_m`` and
       the smooth forces act for the rest of the step, ``U⁺ >= −e U_m + h/2 a_n`` (at least
       0). Since the row closes in the step in which it reaches the barrier (point 3), the
       impact falls at s ∈ (0, h] into the step, on average at the midpoint: a bounce
       shifts the remaining time of a bouncing sequence by ``(1 + e)(s − h/2)/e``, zero on
       average. Newton's law on ``U⁻`` (the plain scheme's) ignores the smooth forces
       during the step and put a ball one step late at every bounce it resolves: for
       e = 0.8 at rest 16 … 34 steps after the Zeno time at h = 1e-3 … 3e-5, growing with
       the number of resolved bounces; with the midpoint law 6 … 19 steps before it at
       every h, the bounces shorter than a step being lost
       (``tests/test_drift_combined.py``). For e = 1 the two laws agree.
    2. **Positions.** After every step the persistent contacts of the step (closed, no
       restitution applied) are projected back onto ``g >= 0`` in the metric of M (the
       QP of :class:`PositionProjection`), whatever their coefficient e. Rows that just
       bounced are left to separate, and rows in flight are left to the next step's
       impact: moving either out of the barrier with its velocity kept would add energy
       against the force that presses it (measured on a block pressed flat against a
       wall by a force: a rocking of 5e-3 … 9e-2 rad/s that does not shrink with h).
    3. **Velocities consistent with the positions.** A row the projection held on
       ``g = 0`` stays in the contact problem of the next steps while it carries an
       impulse without bouncing and its gap does not grow beyond where the projection
       left it (a resting contact is not set free by the projection's round-off), and a
       row that reaches the barrier by the end of a step (``2 g(q_m) − g(q_k) <= 0``)
       enters that step's problem: its impulse then acts before it is inside.

    4. **Located impacts** (``locate_impacts=True``; not the default). The midpoint law
       takes every bounce at s = h/2, so the impact times of a bouncing sequence make a
       random walk of ±(1 + e)/(2e)·h per bounce. With ``locate_impacts`` the impact
       instant s is read off the step's own data, the gap's expansion
       ``g(q_k) + U s + a_n s²/2 = 0`` with ``a_n = G M⁻¹ f``, without splitting the step
       (``moreau.core.kernels.impact_law``). A row closes when the free step's end gap
       ``2 g(q_m) − g(q_k) + h²/2 a_n`` reaches 0; it bounces when its approach at s is
       faster than ``h |a_n|``; Newton's law acts at s, ``U⁺ >= −e U_s + (h − s) a_n``
       with ``U_s = U + s a_n`` (at least 0 unless that motion keeps the row off the
       barrier to the end of the step); and its impulse P moves the end of the step as
       an impulse at s does, ``q⁺ = q_m + h/2 v⁺ + (h/2 − s) M⁻¹ Gᵀ P``. For a ball
       under gravity each bounce is then exact up to the step that contains it, and
       with ``memory=0`` (no persistent contact to keep: a bounce may follow the last
       one after a single step of flight) the ball comes to rest within 10 steps of the
       Zeno time (``tests/test_drift_combined.py``). It is not the default. On the
       piston (``benchmarks/piston_convergence.py --locate``) it counts 219.5 flights
       per cycle at h = 1e-3 and e = 0.9 against 152.5 of an unprojected h = 1e-5 run
       (the default: 148), though from h = 3e-4 on it agrees within 2 % and it gives the
       converged 10 side changes from h = 1e-4 on (the default from 3e-5); for
       e = 0.05 and 0.3 its pressed contacts keep bouncing at speeds just above
       ``h |a_n|`` (6 122 … 519 305 velocity-test onsets per cycle, the default 30 … 327),
       with the side changes and flights of the default. A block pressed flat on a wall
       (point 2) leaves its pressed phase rocking at 0.04 rad/s (e = 0.5, h = 1e-3) and
       0.013 rad/s (h = 3e-4), not at h = 1e-4 or for e = 0.9. The position term is not
       in the power that :func:`moreau.results.diagnostics.energy_ledger` integrates, so the
       ledger of a run with located impacts does not close exactly.

    Measured (``benchmarks/piston_convergence.py``, piston at D = 80.04 mm): at h = 1e-3
    the penetration stays below 0.95 % of the clearance for e = 0 … 0.9 (without drift
    control 100 % … 5 %), the impacts per cycle agree with an unprojected h = 1e-5 run
    within 10 %, and the side changes and their angles are those of h = 1e-5. The
    position-only projection of bouncing rows (``PositionProjection(max_restitution=1)``)
    multiplies the e = 0.9 piston's velocity-test onsets ×19 in its first cycle.

    Parameters
    ----------
    max_iter : int
        Projection passes per step (default 2).
    tol : float
        Accept a remaining penetration up to ``tol`` (gap units; default 0).
    memory : int
        Steps after its last impulse during which a row counts as in persistent contact
        (default 2: a contact that opens for a single step and closes again is the same
        contact). 0 applies restitution at every fast approach.
    locate_impacts : bool
        Newton's law at the impact instant located inside the step, whose impulse then
        moves the end of the step as an impulse at that instant does (point 4; default
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

    @staticmethod
    def _rows(integ, g: np.ndarray, eligible: np.ndarray) -> np.ndarray:
        """Rows of the projection QP: the persistent contacts of the step (closed, no bounce)."""
        return integ.active & ~integ.bounced

    def describe(self) -> dict:
        return {"type": "CombinedProjection", "max_iter": self.max_iter, "tol": self.tol, "memory": self.memory,
                "locate_impacts": self.locate_impacts}
