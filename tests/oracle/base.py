"""The one-step integrator's base: state, model evaluation with checks, drift control,
and the contact solve (:class:`~moreau.step.nonsmooth.NonsmoothSolve`); subclasses write
:meth:`step`."""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from typing import NamedTuple

import numpy as np

from moreau.contact.solvers import ContactSolver, make_solver
from moreau.core.kernels import cho_solve as _cho_solve
from moreau.core.kernels import cholesky as _cholesky
from moreau.core.kernels import symmetry_defect as _symmetry_defect
from moreau.core.validation import as_positive
from moreau.model.scene import Scene
from oracle.checks import _COMPOSITE, BadModelOutput, NonFiniteState, _locate_bad_shape, check_initial_state
from oracle.nonsmooth import NonsmoothSolve

__all__ = ["OneStepIntegrator", "ContactDetails"]

log = logging.getLogger(__name__)


class OneStepIntegrator(NonsmoothSolve, ABC):
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
        # with bilateral rows the solvers see the reduced problem (moreau.contact.equality),
        # whose mass matrix is the identity
        from oracle.bilateral import EqualityRows, constraint_rank

        self._eq = EqualityRows(scene) if scene.nconstraints else None
        if self._eq is not None:
            rank, redundant = constraint_rank(scene, q0)
            if redundant:  # reported, not an error: v stays unique
                log.info("scene %r: %d bilateral rows of rank %d at q0; redundant: %s", scene.name,
                         scene.nconstraints, rank, ", ".join(redundant))
        setup_mass = np.eye(n) if self._eq is not None else self._M if self._constant_mass else None
        self.solver.setup(n, m, setup_mass)
        if self.fallback is not None:
            self.fallback.setup(n, m, setup_mass)
        #: the work of the bilateral rows' impulses (0 up to round-off: ideal joints), and the
        #: kinetic energy the velocity projection onto them at q⁺ removed (<= 0, O(h⁴) per step)
        self.work_constraints = self.work_constraint_projection = 0.0
        self.t0 = t0
        self.t, self.q, self.v, self.k = t0, q0, v0, 0
        self.active = np.zeros(m, dtype=bool)
        self._no_contact = self.active.copy()
        self._no_contact.setflags(write=False)
        self.P = np.zeros(m)
        #: tangential (friction) impulses of the last step, shape (m,); zeros without friction
        self.PT = np.zeros(m)
        self._PT_active = np.zeros(0)
        self._mu = scene.friction
        self._T: np.ndarray | None = None  # the tangent rows of the last contact step
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
        #: velocity updates computed (SolverStats.velocity_updates)
        self.n_updates = 0
        self.worst_residual = 0.0
        self.work_forces = self.work_contacts = 0.0
        #: work of the friction impulses, not in ``work_contacts``: ½ P_T (U_T⁻ + U_T⁺) per step, <= 0
        #: unless the slip reverses within the step (Coulomb's law holds at U_T⁺ only)
        self.work_friction = 0.0
        #: steps with a sliding contact in Painlevé's region, and the first one's message
        self.n_painleve = 0
        self.painleve: str | None = None
        #: the bias terms' share of ``work_forces``, kept when ``track_bias_work`` is set
        self.work_bias = 0.0
        self.track_bias_work = False
        #: (M, G, v_k, v⁺, P) of the last contact step, for last_contact_details
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        #: defer the KKT check of plain contact solves (an iterating step's passes: only the
        #: answer it keeps is checked, by :meth:`_check_deferred`); the unchecked answer
        self._defer_check = False
        self._unchecked: tuple | None = None
        self._initialized = True

    @abstractmethod
    def step(self) -> bool:
        """Advance the state by one step h; return True when a contact problem was solved."""

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

    def tangent_at(self, q, v=None) -> np.ndarray:
        """The scene's tangent rows T(q) (friction), their shape and finiteness checked
        (``BadModelOutput`` naming the contact)."""
        T = self._evaluate(self.scene.tangent_jacobian, (q,), self._shape_G, "tangent", self.t, q, v)
        if not np.isfinite(T).all():
            bad = [c.name for c in self.scene.contacts if np.any(c.friction > 0.0)
                   and not np.isfinite(np.asarray(c.barrier.tangent_jacobian(q), dtype=float)).all()]
            raise BadModelOutput(f"the tangent rows (tangent_jacobian) of contact {', '.join(map(repr, bad))} are "
                                 f"not finite{self._where()}, at q = {np.asarray(q).tolist()}", self.k, self.t)
        return T

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
        impulse = G[act].T @ P_all[act]
        if self._T is not None:  # friction: the tangential impulses are not in the free velocity either
            impulse = impulse + self._T[act].T @ self.PT[act]
        dv = np.linalg.solve(M, impulse)  # M⁻¹ (Gᵀ P + Tᵀ P_T)
        Gr = G[rows]
        U_before = Gr @ v_old
        U_after = Gr @ v_new
        return ContactDetails(
            U_before=U_before,
            U_after=U_after,
            U_free=Gr @ (v_new - dv if self._eq is None else self._eq.v_free),
            energy_lost=-0.5 * P_all[rows] * (U_after + U_before + self.bounce_shift[rows]),
        )


class ContactDetails(NamedTuple):
    """What the last step did at some contact rows; each field has shape (len(rows),).

    Attributes
    ----------
    U_before, U_after : ndarray
        ``G v_k`` and ``G v⁺``.
    U_free : ndarray
        ``G v_free``, the normal velocity the step would have had without contact
        (``U_free − U_before = h a_n``, the smooth forces' normal velocity change; with
        bilateral rows, with the joints held).
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


def _solve_with(L: np.ndarray, f) -> np.ndarray:
    """M⁻¹ f with the Cholesky factor L of M."""
    out = np.empty(L.shape[0])
    _cho_solve(L, np.asarray(f, dtype=float), out, L.shape[0])
    return out
