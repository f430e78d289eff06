"""The front door: :func:`simulate` runs a scene over a time span and returns a Trajectory."""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from moreau.compiled import cache
from moreau.compiled.layout import STEP_ENERGY, STEP_MIDPOINT, STEP_THETA
from moreau.compiled.lowering import lower
from moreau.compiled.runner import run_compiled
from moreau.compiled.variants import VARIANTS, variant
from moreau.contact.refine import ensure_loaded
from moreau.contact.solvers import ContactSolver
from moreau.core.errors import attach_trajectory
from moreau.core.validation import as_positive, as_record_every, as_time_span, checked_start
from moreau.model.scene import Scene
from moreau.model.stability import DEFAULT_ENERGY_GROWTH, as_energy_growth, explicit_limit_message
from moreau.results.trajectory import Trajectory
from moreau.run import trust
from moreau.run.backend import DriftControl, choose_backend, initial_state_only
from moreau.run.flights import flight_gaps, initial_flight
from moreau.run.progress import progress_bar
from moreau.run.trust import check_jacobians, constraint_rank, penetration_warnings, redundancy_warnings
from moreau.step.checks import START_PENETRATION_TOL, check_initial_state
from moreau.step.control import StepControl
from moreau.step.integrator import (
    MoreauJeanEnergyConsistent,
    MoreauJeanMidpoint,
    MoreauJeanPredictorCorrector,
    OneStepIntegrator,
)

__all__ = ["simulate", "ensure_compiled"]

log = logging.getLogger(__name__)

_MAX_STEPS = 1e11  # a guard against a mistyped h, far beyond any run that finishes
_MAX_RECORD_BYTES = 8 * 2**30



def simulate(
    scene: Scene,
    t_span: tuple[float, float],
    q0: ArrayLike,
    v0: ArrayLike,
    h: float,
    *,
    backend: str = "auto",
    solver: str | ContactSolver | None = None,
    fallback: str | ContactSolver | None = "auto",
    integrator: type[OneStepIntegrator] = MoreauJeanMidpoint,
    record_every: int = 1,
    progress: bool | dict[str, Any] | None = None,
    energy: bool = True,
    tol: float = 1e-6,
    drift_control: DriftControl | None = None,
    check_jacobian: bool = True,
    penetration_limit: float | None = None,
    flight_gap: ArrayLike = 0.0,
    initial_penetration: float = START_PENETRATION_TOL,
    energy_growth: tuple[float, float] | None = DEFAULT_ENERGY_GROWTH,
    step_control: StepControl | None = None,
) -> Trajectory:
    """Integrate a scene from ``t_span[0]`` to ``t_span[1]``, with a fixed step or, with
    ``step_control``, a step that adapts to a local error tolerance.

    Parameters
    ----------
    scene : Scene
        System, effects and contacts.
    t_span : (float, float)
        Start and end time; ``t1 > t0``. The run takes ``N = ceil((t1 - t0)/h)`` steps
        (to within 1e-9 h) and ends at ``t0 + N h``; with ``step_control`` it ends at t1.
    q0, v0 : array_like, shape (n,)
        Initial coordinates and velocities. A state that penetrates a barrier is
        refused (``ValueError``); an approaching velocity on a closed contact is
        resolved by the first step's impact.
    h : float
        Step size (> 0, at most t1 − t0); with ``step_control`` the largest step.
    backend : {"auto", "compiled"}
        Kept for existing code: every scene runs in the compiled loop
        (:mod:`moreau.compiled.loop`); ``"python"`` is deprecated (``DeprecationWarning``)
        and runs there too. ``traj.stats.backend`` is ``"compiled"``.
    solver : str or ContactSolver, optional
        ``"exact"`` (default; also ``"auto"``: block pivoting from 8 rows, else or after it
        the dual active set), ``"enum"`` (≤ 12 rows): the loop's own; ``"osqp"``,
        ``"daqp"``, ``"quadprog"`` or a :class:`~moreau.contact.base.ContactSolver`: called
        back (:class:`~moreau.compiled.callbacks.SolverCallback`). Every answer is
        KKT-checked. Friction: the loop's friction solver whatever the solver (Lemke's
        method below 32 closed contacts, projected Gauss–Seidel and a polish from 32).
    fallback : str or ContactSolver or None
        Exact solver for steps the main one fails; ``"auto"``: ``"enum"``, or
        ``"exact"`` when the main solver is ``"enum"``. Never the same as ``solver``.
    integrator : OneStepIntegrator subclass
        The time-stepper (default :class:`MoreauJeanMidpoint`).
    record_every : int
        Record every k-th step (and the last); with ``step_control`` every k-th accepted
        step, so that ``traj.t`` is not uniform. Impulses are summed and activity is
        or-ed over the steps between records; impacts are logged at every step.
    progress : bool or dict or None
        Show a tqdm progress bar. None: only for long runs on a terminal. A dict shows
        one and is passed to ``tqdm`` (e.g. ``{"position": 1, "desc": "case 2"}``).
    energy : bool
        Compute the mechanical energy at the records.
    tol : float
        Largest accepted scaled KKT residual of a contact solve.
    drift_control : CombinedProjection or PositionProjection or None
        Drift control after each step (see :mod:`moreau.step.drift`); default none.
    check_jacobian : bool
        Compare each user barrier's Jacobian with finite differences of its gap at and near q0,
        and a system's own bias force with its M(q)'s (:func:`moreau.check_bias`); default True.
    initial_penetration : float
        An initial state with a gap below ``-initial_penetration`` (gap units) is refused
        (default 1e-12); to continue from where another run ended (an impact step may end
        inside a barrier by about (1 − e)|U|h/2), pass that run's penetration limit.
    penetration_limit : float, optional
        Largest acceptable penetration (gap units). Default: ``h·|U⁻|`` per row, the
        distance its impacts travel in one step. A run beyond it warns
        (``RuntimeWarning``) and says so in ``traj.warnings``.
    flight_gap : float or array_like, shape (m,)
        Per row (gap units, >= 0; default 0): a contact onset is an *impact*
        (``traj.impacts``, :class:`moreau.ImpactLog`) when the row's gap exceeded this at
        the end of a step since its last impulse (the piston: 2 % of the clearance).
    energy_growth : (float, float) or None
        The energy check (:mod:`moreau.model.stability`): energy unaccounted for by the
        work of the applied forces above ``warn`` (default 0.05) times the largest kinetic
        energy so far warns once; above ``stop`` (0.1) the run stops (``SimulationError``
        naming a stable step). None: no check.
    step_control : StepControl, optional
        Adapt the step to a local error tolerance (:class:`StepControl`); ``tol`` above
        stays the contact solve's residual.

    Returns
    -------
    Trajectory
        With ``status == "completed"``.

    Raises
    ------
    ValueError
        Bad input: non-finite or wrongly shaped states, h <= 0, a reversed time span,
        a mass matrix that is not SPD, a penetrating initial state, ...
    SolverError
        Every backend failed on a step; ``exc.trajectory`` holds the run up to it.
    SimulationError
        The state became non-finite, the energy check stopped the run, the mass matrix
        stopped being SPD, a model function returned an array of another shape (named; a
        user callable's output is checked at every call), or a user callable raised;
        ``exc.trajectory`` holds the run up to the last good step.
    KeyboardInterrupt
        Re-raised after Ctrl-C with the part computed so far as ``exc.trajectory``
        (``status == "interrupted"``): nothing computed is lost.
    """
    plan = _plan(scene, t_span, h, tol, record_every, integrator, backend, solver, fallback, drift_control,
                 check_jacobian, penetration_limit, flight_gap, initial_penetration, energy_growth, step_control)
    redundant = redundancy_warnings(scene, q0)
    traj = _run(scene, plan, q0, v0, integrator, drift_control, check_jacobian, progress, energy)
    traj.warnings = redundant + traj.warnings + penetration_warnings(scene, traj, plan.h, plan.penetration_limit,
                                                                         plan.initial_penetration, drift_control)
    return traj


@dataclass
class _Plan:
    """A run's checked arguments and the path it takes."""

    t0: float
    h: float
    tol: float
    n_steps: int
    stride: int
    n_rec: int
    cs: Any
    solver: str | ContactSolver
    fallback: str | ContactSolver | None
    flight_gap: np.ndarray
    penetration_limit: float | None
    initial_penetration: float
    energy_growth: tuple[float, float] | None
    #: (max_iterations, iteration_tol) of an iterating step, checked
    iteration: tuple[int, float] = (1, 0.0)
    #: step-size control's (t_end, atol of each component of (q, v), rtol, h_min), or None for fixed steps
    control: tuple[float, np.ndarray, float, float] | None = None


def _plan(scene: Scene, t_span: tuple[float, float], h: float, tol: float, record_every: int,
          integrator: type[OneStepIntegrator], backend: str, solver: str | ContactSolver | None,
          fallback: str | ContactSolver | None, drift_control: DriftControl | None, check_jacobian: bool,
          penetration_limit: float | None, flight_gap: ArrayLike, initial_penetration: float,
          energy_growth: Any, step_control: StepControl | None = None) -> _Plan:
    """Validate every argument once (``ValueError`` naming the bad one) and choose the path."""
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a Scene, got {scene!r}")
    h, tol = as_positive(h, "step size h"), as_positive(tol, "tol")
    t0, t1, n_steps, stride, n_rec = _steps_and_records(scene, t_span, h, record_every)
    if step_control is None and h > (t1 - t0) * (1.0 + 1e-9):  # one step would end far past t1
        raise ValueError(f"step size h = {h!r} is longer than t_span = ({t0!r}, {t1!r}): the run would end at "
                         f"t = {t0 + h!r}; give h <= {t1 - t0!r}")
    if not (isinstance(integrator, type) and issubclass(integrator, OneStepIntegrator)):
        raise ValueError(f"integrator must be a OneStepIntegrator subclass, got {integrator!r}")
    iteration = _iteration(integrator)  # an iterating step's settings, checked for both paths
    if penetration_limit is not None:
        penetration_limit = as_positive(penetration_limit, "penetration_limit")
    if not isinstance(check_jacobian, bool):
        raise ValueError(f"check_jacobian must be True or False, got {check_jacobian!r}")
    fg = flight_gaps(flight_gap, scene.nrows)
    initial_penetration = as_positive(initial_penetration, "initial_penetration", allow_zero=True)
    control = None
    if step_control is not None:
        if not isinstance(step_control, StepControl):
            raise ValueError(f"step_control must be a StepControl or None, got {step_control!r}")
        control = (t1, step_control.absolute(scene.ndof), step_control.rtol, step_control.smallest(h))
    cs, solver, fallback = choose_backend(backend, scene, integrator, solver, fallback, drift_control)
    return _Plan(t0, h, tol, n_steps, stride, n_rec, cs, solver, fallback, fg, penetration_limit,
                 initial_penetration, as_energy_growth(energy_growth), iteration, control)


def ensure_compiled(*scenes: Scene, integrator: type[OneStepIntegrator] = MoreauJeanMidpoint) -> float:
    """Load the compiled time loop from numba's cache, or compile it there (once per machine
    and version, said in one logged line); returns the seconds it took.

    The loop has three variants (:func:`moreau.compiled.variants.variant`): the plain midpoint
    step's, one with friction, and one with friction, bilateral rows and the later passes of
    :class:`~moreau.MoreauJeanPredictorCorrector` and :class:`~moreau.MoreauJeanEnergyConsistent`;
    a run compiles only the one its scene and ``integrator`` use. With ``scenes``: the
    variants they run; without: all, step-size control's judge of an attempt for each
    (``moreau.compiled.cache.ensure_judged``; else compiled at a variant's first run with
    :class:`~moreau.StepControl`) and the kernels that make OSQP's answers exact
    (``moreau.contact.refine.ensure_loaded``; to warm a cache: ``moreau compile``). Call it before
    starting worker processes: they then load it, never two compiling.
    """
    if not scenes:
        return cache.ensure_compiled(None) + sum(cache.ensure_judged(v) for v in VARIANTS) + ensure_loaded()
    step, iterations = _compiled_step(integrator), _iteration(integrator)[0]
    return sum(cache.ensure_compiled(v)
               for v in sorted({variant(lower(s).ints, step, iterations) for s in scenes}))


def _compiled_step(integrator: type[OneStepIntegrator]) -> int:
    """The compiled loop's code for the step of ``integrator`` (one of the three it has)."""
    if issubclass(integrator, MoreauJeanEnergyConsistent):
        return STEP_ENERGY
    return STEP_THETA if issubclass(integrator, MoreauJeanPredictorCorrector) else STEP_MIDPOINT


def _iteration(integrator: type[OneStepIntegrator]) -> tuple[int, float]:
    """``(max_iterations, iteration_tol)`` of an iterating step (a subclass's own), checked;
    (1, 0) otherwise."""
    if not issubclass(integrator, MoreauJeanEnergyConsistent):
        return 1, 0.0
    its, tol = integrator.max_iterations, integrator.iteration_tol
    if isinstance(its, bool) or not isinstance(its, (int, np.integer)) or its < 1:
        raise ValueError(f"{integrator.__name__}.max_iterations must be an integer >= 1, got {its!r}")
    return int(its), as_positive(tol, f"{integrator.__name__}.iteration_tol")


def _run(scene: Scene, plan: _Plan, q0: ArrayLike, v0: ArrayLike, integrator: type[OneStepIntegrator],
         *rest: Any) -> Trajectory:
    """:func:`_checked_run`, a cold compile's second process started as its checks begin
    (they compile the scene's kernels beside it)."""
    with cache.compiling_ahead(variant(plan.cs.ints, _compiled_step(integrator), plan.iteration[0])):
        return _checked_run(scene, plan, q0, v0, integrator, *rest)


def _checked_run(scene: Scene, plan: _Plan, q0: ArrayLike, v0: ArrayLike, integrator: type[OneStepIntegrator],
                 drift_control: DriftControl | None, check_jacobian: bool,
                 progress: bool | dict[str, Any] | None, energy: bool) -> Trajectory:
    """The run on the compiled loop, from a checked initial state."""
    t0, q, v = checked_start(lambda: check_initial_state(scene, plan.t0, q0, v0, plan.initial_penetration),
                             scene, plan.t0, q0, v0)
    if check_jacobian and (scene.nrows or scene.nconstraints):
        check_jacobians(scene, q)
    if check_jacobian:
        trust.check_bias_force(scene, q)
    step = _compiled_step(integrator)
    # beyond the explicit forces' stability limit (constant M: the energy check cannot see it)
    unstable = (explicit_limit_message(scene, t0, q, v, plan.h) if plan.energy_growth is not None
                and plan.control is None and step == STEP_MIDPOINT else None)
    if unstable:
        warnings.warn(unstable, RuntimeWarning, stacklevel=3)
    rank, redundant = constraint_rank(scene, q)
    if redundant:  # reported, not an error: v stays unique
        log.info("scene %r: %d bilateral rows of rank %d at q0; redundant: %s", scene.name, scene.nconstraints, rank,
                 ", ".join(redundant))
    bar = None
    try:
        # the loop's variant, before the progress bar moves: a compile says so
        cache.ensure_compiled(variant(plan.cs.ints, step, plan.iteration[0]))
        bar = progress_bar(progress, plan.n_steps, scene.name)
        traj = run_compiled(scene, plan.cs, t0, q, v, plan.h, plan.n_steps,
                            step=step, iteration=plan.iteration,
                            solver=plan.solver,
                            fallback=plan.fallback, stride=plan.stride, bar=bar, energy=energy, tol=plan.tol,
                            drift_control=drift_control, flight_gap=plan.flight_gap,
                            gmax0=initial_flight(scene, q, v), energy_growth=plan.energy_growth,
                            control=plan.control)
        traj.warnings = ([unstable] if unstable else []) + traj.warnings
        return traj
    except KeyboardInterrupt as exc:  # before the loop took over: the initial state is the run
        if getattr(exc, "trajectory", None) is None:
            attach_trajectory(exc, initial_state_only(scene, t0, q, v, plan.h, plan.stride, plan.solver,
                                                      plan.fallback))
        raise
    finally:
        if bar is not None:
            bar.close()


def _steps_and_records(scene: Scene, t_span: tuple[float, float], h: float,
                       record_every: int) -> tuple[float, float, int, int, int]:
    """``(t0, t1, steps, record stride, records)`` of a run with a checked step ``h``, refusing a
    step count or a record size beyond the guards."""
    t0, t1 = as_time_span(t_span)
    stride = int(as_record_every(record_every))
    ratio = (t1 - t0) / h
    if not ratio < _MAX_STEPS:
        raise ValueError(f"step size h = {h!r} gives {ratio:.3g} steps over t_span = ({t0!r}, {t1!r}); "
                         f"at most {_MAX_STEPS:.0e} steps are allowed")
    n_steps = max(1, math.ceil(ratio - 1e-9))
    n, m = scene.ndof, scene.nrows
    n_rec = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    record_bytes = n_rec * (8 * (2 + 2 * n + 2 * m) + m)
    if record_bytes > _MAX_RECORD_BYTES:
        raise ValueError(f"recording {n_rec} states (h = {h!r}, record_every = {stride}) needs "
                         f"{record_bytes / 2**30:.1f} GiB; raise record_every")
    return t0, t1, n_steps, stride, n_rec
