"""The Python reference loop of :func:`moreau.simulate`: one
:meth:`~moreau.step.base.OneStepIntegrator.step` call per step, recording every
``stride``-th state and logging impacts."""

from __future__ import annotations

import logging
import time
import warnings
from typing import Any

import numpy as np

from moreau.core.errors import SimulationError, SolverError, attach_trajectory
from moreau.model.scene import Scene
from moreau.model.stability import ENERGY_CHECK_EVERY, energy_growth_message, kept_until
from moreau.results.assemble import assemble
from moreau.results.impacts import ImpactLog, ImpactRow, SolverStats
from moreau.results.trajectory import Trajectory
from moreau.run.progress import progress_bar
from oracle.base import OneStepIntegrator
from oracle.checks import BadModelOutput, NonFiniteState, NotConverged

__all__ = ["run_python"]

log = logging.getLogger("moreau.run.simulation")


def run_python(scene: Scene, integ: OneStepIntegrator, h: float, n_steps: int, stride: int, n_rec: int,
                progress: bool | dict[str, Any] | None, energy: bool, flight_gap: np.ndarray,
               gmax: np.ndarray, energy_growth: tuple[float, float] | None = None) -> Trajectory:
    """The reference loop: one :meth:`OneStepIntegrator.step` call per step, with the
    energy check of :mod:`moreau.model.stability` every ``ENERGY_CHECK_EVERY`` steps."""
    n, m = scene.ndof, scene.nrows
    t0 = integ.t
    T, Q, V = np.empty(n_rec), np.empty((n_rec, n)), np.empty((n_rec, n))
    PS, ACT = np.zeros((n_rec, m)), np.zeros((n_rec, m), dtype=bool)
    friction = scene.has_friction
    PTS = np.zeros((n_rec, m) if friction else (0, m))  # tangential impulses per record
    me, eq = scene.nconstraints, integ._eq
    PES, PE_acc = np.zeros((n_rec, me)), np.zeros(me)  # the bilateral rows' impulses per record
    T[0], Q[0], V[0] = t0, integ.q, integ.v
    rec = 1
    impacts: list[ImpactRow] = []
    P_acc, PT_acc = np.zeros(m), np.zeros(m)
    act_acc, in_contact = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
    has_contacts = m > 0
    gmax = gmax.copy()

    bar = progress_bar(progress, n_steps, scene.name)
    pen, pen_t = np.zeros(m), np.full(m, np.nan)
    chunk = max(1, min(10_000, n_steps // 200))

    status, message = "completed", ""
    error: BaseException | None = None
    check, stepped_back, n_impacts = _EnergyCheck(scene, integ, energy_growth), False, 0
    wall0 = time.perf_counter()
    k = 0
    try:
        step, gaps_at = integ.step, integ.gaps_at
        g_start = gaps_at(integ.q, integ.v) if has_contacts else None  # each step's start gaps (t_cross)
        for k in range(1, n_steps + 1):
            contact = step()
            if eq is not None:
                PE_acc += eq.PE
            if has_contacts:
                if contact:
                    P = integ.P
                    P_acc += P
                    if friction:
                        PT_acc += integ.PT
                    act_acc |= integ.active
                    now = P > 0.0
                    new = now & ~in_contact
                    if new.any():
                        _log_impacts(integ, np.flatnonzero(new), gmax > flight_gap, g_start, impacts)
                    in_contact = now
                elif in_contact.any():
                    in_contact = np.zeros(m, dtype=bool)
                g_end = gaps_at(integ.q, integ.v)
                pen_t[-g_end > pen], pen[:] = integ.t, np.maximum(pen, -g_end)
                gmax = np.where(in_contact, -np.inf, np.maximum(gmax, g_end))
                g_start = g_end
            if k % ENERGY_CHECK_EVERY == 0 or len(impacts) > n_impacts:  # and after a logged impact
                check(k)
                n_impacts = len(impacts)
            if k % stride == 0 or k == n_steps:
                T[rec], Q[rec], V[rec] = integ.t, integ.q, integ.v
                if me:
                    PES[rec] = PE_acc
                    PE_acc[:] = 0.0
                if has_contacts:
                    PS[rec] = P_acc
                    ACT[rec] = act_acc
                    if friction:
                        PTS[rec] = PT_acc
                        PT_acc[:] = 0.0
                    P_acc[:] = 0.0
                    act_acc[:] = False
                rec += 1
            if bar is not None and k % chunk == 0:
                bar.update(chunk)
    except KeyboardInterrupt as exc:
        status, message = "interrupted", f"{str(exc) or 'interrupted by the user'} at step {k} (t = {integ.t:.9g})"
        log.warning("%s; %d records computed so far are attached to the KeyboardInterrupt", message, rec)
        error = exc
    except _EnergyGrew as exc:  # kept up to the last check that passed: the rest ran away
        status, stepped_back = "failed", True
        rec, impacts = _step_back(T, rec, impacts, t0 + check.ok_step * h + 1e-9 * h)
        message = kept_until(str(exc), float(T[rec - 1]))
        error = SimulationError(message, None, k)
    except SolverError as exc:
        status, message, error = "failed", str(exc), exc
    except (NonFiniteState, NotConverged, BadModelOutput) as exc:
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
    if status != "completed" and not stepped_back and T[rec - 1] != integ.t:
        # keep the last good state even when it falls between two records
        T[rec], Q[rec], V[rec] = integ.t, integ.q, integ.v
        PES[rec] = PE_acc
        if has_contacts:
            PS[rec], ACT[rec] = P_acc, act_acc
            if friction:
                PTS[rec] = PT_acc
        rec += 1

    traj = assemble(scene, t=T[:rec], q=Q[:rec], v=V[:rec], impulses=PS[:rec], active=ACT[:rec],
                    onsets=ImpactLog.from_rows(impacts), stats=_stats(integ, wall), h=h, stride=stride,
                    status=status, message=message, work=_work(integ, friction, me), max_penetration=pen,
                    max_penetration_t=pen_t, energy=energy, tangential_impulses=PTS[:rec] if friction else None,
                    constraint_impulses=PES[:rec] if me else None)
    for said in (check.warned, integ.painleve):
        if said is not None:
            traj.warnings.append(said)
            warnings.warn(said, RuntimeWarning, stacklevel=4)
    if error is not None:
        attach_trajectory(error, traj)
        raise error
    return traj


def _stats(integ: OneStepIntegrator, wall: float) -> SolverStats:
    return SolverStats(
        solver=integ.solver.name, fallback=integ.fallback.name if integ.fallback is not None else "",
        steps=integ.k, contact_steps=integ.n_contact_steps, solves=integ.n_solves, fallbacks=integ.n_fallbacks,
        projections=integ.n_projections, worst_residual=integ.worst_residual, wall_time=wall,
        velocity_updates=integ.n_updates,
    )


def _work(integ: OneStepIntegrator, friction: bool, constraints: int) -> dict[str, float]:
    """The energy ledger's terms of the run."""
    return {"forces": integ.work_forces, "contacts": integ.work_contacts,
            **({"friction": integ.work_friction} if friction else {}),
            **({"constraints": integ.work_constraints,
                "constraint_projection": integ.work_constraint_projection} if constraints else {})}


def _log_impacts(integ: OneStepIntegrator, rows: np.ndarray, after_flight: np.ndarray, g_start: np.ndarray,
                 out: list[ImpactRow]) -> None:
    """Log the contact onsets of the last step (``rows``) that are impacts by the flight
    test (``after_flight``, shape (m,)) or the velocity test (see :class:`ImpactLog`).

    Velocity test: ``−U_before > h |a_n|`` with ``h a_n = U_free − U_before``; slower
    onsets are a sliding contact closing again after the midpoint drift opened it for a
    step (on a curved barrier the scheme does that). The crossing time: the start gap
    ``g_start`` closed at the approach speed, within the step.
    """
    d = integ.last_contact_details(rows)
    t_start = integ.t - integ.h
    for j, r in enumerate(rows):
        fast = bool(-d.U_before[j] > abs(d.U_free[j] - d.U_before[j]))
        flight = bool(after_flight[r])
        if fast or flight:
            ub, g0 = float(d.U_before[j]), float(g_start[r])
            cross = t_start + (max(-integ.h, min(integ.h, g0 / -ub)) if ub < 0.0 else 0.0)
            out.append((t_start, integ.k - 1, int(r), ub, float(d.U_after[j]),
                        float(integ.P[r]), float(d.energy_lost[j]), flight, fast, cross))


def _step_back(T: np.ndarray, rec: int, impacts: list[ImpactRow], t_ok: float) -> tuple[int, list[ImpactRow]]:
    """The records and impacts up to ``t_ok`` (the last energy check that passed)."""
    return max(1, int(np.searchsorted(T[:rec], t_ok, side="right"))), [r for r in impacts if r[0] <= t_ok]


class _EnergyGrew(Exception):
    """The energy check's stop bound was passed (the message says by how much)."""


class _EnergyCheck:
    """The energy check (see :mod:`moreau.model.stability`): T(q, v) against T₀ plus the
    integrator's work of forces and contacts, relative to the largest T so far."""

    def __init__(self, scene: Scene, integ: OneStepIntegrator, bounds: tuple[float, float] | None) -> None:
        self.scene, self.integ, self.bounds = scene, integ, bounds
        self.ke0 = self.ke_max = float(scene.kinetic_energy(integ.q, integ.v)) if bounds is not None else 0.0
        integ.track_bias_work = bounds is not None and scene.system.has_bias
        self.warned: str | None = None
        self.level = 0  # the bound the last check found passed: 0 none, 1 warn, 2 stop
        self.ok_step = 0  # the step of the last check below both bounds

    def __call__(self, k: int) -> None:
        if self.bounds is None:
            return
        integ = self.integ
        ke = float(self.scene.kinetic_energy(integ.q, integ.v))
        self.ke_max = max(self.ke_max, ke)
        du = ke - self.ke0 - (integ.work_forces - integ.work_bias)
        warn, stop = self.bounds
        level = 0
        if du > 1e-12 * (1.0 + self.ke_max):
            level = 2 if du > stop * self.ke_max else 1 if du > warn * self.ke_max else 0
        prev, self.level = self.level, level
        if level == 0:
            self.ok_step = k
        # the stop bound counts when two checks in a row find it passed (an impact step's
        # transient warns, but is not a growth)
        if level == 2 and prev == 2:
            raise _EnergyGrew(energy_growth_message(self.scene, integ.t, integ.q, integ.v, du, self.ke_max, integ.h))
        if self.warned is None and level >= 1:
            self.warned = energy_growth_message(self.scene, integ.t, integ.q, integ.v, du, self.ke_max, integ.h)
