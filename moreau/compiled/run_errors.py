"""The loop's status codes as the exceptions of :func:`moreau.simulate`, and the warnings
of a run (energy check, Painlevé's region, step-size control), each naming where and why."""

from __future__ import annotations

import warnings

import numpy as np

from moreau.compiled import layout as lay
from moreau.compiled.lowering import CompiledScene
from moreau.compiled.usercalls import SLOT_WORDS, decode
from moreau.contact.friction import FRICTION_RESIDUALS
from moreau.contact.painleve import painleve_message
from moreau.core.errors import SimulationError, SolverError
from moreau.model.stability import energy_growth_message, not_converged_message, runaway_message
from moreau.results.trajectory import Trajectory


def _name(solver) -> str:
    """A solver's name in results: the name given, or an instance's ``name``; "" for none."""
    return "" if solver is None else solver if isinstance(solver, str) else str(getattr(solver, "name", solver))


def run_warnings(scene, traj: Trajectory, cnt, acc, h, work) -> None:
    """The run's warnings (energy check, Painlevé), once each, also in ``traj.warnings``."""
    if cnt[lay.C_EWARN] > 0:
        _energy_warning(scene, traj, float(acc[lay.A_T_EWARN]), float(acc[lay.A_DU_WARN]),
                        float(acc[lay.A_KEMAX_WARN]), h, work[2].q_warn, work[2].v_warn)
    if cnt[lay.C_PAINLEVE_STEP] > 0:  # one warning, kept in traj.warnings
        k0, row = int(cnt[lay.C_PAINLEVE_STEP]) - 1, int(cnt[lay.C_PAINLEVE_ROW])
        adaptive = cnt[lay.C_ACCEPTED] > 0  # (its loop steps are attempts and halves: no step number)
        msg = painleve_message(float(acc[lay.A_T_PAINLEVE]), None if adaptive else k0, [scene.row_names[row]],
                               [float(scene.friction[row])])
        traj.warnings.append(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=4)
    if cnt[lay.C_FORCED] > 0:
        msg = (f"step-size control: {int(cnt[lay.C_FORCED])} steps were accepted at the smallest step h_min "
               "with a local error above the tolerance: a switch that h_min does not resolve, or a tolerance "
               "below the round-off of the step and its contact solve (lower h_min, or raise tol)")
        traj.warnings.append(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=4)


def run_error(code, scene, k, t, q, v, h, fail, cs, user_status, acc, tol=float("nan"), cnt_row=None, max_iter=0,
           active=None, projected=None, names=("main", "fallback"), errors=("", "")):
    """The exception for the loop's status ``code`` at step ``k`` (time ``t``, state q, v),
    naming what failed, where, and the residuals or the callable involved."""
    where = f"at step {k} (t = {t:.9g})"
    if code == lay.ENERGY_GROWTH and acc[lay.A_RUNAWAY] > 0.0:
        return SimulationError(runaway_message(scene, t, q, v, float(acc[lay.A_RUNAWAY]), h), None, k)
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
    if code == lay.NATIVE_MISMATCH:  # never seen: tests run every variant's projection and friction solve
        return SimulationError(f"internal error {where}: the machine code of a call through its address (the drift "
                               "projection, the friction solve or a chain's warm start) was made for other argument "
                               "types than the loop's call (please report this moreau bug)", None, k)
    if code == lay.NOT_SPD:
        msg = (f"the mass matrix stopped being symmetric positive definite {where}: "
               f"M = {scene.system.mass_matrix(q + 0.5 * h * v).tolist()}")
    elif code == lay.NONFINITE_GAP:
        msg = f"gaps became non-finite {where}"
    else:
        msg = f"state became non-finite {where}: q = {q.tolist()}, v = {v.tolist()}"
    return SimulationError(msg, None, k)


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


def _energy_warning(scene, traj: Trajectory, t: float, du: float, ke_max: float, h: float, q: np.ndarray,
                    v: np.ndarray) -> None:
    """Warn once (``RuntimeWarning``, and in ``traj.warnings``) that the energy check's first
    bound was passed at time ``t``, where the state was ``q, v`` (the step size advice's)."""
    msg = energy_growth_message(scene, t, q, v, du, ke_max, h)
    traj.warnings.append(msg)
    warnings.warn(msg, RuntimeWarning, stacklevel=5)
