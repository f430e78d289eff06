"""Work–precision study, part 2: the problems and their references.

Each :class:`Problem` runs a configuration at a step size and measures its errors
against an independent reference (analytic, event-driven, DOP853, or a run at a much
smaller step); ``benchmarks/work_precision.py`` describes each problem.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from wp_configs import Config, Run, _timed

import moreau as mo
from moreau.problems.event_driven import moreau_impact_times as impact_times


class Problem:
    """A study problem: a ladder of steps, the configurations to run, a reference.

    Subclasses set ``name``, ``primary`` (the metric plotted) and ``metrics`` (all error
    names, in table order) and implement :meth:`run`.
    """

    name = "problem"
    primary = "error"
    metrics: tuple = ()

    def __init__(self, ladder: Sequence[float], config_list: Sequence[Config]) -> None:
        self.ladder = [float(h) for h in ladder]
        self.configs = list(config_list)

    def prepare(self) -> None:
        """Compute the reference (called once before the runs)."""

    def run(self, config: Config, h: float) -> Run:
        raise NotImplementedError

    def _run(self, config, h, traj, wall, status, metrics) -> Run:
        return Run(self.name, config, h, wall, int(traj.stats.steps), int(traj.stats.fallbacks), status,
                   float(metrics.get(self.primary, np.nan)) if status == "completed" else float("nan"),
                   metrics)


class BallProblem(Problem):
    """Bouncing ball against :class:`~moreau.problems.bouncing_ball.BallSolution`."""

    name = "ball"
    primary = "impact_time"
    metrics = ("impact_time", "apex", "zeno_time", "position")

    def __init__(self, ladder, config_list, e=0.8, h0=1.0, t_end=4.5, n_impacts=6):
        super().__init__(ladder, config_list)
        from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

        self.e, self.h0, self.t_end, self.K = e, h0, t_end, n_impacts
        self.exact = BallSolution(h0, e)
        self.scene = bouncing_ball(e)

    def run(self, config, h):
        hs, kw = config.run_args(h)
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, self.t_end), [self.h0], [0.0], hs, energy=False, **kw), repeat_below=0.5)
        m = {}
        if status == "completed":
            sol, K = self.exact, self.K
            ti = impact_times(traj)
            t_ref = np.array([sol.impact_time(k) for k in range(1, K + 1)])
            if ti.size >= K:
                m["impact_time"] = float(np.abs(ti[:K] - t_ref).max())
                y, t = traj.q[:, 0], traj.t
                apex = np.array([y[(t > ti[k]) & (t < ti[k + 1])].max() for k in range(K - 1)])
                m["apex"] = float(np.abs(apex - [sol.apex_height(k) for k in range(1, K)]).max())
            else:
                m["impact_time"] = m["apex"] = float("inf")
            # the discrete ball stops bouncing when its impacts fall below h g (the impact
            # log's threshold): its last logged impact estimates the Zeno time
            m["zeno_time"] = float(abs(ti[-1] - sol.zeno_time)) if ti.size else float("inf")
            m["position"] = float(np.abs(traj.q[:, 0] - sol.position(traj.t)).max())
            m["impacts"] = len(traj.impacts)
        return self._run(config, h, traj, wall, status, m)


class PendulumWallProblem(Problem):
    """Damped pendulum hitting a wall against the event-driven reference."""

    name = "pendulum"
    primary = "impact_time"
    metrics = ("impact_time", "impact_time_max", "theta")

    def __init__(self, ladder, config_list, e=0.9, wall_x=0.5, damping=0.05, omega0=4.0, t_end=12.0):
        super().__init__(ladder, config_list)
        from moreau.problems.pendulum_wall import pendulum_wall

        self.e, self.wall_x, self.damping, self.omega0, self.t_end = e, wall_x, damping, omega0, t_end
        self.scene = pendulum_wall(e=e, wall_x=wall_x, damping=damping)
        self.ref = None

    def prepare(self):
        from moreau.problems.event_driven import pendulum_wall_reference

        if self.ref is None:
            self.ref = pendulum_wall_reference(self.e, self.wall_x, self.t_end + 1.0, 0.0, self.omega0,
                                               self.damping)
            self.ref_impacts = self.ref.impact_times[self.ref.impact_times <= self.t_end]

    def run(self, config, h):
        self.prepare()
        hs, kw = config.run_args(h)
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, self.t_end), [0.0], [self.omega0], hs, energy=False, **kw), repeat_below=0.5)
        m = {}
        if status == "completed":
            ti = impact_times(traj)
            ref = self.ref_impacts
            if ti.size == ref.size:
                d = np.abs(ti - ref)
                m["impact_time"], m["impact_time_max"] = float(d.mean()), float(d.max())
            else:
                m["impact_time"] = m["impact_time_max"] = float("inf")
            Q, _ = self.ref.state(traj.t)
            m["theta"] = float(np.abs(traj.q[:, 0] - Q[:, 0]).max())
            m["impacts"] = int(ti.size)
        return self._run(config, h, traj, wall, status, m)


class SmoothPendulumProblem(Problem):
    """Damped pendulum without a wall against DOP853: smooth-phase order."""

    name = "pendulum-smooth"
    primary = "state"
    metrics = ("state",)

    def __init__(self, ladder, config_list, damping=0.5, t_end=2.0, y0=(1.0, 0.5)):
        super().__init__(ladder, config_list)
        from scipy.integrate import solve_ivp

        from moreau.problems.pendulum_wall import pendulum_rhs, pendulum_wall

        self.scene = pendulum_wall(wall_x=None, damping=damping)
        self.t_end, self.y0 = t_end, y0
        ref = solve_ivp(pendulum_rhs(damping=damping), (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13)
        self.y_end = ref.y[:, -1]

    def run(self, config, h):
        hs, kw = config.run_args(h, h_max=0.1)
        t_end = self.t_end if config.adaptive else round(self.t_end / h) * h
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, t_end), [self.y0[0]], [self.y0[1]], hs, energy=False, **kw), repeat_below=0.5)
        m = {}
        if status == "completed" and abs(t_end - self.t_end) < 1e-12:
            m["state"] = float(max(abs(traj.q[-1, 0] - self.y_end[0]), abs(traj.v[-1, 0] - self.y_end[1])))
        return self._run(config, h, traj, wall, status, m)


def _angle_distance(a: Sequence[float], b: Sequence[float], period: float = 720.0) -> float:
    """Largest distance (deg, on the circle of one cycle) from an angle of one set to the
    nearest angle of the other (Hausdorff distance); inf when one set is empty."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.size == 0 and b.size == 0:
        return 0.0
    if a.size == 0 or b.size == 0:
        return float("inf")
    d = np.abs(a[:, None] - b[None, :]) % period
    d = np.minimum(d, period - d)
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


class PistonProblem(Problem):
    """The engine against a run at a much smaller step: structural figures of the last
    complete cycle of ``cycles`` simulated from the standard start."""

    primary = "angles"
    metrics = ("angles", "rpm", "impacts", "penetration")

    def __init__(self, ladder, config_list, e=0.0, cycles=2, h_ref=3e-5, record_dt=5e-4,
                 ref_config: Config | None = None):
        super().__init__(ladder, config_list)
        if ref_config is None:
            # e = 0: drift control removes the O(h) penetration from the reference. e > 0:
            # not, because PositionProjection (positions moved, velocities kept) sustains
            # a chatter of O(h g) bounces on a pressed contact with e > 0 (14 600 "impacts"
            # in a cycle of the e = 0.9 piston at h = 3e-5, against ~500 without it); the
            # penetration it would remove is ~0.1 % of the clearance at h = 3e-5.
            ref_config = Config("mid", "enum", e == 0.0)
        from moreau.problems.piston.model import piston_model
        from moreau.problems.piston.params import PistonParameters

        self.e, self.cycles, self.h_ref, self.record_dt = e, cycles, h_ref, record_dt
        self.name = f"piston-e{e:g}"
        self.params = PistonParameters(e=e)
        self.model = piston_model(self.params)
        self.ref_config = ref_config
        self.ref = None
        self._cache: dict = {}

    def simulate(self, config: Config, h: float):
        """(figures of the last cycle, wall time, status, solver stats) of one run; runs
        are cached by (config, h) so that the comparisons reuse the sweep's runs."""
        key = (config, float(h))
        if key not in self._cache:
            rec = 1 if config.adaptive else max(1, int(round(self.record_dt / h)))
            # adaptive: the largest step; without drift control the one the clearance allows
            hs, kw = config.run_args(h, h_max=1e-3 if config.drift == "none" else 1e-2, ndof=self.model.scene.ndof)
            traj, wall, status = _timed(lambda: self.model.simulate(
                self.cycles, hs, record_every=rec, energy=False, **kw), repeat_below=0.5)
            f = self.figures(traj) if status == "completed" else {}
            self._cache[key] = (f, wall, status, traj.stats, traj.message)
        return self._cache[key]

    def figures(self, traj) -> dict:
        """Figures of the last complete cycle: side-change angles, mean speed, impacts,
        penetration (fraction of the clearance), side changes."""
        from moreau.problems.piston.analysis import cycle_figures

        figs = cycle_figures(traj, self.params)
        if not figs:
            return {}
        last = figs[-1]
        return {"cycle": last.cycle, "angles": last.change_angles_deg, "rpm": last.mean_rpm,
                "impacts": last.impacts, "penetration": last.max_penetration,
                "side_changes": last.side_changes}

    def prepare(self):
        if self.ref is None:
            f, wall, status, _, message = self.simulate(self.ref_config, self.h_ref)
            if status != "completed" or not f:
                raise RuntimeError(f"{self.name}: the reference run failed: {message}")
            self.ref = f
            self.ref_wall = wall

    def run(self, config, h):
        self.prepare()
        f, wall, status, stats, _ = self.simulate(config, h)
        m = {}
        if f and f["cycle"] == self.ref["cycle"]:
            r = self.ref
            m = {
                "angles": _angle_distance(f["angles"], r["angles"]),
                "rpm": abs(f["rpm"] - r["rpm"]),
                "impacts": abs(f["impacts"] - r["impacts"]),
                "penetration": abs(f["penetration"] - r["penetration"]),
                "side_changes_run": f["side_changes"],
                "impacts_run": f["impacts"],
                "penetration_run": f["penetration"],
                "projections": int(stats.projections),
            }
        elif status == "completed":
            status = "no complete cycle"
        return Run(self.name, config, h, wall, int(stats.steps), int(stats.fallbacks), status,
                   float(m.get(self.primary, np.nan)) if status == "completed" else float("nan"), m)


class ChainWallsProblem(Problem):
    """A triple pendulum chain falling against three walls (e = 0.8, 0.5, 0.9) over 1.5 s,
    against the compiled midpoint run at h = 1e-6 (5 impacts): the angles in L∞ on a
    0.01 s grid (``state``) and the final state (``final``). The chain has a
    configuration-dependent M and gyroscopic terms (the class where the predictor–corrector
    is said to gain), and its impacts hit curved constraints."""

    name = "chain"
    primary = "state"
    metrics = ("state", "final")

    def __init__(self, ladder, config_list, t_end=1.5, h_ref=1e-6, record_dt=0.01):
        super().__init__(ladder, config_list)
        from moreau.problems.chain_walls import chain_walls

        self.scene, self.q0, self.v0 = chain_walls()
        self.t_end, self.h_ref, self.record_dt = t_end, h_ref, record_dt
        self.ref_config = Config("mid", "exact", "none")
        self.ref = None

    def _simulate(self, config, h):
        rec = int(round(self.record_dt / h))
        if abs(rec * h - self.record_dt) > 1e-9 * self.record_dt:
            raise ValueError(f"h = {h:g} does not divide the record interval {self.record_dt:g}")
        return _timed(lambda: mo.simulate(self.scene, (0.0, self.t_end), self.q0, self.v0, h, energy=False,
                                          record_every=rec, **config.simulate_kwargs()), repeat_below=0.5)

    def prepare(self):
        if self.ref is None:
            traj, self.ref_wall, status = self._simulate(self.ref_config, self.h_ref)
            if status != "completed":
                raise RuntimeError(f"chain: the reference run failed: {traj.message}")
            self.ref = traj

    def run(self, config, h):
        self.prepare()
        traj, wall, status = self._simulate(config, h)
        m = {}
        if status == "completed" and len(traj) == len(self.ref):
            r = self.ref
            m["state"] = float(np.abs(traj.q - r.q).max())
            m["final"] = float(max(np.abs(traj.q[-1] - r.q[-1]).max(), np.abs(traj.v[-1] - r.v[-1]).max()))
            m["impacts_run"] = len(traj.impacts)
        return self._run(config, h, traj, wall, status, m)
