"""Driver of the compiled path: lower the scene, run :func:`moreau.loop.run_chunk` chunk
by chunk, and turn its buffers into a :class:`~moreau.result.Trajectory`.

Python is entered only to start, to advance the progress bar between chunks (each
about a quarter of a second of stepping), to honour Ctrl-C there, to grow the impact
buffer, and to finish. Status codes of the loop become the exceptions of
:func:`moreau.simulate`, each carrying the partial trajectory.
"""

from __future__ import annotations

import logging
import time
import warnings

import numpy as np

from . import loop as lp
from .errors import SimulationError, SolverError, attach_trajectory
from .flights import initial_flight
from .lowering import CompiledScene, lower
from .result import ImpactLog, SolverStats, Trajectory

__all__ = ["COMPILED_SOLVERS", "run_compiled"]

log = logging.getLogger(__name__)

#: contact solvers that run inside the compiled loop, by name → LCP method code
COMPILED_SOLVERS = {"exact": 0, "enum": 1}


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
    :func:`moreau.simulate`, which calls this)."""
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
    cnt = np.zeros(8, dtype=np.int64)
    cnt[lp.C_REC] = 1
    acc = np.zeros(3)
    fail = np.zeros((2, 4))
    model = cs.arrays()
    # a scene of built-in kernels runs in the loop compiled without reference counting
    run = lp.run_chunk_builtin if cs.builtin else lp.run_chunk
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
                code = run(model, cs.user, iset, fset, Minv, eligible, q, v,
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
        error = _error(code, scene, k, t_now, q, v, h, fail)
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
    from . import __version__

    traj = Trajectory(
        t=T[:rec], q=Q[:rec], v=V[:rec], gaps=GP[:rec], impulses=PS[:rec], active=ACT[:rec],
        onsets=onsets, stats=stats, h=h, record_every=stride, row_names=list(scene.row_names),
        scene=scene.describe(), energy=(KE[:rec] + PE[:rec]) if energy else None,
        kinetic_energy=KE[:rec] if energy else None, potential_energy=PE[:rec] if energy else None,
        status=status, message=message, version=__version__, max_penetration=pen.copy(),
        work={"forces": float(acc[lp.A_WORK_F]), "contacts": float(acc[lp.A_WORK_C])},
    )
    return traj, error


def _error(code, scene, k, t, q, v, h, fail):
    where = f"at step {k} (t = {t:.9g})"
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
    from . import evaluate as ev

    ints, ekind, eoff, *_ = cs.arrays()
    from .kernels import cos_sin

    return float(scene.potential_energy(q0) - ev.potential(ints, ekind, eoff, cs.pool, q0, *cos_sin(q0)))


def _experimental_warning():
    from numba.core.errors import NumbaExperimentalFeatureWarning

    return NumbaExperimentalFeatureWarning
