"""The front door: :func:`simulate` runs a scene over a time span and returns a Trajectory."""

from __future__ import annotations

import logging
import math
import sys
import time
from typing import Any, Protocol, cast

import numpy as np
from numpy.typing import ArrayLike

from moreau.contact.solvers import ContactSolver
from moreau.core.errors import SimulationError, SolverError, attach_trajectory
from moreau.core.validation import as_positive, as_record_every, as_time_span, checked_start
from moreau.model.scene import Scene
from moreau.results.trajectory import ImpactLog, ImpactRow, SolverStats, Trajectory
from moreau.run.flights import flight_gaps, initial_flight
from moreau.run.trust import check_jacobians, penetration_warnings
from moreau.step.integrator import (
    BadModelOutput,
    MoreauJeanMidpoint,
    MoreauJeanPredictorCorrector,
    NonFiniteState,
    OneStepIntegrator,
    check_initial_state,
)

__all__ = ["simulate"]

log = logging.getLogger(__name__)

_PROGRESS_MIN_STEPS = 20_000
_MAX_STEPS = 1e11  # a guard against a mistyped h, far beyond any run that finishes
_MAX_RECORD_BYTES = 8 * 2**30



class DriftControl(Protocol):
    """What ``simulate(..., drift_control=...)`` accepts (:class:`moreau.PositionProjection`)."""

    def project(self, integ: Any, q: np.ndarray) -> np.ndarray:
        """The corrected end position q⁺ of the integrator's last step."""
        ...


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
    initial_penetration: float = 1e-12,
) -> Trajectory:
    """Integrate a scene with a fixed step from ``t_span[0]`` to ``t_span[1]``.

    Parameters
    ----------
    scene : Scene
        System, effects and contacts.
    t_span : (float, float)
        Start and end time; ``t1 > t0``. The run takes ``N = ceil((t1 - t0)/h)`` steps
        (to within 1e-9 h) and ends at ``t0 + N h``.
    q0, v0 : array_like, shape (n,)
        Initial coordinates and velocities. A state that penetrates a barrier is
        refused (``ValueError``); an approaching velocity on a closed contact is
        resolved by the first step's impact.
    h : float
        Step size (> 0).
    backend : {"auto", "compiled", "python"}
        Where the time loop runs. ``"compiled"``: the whole loop in machine code
        (numba; :mod:`moreau.compiled.loop`), for scenes whose every part has a compiled kernel
        (all built-in systems, effects and barriers, and user callables decorated with
        ``@numba.njit``), the integrators :class:`MoreauJeanMidpoint` and
        :class:`MoreauJeanPredictorCorrector`, drift control :class:`CombinedProjection` and
        :class:`PositionProjection`, and the
        compiled solvers ``"exact"`` and ``"enum"``; it raises ``ValueError`` naming
        what does not compile. ``"python"``: the readable reference path, with any
        solver. ``"auto"`` (default): compiled when everything compiles, else Python
        (logged). Both paths evaluate the same kernels and return the same fields;
        ``traj.stats.backend`` says which ran.
    solver : str or ContactSolver, optional
        Contact solver: ``"exact"`` (dual active set, exact, any number of rows; the
        default of the compiled path), ``"enum"`` (enumeration, ≤ 12 rows), ``"osqp"``
        (the default of the Python path), ``"daqp"``, ``"quadprog"``.
    fallback : str or ContactSolver or None
        Exact solver for steps the main one fails; ``"auto"``: ``"enum"``, or
        ``"exact"`` when the main solver is ``"enum"``. Never the same as ``solver``.
    integrator : OneStepIntegrator subclass
        The time-stepper (default :class:`MoreauJeanMidpoint`).
    record_every : int
        Record every k-th step (and the last). Impulses are summed and activity is
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
        Compare every barrier's Jacobian with finite differences of its gap at q0 and
        refuse a mismatch (``ValueError`` naming the row); default True.
    initial_penetration : float
        An initial state with a gap below ``-initial_penetration`` (gap units) is refused
        (default 1e-12). A run that continues from the state another run ended in may
        start inside a barrier: the midpoint scheme ends an impact step with a penetration
        of up to about (1 − e)|U|h/2, and a drift-controlled run leaves round-off-level
        penetrations; pass that run's penetration limit here to continue it.
    penetration_limit : float, optional
        Largest acceptable penetration (gap units). Default: ``h·|U⁻|`` per row, the
        distance its impacts travel in one step. A run beyond it warns
        (``RuntimeWarning``) and says so in ``traj.warnings``.
    flight_gap : float or array_like, shape (m,)
        The flight gap of each row (gap units, >= 0; default 0): a contact onset is an
        *impact* (``traj.impacts``) when, since the row last carried an impulse, its gap
        exceeded this at the end of some step. Set it to a small fraction of the
        problem's length scale to count only bounces that lift the contact visibly (the
        bundled piston uses 2 % of the clearance); with 0 every bounce the step
        resolves counts. See :class:`moreau.ImpactLog`.

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
        The state became non-finite, the mass matrix stopped being SPD, a model function
        (mass matrix, force, gap, Jacobian) returned an array of another shape (the
        message names it, with the expected and the received shape; checked at every
        call on the Python path, at the initial state on the compiled one), or a user
        callable raised; ``exc.trajectory`` holds the run up to the last good step.
    KeyboardInterrupt
        Re-raised after Ctrl-C with the part computed so far as ``exc.trajectory``
        (``status == "interrupted"``): nothing computed is lost, and a script that
        loops over runs stops.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a Scene, got {scene!r}")
    t0, t1 = as_time_span(t_span)
    h = as_positive(h, "step size h")
    tol = as_positive(tol, "tol")
    record_every = as_record_every(record_every)
    if not (isinstance(integrator, type) and issubclass(integrator, OneStepIntegrator)):
        raise ValueError(f"integrator must be a OneStepIntegrator subclass, got {integrator!r}")

    ratio = (t1 - t0) / h
    if not ratio < _MAX_STEPS:
        raise ValueError(f"step size h = {h!r} gives {ratio:.3g} steps over t_span = ({t0!r}, {t1!r}); "
                         f"at most {_MAX_STEPS:.0e} steps are allowed")
    n_steps = max(1, math.ceil(ratio - 1e-9))
    n, m = scene.ndof, scene.nrows
    stride = int(record_every)
    n_rec = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    record_bytes = n_rec * (8 * (2 + 2 * n + 2 * m) + m)
    if record_bytes > _MAX_RECORD_BYTES:
        raise ValueError(f"recording {n_rec} states (h = {h!r}, record_every = {stride}) needs "
                         f"{record_bytes / 2**30:.1f} GiB; raise record_every")
    if penetration_limit is not None:
        penetration_limit = as_positive(penetration_limit, "penetration_limit")
    if not isinstance(check_jacobian, bool):
        raise ValueError(f"check_jacobian must be True or False, got {check_jacobian!r}")
    flight_gap = flight_gaps(flight_gap, m)
    initial_penetration = as_positive(initial_penetration, "initial_penetration", allow_zero=True)
    path, cs, solver, fallback = _choose_backend(backend, scene, integrator, solver, fallback, drift_control)
    if path == "compiled":
        from moreau.compiled.runner import run_compiled

        t0, q0, v0 = checked_start(lambda: check_initial_state(scene, t0, q0, v0, initial_penetration),
                                   scene, t0, q0, v0)
        if check_jacobian and m:
            check_jacobians(scene, q0)
        bar = None
        try:
            bar = _progress_bar(progress, n_steps, scene.name)
            traj = run_compiled(scene, cs, t0, q0, v0, h, n_steps, theta=integrator is MoreauJeanPredictorCorrector,
                                solver=cast(str, solver), fallback=fallback, stride=stride, bar=bar, energy=energy,
                                tol=tol, drift_control=drift_control, flight_gap=flight_gap)
        except KeyboardInterrupt as exc:  # before the loop took over: the initial state is the run
            if getattr(exc, "trajectory", None) is None:
                attach_trajectory(exc, _initial_state_only(scene, t0, q0, v0, h, stride, solver, fallback))
            raise
        finally:
            if bar is not None:
                bar.close()
    else:
        # penetration_tol only when set: an integrator subclass of the user's may not take it
        tol_kw = {} if initial_penetration == 1e-12 else {"penetration_tol": initial_penetration}
        integ = integrator(scene, h, solver=solver, fallback=fallback, tol=tol, drift_control=drift_control, **tol_kw)
        checked_start(lambda: integ.init(t0, q0, v0), scene, t0, q0, v0)
        if check_jacobian and m:
            check_jacobians(scene, integ.q)
        traj = _run_python(scene, integ, h, n_steps, stride, n_rec, progress, energy, flight_gap)
    traj.warnings = penetration_warnings(scene, traj, h, penetration_limit)
    return traj


def _initial_state_only(scene: Scene, t0: float, q0: np.ndarray, v0: np.ndarray, h: float, stride: int,
                        solver: str | ContactSolver | None, fallback: str | ContactSolver | None) -> Trajectory:
    """The trajectory of a run interrupted before its first step: the initial state."""
    from moreau.core.version import __version__

    m = scene.nrows
    return Trajectory(
        t=np.array([t0]), q=q0[None, :].copy(), v=v0[None, :].copy(),
        gaps=np.full((1, m), np.nan), impulses=np.zeros((1, m)), active=np.zeros((1, m), dtype=bool),
        onsets=ImpactLog(), stats=SolverStats(solver=str(solver), fallback=str(fallback or ""), backend="compiled"),
        h=h, record_every=stride, row_names=list(scene.row_names), scene=scene.describe(),
        status="interrupted", message=f"interrupted by the user at step 0 (t = {t0:.9g})", version=__version__,
        max_penetration=np.zeros(m),
    )


def _choose_backend(backend: str, scene: Scene, integrator: type[OneStepIntegrator],
                    solver: str | ContactSolver | None, fallback: str | ContactSolver | None,
                    drift_control: DriftControl | None,
                    ) -> tuple[str, Any, str | ContactSolver, str | ContactSolver | None]:
    """``(path, compiled scene or None, solver, fallback)`` for :func:`simulate`."""
    from moreau.compiled.lowering import NotCompilable, lower
    from moreau.compiled.runner import COMPILED_SOLVERS
    from moreau.contact.solvers import ContactSolver
    from moreau.step.drift import CombinedProjection, PositionProjection

    if backend not in ("auto", "compiled", "python"):
        raise ValueError(f"backend must be 'auto', 'compiled' or 'python', got {backend!r}")
    for what, x in (("solver", solver), ("fallback", fallback)):
        if x is not None and not isinstance(x, (str, ContactSolver)):
            raise ValueError(f"{what} must be a name or a ContactSolver, got {x!r}")
    reason = ""
    if backend != "python":
        if integrator not in (MoreauJeanMidpoint, MoreauJeanPredictorCorrector):
            reason = f"integrator {integrator.__name__} has no compiled form"
        elif drift_control is not None and type(drift_control) not in (PositionProjection, CombinedProjection):
            reason = f"drift control {type(drift_control).__name__} has no compiled form"
        elif solver is not None and solver not in COMPILED_SOLVERS:
            reason = f"solver {solver!r} does not run in compiled code (compiled: {sorted(COMPILED_SOLVERS)})"
        elif fallback not in ("auto", None) and fallback not in COMPILED_SOLVERS:
            reason = f"fallback {fallback!r} does not run in compiled code (compiled: {sorted(COMPILED_SOLVERS)})"
        else:
            try:
                cs = lower(scene)
            except NotCompilable as exc:
                reason = str(exc)
    if backend == "compiled" and reason:
        raise ValueError(f"backend='compiled': {reason}")
    path = "python" if (backend == "python" or reason) else "compiled"
    if backend == "auto" and reason:
        log.info("running %r on the Python path: %s", scene.name, reason)
    if solver is None:
        solver = "exact" if path == "compiled" else "osqp"
    if fallback == "auto":
        fallback = "exact" if solver == "enum" else "enum"
    if isinstance(solver, str) and solver == fallback:
        raise ValueError(f"fallback must differ from the main solver, got {solver!r} twice")
    return path, (cs if path == "compiled" else None), solver, fallback


def _progress_bar(progress: bool | dict[str, Any] | None, n_steps: int, desc: str) -> Any:
    show = bool(progress) if progress is not None else (n_steps >= _PROGRESS_MIN_STEPS and sys.stderr.isatty())
    if not show:
        return None
    from tqdm.auto import tqdm

    bar_kw: dict[str, Any] = {"unit": "step", "desc": desc, "mininterval": 0.5, "leave": False}
    if isinstance(progress, dict):
        bar_kw.update(progress)
    return tqdm(total=n_steps, **bar_kw)


def _run_python(scene: Scene, integ: OneStepIntegrator, h: float, n_steps: int, stride: int, n_rec: int,
                progress: bool | dict[str, Any] | None, energy: bool, flight_gap: np.ndarray) -> Trajectory:
    """The reference loop: one :meth:`OneStepIntegrator.step` call per step."""
    n, m = scene.ndof, scene.nrows
    t0 = integ.t
    T = np.empty(n_rec)
    Q = np.empty((n_rec, n))
    V = np.empty((n_rec, n))
    PS = np.zeros((n_rec, m))
    ACT = np.zeros((n_rec, m), dtype=bool)
    T[0], Q[0], V[0] = t0, integ.q, integ.v
    rec = 1
    impacts: list[ImpactRow] = []
    P_acc = np.zeros(m)
    act_acc = np.zeros(m, dtype=bool)
    in_contact = np.zeros(m, dtype=bool)
    has_contacts = m > 0
    gmax = initial_flight(scene, integ.q, integ.v)

    bar = _progress_bar(progress, n_steps, scene.name)
    pen = np.zeros(m)
    chunk = max(1, min(10_000, n_steps // 200))

    status, message = "completed", ""
    error: BaseException | None = None
    wall0 = time.perf_counter()
    k = 0
    try:
        step, gaps_at = integ.step, integ.gaps_at
        for k in range(1, n_steps + 1):
            contact = step()
            if has_contacts:
                if contact:
                    P = integ.P
                    P_acc += P
                    act_acc |= integ.active
                    now = P > 0.0
                    new = now & ~in_contact
                    if new.any():
                        _log_impacts(integ, np.flatnonzero(new), gmax > flight_gap, impacts)
                    in_contact = now
                elif in_contact.any():
                    in_contact = np.zeros(m, dtype=bool)
                g_end = gaps_at(integ.q, integ.v)
                np.maximum(pen, -g_end, out=pen)
                gmax = np.where(in_contact, -np.inf, np.maximum(gmax, g_end))
            if k % stride == 0 or k == n_steps:
                T[rec], Q[rec], V[rec] = integ.t, integ.q, integ.v
                if has_contacts:
                    PS[rec] = P_acc
                    ACT[rec] = act_acc
                    P_acc[:] = 0.0
                    act_acc[:] = False
                rec += 1
            if bar is not None and k % chunk == 0:
                bar.update(chunk)
    except KeyboardInterrupt as exc:
        status, message = "interrupted", f"interrupted by the user at step {k} (t = {integ.t:.9g})"
        log.warning("%s; %d records computed so far are attached to the KeyboardInterrupt", message, rec)
        error = exc
    except SolverError as exc:
        status, message, error = "failed", str(exc), exc
    except (NonFiniteState, BadModelOutput) as exc:
        status, message = "failed", str(exc)
        error = SimulationError(message, None, exc.step)
        error.__cause__ = exc
    except Exception as exc:  # a user callable raised inside the step
        status = "failed"
        message = f"step {k - 1} (t = {integ.t:.9g}) raised {type(exc).__name__}: {exc}"
        error = SimulationError(message, None, k - 1)
        error.__cause__ = exc
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - wall0
    if status != "completed" and T[rec - 1] != integ.t:
        # keep the last good state even when it falls between two records
        T[rec], Q[rec], V[rec] = integ.t, integ.q, integ.v
        if has_contacts:
            PS[rec], ACT[rec] = P_acc, act_acc
        rec += 1

    traj = _assemble(scene, integ, h, stride, T[:rec], Q[:rec], V[:rec], PS[:rec], ACT[:rec],
                     impacts, wall, status, message, energy)
    traj.max_penetration = pen
    if error is not None:
        attach_trajectory(error, traj)
        raise error
    return traj


def _log_impacts(integ: OneStepIntegrator, rows: np.ndarray, after_flight: np.ndarray,
                 out: list[ImpactRow]) -> None:
    """Log the contact onsets of the last step (``rows``) that are impacts by the flight
    test (``after_flight``, shape (m,)) or the velocity test (see :class:`ImpactLog`).

    Velocity test: ``−U_before > h |a_n|`` with ``h a_n = U_free − U_before``; slower
    onsets are a sliding contact closing again after the midpoint drift opened it for a
    step (on a curved barrier the scheme does that).
    """
    d = integ.last_contact_details(rows)
    t_start = integ.t - integ.h
    for j, r in enumerate(rows):
        fast = bool(-d.U_before[j] > abs(d.U_free[j] - d.U_before[j]))
        flight = bool(after_flight[r])
        if fast or flight:
            out.append((t_start, integ.k - 1, int(r), float(d.U_before[j]), float(d.U_after[j]),
                        float(integ.P[r]), float(d.energy_lost[j]), flight, fast))


def _assemble(scene: Scene, integ: OneStepIntegrator, h: float, stride: int, T: np.ndarray, Q: np.ndarray,
              V: np.ndarray, PS: np.ndarray, ACT: np.ndarray, impacts: list[ImpactRow], wall: float, status: str,
              message: str, energy: bool) -> Trajectory:
    from moreau.core.version import __version__

    m = scene.nrows
    N = T.shape[0]
    gaps = np.full((N, m), np.nan)
    KE = PE = E = None
    # post-processing of what was computed: a user callable failing here must not lose
    # the trajectory (it may be why the run stopped), so failures leave NaN and a warning
    try:
        gaps_of = scene.gaps if scene.gaps is not None else _no_gaps
        for i in range(N if m else 0):
            gaps[i] = gaps_of(Q[i])
        if energy and N:
            KE = np.array([scene.kinetic_energy(Q[i], V[i]) for i in range(N)])
            PE = np.array([scene.potential_energy(Q[i]) for i in range(N)])
            E = KE + PE
    except Exception as exc:  # noqa: BLE001 - reported, and the data kept
        log.warning("could not evaluate gaps/energy on the recorded states: %s", exc)
    stats = SolverStats(
        solver=integ.solver.name,
        fallback=integ.fallback.name if integ.fallback is not None else "",
        steps=integ.k,
        contact_steps=integ.n_contact_steps,
        solves=integ.n_solves,
        fallbacks=integ.n_fallbacks,
        projections=integ.n_projections,
        worst_residual=integ.worst_residual,
        wall_time=wall,
    )
    return Trajectory(
        t=T, q=Q, v=V, gaps=gaps, impulses=PS, active=ACT,
        onsets=ImpactLog.from_rows(impacts), stats=stats, h=h, record_every=stride,
        row_names=list(scene.row_names), scene=scene.describe(), energy=E,
        kinetic_energy=KE, potential_energy=PE, status=status, message=message,
        version=__version__, work={"forces": integ.work_forces, "contacts": integ.work_contacts},
    )


def _no_gaps(q: np.ndarray) -> np.ndarray:
    """The gaps of a scene without contacts (none)."""
    return np.zeros(0)
