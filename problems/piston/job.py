"""The main job: simulate the paper's piston cases, discard the transient, write figures,
a summary table and the trajectories. Used by ``moreau piston``.

Speeds in the summary (rev/min): ``mean_speed_rpm`` is the mean crank speed over the
analysed cycles (:func:`~moreau.problems.piston.analysis.mean_speed_rpm`; the runs start
at 2000 rpm and keep about that speed for thousands of cycles), ``settled_speed_rpm`` the
energy-balance estimate of the speed the engine settles at, from the same cycles
(:func:`~moreau.problems.piston.analysis.settled_speed_rpm`).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

import moreau as mo
from moreau.cli.common import save_figure
from moreau.sweeps.pool import interrupt_for_signal, run_jobs

from .analysis import cycle_figures, max_penetration_ratio, mean_speed_rpm, settled_speed_rpm
from .model import PistonModel, piston_model
from .params import PistonParameters

__all__ = ["PAPER_CASES", "STATUSES", "Case", "run_case", "run_cases", "summary_row", "case_files"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Case:
    """One run of the engine.

    Attributes
    ----------
    e : float
        Restitution at the corners.
    D : float
        Cylinder diameter (m).
    h : float
        Step size in non-dimensional time τ = ω t.
    cycles : int
        Engine cycles analyzed after the transient.
    transient : int
        Engine cycles simulated first and discarded.
    solver : str
        Contact solver (``"exact"``: compiled dual active set).
    backend : str
        Where the loop runs: ``"auto"``, ``"compiled"`` or ``"python"`` (see
        :func:`moreau.simulate`).
    drift_control : bool
        Drift control (:meth:`~moreau.problems.piston.model.PistonModel.drift_control`, a
        :class:`moreau.CombinedProjection`): positions projected back onto the cylinder
        after each step for every e, restitution only at impacts;
        without it the midpoint drift leaves the piston ≈ 10 % of the clearance inside
        the wall at h = 1e-4 (e = 0).
    record_every : int, optional
        Keep every k-th step (default: about one record per 0.1° of crank angle).
    mu : float
        Skirt friction at the cylinder wall (0: the paper's frictionless model).
    """

    e: float
    D: float
    h: float = 1e-4
    cycles: int = 3
    transient: int = 1
    solver: str = "exact"
    backend: str = "auto"
    drift_control: bool = True
    record_every: int | None = None
    mu: float = 0.0

    @property
    def label(self) -> str:
        return f"e{self.e:g}_D{1e3 * self.D:.2f}mm" + (f"_mu{self.mu:g}" if self.mu else "")


PAPER_CASES = ((0.0, 0.08004), (0.9, 0.08004), (0.9, 0.0802))


STATUSES = ("completed", "failed", "interrupted", "not started")


def case_files(case: Case, out: str) -> list[str]:
    """Every file a run of ``case`` may write into ``out`` (trajectory, partial trajectory,
    figure)."""
    stem = os.path.join(out, f"piston_{case.label}")
    return [stem + ".npz", stem + ".partial.npz", stem + ".png"]


def run_case(case: Case, out: str, progress: bool | dict = False) -> dict:
    """Run one case; save its trajectory and figure into ``out``; return its summary row.

    A run that fails or is interrupted (Ctrl-C, SIGTERM) saves what it computed
    (``*.partial.npz``) and its row says so in ``status``; an interrupt is not re-raised
    here (the caller stops starting cases). Both ways an interrupt may arrive are handled:
    a returned trajectory with ``status == "interrupted"``, or a ``KeyboardInterrupt``
    carrying it as ``exc.trajectory`` (which may be None).
    """
    params = PistonParameters(e=case.e, D=case.D, mu=case.mu)
    stem = os.path.join(out, f"piston_{case.label}")
    record_every = case.record_every or max(1, int(round(2e-3 / case.h)))  # ~0.1° of crank angle per record
    wall0 = time.perf_counter()
    traj, status, model = None, None, None
    try:
        model = piston_model(params)
        traj = model.simulate(case.transient + case.cycles, case.h, solver=case.solver, backend=case.backend,
                              record_every=record_every, progress=progress, energy=False,
                              drift_control=model.drift_control() if case.drift_control else None)
    except (mo.SolverError, mo.SimulationError) as exc:
        traj = exc.trajectory
        log.error("case %s failed: %s", case.label, exc)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM (moreau.sweeps.pool.Terminated)
        traj, status = getattr(exc, "trajectory", None), "interrupted"
        log.warning("case %s interrupted", case.label)
    wall = time.perf_counter() - wall0
    if traj is None:
        return summary_row(case, status or "failed", wall=wall)
    traj.extra.update({"case": asdict(case), "params": asdict(params)})
    # the row is computed in memory first: a file that cannot be written (a full disk)
    # costs that file, never the numbers, and the row names the file and the reason
    row, figs = _figures_row(case, params, traj, status or traj.status, wall, model)
    unsaved = []
    path = stem + (".npz" if traj.completed else ".partial.npz")
    try:
        traj.save(path)
        if traj.completed and os.path.exists(stem + ".partial.npz"):  # an earlier, stopped run of the case
            os.remove(stem + ".partial.npz")
    except OSError as exc:
        unsaved.append(f"{path} not saved: {exc.strerror or exc}")
    if figs:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from .figures import plot_cycle

        last = figs[-1]
        fig = plot_cycle(traj, params, last.cycle,
                         title=f"e = {case.e:g}, D = {1e3 * case.D:.2f} mm"
                               + (f", mu = {case.mu:g}" if case.mu else "") + f": cycle {last.cycle}, "
                               f"{last.side_changes} side changes, {last.impacts} impacts"
                               + (f", friction {last.friction_loss:.3g} J" if case.mu else ""))
        try:
            save_figure(fig, stem + ".png")
        except OSError as exc:
            unsaved.append(f"{stem}.png not saved: {exc.strerror or exc}")
        plt.close(fig)
    if unsaved:
        log.error("case %s: %s", case.label, "; ".join(unsaved))
        row["warnings"] = "; ".join(filter(None, [row["warnings"], *unsaved]))
    return row


def summary_row(case: Case, status: str, wall: float = float("nan")) -> dict:
    """The summary row of a case without a trajectory (not started, or stopped before its
    first step): its parameters and status, NaN figures."""
    nan = float("nan")
    return {
        "e": case.e, "D_mm": round(1e3 * case.D, 4), "mu": case.mu, "h": case.h, "status": status, "cycles": 0,
        "mean_speed_rpm": nan, "settled_speed_rpm": nan,
        "side_changes_per_cycle": "", "side_change_angles_deg": "", "impacts_per_cycle": nan,
        "max_penetration_over_clearance": nan, "energy_lost_per_cycle_J": nan, "friction_loss_per_cycle_J": nan,
        "max_slap_impulse_Ns": nan,
        "drift_control": case.drift_control, "fallbacks": 0, "wall_time_s": round(wall, 2), "us_per_step": nan,
        "warnings": "",
    }


def _figures_row(case: Case, params: PistonParameters, traj: mo.Trajectory, status: str, wall: float,
                 model: PistonModel | None = None):
    figs = [c for c in cycle_figures(traj, params) if c.cycle >= case.transient]
    nan = float("nan")
    row = {
        "e": case.e,
        "D_mm": round(1e3 * case.D, 4),
        "mu": case.mu,
        "h": case.h,
        "status": status,
        "cycles": len(figs),
        # the speed the run had over the analysed cycles (it starts at params.rpm), and the
        # energy-balance estimate of the speed the engine settles at (analysis.settled_speed_rpm)
        "mean_speed_rpm": mean_speed_rpm(traj, params, skip_cycles=case.transient) if figs else nan,
        "settled_speed_rpm": settled_speed_rpm(traj, params, case.transient, model) if figs else nan,
        "side_changes_per_cycle": " ".join(str(c.side_changes) for c in figs),
        "side_change_angles_deg": " ".join(f"{a:.0f}" for a in figs[-1].change_angles_deg) if figs else "",
        "impacts_per_cycle": float(np.mean([c.impacts for c in figs])) if figs else float("nan"),
        "max_penetration_over_clearance": max_penetration_ratio(traj, params),
        "energy_lost_per_cycle_J": float(np.mean([c.energy_lost for c in figs])) if figs else float("nan"),
        "friction_loss_per_cycle_J": float(np.mean([c.friction_loss for c in figs])) if figs else float("nan"),
        "max_slap_impulse_Ns": max((c.max_impulse for c in figs), default=float("nan")),
        "drift_control": case.drift_control,
        "fallbacks": traj.stats.fallbacks,
        "wall_time_s": round(wall, 2),
        "us_per_step": round(traj.stats.us_per_step, 1),
        "warnings": "; ".join(traj.warnings),
    }
    return row, figs


def clear_case_files(cases: Sequence[Case], out: str) -> list[str]:
    """Remove the files an earlier run left for these cases in ``out`` (and its
    ``summary.csv``), so that nothing old looks like a result of this run; returns what
    was removed."""
    removed = []
    for path in [p for c in cases for p in case_files(c, out)] + [os.path.join(out, "summary.csv")]:
        try:
            os.remove(path)
            removed.append(path)
        except FileNotFoundError:
            pass
    if removed:
        log.warning("removed %d file(s) of an earlier run from %s", len(removed), out)
    return removed


def run_cases(cases: Sequence[Case], out: str, progress: bool = True, workers: int | None = None,
              report: Callable[[str], None] | None = None) -> list[dict]:
    """Run cases, in parallel processes (one per core by default); one row per case, in
    input order, whatever happens. ``progress``: a bar per case (a terminal's); ``report``:
    called with one line as each case ends (where no terminal shows the bars).

    The files an earlier run left for these cases in ``out`` are removed first. On Ctrl-C
    or SIGTERM no further case starts, the running ones save what they computed, and the
    ``KeyboardInterrupt`` (``moreau.sweeps.pool.Terminated`` after SIGTERM) is re-raised
    with the rows of every case as ``exc.rows`` (status ``"interrupted"`` or
    ``"not started"`` for those that did not complete).
    """
    os.makedirs(out, exist_ok=True)
    clear_case_files(cases, out)
    workers = workers or min(len(cases), os.cpu_count() or 1)
    jobs = [(c, out, {"position": i, "desc": c.label} if progress else False) for i, c in enumerate(cases)]
    rows: list = [None] * len(jobs)

    def on_done(i: int, row: dict | None, exc: BaseException | None) -> None:
        if exc is not None:
            status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
            log.warning("case %s %s: %s: %s", cases[i].label, status, type(exc).__name__, exc)
            row = summary_row(cases[i], status)
            if status == "failed":  # the reason, in one line
                row["warnings"] = f"{type(exc).__name__}: {exc}".replace("\n", " ")
        rows[i] = row
        if report is not None and row is not None:
            report(f"case {cases[i].label}: {row['status']} (simulated in {row['wall_time_s']} s; "
                   f"{sum(r is not None for r in rows)} of {len(cases)} cases done)")

    try:
        if workers == 1 or len(cases) == 1:
            for i, job in enumerate(jobs):
                try:
                    on_done(i, run_case(*job), None)
                except KeyboardInterrupt:  # after the simulation: the row is lost, the files are not
                    rows[i] = summary_row(cases[i], "interrupted")
                    raise
                if rows[i]["status"] == "interrupted":  # the interrupt stopped this run: stop here
                    raise interrupt_for_signal()
        else:
            # once, here, the loop's variants the cases run: the workers load them (never two compiling)
            mo.ensure_compiled(*(piston_model(PistonParameters(mu=mu)).scene for mu in {c.mu for c in cases}))
            run_jobs(run_case, jobs, workers, on_done)
    except KeyboardInterrupt as exc:
        exc.rows = [r if r is not None else summary_row(c, "not started") for r, c in zip(rows, cases)]
        log.warning("interrupted: %d of %d cases returned a (partial) result",
                    sum(r is not None for r in rows), len(cases))
        raise
    return rows
