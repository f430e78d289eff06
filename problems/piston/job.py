"""The main job: simulate the paper's piston cases, discard the transient, write figures,
a summary table and the trajectories. Used by ``moreau piston``.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass

import numpy as np

import moreau as mo

from .analysis import cycle_figures, max_penetration_ratio, steady_speed_rpm
from .model import piston_model
from .params import PistonParameters

__all__ = ["PAPER_CASES", "Case", "run_case", "run_cases"]

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
        Contact solver backend.
    drift_control : bool
        Project positions back onto the cylinder after each step
        (:class:`moreau.PositionProjection`); without it the midpoint drift leaves the
        piston ≈ 10 % of the clearance inside the wall at h = 1e-4.
    """

    e: float
    D: float
    h: float = 1e-4
    cycles: int = 3
    transient: int = 1
    solver: str = "enum"
    drift_control: bool = True

    @property
    def label(self) -> str:
        return f"e{self.e:g}_D{1e3 * self.D:.2f}mm"


PAPER_CASES = ((0.0, 0.08004), (0.9, 0.08004), (0.9, 0.0802))


def run_case(case: Case, out: str, progress: bool | dict = False) -> dict:
    """Run one case; save its trajectory and figure into ``out``; return its summary row.

    A run that fails or is interrupted saves what it computed (``*.partial.npz``) and its
    row says so in ``status``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .figures import plot_cycle

    params = PistonParameters(e=case.e, D=case.D)
    model = piston_model(params)
    stem = os.path.join(out, f"piston_{case.label}")
    record_every = max(1, int(round(2e-3 / case.h)))  # ~0.1° of crank angle per record
    wall0 = time.perf_counter()
    try:
        traj = model.simulate(case.transient + case.cycles, case.h, solver=case.solver,
                              record_every=record_every, progress=progress, energy=False,
                              drift_control=mo.PositionProjection() if case.drift_control else None)
    except (mo.SolverError, mo.SimulationError) as exc:
        traj = exc.trajectory
        log.error("case %s failed: %s", case.label, exc)
    wall = time.perf_counter() - wall0
    traj.extra.update({"case": asdict(case), "params": asdict(params)})
    traj.save(stem + (".npz" if traj.completed else ".partial.npz"))

    figs = [c for c in cycle_figures(traj, params) if c.cycle >= case.transient]
    row = {
        "e": case.e,
        "D_mm": round(1e3 * case.D, 4),
        "h": case.h,
        "status": traj.status,
        "cycles": len(figs),
        "rpm": steady_speed_rpm(traj, params, skip_cycles=case.transient) if figs else float("nan"),
        "side_changes_per_cycle": " ".join(str(c.side_changes) for c in figs),
        "side_change_angles_deg": " ".join(f"{a:.0f}" for a in figs[-1].change_angles_deg) if figs else "",
        "impacts_per_cycle": float(np.mean([c.impacts for c in figs])) if figs else float("nan"),
        "max_penetration_over_clearance": max_penetration_ratio(traj, params),
        "energy_lost_per_cycle_J": float(np.mean([c.energy_lost for c in figs])) if figs else float("nan"),
        "max_slap_impulse_Ns": max((c.max_impulse for c in figs), default=float("nan")),
        "drift_control": case.drift_control,
        "fallbacks": traj.stats.fallbacks,
        "wall_time_s": round(wall, 2),
        "us_per_step": round(traj.stats.us_per_step, 1),
    }
    if figs:
        last = figs[-1]
        fig = plot_cycle(traj, params, last.cycle,
                         title=f"e = {case.e:g}, D = {1e3 * case.D:.2f} mm: cycle {last.cycle}, "
                               f"{last.side_changes} side changes, {last.impacts} impacts")
        fig.savefig(stem + ".png", dpi=110)
        plt.close(fig)
    return row


def run_cases(cases: Sequence[Case], out: str, progress: bool = True, workers: int | None = None) -> list[dict]:
    """Run cases in parallel processes (one per core by default); rows in input order."""
    os.makedirs(out, exist_ok=True)
    workers = workers or min(len(cases), os.cpu_count() or 1)
    jobs = [(c, out, {"position": i, "desc": c.label} if progress else False) for i, c in enumerate(cases)]
    if workers == 1 or len(cases) == 1:
        return [run_case(*j) for j in jobs]
    rows: list = [None] * len(jobs)
    queue = list(enumerate(jobs))
    with ProcessPoolExecutor(max_workers=workers) as pool:
        running: dict = {}
        try:
            # submit a case only when a worker is free, so that an interrupt leaves no case
            # queued in the pool (its queue would start it after the interrupt)
            while queue or running:
                while queue and len(running) < workers:
                    i, job = queue.pop(0)
                    running[pool.submit(run_case, *job)] = i
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for f in done:
                    rows[running.pop(f)] = f.result()
        except KeyboardInterrupt:
            # the running cases got the interrupt too and save what they computed
            for f, i in running.items():
                try:
                    rows[i] = f.result()
                except Exception as exc:  # noqa: BLE001 - reported, the others kept
                    log.warning("case %s: %s", jobs[i][0].label, exc)
            log.warning("interrupted: %d of %d cases returned a (partial) result",
                        sum(r is not None for r in rows), len(cases))
    return [r for r in rows if r is not None]
