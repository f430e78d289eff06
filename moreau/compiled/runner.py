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

from moreau.compiled import layout as lay
from moreau.compiled import loop as lp
from moreau.compiled.at_records import slips
from moreau.compiled.callbacks import SolverCallback
from moreau.compiled.lowering import CompiledScene, lower
from moreau.compiled.usercalls import SLOT_WORDS, decode
from moreau.contact.friction import FRICTION_RESIDUALS
from moreau.contact.painleve import painleve_message
from moreau.contact.solvers import make_solver
from moreau.core.errors import SimulationError, SolverError, attach_trajectory
from moreau.model.stability import ENERGY_CHECK_EVERY, energy_growth_message, kept_until, not_converged_message
from moreau.results.assemble import assemble
from moreau.results.impacts import ImpactLog, SolverStats
from moreau.results.trajectory import Trajectory

__all__ = ["COMPILED_SOLVERS", "run_compiled"]

log = logging.getLogger(__name__)

#: contact solvers with a method of the compiled loop's own, by name → LCP method code; any
#: other solver is called back (:class:`moreau.compiled.callbacks.SolverCallback`)
COMPILED_SOLVERS = {"exact": lay.METHOD_EXACT, "enum": lay.METHOD_ENUM}


def _method(spec, n: int, m: int) -> tuple[int, SolverCallback | None]:
    """The loop's method code for a solver name or instance, and its callback if it has one."""
    if spec is None:
        return -1, None
    if isinstance(spec, str) and spec in COMPILED_SOLVERS:
        return COMPILED_SOLVERS[spec], None
    return lay.METHOD_EXTERNAL, SolverCallback(make_solver(spec), n, m)


def _settings(scene, t0: float, h: float, n_steps: int, step: int, solver, fallback, stride: int,
              energy: bool, tol: float, drift_control, energy_growth, iteration: tuple[int, float] = (1, 0.0),
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[SolverCallback | None, ...]]:
    """The loop's settings (int and float arrays, see :mod:`moreau.compiled.layout`), the
    rows eligible for drift control and the called-back solvers (kept alive through the run).
    ``step``: the step (``layout.STEP_*``); ``iteration``: the energy-consistent step's
    iterates allowed per step and tolerance."""
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
    echeck = ENERGY_CHECK_EVERY if energy_growth is not None else 0
    iset = np.array([step, drift_mode, drift_iter, stride, n_steps, method, fb, int(energy), memory, locate,
                     echeck, iteration[0], main.address if main else 0, back.address if back else 0],
                    dtype=np.int64)
    warn, stop = energy_growth if energy_growth is not None else (math.inf, math.inf)
    return iset, np.array([h, t0, tol, drift_tol, 0.0, warn, stop, iteration[1]]), eligible, (main, back)


def run_compiled(scene, cs: CompiledScene | None, t0: float, q0: np.ndarray, v0: np.ndarray,
                 h: float, n_steps: int, *, step: int, solver, fallback, stride: int,
                 bar, energy: bool, tol: float, drift_control, flight_gap: np.ndarray,
                 gmax0: np.ndarray, energy_growth: tuple[float, float] | None = None,
                 iteration: tuple[int, float] = (1, 0.0), full: bool | None = None) -> Trajectory:
    """Run ``n_steps`` steps compiled from a validated initial state (see :func:`moreau.simulate`,
    which calls this after :func:`~moreau.compiled.cache.ensure_compiled`); ``gmax0`` is each
    row's initial flight gap (``moreau.run.flights.initial_flight``); ``energy_growth`` the energy
    check's ``(warn, stop)`` (None: no check); ``step``, ``iteration``: see ``_settings``;
    ``full``: the loop's variant (:func:`moreau.compiled.loop.variant`; None: the scene's)."""
    cs = lower(scene) if cs is None else cs
    n, m = scene.ndof, scene.nrows
    iset, fset, eligible, called = _settings(scene, t0, h, n_steps, step, solver, fallback, stride, energy, tol,
                                             drift_control, energy_growth, iteration)
    n_rec = n_steps // stride + 1 + (1 if n_steps % stride else 0)
    T, Q, V = np.empty(n_rec), np.empty((n_rec, n)), np.empty((n_rec, n))
    me = scene.nconstraints
    # the bilateral rows' impulses and residuals are recorded after the contact rows
    PS = np.zeros((n_rec, m + me))
    ACT = np.zeros((n_rec, m), dtype=np.bool_)
    GP = np.full((n_rec, m + me), np.nan)
    KE, PE = np.full(n_rec, np.nan), np.full(n_rec, np.nan)
    T[0], Q[0], V[0] = t0, q0, v0
    q, v = q0.copy(), v0.copy()
    in_contact = np.zeros(m, dtype=np.bool_)
    P_acc, act_acc = np.zeros(m), np.zeros(m, dtype=np.bool_)
    IMP = np.empty((max(64, 16 * m), 9))
    last_imp = np.full(m, -(1 << 62), dtype=np.int64)
    gmax = np.full(m, -np.inf)
    fgap = np.ascontiguousarray(flight_gap, dtype=float)
    rs = np.zeros((m, 6))  # CombinedProjection's per-row state (gap at q_k, flags, impact instants)
    pen = np.zeros((2, m))  # per row: the deepest penetration, the count of steps at its end
    cnt = np.zeros(lay.N_COUNTERS, dtype=np.int64)
    cnt[lay.C_REC] = 1
    acc, fail = np.zeros(lay.N_ACCUMULATORS), np.zeros((2, 6))
    model, user = cs.arrays(), cs.user.addresses
    mf = int(cs.ints[lay.SC_MF])
    full = lp.variant(cs.ints, step, iteration[0]) if full is None else full
    work = lp.loop_workspace(n, m, mf, cs.friction, cs.tangent_row, me, full)
    fr, eqw = work[3], work[4]  # friction's and the bilateral rows' arrays, None without them
    PTS = np.zeros((n_rec, m) if mf else (1, m))

    status, message, interrupt = "completed", "", None
    chunk = 2000
    wall0 = time.perf_counter()
    code = lay.DONE
    try:  # from here on a Ctrl-C (or SIGTERM) keeps what exists: the first call of each
        # kernel in a new process loads its machine code, which takes a moment
        if me:
            GP[0, m:] = scene.constraint_gaps(q0)
        if m:
            GP[0, :m] = scene.gaps(q0)
            gmax[:] = gmax0
            rs[:, lay.R_GAP] = GP[0, :m]
        acc[lay.A_KE0] = acc[lay.A_KEMAX] = scene.kinetic_energy(q0, v0)
        if energy:
            KE[0] = acc[lay.A_KE0]
            PE[0] = scene.potential_energy(q0)
        # the inverse of a constant M, as the reference path uses it for free steps
        Minv = np.linalg.inv(scene.system.mass_matrix(q0)) if scene.system.constant_mass else np.zeros((n, n))
        settings = lay.Settings(iset, fset, Minv, eligible, fgap)
        state = lay.RunState(q, v, in_contact, P_acc, act_acc, last_imp, gmax, rs, pen)
        tally = lay.Tally(cnt, acc, fail)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=_experimental_warning())
            if energy:
                fset[lay.F_PE0] = _potential_offset(scene, cs, q0)
            while cnt[lay.C_K] < n_steps:
                k_before = int(cnt[lay.C_K])
                c0 = time.perf_counter()
                code = lp.run_chunk(model, user, settings, state, lay.Records(T, Q, V, PS, ACT, GP, KE, PE, IMP, PTS),
                           tally, work, min(n_steps, k_before + chunk))
                if bar is not None:
                    bar.update(int(cnt[lay.C_K]) - k_before)
                if (code == lay.USER_FAILED and _interrupted(cs)) or any(c and c.interrupted for c in called):
                    raise KeyboardInterrupt  # Ctrl-C inside a Python callback
                if code == lay.IMPACTS_FULL:
                    IMP = np.concatenate([IMP, np.empty_like(IMP)])
                    continue
                if code != lay.DONE:
                    break
                elapsed = time.perf_counter() - c0
                if elapsed < 0.1:
                    chunk = min(chunk * 2, 1 << 22)
                elif elapsed > 0.5 and chunk > 100:
                    chunk //= 2
    except KeyboardInterrupt as exc:
        k = int(cnt[lay.C_K])
        status, message = "interrupted", f"{str(exc) or 'interrupted by the user'} at step {k} (t = {t0 + k * h:.9g})"
        interrupt = exc
    wall = time.perf_counter() - wall0
    while True:  # an interrupt arriving while the result is assembled waits for it
        try:
            traj, error = _assemble(scene, status, message, code, n_rec, T, Q, V, PS, ACT, GP, KE, PE, IMP,
                                    q, v, P_acc, act_acc, pen, cnt, acc, fail, cs, t0, h, stride, solver,
                                    fallback, energy, wall, PTS if mf else None, None if fr is None else fr.PT_acc,
                                    tol, None if eqw is None else eqw.PE_acc, int(iset[lay.S_ITER]), work[0].active,
                                    work[2].sel,
                                    tuple(c.error if c else "" for c in called))
            break
        except KeyboardInterrupt as exc:
            if interrupt is None:
                interrupt, status = exc, "interrupted"
                message = "interrupted by the user while the result was assembled"
    if cnt[lay.C_EWARN] > 0:
        _energy_warning(scene, traj, int(cnt[lay.C_EWARN]), float(acc[lay.A_DU_WARN]), float(acc[lay.A_KEMAX_WARN]),
                        h, work[2].q_warn, work[2].v_warn)
    if cnt[lay.C_PAINLEVE_STEP] > 0:  # one warning, kept in traj.warnings
        k0, row = int(cnt[lay.C_PAINLEVE_STEP]) - 1, int(cnt[lay.C_PAINLEVE_ROW])
        msg = painleve_message(t0 + k0 * h, k0, [scene.row_names[row]], [float(scene.friction[row])])
        traj.warnings.append(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=3)
    if interrupt is not None:
        log.warning("%s; %d records computed so far are attached to the KeyboardInterrupt", traj.message, len(traj))
        attach_trajectory(interrupt, traj)
        raise interrupt
    if error is not None:
        attach_trajectory(error, traj)
        raise error
    return traj


def _assemble(scene, status, message, code, n_rec, T, Q, V, PS, ACT, GP, KE, PE, IMP, q, v, P_acc, act_acc,
              pen, cnt, acc, fail, cs, t0, h, stride, solver, fallback, energy, wall, PTS=None, PT_acc=None,
              tol=float("nan"), PE_acc=None, max_iter=0, active=None, projected=None, errors=("", "")):
    """The Trajectory (and the error to raise, if any) from the loop's buffers (``PTS``:
    the tangential impulses of a scene with friction, else None; ``active``: the rows the
    last step closed; ``projected``: the rows of drift control's last projection)."""
    m = scene.nrows
    me = scene.nconstraints
    error = None
    k = int(cnt[lay.C_K])
    t_now = t0 + k * h
    if code != lay.DONE and status == "completed":
        status = "failed"
        error = _error(code, scene, k, t_now, q, v, h, fail, cs, int(cnt[lay.C_USER]), acc, tol,
                       cnt[lay.C_EQROW:lay.C_EQROW + 1], max_iter, active, projected, (solver, fallback), errors)
        message = str(error)
    rec = int(cnt[lay.C_REC])
    nimp = int(cnt[lay.C_NIMP])
    if code == lay.ENERGY_GROWTH:  # kept up to the last energy check that passed: the rest ran away
        t_ok = t0 + int(cnt[lay.C_EOK]) * h
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
                       fast=I[:, lay.I_FAST] != 0.0)
    stats = SolverStats(
        solver=_name(solver), fallback=_name(fallback), steps=k, contact_steps=int(cnt[lay.C_CONTACT]),
        solves=int(cnt[lay.C_SOLVES]), fallbacks=int(cnt[lay.C_FALLBACKS]),
        projections=int(cnt[lay.C_PROJ]), worst_residual=float(acc[lay.A_WORST]), wall_time=wall,
        backend="compiled", velocity_updates=int(cnt[lay.C_UPDATES]),
    )
    traj = assemble(
        scene, t=T[:rec], q=Q[:rec], v=V[:rec], impulses=np.ascontiguousarray(PS[:rec, :m]), active=ACT[:rec],
        onsets=onsets, stats=stats,
        h=h, stride=stride, status=status, message=message, max_penetration=pen[0].copy(),
        max_penetration_t=np.where(pen[0] > 0.0, t0 + pen[1] * h, np.nan), energy=energy,
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


def _name(solver) -> str:
    """A solver's name in results: the name given, or an instance's ``name``; "" for none."""
    return "" if solver is None else solver if isinstance(solver, str) else str(getattr(solver, "name", solver))


def _error(code, scene, k, t, q, v, h, fail, cs, user_status, acc, tol=float("nan"), cnt_row=None, max_iter=0,
           active=None, projected=None, names=("main", "fallback"), errors=("", "")):
    where = f"at step {k} (t = {t:.9g})"
    if code == lay.ENERGY_GROWTH:
        return SimulationError(energy_growth_message(scene, t, q, v, float(acc[lay.A_DU]), float(acc[lay.A_KEMAX]), h),
                               None, k)
    if code == lay.NOT_CONVERGED:
        return SimulationError(not_converged_message(scene, t, q, v, h, where, int(max_iter)), None, k)
    if code == lay.USER_FAILED:
        return _user_error(scene, cs, user_status, where, k, t, q, v, h)
    if code in (lay.SOLVER_FAILED, lay.PROJECTION_FAILED):
        # the rows the step closed (also those closed ahead of the barrier: the
        # energy-consistent step, CombinedProjection), else the rows closed at q_m; a
        # projection's own rows ("projection solve failed")
        kind = "contact"
        if code == lay.PROJECTION_FAILED:
            kind, active = "projection", projected
        if active is not None:
            closed = np.flatnonzero(active[:scene.nrows])
        else:
            closed = np.flatnonzero(scene.gaps(q + 0.5 * h * v) <= scene.activation_tol) if scene.nrows \
                else np.zeros(0, dtype=int)
        rows = [scene.row_names[i] for i in closed]
        if cs.ints[lay.SC_MF]:  # friction: Lemke's method and the full law's six residuals, no fallback
            mu = [float(cs.friction[i]) for i in closed]
            residuals = {"lemke": dict(zip(FRICTION_RESIDUALS, fail[0].tolist()))}
            why = ("Lemke's method and the enumeration of contact states found no solution"
                   if not np.isfinite(fail[0]).all() else
                   f"no answer passed the law check (tol = {tol:g}); the best one's residuals")
            return SolverError(f"contact solve with friction failed {where}, active rows {rows}, mu = {mu}: "
                               f"{why}: {residuals}", step=k, t=t, rows=rows, residuals=residuals)
        residuals = {_name(names[i]) or "fallback": errors[i] or dict(zip(("primal", "dual", "complementarity",
                                                                      "stationarity"), fail[i, :4].tolist()))
                     for i in range(2) if i == 0 or names[1]}
        return SolverError(f"{kind} solve failed {where}, active rows {rows}: {residuals}",
                           step=k, t=t, rows=rows, residuals=residuals)
    if code in (lay.CONSTRAINTS_INCONSISTENT, lay.CONSTRAINTS_NOT_HELD):
        row = scene.constraint_names[int(cnt_row[0])] if cnt_row is not None else "?"
        if code == lay.CONSTRAINTS_INCONSISTENT:
            msg = (f"the bilateral constraints are inconsistent {where}: row {row!r} cannot be held together "
                   "with the others")
        else:
            msg = (f"the bilateral constraints could not be held {where}: row {row!r} stayed off g = 0 after the "
                   "projection steps (a singular configuration, or a step too large for the motion)")
        return SolverError(msg, step=k, t=t, rows=[row], residuals={})
    if code == lay.NOT_SPD:
        msg = (f"the mass matrix stopped being symmetric positive definite {where}: "
               f"M = {scene.system.mass_matrix(q + 0.5 * h * v).tolist()}")
    elif code == lay.NONFINITE_GAP:
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


def _user_error(scene, cs: CompiledScene, status: int, where: str, k: int, t: float, q, v, h) -> SimulationError:
    """The error of a user callable that failed in the loop: which one, what it did, when.
    An exception it raised is reproduced at the step's midpoint state and chained."""
    slot, index, what = decode(status)
    callables = cs.user_callables.get(slot, [])
    name, fun = callables[index] if 0 <= index < len(callables) else (f"#{index}", None)
    kind = SLOT_WORDS[slot]
    error = SimulationError(f"user {kind} {name!r} {what} {where}", None, k)
    if not what.startswith("raised") or fun is None:
        return error
    kept = [w.error for w in cs.user.callbacks if w.slot == slot and w.error is not None]
    if kept:  # a Python callback kept what it raised
        exc = kept[0]
        for w in cs.user.callbacks:
            w.error = None
    else:  # compiled: call it again where the step evaluates it (the midpoint, the end, the start)
        exc = None
        for x in (q + 0.5 * h * v, q + h * v, q):
            try:
                fun(*{"forces": (t + 0.5 * h, x, v), "bias": (x, v)}.get(slot, (x,)))
            except Exception as e:  # noqa: BLE001 - the user's own exception, named in the message
                exc = e
                break
    if exc is not None:
        error = SimulationError(f"user {kind} {name!r} raised {type(exc).__name__}: {exc} {where}", None, k)
        error.__cause__ = exc
    return error


def _energy_warning(scene, traj: Trajectory, step: int, du: float, ke_max: float, h: float, q: np.ndarray,
                    v: np.ndarray) -> None:
    """Warn once (``RuntimeWarning``, and in ``traj.warnings``) that the energy check's first
    bound was passed at ``step``, where the state was ``q, v`` (the step size advice's)."""
    msg = energy_growth_message(scene, traj.t[0] + step * h, q, v, du, ke_max, h)
    traj.warnings.append(msg)
    warnings.warn(msg, RuntimeWarning, stacklevel=4)
