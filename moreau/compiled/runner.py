"""Driver of the compiled path: lower the scene, run :func:`moreau.compiled.loop.run_chunk` chunk
by chunk, and turn its buffers into a :class:`~moreau.results.trajectory.Trajectory`.

Python is entered only to start, to advance the progress bar between chunks (each
about a quarter of a second of stepping), to honour Ctrl-C there, to grow the impact
buffer, and to finish. Status codes of the loop become the exceptions of
:func:`moreau.run.simulation`, each carrying the partial trajectory.
"""

from __future__ import annotations

import contextlib
import glob
import logging
import os
import pickle
import signal
import threading
import time
import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np

from moreau.compiled import loop as lp
from moreau.compiled.lowering import CompiledScene, lower
from moreau.compiled.usercalls import decode
from moreau.core.errors import SimulationError, SolverError, attach_trajectory
from moreau.core.jitcache import cache_dir, clear, compile_lock
from moreau.results.trajectory import ImpactLog, SolverStats, Trajectory
from moreau.run.flights import initial_flight

__all__ = ["COMPILED_SOLVERS", "COMPILE_SECONDS", "ensure_compiled", "run_compiled"]

log = logging.getLogger(__name__)

#: contact solvers that run inside the compiled loop, by name → LCP method code
COMPILED_SOLVERS = {"exact": 0, "enum": 1}


#: what the first compile of the loop takes on a 2-core machine (benchmarks/compile_cost.py), s
COMPILE_SECONDS = 30
_ready = threading.Event()
_ready_lock = threading.Lock()


def ensure_compiled() -> float:
    """Load the compiled time loop from numba's cache, or compile it (once per machine
    and version, saying so in one logged line) when it is not there; returns the seconds
    it took (0 when this process has it already).

    Processes started together on an empty cache compile once: the first holds a lock
    in the cache directory (:func:`moreau.core.jitcache.compile_lock`), the others wait and
    then load what it saved. Call it before starting worker processes, or to warm a
    cache (``moreau compile`` does).
    """
    if _ready.is_set():
        return 0.0
    with _ready_lock:
        if _ready.is_set():
            return 0.0
        t = time.perf_counter()
        with compile_lock():
            d = cache_dir()
            cold = d is None or not glob.glob(os.path.join(d, "loop.run_chunk-*.nbi"))
            if cold:
                log.warning("moreau: compiling the time loop once for this machine (about %d s; later runs "
                            "load it from %s)", COMPILE_SECONDS, d or "nowhere: the cache is not writable")
            _ready.set()  # the warm-up run below calls ensure_compiled again
            try:
                try:
                    # loading machine code runs through LLVM callbacks: a Ctrl-C or SIGTERM
                    # raised inside one aborted the process (seen: exit -6), so during a load
                    # (0.3 s) they wait and are acted on right after it
                    with (contextlib.nullcontext() if cold else _signals_deferred()):
                        _warm_up()
                except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError,
                        ImportError, OSError) as exc:  # what an unreadable cache file raises
                    removed = clear()
                    log.warning("moreau: numba's cache in %s could not be read (%s: %s); removed %d files of it "
                                "and compiling the time loop again (about %d s)", d, type(exc).__name__, exc,
                                removed, COMPILE_SECONDS)
                    _warm_up()
            except BaseException:
                _ready.clear()
                raise
        return time.perf_counter() - t


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM are recorded, and handled as before once it ends
    (main thread only; elsewhere nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    old: dict[int, Any] = {}
    for s in (signal.SIGINT, signal.SIGTERM):
        old[int(s)] = signal.signal(s, lambda signum, frame: got.append(signum))
    try:
        yield
    finally:
        for num, handler in old.items():
            signal.signal(num, handler)
        for num in got:
            handler = old[int(num)]
            if callable(handler):
                handler(num, None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), num)


def _warm_up() -> None:
    """Two steps of a one-row scene: loads (or compiles) every compiled function a run calls."""
    from moreau.model.barriers import LinearBarrier
    from moreau.model.forces import ConstantForce
    from moreau.model.scene import Contact, Scene
    from moreau.model.system import FunctionSystem

    scene = Scene(FunctionSystem(np.eye(1)), [ConstantForce([-1.0])],
                  [Contact(LinearBarrier([[1.0]], [0.0]), 0.5)])
    run_compiled(scene, None, 0.0, np.array([1e-3]), np.array([-1.0]), 1e-3, 2, theta=False, solver="exact",
                 fallback=None, stride=1, bar=None, energy=True, tol=1e-8, drift_control=None,
                 flight_gap=np.zeros(1))


def _methods(solver, fallback) -> tuple[int, int]:
    if solver not in COMPILED_SOLVERS:
        raise ValueError(f"solver {solver!r} does not run in compiled code; compiled solvers are "
                         f"{sorted(COMPILED_SOLVERS)} (or use backend='python')")
    if fallback is not None and fallback not in COMPILED_SOLVERS:
        raise ValueError(f"fallback {fallback!r} does not run in compiled code; choose one of "
                         f"{sorted(COMPILED_SOLVERS)} or None")
    if fallback == solver:
        raise ValueError(f"fallback must differ from the main solver, got {solver!r} twice")
    return COMPILED_SOLVERS[solver], (-1 if fallback is None else COMPILED_SOLVERS[fallback])


def run_compiled(scene, cs: CompiledScene | None, t0: float, q0: np.ndarray, v0: np.ndarray,
                 h: float, n_steps: int, *, theta: bool, solver: str, fallback, stride: int,
                 bar, energy: bool, tol: float, drift_control, flight_gap: np.ndarray) -> Trajectory:
    """Run ``n_steps`` steps compiled from a validated initial state (see
    :func:`moreau.run.simulation`, which calls this)."""
    if cs is None:
        cs = lower(scene)
    method, fb = _methods(solver, fallback)
    n, m = scene.ndof, scene.nrows
    eligible = np.zeros(m, dtype=np.bool_)
    drift_iter, drift_tol = 1, 0.0
    if drift_control is not None and m:
        eligible = np.ascontiguousarray(drift_control.eligible_rows(scene))
        drift_iter, drift_tol = drift_control.max_iter, drift_control.tol
    drift_mode = lp.DRIFT_NONE
    if drift_control is not None and m > 0 and bool(eligible.any()):
        drift_mode = lp.DRIFT_COMBINED if getattr(drift_control, "impacts_only", False) else lp.DRIFT_POSITION
    memory = int(getattr(drift_control, "memory", 0))
    locate = int(bool(getattr(drift_control, "locate_impacts", False)))
    n_rec = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    iset = np.array([int(theta), drift_mode, drift_iter, stride, n_steps, method, fb, int(energy), memory, locate],
                    dtype=np.int64)
    fset = np.array([h, t0, tol, drift_tol, 0.0])
    T = np.empty(n_rec)
    Q = np.empty((n_rec, n))
    V = np.empty((n_rec, n))
    PS = np.zeros((n_rec, m))
    ACT = np.zeros((n_rec, m), dtype=np.bool_)
    GP = np.full((n_rec, m), np.nan)
    KE = np.full(n_rec, np.nan)
    PE = np.full(n_rec, np.nan)
    T[0], Q[0], V[0] = t0, q0, v0
    q, v = q0.copy(), v0.copy()
    in_contact = np.zeros(m, dtype=np.bool_)
    P_acc = np.zeros(m)
    act_acc = np.zeros(m, dtype=np.bool_)
    IMP = np.empty((max(64, 16 * m), 9))
    last_imp = np.full(m, -(1 << 62), dtype=np.int64)
    gmax = np.full(m, -np.inf)
    fgap = np.ascontiguousarray(flight_gap, dtype=float)
    rs = np.zeros((m, 6))  # CombinedProjection's per-row state (gap at q_k, flags, impact instants)
    pen = np.zeros(m)
    cnt = np.zeros(lp.N_COUNTERS, dtype=np.int64)
    cnt[lp.C_REC] = 1
    acc = np.zeros(3)
    fail = np.zeros((2, 4))
    model = cs.arrays()
    user = cs.user.addresses
    ensure_compiled()  # before the progress bar moves: a first compile says so
    run = lp.run_chunk
    work = lp.loop_workspace(n, m)

    status, message, interrupt = "completed", "", None
    chunk = 2000
    wall0 = time.perf_counter()
    code = lp.DONE
    try:  # from here on a Ctrl-C (or SIGTERM) keeps what exists: the first call of each
        # kernel in a new process loads its machine code, which takes a moment
        if m:
            GP[0] = scene.gaps(q0)
            gmax[:] = initial_flight(scene, q0, v0)
            rs[:, lp.R_GAP] = GP[0]
        if energy:
            KE[0] = scene.kinetic_energy(q0, v0)
            PE[0] = scene.potential_energy(q0)
        # the inverse of a constant M, as the reference path uses it for free steps
        Minv = np.linalg.inv(scene.system.mass_matrix(q0)) if scene.system.constant_mass else np.zeros((n, n))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=_experimental_warning())
            if energy:
                fset[lp.F_PE0] = _potential_offset(scene, cs, q0)
            while cnt[lp.C_K] < n_steps:
                k_before = int(cnt[lp.C_K])
                c0 = time.perf_counter()
                code = run(model, user, iset, fset, Minv, eligible, q, v,
                           min(n_steps, k_before + chunk), in_contact, P_acc, act_acc,
                           T, Q, V, PS, ACT, GP, KE, PE, IMP, pen, cnt, acc, fail, last_imp, gmax,
                           fgap, rs, work)
                if bar is not None:
                    bar.update(int(cnt[lp.C_K]) - k_before)
                if code == lp.IMPACTS_FULL:
                    IMP = np.concatenate([IMP, np.empty_like(IMP)])
                    continue
                if code != lp.DONE:
                    break
                elapsed = time.perf_counter() - c0
                if elapsed < 0.1:
                    chunk = min(chunk * 2, 1 << 22)
                elif elapsed > 0.5 and chunk > 100:
                    chunk //= 2
    except KeyboardInterrupt as exc:
        k = int(cnt[lp.C_K])
        status, message = "interrupted", f"interrupted by the user at step {k} (t = {t0 + k * h:.9g})"
        interrupt = exc
    wall = time.perf_counter() - wall0
    while True:  # an interrupt arriving while the result is assembled waits for it
        try:
            traj, error = _assemble(scene, status, message, code, n_rec, T, Q, V, PS, ACT, GP, KE, PE, IMP,
                                    q, v, P_acc, act_acc, pen, cnt, acc, fail, cs, t0, h, stride, solver,
                                    fallback, energy, wall)
            break
        except KeyboardInterrupt as exc:
            if interrupt is None:
                interrupt, status = exc, "interrupted"
                message = "interrupted by the user while the result was assembled"
    if interrupt is not None:
        log.warning("%s; %d records computed so far are attached to the KeyboardInterrupt", traj.message, len(traj))
        attach_trajectory(interrupt, traj)
        raise interrupt
    if error is not None:
        attach_trajectory(error, traj)
        raise error
    return traj


def _assemble(scene, status, message, code, n_rec, T, Q, V, PS, ACT, GP, KE, PE, IMP, q, v, P_acc, act_acc,
              pen, cnt, acc, fail, cs, t0, h, stride, solver, fallback, energy, wall):
    """The Trajectory (and the error to raise, if any) from the loop's buffers."""
    m = scene.nrows
    error = None
    k = int(cnt[lp.C_K])
    t_now = t0 + k * h
    if code != lp.DONE and status == "completed":
        status = "failed"
        error = _error(code, scene, k, t_now, q, v, h, fail, cs, int(cnt[lp.C_USER]))
        message = str(error)
    rec = int(cnt[lp.C_REC])
    if status != "completed" and T[rec - 1] != t_now and rec < n_rec + 1:
        # keep the last good state even when it falls between two records
        T, Q, V, PS, ACT, GP, KE, PE = (np.concatenate([a[:rec], a[:1]]) for a in (T, Q, V, PS, ACT, GP, KE, PE))
        T[rec], Q[rec], V[rec], PS[rec], ACT[rec] = t_now, q, v, P_acc, act_acc
        if m:
            GP[rec] = scene.gaps(q)
        if energy:
            KE[rec], PE[rec] = scene.kinetic_energy(q, v), scene.potential_energy(q)
        rec += 1
    if energy and any(e.has_potential and isinstance(e.kernel(), tuple) and e.kernel()[0] == "user"
                      for e in scene.effects):  # user potentials are Python callables
        PE[:rec] = [scene.potential_energy(Q[i]) for i in range(rec)]
    nimp = int(cnt[lp.C_NIMP])
    I = IMP[:nimp]
    onsets = ImpactLog(t=I[:, lp.I_T].copy(), step=I[:, lp.I_STEP].astype(int), row=I[:, lp.I_ROW].astype(int),
                       U_before=I[:, lp.I_UB].copy(), U_after=I[:, lp.I_UA].copy(), impulse=I[:, lp.I_P].copy(),
                       energy_lost=I[:, lp.I_LOST].copy(), flight=I[:, lp.I_FLIGHT] != 0.0,
                       fast=I[:, lp.I_FAST] != 0.0)
    stats = SolverStats(
        solver=solver, fallback=fallback or "", steps=k, contact_steps=int(cnt[lp.C_CONTACT]),
        solves=int(cnt[lp.C_SOLVES]), fallbacks=int(cnt[lp.C_FALLBACKS]),
        projections=int(cnt[lp.C_PROJ]), worst_residual=float(acc[lp.A_WORST]), wall_time=wall,
        backend="compiled",
    )
    from moreau.core.version import __version__

    traj = Trajectory(
        t=T[:rec], q=Q[:rec], v=V[:rec], gaps=GP[:rec], impulses=PS[:rec], active=ACT[:rec],
        onsets=onsets, stats=stats, h=h, record_every=stride, row_names=list(scene.row_names),
        scene=scene.describe(), energy=(KE[:rec] + PE[:rec]) if energy else None,
        kinetic_energy=KE[:rec] if energy else None, potential_energy=PE[:rec] if energy else None,
        status=status, message=message, version=__version__, max_penetration=pen.copy(),
        work={"forces": float(acc[lp.A_WORK_F]), "contacts": float(acc[lp.A_WORK_C])},
    )
    return traj, error


def _error(code, scene, k, t, q, v, h, fail, cs, user_status):
    where = f"at step {k} (t = {t:.9g})"
    if code == lp.USER_FAILED:
        return _user_error(scene, cs, user_status, where, k, t, q, v, h)
    if code == lp.SOLVER_FAILED:
        qm = q + 0.5 * h * v
        g = scene.gaps(qm) if scene.nrows else np.zeros(0)
        rows = [scene.row_names[i] for i in np.flatnonzero(g <= scene.activation_tol)]
        names = ["main", "fallback"]
        residuals = {names[i]: dict(zip(("primal", "dual", "complementarity", "stationarity"),
                                        fail[i].tolist())) for i in range(2)}
        return SolverError(f"contact solve failed {where}, active rows {rows}: {residuals}",
                           step=k, t=t, rows=rows, residuals=residuals)
    if code == lp.NOT_SPD:
        msg = (f"the mass matrix stopped being symmetric positive definite {where}: "
               f"M = {scene.system.mass_matrix(q + 0.5 * h * v).tolist()}")
    elif code == lp.NONFINITE_GAP:
        msg = f"gaps became non-finite {where}"
    else:
        msg = f"state became non-finite {where}: q = {q.tolist()}, v = {v.tolist()}"
    return SimulationError(msg, None, k)


def _potential_offset(scene, cs: CompiledScene, q0: np.ndarray) -> float:
    """The constant that makes the compiled potential equal ``scene.potential_energy``."""
    from moreau.compiled import evaluate as ev

    ints, ekind, eoff, *_ = cs.arrays()
    from moreau.core.kernels import cos_sin

    return float(scene.potential_energy(q0) - ev.potential(ints, ekind, eoff, cs.pool, q0, *cos_sin(q0)))


def _experimental_warning():
    from numba.core.errors import NumbaExperimentalFeatureWarning

    return NumbaExperimentalFeatureWarning


def _user_error(scene, cs: CompiledScene, status: int, where: str, k: int, t: float, q, v, h) -> SimulationError:
    """The error of a user callable that failed in the loop: which one, what it did, when.
    An exception it raised is reproduced at the step's midpoint state and chained."""
    slot, index, what = decode(status)
    callables = cs.user_callables.get(slot, [])
    name, fun = callables[index] if 0 <= index < len(callables) else (f"#{index}", None)
    kind = {"mass": "mass matrix", "bias": "bias", "forces": "force", "gaps": "gap function",
            "jacobians": "Jacobian"}[slot]
    error = SimulationError(f"user {kind} {name!r} {what} {where}", None, k)
    if what.startswith("raised") and fun is not None:
        qm = q + 0.5 * h * v  # where the step evaluates it
        args = {"forces": (t + 0.5 * h, qm, v), "bias": (qm, v)}.get(slot, (qm,))
        try:
            fun(*args)
        except Exception as exc:  # noqa: BLE001 - the user's own exception, named in the message
            error = SimulationError(f"user {kind} {name!r} raised {type(exc).__name__}: {exc} {where}", None, k)
            error.__cause__ = exc
    return error
