"""One-step integrators: the Moreau–Jean midpoint time-stepper.

An integrator holds the state (t, q, v) of one scene and advances it by one step with
:meth:`~OneStepIntegrator.step`; it has no loop (that is :func:`moreau.run.simulation`). It can
be used by hand::

    integ = MoreauJeanMidpoint(scene, h=1e-3)
    integ.init(0.0, q0, v0)
    for _ in range(1000):
        integ.step()
    integ.t, integ.q, integ.v
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from collections.abc import Callable
from functools import partial
from typing import Any, NamedTuple

import numpy as np

from moreau.contact.problem import kkt_residuals
from moreau.contact.solvers import ContactSolver, SolveFailed, make_solver
from moreau.core.errors import SolverError
from moreau.core.kernels import cho_solve as _cho_solve
from moreau.core.kernels import cholesky as _cholesky
from moreau.core.kernels import impact_law as _impact_law
from moreau.core.kernels import symmetry_defect as _symmetry_defect
from moreau.core.validation import as_positive, as_vector
from moreau.model.scene import Scene

__all__ = ["OneStepIntegrator", "MoreauJeanMidpoint", "MoreauJeanPredictorCorrector", "NonFiniteState",
           "BadModelOutput", "ContactDetails", "check_initial_state"]

log = logging.getLogger(__name__)


class NonFiniteState(FloatingPointError):
    """The state became NaN or infinite during a step (``step`` and ``t`` say where)."""

    def __init__(self, message: str, step: int, t: float) -> None:
        super().__init__(message)
        self.step = step
        self.t = t


class BadModelOutput(ValueError):
    """A model function (mass matrix, force, gap, Jacobian) returned an array of another
    shape during a step; the message names it with the expected and the received shape
    (``step`` and ``t`` say where)."""

    def __init__(self, message: str, step: int, t: float) -> None:
        super().__init__(message)
        self.step = step
        self.t = t


class OneStepIntegrator(ABC):
    """What every time-stepper shares: the state, the contact solve, its checks.

    Parameters
    ----------
    scene : Scene
        What to integrate.
    h : float
        Time step (s, or the scene's time unit), > 0.
    solver : str or ContactSolver
        Contact solver backend (default ``"osqp"``); see :mod:`moreau.contact.solvers`.
    fallback : str or ContactSolver or None
        Exact backend used when the main one fails or its answer does not pass the KKT
        check; ``"auto"`` (default): ``"enum"``, or ``"exact"`` when the main solver is
        ``"enum"``. Never the main solver again (the same name is refused: its failures
        would be indistinguishable); None disables the fallback.
    tol : float
        Largest accepted scaled KKT residual (see :class:`moreau.contact.problem.Residuals`).
    penetration_tol : float
        An initial state with a gap below ``-penetration_tol`` is refused.
    drift_control : PositionProjection or None
        Applied to q⁺ after every step (see :mod:`moreau.step.drift`); None: no correction.

    Attributes
    ----------
    t : float
        Current time.
    q, v : ndarray, shape (n,)
        Current coordinates and velocities.
    k : int
        Number of steps taken since :meth:`init`.
    active : ndarray of bool, shape (m,)
        Rows closed at the last step's midpoint.
    P : ndarray, shape (m,)
        Contact impulses of the last step (zero on open rows).
    last_impulse_step : ndarray of int, shape (m,)
        Per row, the index of the last step in which it carried an impulse.
    contact_step : bool
        True when the last step solved a contact problem.
    n_solves, n_fallbacks, n_contact_steps : int
        Solver statistics since :meth:`init`.
    worst_residual : float
        Largest accepted scaled KKT residual so far.

    Every call of the scene's mass matrix, force, gaps and Jacobian in a step is checked
    for its shape: another shape raises ``BadModelOutput`` naming the part (the
    contact or effect), the expected and the received shape. A configuration-dependent M
    is factorized once per step (Cholesky), and that factor serves the step's solves and
    the KKT check.
    """

    def __init__(
        self,
        scene: Scene,
        h: float,
        solver: str | ContactSolver = "osqp",
        fallback: str | ContactSolver | None = "auto",
        tol: float = 1e-6,
        penetration_tol: float = 1e-12,
        drift_control=None,
    ) -> None:
        if not isinstance(scene, Scene):
            raise ValueError(f"scene must be a Scene, got {scene!r}")
        self.scene = scene
        self.h = as_positive(h, "step size h")
        self.solver = make_solver(solver)
        if isinstance(fallback, str) and fallback == "auto":
            fallback = "exact" if self.solver.name == "enum" else "enum"
        self.fallback = None if fallback is None else make_solver(fallback)
        if self.fallback is self.solver:
            raise ValueError("fallback must be a different solver object than solver")
        if self.fallback is not None and self.fallback.name == self.solver.name:
            raise ValueError(f"fallback must be another solver than the main one, got {self.solver.name!r} twice")
        self.tol = as_positive(tol, "tol")
        self.penetration_tol = as_positive(penetration_tol, "penetration_tol", allow_zero=True)
        if drift_control is not None and not hasattr(drift_control, "project"):
            raise ValueError(f"drift_control must have a project(integrator, q) method, got {drift_control!r}")
        self.drift_control = drift_control
        self._initialized = False

    # -- state ------------------------------------------------------------------------
    def init(self, t0: float, q0, v0) -> None:
        """Set the initial state and prepare the solver.

        Raises ``ValueError`` for non-finite or wrongly shaped q0/v0, a mass matrix that
        is not symmetric positive definite at q0, malformed forces/gaps/Jacobians, and an
        initial state that penetrates a barrier (gap < ``-penetration_tol``): moreau
        refuses it rather than projecting silently.
        """
        scene = self.scene
        n, m = scene.ndof, scene.nrows
        t0, q0, v0 = check_initial_state(scene, t0, q0, v0, self.penetration_tol)
        sysm = scene.system
        self._constant_mass = sysm.constant_mass
        # the constant mass matrix and its inverse; None when M depends on q
        self._M: np.ndarray | None = None
        self._Minv: np.ndarray | None = None
        self._L: np.ndarray | None = None  # the Cholesky factor of the constant M
        if self._constant_mass:
            self._M = np.array(sysm.mass_matrix(q0), dtype=float)
            self._Minv = np.linalg.inv(self._M)
            self._L = np.linalg.cholesky(self._M)
        # what every model function must return (checked at every call on this path)
        self._shape_f, self._shape_g, self._shape_G, self._shape_M = (n,), (m,), (m, n), (n, n)
        self._e = scene.restitution
        self._impacts_only = bool(getattr(self.drift_control, "impacts_only", False))
        self._memory = int(getattr(self.drift_control, "memory", 0))
        self._locate = bool(getattr(self.drift_control, "locate_impacts", False))
        self.solver.setup(n, m, self._M if self._constant_mass else None)
        if self.fallback is not None:
            self.fallback.setup(n, m, self._M if self._constant_mass else None)
        self.t0 = t0
        self.t, self.q, self.v, self.k = t0, q0, v0, 0
        self.active = np.zeros(m, dtype=bool)
        self._no_contact = self.active.copy()
        self._no_contact.setflags(write=False)
        self.P = np.zeros(m)
        self.last_impulse_step = np.full(m, -(1 << 62), dtype=np.int64)
        self.pinned = np.zeros(m, dtype=bool)
        self.pin_gap = np.zeros(m)
        self.bounced = np.zeros(m, dtype=bool)
        # per row that bounced at s into the step: h/2 − s, and (2 s − h) a_n, what the
        # velocities at s add to U + U⁺ (both 0 for Newton's law at the midpoint)
        self.bounce_delay = np.zeros(m)
        self.bounce_shift = np.zeros(m)
        self.contact_step = False
        self.n_solves = self.n_fallbacks = self.n_contact_steps = self.n_projections = 0
        self.worst_residual = 0.0
        self.work_forces = self.work_contacts = 0.0
        #: (M, G, v_k, v⁺, P) of the last contact step, for last_contact_details
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._initialized = True

    @abstractmethod
    def step(self) -> bool:
        """Advance the state by one step h; return True when a contact problem was solved."""

    # -- contact solve ------------------------------------------------------------------
    def _solve_contact(self, M, b, G, c, rows, kind: str = "contact", L=None):
        """Solve the step's QP with the main solver, check it, fall back if needed.

        ``kind`` names the problem in errors (``"contact"``, or ``"projection"`` for drift
        control, whose solves are not counted in ``n_solves``). ``L``: the Cholesky factor
        of M when the step has it (the check then does not factorize M again).
        """
        if kind == "contact":
            self.n_solves += 1
        GA, cA = G[rows], c[rows]
        failures: dict[str, dict[str, float] | str] = {}
        for solver in (self.solver, self.fallback):
            if solver is None:
                break
            if failures:  # the main solver failed: this is the fallback
                self.n_fallbacks += 1
                log.debug("step %d: %s failed (%s), falling back to %s", self.k, self.solver.name,
                          failures[self.solver.name], solver.name)
            try:
                v, P = solver.solve(M, b, G, c, rows)
                res = kkt_residuals(M, b, GA, cA, v, P, L=L)
                if res.worst <= self.tol:
                    if res.worst > self.worst_residual:
                        self.worst_residual = res.worst
                    return v, P
                failures[solver.name] = res.as_dict()
            except (SolveFailed, np.linalg.LinAlgError, ValueError) as exc:
                failures[solver.name] = str(exc)
        names = [self.scene.row_names[i] for i in rows]
        raise SolverError(
            f"{kind} solve failed at step {self.k} (t = {self.t:.9g}), active rows {names}: {failures}",
            step=self.k, t=self.t, rows=names, residuals=failures,
        )

    def _mass_at(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """``(M(q), L)`` with L its Cholesky factor, factorized once as the compiled step
        does (the step's solves use L): a matrix of another shape raises
        ``BadModelOutput``, one that stops being symmetric positive definite
        :class:`NonFiniteState`, at this step."""
        M = self._evaluate(self.scene.system.mass_matrix, (q,), self._shape_M, "mass", self.t, q, v)
        M = np.ascontiguousarray(M, dtype=float)
        n = self.scene.ndof
        L = np.empty((n, n))
        if _symmetry_defect(M) > 1e-10 or _cholesky(M, L, n) >= 0:
            raise NonFiniteState(
                f"the mass matrix stopped being symmetric positive definite at step {self.k} "
                f"(t = {self.t:.9g}): M = {M.tolist()}", self.k, self.t)
        return M, L

    # -- model calls, checked at every call ------------------------------------------------
    def _evaluate(self, fun, args, shape, kind, t, q, v):
        """``fun(*args)``, checked to have ``shape``; else ``BadModelOutput`` naming the
        part of the scene that returned another shape (``kind``: ``"mass"``, ``"force"``,
        ``"gaps"`` or ``"jacobian"``; t, q, v: where it was evaluated)."""
        try:
            out = fun(*args)
        except Exception as exc:  # a part of another shape can break the scene's sum
            msg = _locate_bad_shape(self.scene, kind, t, q, v, self._where())
            if msg is None:
                raise
            raise BadModelOutput(msg, self.k, self.t) from exc
        if np.shape(out) != shape:
            msg = _locate_bad_shape(self.scene, kind, t, q, v, self._where()) or (
                f"{_COMPOSITE[kind]}{self._where()} has shape {np.shape(out)}, expected {shape}")
            raise BadModelOutput(msg, self.k, self.t)
        return out

    def _where(self) -> str:
        return f" at step {self.k} (t = {self.t:.9g})"

    def force_at(self, t, q, v) -> np.ndarray:
        """The scene's force f(t, q, v), its shape checked (``BadModelOutput``)."""
        return self._evaluate(self.scene.force, (t, q, v), self._shape_f, "force", t, q, v)

    def gaps_at(self, q, v=None) -> np.ndarray:
        """The scene's gaps g(q), their shape checked (``BadModelOutput``)."""
        return self._evaluate(self.scene.gaps, (q,), self._shape_g, "gaps", self.t, q, v)

    def jacobian_at(self, q, v=None) -> np.ndarray:
        """The scene's Jacobian G(q), its shape checked (``BadModelOutput``)."""
        return self._evaluate(self.scene.jacobian, (q,), self._shape_G, "jacobian", self.t, q, v)

    def _check_finite(self, q_new, v_new) -> None:
        s = float(v_new.sum()) + float(q_new.sum())
        if s - s != 0.0:  # NaN or inf
            raise NonFiniteState(
                f"state became non-finite at step {self.k} (t = {self.t:.9g}): "
                f"q = {q_new.tolist()}, v = {v_new.tolist()}",
                self.k, self.t,
            )

    def _impulse_timing(self) -> np.ndarray:
        """Δq of the impulses of the rows that bounced acting at their located instants s
        instead of at the midpoint: ``M⁻¹ Σ (h/2 − s_r) G_rᵀ P_r`` (M, G at q_m)."""
        assert self._last is not None  # set by the contact solve of this step
        M, G, _, _, P = self._last
        rhs = G.T @ (self.bounce_delay * np.where(self.bounced, P, 0.0))
        return self._Minv @ rhs if self._Minv is not None else np.linalg.solve(M, rhs)

    # -- what the last step did at the contacts (computed on request only) --------------
    def last_contact_details(self, rows: np.ndarray) -> ContactDetails:
        """Normal velocities of the last step at the given rows (all must have been
        active) and the kinetic energy the contact impulses dissipated there (for a row
        that bounced at an instant s into the step, with the velocities at s).

        Computed on request only (a solve with M), never in the step itself.
        """
        if self._last is None:
            raise ValueError("no contact step has been taken yet")
        M, G, v_old, v_new, P_all = self._last
        act = self.active
        dv = np.linalg.solve(M, G[act].T @ P_all[act])  # M⁻¹ Gᵀ P
        Gr = G[rows]
        U_before = Gr @ v_old
        U_after = Gr @ v_new
        return ContactDetails(
            U_before=U_before,
            U_after=U_after,
            U_free=Gr @ (v_new - dv),
            energy_lost=-0.5 * P_all[rows] * (U_after + U_before + self.bounce_shift[rows]),
        )


def check_initial_state(scene: Scene, t0: Any, q0: Any, v0: Any,
                        penetration_tol: float = 1e-12) -> tuple[float, np.ndarray, np.ndarray]:
    """Validate an initial state for ``scene``; return ``(t0, q0, v0)`` as floats/arrays.

    Raises ``ValueError`` for non-finite or wrongly shaped q0/v0, a mass matrix that is
    not symmetric positive definite at q0, malformed forces/gaps/Jacobians, and a state
    that penetrates a barrier (gap < ``-penetration_tol``): moreau refuses it rather than
    projecting silently. Shared by both paths of :func:`moreau.run.simulation`.
    """
    n, m = scene.ndof, scene.nrows
    t0 = float(t0)
    if not np.isfinite(t0):
        raise ValueError(f"t0 must be finite, got {t0!r}")
    q0 = as_vector(q0, "q0", n)
    v0 = as_vector(v0, "v0", n)
    scene.check_state(t0, q0, v0, where=" at the initial state")
    if m:
        assert scene.gaps is not None  # a scene with rows has gaps
        g0 = np.asarray(scene.gaps(q0), dtype=float)
        bad = np.flatnonzero(g0 < -penetration_tol)
        if bad.size:
            names = ", ".join(f"{scene.row_names[i]}: g = {g0[i]:.6g}" for i in bad)
            raise ValueError(
                f"initial state penetrates a barrier ({names}); moreau refuses a penetrating "
                "start: move q0 onto the admissible side (g >= 0)"
            )
    return t0, q0, v0


def _solve_with(L: np.ndarray, f) -> np.ndarray:
    """M⁻¹ f with the Cholesky factor L of M."""
    out = np.empty(L.shape[0])
    _cho_solve(L, np.asarray(f, dtype=float), out, L.shape[0])
    return out


_COMPOSITE = {"mass": "mass matrix", "force": "force of the scene", "gaps": "gaps of the scene",
              "jacobian": "Jacobian of the scene"}


def _locate_bad_shape(scene: Scene, kind: str, t, q, v, where: str) -> str | None:
    """The part of ``scene`` behind a composite of another shape: evaluate its parts of
    ``kind`` one by one and name the first whose shape is not the expected one (as
    :meth:`Scene.check_state` names them at the initial state); None when every part that
    evaluates has its shape (a part that raises is skipped: its own error stands)."""
    n = scene.ndof
    parts: list[tuple[str, Callable[[], Any], tuple[int, ...]]] = []
    if kind == "mass":
        parts.append(("mass matrix", partial(scene.system.mass_matrix, q), (n, n)))
    elif kind == "force":
        vv = np.zeros(n) if v is None else v
        if scene.system.has_bias:
            parts.append(("bias force", partial(scene.system.bias_force, q, vv), (n,)))
        for e in scene.effects:
            parts.append((f"force of effect {e.name!r}", partial(e.force, t, q, vv), (n,)))
    else:
        for c in scene.contacts:
            b = c.barrier
            if kind == "gaps":
                parts.append((f"gap of contact {c.name!r}", partial(b.gap, q), (b.nrows,)))
            else:
                parts.append((f"Jacobian of contact {c.name!r}", partial(b.jacobian, q), (b.nrows, n)))
    for what, call, shape in parts:
        try:
            got = np.shape(call())
        except Exception:  # noqa: BLE001 - its own error is reported by the caller
            continue
        if got != shape:
            return f"{what}{where} has shape {got}, expected {shape}"
    return None


class ContactDetails(NamedTuple):
    """What the last step did at some contact rows; each field has shape (len(rows),).

    Attributes
    ----------
    U_before, U_after : ndarray
        ``G v_k`` and ``G v⁺``.
    U_free : ndarray
        ``G v_free``, the normal velocity the step would have had without contact
        (``U_free − U_before = h a_n``, the smooth forces' normal velocity change).
    energy_lost : ndarray
        Per row ``−½ P_i (U⁻_i + U⁺_i)`` (J), the contact's share of the step's exact
        kinetic energy balance ``½v⁺ᵀMv⁺ − ½v_kᵀMv_k = h fᵀ(v_k + v⁺)/2 + ½ Pᵀ(U⁻ + U⁺)``.
        With Newton's law (U⁺ = −e U⁻ where P > 0) it is ``½ P |U⁻| (1 − e) >= 0``: never a
        gain for e <= 1, zero for e = 1, and ½ m_eff U²(1 − e²) for an isolated impact.
    """

    U_before: np.ndarray
    U_after: np.ndarray
    U_free: np.ndarray
    energy_lost: np.ndarray


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
                    c = -self._e * U
                b = M @ v + h * f
                v_new, PA = self._solve_contact(M, b, G, c, rows, L=L)
                P = np.zeros(scene.nrows)
                P[rows] = PA
                self.active, self.P = active, P
                self._last = (M, G, v, v_new, P)
                return v_new, True
        if self._Minv is not None:  # a constant mass matrix
            return v + h * (self._Minv @ f), False
        return v + h * _solve_with(L, f), False  # the step's one factorization

    def _finish(self, qm, v_new, contact: bool, f) -> bool:
        """Move to q⁺ = q_m + h/2 v⁺ (then drift control), check, advance time; add the
        step's energy-ledger terms (smooth-force and contact work)."""
        q_new = qm + (0.5 * self.h) * v_new
        if contact and self._locate and self.bounced.any():
            q_new = q_new + self._impulse_timing()
        self._check_finite(q_new, v_new)
        self.work_forces += 0.5 * self.h * float(f @ (self.v + v_new))
        if contact:
            self.n_contact_steps += 1
            assert self._last is not None  # set by the contact solve of this step
            _, G, v_old, _, P = self._last
            act = self.active
            self.work_contacts += 0.5 * float(P[act] @ (G[act] @ (v_old + v_new)))
        elif self.active is not self._no_contact:
            # no contact in this step (also when only a θ predictor closed one): clear
            self.active = self._no_contact
            self.P = np.zeros(self.scene.nrows)
        self.contact_step = contact
        if contact:
            self.last_impulse_step[self.P > 0.0] = self.k
        if self.drift_control is not None and self.scene.nrows:
            q_new = self.drift_control.project(self, q_new)
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
        f = force(tm, qm, 0.5 * (v + v_pred))
        v_new, contact = self._velocity_update(qm, M, L, f, v)
        return self._finish(qm, v_new, contact, f)


#: The former name of :class:`MoreauJeanPredictorCorrector` (kept for existing scripts).
MoreauJeanTheta = MoreauJeanPredictorCorrector
