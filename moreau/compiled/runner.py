"""Driver of the compiled path: lower the scene, run :func:`moreau.compiled.loop.run_chunk` chunk
by chunk, and turn its buffers into a :class:`~moreau.results.trajectory.Trajectory`.

Python is entered only to start, to advance the progress bar between chunks (each
about a quarter of a second of stepping), to honour Ctrl-C there, to grow the impact
buffer, and to finish. Status codes of the loop become the exceptions of
:func:`moreau.simulate`, each carrying the partial trajectory.
"""

from __future__ import annotations

import logging
import math
import time
import warnings

import numpy as np

from moreau.compiled import adaptive as ad
from moreau.compiled import layout as lay
from moreau.compiled import loop as lp
from moreau.compiled import variants as vs
from moreau.compiled.at_records import slips
from moreau.compiled.callbacks import SolverCallback
from moreau.compiled.drift import projection_address
from moreau.compiled.friction import friction_address
from moreau.compiled.lowering import CompiledScene, lower
from moreau.compiled.run_errors import _name, run_error, run_warnings
from moreau.compiled.step import warm_start_addresses
from moreau.contact.exact import EnumerationSolver, ExactSolver
from moreau.contact.solvers import make_solver
from moreau.core.errors import SimulationError, attach_trajectory
from moreau.model.stability import ENERGY_CHECK_EVERY, kept_until
from moreau.results.assemble import assemble
from moreau.results.impacts import ImpactLog, SolverStats
from moreau.results.trajectory import Trajectory

__all__ = ["COMPILED_SOLVERS", "run_compiled"]

log = logging.getLogger(__name__)

#: contact solvers with a method of the compiled loop's own, by name → LCP method code; any
#: other solver is called back (:class:`moreau.compiled.callbacks.SolverCallback`)
COMPILED_SOLVERS = {"exact": lay.METHOD_EXACT, "enum": lay.METHOD_ENUM}
#: steps of the first chunk (then doubled or halved to about a quarter of a second each)
FIRST_CHUNK = 2000


def _method(spec, n: int, m: int) -> tuple[int, SolverCallback | None]:
    """The loop's method code for a solver name or instance, and its callback if it has one."""
    if spec is None:
        return -1, None
    if isinstance(spec, str) and spec in COMPILED_SOLVERS:
        return COMPILED_SOLVERS[spec], None
    # an instance of the loop's own solvers, as their names make them: the loop's method, not a call back into it
    if type(spec) is ExactSolver or (type(spec) is EnumerationSolver and spec.max_rows == EnumerationSolver().max_rows):
        return COMPILED_SOLVERS[spec.name], None
    return lay.METHOD_EXTERNAL, SolverCallback(make_solver(spec), n, m)


def _settings(scene, t0: float, h: float, n_steps: int, step: int, solver, fallback, stride: int,
              energy: bool, tol: float, drift_control, energy_growth, iteration: tuple[int, float] = (1, 0.0),
              adaptive: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[SolverCallback | None, ...]]:
    """The loop's settings (int and float arrays, see :mod:`moreau.compiled.layout`), the
    rows eligible for drift control and the called-back solvers (kept alive through the run).
    ``step``: the step (``layout.STEP_*``); ``iteration``: the energy-consistent step's
    iterates allowed per step and tolerance; ``adaptive``: step-size control records every
    ``stride`` accepted steps (``S_RECORD``), the steps themselves never."""
    m = scene.nrows
    (method, main), (fb, back) = _method(solver, scene.ndof, m), _method(fallback, scene.ndof, m)
    eligible = np.zeros(m, dtype=np.bool_)
    drift_iter, drift_tol = 1, 0.0
    if drift_control is not None and m:
        eligible = np.ascontiguousarray(drift_control.eligible_rows(scene))
        drift_iter, drift_tol = drift_control.max_iter, drift_control.tol
    drift_mode = lay.DRIFT_NONE
    if drift_control is not None and m > 0 and bool(eligible.any()):
        drift_mode = lay.DRIFT_COMBINED if getattr(drift_control, "impacts_only", False) else lay.DRIFT_POSITION
    memory = int(getattr(drift_control, "memory", 0))
    locate = int(bool(getattr(drift_control, "locate_impacts", False)))
    velocity = int(bool(getattr(drift_control, "velocity", False)))
    echeck = ENERGY_CHECK_EVERY if energy_growth is not None else 0
    steps = (1 << 62, -1) if adaptive else (stride, n_steps)
    iset = np.array([step, drift_mode, drift_iter, *steps, method, fb, int(energy), memory, locate,
                     echeck, iteration[0], main.address if main else 0, back.address if back else 0, stride,
                     0, velocity, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], dtype=np.int64)  # (S_MASS_READY: not yet;
    # S_PROJECT, S_FRICTION, S_WARM, S_DELASSUS, S_JUDGE: run_compiled's)
    assert iset.shape[0] == lay.N_SETTINGS
    warn, stop = energy_growth if energy_growth is not None else (math.inf, math.inf)
    return iset, np.array([h, t0, tol, drift_tol, 0.0, warn, stop, iteration[1]]), eligible, (main, back)


def run_compiled(scene, cs: CompiledScene | None, t0: float, q0: np.ndarray, v0: np.ndarray,
                 h: float, n_steps: int, *, step: int, solver, fallback, stride: int,
                 bar, energy: bool, tol: float, drift_control, flight_gap: np.ndarray,
                 gmax0: np.ndarray, energy_growth: tuple[float, float] | None = None,
                 iteration: tuple[int, float] = (1, 0.0), variant: str | None = None,
                 control: tuple[float, np.ndarray, float, float] | None = None) -> Trajectory:
    """Run ``n_steps`` steps compiled from a validated initial state (see :func:`moreau.simulate`,
    which calls this after :func:`~moreau.compiled.cache.ensure_compiled`); ``gmax0`` is each
    row's initial flight gap (``moreau.run.flights.initial_flight``); ``energy_growth`` the energy
    check's ``(warn, stop)`` (None: no check); ``step``, ``iteration``: see ``_settings``;
    ``variant``: the loop's variant (:data:`moreau.compiled.variants.VARIANTS`; None: the scene's,
    :func:`moreau.compiled.variants.variant`; one without a feature the scene has is refused);
    ``control``: step-size control's ``(t_end, atol, rtol, h_min)``, atol of shape (2 n,)
    (:mod:`moreau.compiled.adaptive`; ``h`` the largest step, ``stride`` in accepted steps), None
    for fixed steps."""
    cs = lower(scene) if cs is None else cs
    n, m = scene.ndof, scene.nrows
    iset, fset, eligible, called = _settings(scene, t0, h, n_steps, step, solver, fallback, stride, energy, tol,
                                             drift_control, energy_growth, iteration, control is not None)
    n_rec = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    me, mf = scene.nconstraints, int(cs.ints[lay.SC_MF])
    needed = vs.variant(cs.ints, step, iteration[0])
    variant = needed if variant is None else variant
    if variant not in vs.VARIANTS or vs.VARIANTS.index(variant) < vs.VARIANTS.index(needed):
        raise ValueError(f"variant={variant!r}: this scene needs the loop's {needed!r} variant or a larger one "
                         f"of {vs.VARIANTS}")
    # with step control n_rec (at steps of H, the largest) is the fewest records: room for 4x, grown if need be
    settings, state, recs, tally, work = _allocate(cs, q0, v0, t0, min(4 * n_rec, 4096) if control else n_rec, iset,
                                                   fset, eligible, flight_gap, me, variant)
    box = [recs]  # the buffers, grown in place of the first when they fill (kept on Ctrl-C too)
    q, v, in_contact, P_acc, act_acc, _, gmax, rs, pen = state
    cnt, acc, fail = tally
    model, user = cs.arrays(), cs.user.addresses
    # the drift projection for these arrays (loaded once a process, or compiled); also without drift
    # control, so that a warm-up (cache._warm_up) loads or compiles it with its variant
    iset[lay.S_PROJECT], iset[lay.S_PROJECT_KEY] = projection_address(model, user, settings, state, recs, tally, work)
    iset[[lay.S_WARM, lay.S_WARM_KEY, lay.S_DELASSUS, lay.S_DELASSUS_KEY]] = warm_start_addresses(model, work)
    fr, eqw = work[3], work[4]  # friction's and the bilateral rows' arrays, None without them
    if fr is not None:  # the friction solve likewise (every run of a variant with friction: its warm-up too)
        iset[lay.S_FRICTION], iset[lay.S_FRICTION_KEY] = friction_address(settings, work)
    ctl, snap = None, None
    if control is not None:
        t_end, atol, rtol, h_min = control
        ctl = np.zeros(lay.N_CONTROL)
        ctl[[lay.K_H, lay.K_T, lay.K_END, lay.K_RTOL, lay.K_HMAX, lay.K_HMIN, lay.K_TOK]] = (
            h, t0, t_end, rtol, h, h_min, t0)
        snap = ad.snapshot(n, m, mf, me)
        snap.atol[:] = atol  # one per component of (q, v)
        iset[lay.S_JUDGE], iset[lay.S_JUDGE_KEY] = ad.judge_address(model, user, settings, state, recs, tally, work,
                                                                    ctl, snap)

    status, message, interrupt = "completed", "", None
    wall0 = time.perf_counter()
    code = lay.DONE
    try:  # from here on a Ctrl-C (or SIGTERM) keeps what exists: the first call of each
        # kernel in a new process loads its machine code, which takes a moment
        if me:
            recs.GP[0, m:] = scene.constraint_gaps(q0)
        if m:
            recs.GP[0, :m] = scene.gaps(q0)
            gmax[:] = gmax0
            rs[:, lay.R_GAP] = recs.GP[0, :m]
        acc[lay.A_KE0] = acc[lay.A_KEMAX] = scene.kinetic_energy(q0, v0)
        if energy:
            recs.KE[0] = acc[lay.A_KE0]
            recs.PE[0] = scene.potential_energy(q0)
        if scene.system.constant_mass:  # the inverse of a constant M, as the reference path uses it for free steps
            settings.Minv[:] = np.linalg.inv(scene.system.mass_matrix(q0))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=_experimental_warning())
            if energy:
                fset[lay.F_PE0] = _potential_offset(scene, cs, q0)
            code = _chunks(cs, called, bar, model, user, settings, state, box, tally, work, n_steps, h, ctl, snap)
    except KeyboardInterrupt as exc:
        k = int(cnt[lay.C_K])
        t_now = t0 + k * h if ctl is None else float(ctl[lay.K_T])
        status, message = "interrupted", f"{str(exc) or 'interrupted by the user'} at step {k} (t = {t_now:.9g})"
        interrupt = exc
    wall = time.perf_counter() - wall0
    recs = box[0]
    while True:  # an interrupt arriving while the result is assembled waits for it
        try:
            traj, error = _assemble(scene, status, message, code, recs.T.shape[0], *recs[:9],
                                    q, v, P_acc, act_acc, pen, cnt, acc, fail, cs, t0, h, stride, solver,
                                    fallback, energy, wall, recs.PTS if mf else None,
                                    None if fr is None else fr.PT_acc,
                                    tol, None if eqw is None else eqw.PE_acc, int(iset[lay.S_ITER]), work[0].active,
                                    work[2].sel,
                                    tuple(c.error if c else "" for c in called), ctl,
                                    None if snap is None else snap.pen_t)
            break
        except KeyboardInterrupt as exc:
            if interrupt is None:
                interrupt, status = exc, "interrupted"
                message = "interrupted by the user while the result was assembled"
    run_warnings(scene, traj, cnt, acc, h, work)
    if interrupt is not None:
        log.warning("%s; %d records computed so far are attached to the KeyboardInterrupt", traj.message, len(traj))
        attach_trajectory(interrupt, traj)
        raise interrupt
    if error is not None:
        attach_trajectory(error, traj)
        raise error
    return traj


def _allocate(cs: CompiledScene, q0: np.ndarray, v0: np.ndarray, t0: float, n_rec: int, iset: np.ndarray,
              fset: np.ndarray, eligible: np.ndarray, flight_gap: np.ndarray, me: int,
              variant: str) -> tuple[lay.Settings, lay.RunState, lay.Records, lay.Tally, tuple]:
    """A run's arrays, as :func:`moreau.compiled.loop.run_chunk` takes them: ``(settings,
    state, records, tally, work)`` (``layout``'s named tuples; ``work`` from
    :func:`~moreau.compiled.variants.loop_workspace`), the state at ``q0, v0``, ``n_rec`` records."""
    n, m, mf = int(cs.ints[lay.SC_N]), int(cs.ints[lay.SC_M]), int(cs.ints[lay.SC_MF])
    records = _records(n_rec, n, m, me, mf, q0, v0, t0)
    # per row: in contact, impulse and activity since the last record, the step of its last impulse, its largest gap
    # since then; CombinedProjection's per-row state (gap at q_k, flags, impact instants); the deepest penetration
    # and the count of steps at its end
    q, v, in_contact = q0.copy(), v0.copy(), np.zeros(m, dtype=np.bool_)
    P_acc, act_acc = np.zeros(m), np.zeros(m, dtype=np.bool_)
    last_imp, gmax = np.full(m, -(1 << 62), dtype=np.int64), np.full(m, -np.inf)
    fgap = np.ascontiguousarray(flight_gap, dtype=float)
    rs = np.zeros((m, lay.N_ROWSTATE))
    state = lay.RunState(q, v, in_contact, P_acc, act_acc, last_imp, gmax, rs, np.zeros((2, m)))
    tally = lay.Tally(np.zeros(lay.N_COUNTERS, dtype=np.int64), np.zeros(lay.N_ACCUMULATORS), np.zeros((2, 6)))
    tally.cnt[lay.C_REC] = 1
    work = vs.loop_workspace(n, m, mf, cs.friction, cs.tangent_row, me, variant)
    return lay.Settings(iset, fset, np.zeros((n, n)), eligible, fgap), state, records, tally, work


def one_row_scene():
    """A unit mass falling onto a floor (one coordinate, one contact row): what warms the
    loop up (:func:`moreau.compiled.cache.ensure_compiled`) and types it (:func:`chunk_example`)."""
    from moreau.model.barriers import LinearBarrier
    from moreau.model.forces import ConstantForce
    from moreau.model.scene import Contact, Scene
    from moreau.model.system import FunctionSystem

    return Scene(FunctionSystem(np.eye(1)), [ConstantForce([-1.0])], [Contact(LinearBarrier([[1.0]], [0.0]), 0.5)])


def chunk_example(variant: str) -> tuple:
    """:func:`moreau.compiled.loop.run_chunk`'s arguments for :func:`one_row_scene` on a
    variant of the loop (:data:`moreau.compiled.variants.VARIANTS`), nothing run: their types are every run's
    (:mod:`moreau.compiled.side_compile` compiles with them)."""
    scene = one_row_scene()
    cs = lower(scene)
    iset, fset, eligible, _ = _settings(scene, 0.0, 1e-3, 1, lay.STEP_MIDPOINT, "exact", None, 1, True, 1e-8, None,
                                        None)
    arrays = _allocate(cs, np.zeros(1), np.zeros(1), 0.0, 2, iset, fset, eligible, np.zeros(1), 0, variant)
    return (cs.arrays(), cs.user.addresses, *arrays, 1)


def _records(n_rec: int, n: int, m: int, me: int, mf: int, q0, v0, t0: float) -> lay.Records:
    """The record buffers of ``n_rec`` records, the first one the initial state."""
    T, Q, V = np.empty(n_rec), np.empty((n_rec, n)), np.empty((n_rec, n))
    # the bilateral rows' impulses and residuals are recorded after the contact rows
    recs = lay.Records(T, Q, V, np.zeros((n_rec, m + me)), np.zeros((n_rec, m), dtype=np.bool_),
                       np.full((n_rec, m + me), np.nan), np.full(n_rec, np.nan), np.full(n_rec, np.nan),
                       np.empty((max(64, 16 * m), lay.N_IMPACT)), np.zeros((n_rec, m) if mf else (1, m)))
    T[0], Q[0], V[0] = t0, q0, v0
    return recs


def _grown(recs: lay.Records, impacts: bool) -> lay.Records:
    """The buffers with twice the room for impacts (``impacts``) or for records, the
    contents kept."""
    if impacts:
        return recs._replace(IMP=np.concatenate([recs.IMP, np.empty_like(recs.IMP)]))
    grown = {f: np.concatenate([a, np.full_like(a, np.nan if a.dtype.kind == "f" else 0)])
             for f, a in recs._asdict().items() if f not in ("IMP",) and not (f == "PTS" and a.shape[0] == 1)}
    return recs._replace(**grown)


def _chunks(cs, called, bar, model, user, settings, state, box, tally, work, n_steps, h, ctl, snap):
    """Call the loop chunk after chunk (each about a quarter of a second) to the end, growing
    the buffers ``box[0]`` when they fill (replaced there at once, so that an interrupt
    keeps the ones in use), advancing the progress bar; returns the last status. With
    step-size control (``ctl``) a chunk counts accepted steps and the bar advances by ``h``
    of time a unit."""
    cnt = tally.cnt
    chunk, code, done = FIRST_CHUNK, lay.DONE, 0
    while cnt[lay.C_K] < n_steps if ctl is None else ctl[lay.K_T] < ctl[lay.K_END]:
        c0 = time.perf_counter()
        recs = box[0]
        k_before = int(cnt[lay.C_K])
        k_end = min(n_steps, k_before + chunk) if ctl is None else int(cnt[lay.C_ACCEPTED]) + chunk  # (accepted)
        code = lp.run_chunk(model, user, settings, state, recs, tally, work, k_end, ctl, snap)
        if ctl is None:
            advanced = int(cnt[lay.C_K]) - k_before
        else:
            advanced = min(n_steps, int((ctl[lay.K_T] - recs.T[0]) / h + 1e-9)) - done
        done += advanced
        if bar is not None:
            bar.update(advanced)
        if (code == lay.USER_FAILED and _interrupted(cs)) or any(c and c.interrupted for c in called):
            raise KeyboardInterrupt  # Ctrl-C inside a Python callback
        if code in (lay.IMPACTS_FULL, lay.RECORDS_FULL):
            box[0] = _grown(recs, code == lay.IMPACTS_FULL)
            continue
        if code != lay.DONE:
            break
        elapsed = time.perf_counter() - c0
        if elapsed < 0.1:
            chunk = min(chunk * 2, 1 << 22)
        elif elapsed > 0.5 and chunk > 100:
            chunk //= 2
    return code


def _assemble(scene, status, message, code, n_rec, T, Q, V, PS, ACT, GP, KE, PE, IMP, q, v, P_acc, act_acc,
              pen, cnt, acc, fail, cs, t0, h, stride, solver, fallback, energy, wall, PTS=None, PT_acc=None,
              tol=float("nan"), PE_acc=None, max_iter=0, active=None, projected=None, errors=("", ""), ctl=None,
              pen_t=None):
    """The Trajectory (and the error to raise, if any) from the loop's buffers (``PTS``:
    the tangential impulses of a scene with friction, else None; ``active``: the rows the
    last step closed; ``projected``: the rows of drift control's last projection)."""
    m = scene.nrows
    me = scene.nconstraints
    error = None
    k = int(cnt[lay.C_K])
    t_now = t0 + k * h if ctl is None else float(ctl[lay.K_T])
    if code != lay.DONE and status == "completed":
        status = "failed"
        error = run_error(code, scene, k, t_now, q, v, h, fail, cs, int(cnt[lay.C_USER]), acc, tol,
                       cnt[lay.C_EQROW:lay.C_EQROW + 1], max_iter, active, projected, (solver, fallback), errors)
        message = str(error)
    rec = int(cnt[lay.C_REC])
    nimp = int(cnt[lay.C_NIMP])
    if code == lay.ENERGY_GROWTH:  # kept up to the last energy check that passed: the rest ran away
        t_ok = t0 + int(cnt[lay.C_EOK]) * h if ctl is None else float(ctl[lay.K_TOK])
        rec = max(1, int(np.searchsorted(T[:rec], t_ok + 1e-9 * h, side="right")))
        nimp = int(np.searchsorted(IMP[:nimp, lay.I_T], t_ok + 1e-9 * h, side="right"))
        message = kept_until(message, float(T[rec - 1]))
        error = SimulationError(message, None, k)
    elif status != "completed" and T[rec - 1] != t_now and rec < n_rec + 1:
        # keep the last good state even when it falls between two records
        T, Q, V, PS, ACT, GP, KE, PE = (np.concatenate([a[:rec], a[:1]]) for a in (T, Q, V, PS, ACT, GP, KE, PE))
        T[rec], Q[rec], V[rec], PS[rec, :m], ACT[rec] = t_now, q, v, P_acc, act_acc
        if PTS is not None:
            PTS = np.concatenate([PTS[:rec], PT_acc[None, :]])
        if m:
            GP[rec, :m] = scene.gaps(q)
        if me:
            PS[rec, m:] = PE_acc[:me]
            GP[rec, m:] = scene.constraint_gaps(q)
        if energy:
            KE[rec], PE[rec] = scene.kinetic_energy(q, v), scene.potential_energy(q)
        rec += 1
    if energy and cs.python_potentials:  # user potentials are Python callables
        PE[:rec] = [scene.potential_energy(Q[i]) for i in range(rec)]
    I = IMP[:nimp]
    onsets = ImpactLog(t=I[:, lay.I_T].copy(), step=I[:, lay.I_STEP].astype(int), row=I[:, lay.I_ROW].astype(int),
                       U_before=I[:, lay.I_UB].copy(), U_after=I[:, lay.I_UA].copy(), impulse=I[:, lay.I_P].copy(),
                       energy_lost=I[:, lay.I_LOST].copy(), flight=I[:, lay.I_FLIGHT] != 0.0,
                       fast=I[:, lay.I_FAST] != 0.0, t_cross=I[:, lay.I_CROSS].copy())
    stats = SolverStats(
        solver=_name(solver), fallback=_name(fallback), steps=k if ctl is None else int(cnt[lay.C_ACCEPTED]),
        contact_steps=int(cnt[lay.C_CONTACT]),
        solves=int(cnt[lay.C_SOLVES]), fallbacks=int(cnt[lay.C_FALLBACKS]),
        projections=int(cnt[lay.C_PROJ]), worst_residual=float(acc[lay.A_WORST]), wall_time=wall,
        backend="compiled", velocity_updates=int(cnt[lay.C_UPDATES]),
        rejected=int(cnt[lay.C_REJECTED]), forced=int(cnt[lay.C_FORCED]),
    )
    traj = assemble(
        scene, t=T[:rec], q=Q[:rec], v=V[:rec], impulses=np.ascontiguousarray(PS[:rec, :m]), active=ACT[:rec],
        onsets=onsets, stats=stats,
        h=h, stride=stride, status=status, message=message, max_penetration=pen[0].copy(),
        max_penetration_t=np.where(pen[0] > 0.0, t0 + pen[1] * h if pen_t is None else pen_t, np.nan), energy=energy,
        work={"forces": float(acc[lay.A_WORK_F]), "contacts": float(acc[lay.A_WORK_C]),
              **({"friction": float(acc[lay.A_WORK_T])} if PTS is not None else {}),
              **({"constraints": float(acc[lay.A_WORK_E]),
                  "constraint_projection": float(acc[lay.A_WORK_EV])} if me else {})},
        gaps=np.ascontiguousarray(GP[:rec, :m]), kinetic=KE[:rec] if energy else None,
        potential=PE[:rec] if energy else None,
        tangential_impulses=PTS[:rec] if PTS is not None else None,
        slip=slips(cs, Q[:rec], V[:rec]) if PTS is not None else None,
        constraint_impulses=np.ascontiguousarray(PS[:rec, m:]) if me else None,
        constraint_residuals=np.ascontiguousarray(GP[:rec, m:]) if me else None,
    )
    return traj, error


def _potential_offset(scene, cs: CompiledScene, q0: np.ndarray) -> float:
    """The constant that makes the compiled potential equal ``scene.potential_energy``."""
    from moreau.compiled import evaluate as ev

    ints, ekind, eoff, *_ = cs.arrays()
    from moreau.core.kernels import cos_sin

    return float(scene.potential_energy(q0) - ev.potential(ints, ekind, eoff, cs.pool, q0, *cos_sin(q0)))


def _interrupted(cs: CompiledScene) -> bool:
    """A Ctrl-C (or SIGTERM) arrived inside one of the scene's Python callbacks (the flag
    is cleared: the scene may run again)."""
    hit = False
    for cb in cs.user.callbacks:
        hit, cb.interrupted = hit or cb.interrupted, False
    return hit


def _experimental_warning():
    from numba.core.errors import NumbaExperimentalFeatureWarning

    return NumbaExperimentalFeatureWarning
