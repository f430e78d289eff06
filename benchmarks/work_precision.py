"""Work–precision study: what accuracy costs in time (issue 5).

For a ladder of step sizes, each integrator (:class:`~moreau.MoreauJeanMidpoint`,
:class:`~moreau.MoreauJeanPredictorCorrector`), each contact solver (OSQP at its default eps 1e-9
with polishing and at loose tolerances, the exact ``enum`` and ``daqp``) and with and
without drift control (:class:`~moreau.PositionProjection`), measure the wall time of the
run and its error against an independent reference; fit the observed order of
convergence per configuration (:func:`moreau.diagnostics.convergence_order`).

Problems and their references (the *primary* error, plotted against wall time, first):

``ball``
    Ball dropped from 1 m, e = 0.8, over 4.5 s, against the analytic solution
    (:class:`moreau.problems.bouncing_ball.BallSolution`): impact times of the first 6 impacts,
    apex heights between them, the Zeno time, position in L∞ over the run.
``pendulum``
    Pendulum hitting the wall x = 0.5 with e = 0.9 and pivot damping c = 0.05, from
    θ = 0, θ̇ = 4 rad/s, over 12 s (8 impacts), against the event-driven reference
    (:func:`moreau.problems.event_driven.pendulum_wall_reference`): impact times (mean over the
    impacts), θ in L∞ over the run.
``pendulum-smooth``
    The same pendulum with damping c = 0.5 and no wall, against DOP853: the smooth-phase
    order (1 for the midpoint, 2 for the θ variant).
``chain``
    A triple pendulum chain falling against three walls (e = 0.8, 0.5, 0.9) over 1.5 s,
    5 impacts, against the compiled midpoint run at h = 1e-6 (:class:`ChainWallsProblem`):
    the angles in L∞ on a 0.01 s grid, and the final state.
``piston-e0``, ``piston-e0.9``
    The engine of :mod:`moreau.problems.piston` over 2 cycles from its standard start, against a
    run at a much smaller step (h = 3e-5; midpoint, exact solver; drift control for
    e = 0 only, see :class:`PistonProblem`): structural figures of the last cycle, not
    pointwise states — the crank angles of the side changes (largest distance between
    the two sets of angles, degrees), the mean speed (rpm), impacts per cycle, the
    largest penetration (fraction of the clearance). For e = 0.9 the impact count is
    not a convergent figure: it grows like log(1/h) (each burst of bounces is resolved
    down to normal speeds ~ h a), so its "error" only measures the distance in h.

Impact times of a moreau run are read from the impact log as the crossing time of the
step in which the impact happened, ``t_k + g(q_k)/(−G v_k)`` (:func:`impact_times`):
the start of the step alone would add an O(h) quantization noise that hides the order.

Loose OSQP tolerances are run *unchecked* (``fallback=None`` and no KKT acceptance
test): with moreau's default checks (``tol=1e-6``, fallback ``enum``) a loose answer is
rejected and re-solved exactly, which costs time but no accuracy; the comparison on the
e = 0.9 piston (:func:`osqp_comparison`) shows both.

Run::

    python benchmarks/work_precision.py --quick      # ~2 min: prints the tables
    python benchmarks/work_precision.py              # full study (~18-20 min), writes
                                                     # docs/work_precision.{csv,png}

Absolute times on a shared machine drift; ratios measured in one run hold better.
The functions are importable (``run_study``, ``fit_orders``, ``drift_cost``,
``osqp_comparison``, ``format_table``, ...).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if _ROOT not in sys.path:  # `python benchmarks/work_precision.py` from anywhere
    sys.path.insert(0, _ROOT)

import moreau as mo  # noqa: E402
from moreau.diagnostics import convergence_order  # noqa: E402
from moreau.problems.event_driven import moreau_impact_times as impact_times  # noqa: E402

__all__ = [
    "SolverSpec", "Config", "Run", "Problem", "BallProblem", "PendulumWallProblem",
    "SmoothPendulumProblem", "PistonProblem", "SOLVERS", "impact_times", "configs",
    "make_problems", "run_study", "fit_orders", "drift_cost", "osqp_comparison",
    "format_table", "format_orders", "cheapest", "format_cheapest", "write_csv", "plot", "main",
]

# ----------------------------------------------------------------------------------------
# configurations
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SolverSpec:
    """A contact solver as the study runs it.

    ``checked``: moreau's default acceptance test (scaled KKT residual <= 1e-6) with the
    exact ``enum`` fallback; unchecked runs take the backend's answer as it is.
    """

    label: str
    make: Callable[[], mo.ContactSolver | str]
    checked: bool = True

    def simulate_kwargs(self) -> dict:
        if self.checked:
            return {"solver": self.make(), "fallback": "auto"}  # enum, or exact when the main is enum
        return {"solver": self.make(), "fallback": None, "tol": 1e30}


SOLVERS: dict[str, SolverSpec] = {
    "osqp": SolverSpec("osqp", lambda: mo.OSQPSolver()),  # eps 1e-9, polish: the default
    "osqp1e-5": SolverSpec("osqp1e-5", lambda: mo.OSQPSolver(eps=1e-5, polish=False), checked=False),
    "osqp1e-3": SolverSpec("osqp1e-3", lambda: mo.OSQPSolver(eps=1e-3, polish=False), checked=False),
    "enum": SolverSpec("enum", lambda: "enum"),
    "exact": SolverSpec("exact", lambda: "exact"),  # the compiled default: runs the compiled loop
    "daqp": SolverSpec("daqp", lambda: "daqp"),
    # checked variants of the loose tolerances (rejected answers fall back to enum)
    "osqp1e-5+check": SolverSpec("osqp1e-5+check", lambda: mo.OSQPSolver(eps=1e-5, polish=False)),
    "osqp1e-3+check": SolverSpec("osqp1e-3+check", lambda: mo.OSQPSolver(eps=1e-3, polish=False)),
}

_INTEGRATORS = {"mid": mo.MoreauJeanMidpoint, "theta": mo.MoreauJeanPredictorCorrector}
#: drift control variants: none, PositionProjection (plastic rows), CombinedProjection (every e)
_DRIFTS = {"none": None, "proj": mo.PositionProjection, "comb": mo.CombinedProjection}


@dataclass(frozen=True)
class Config:
    """One configuration: integrator (``"mid"`` or ``"theta"``), solver, drift control
    (``"none"``, ``"proj"``: :class:`~moreau.PositionProjection`, ``"comb"``:
    :class:`~moreau.CombinedProjection`; ``False``/``True`` mean none/proj)."""

    integrator: str
    solver: str
    drift: str = "none"

    def __post_init__(self) -> None:
        d = {False: "none", True: "proj"}[self.drift] if isinstance(self.drift, bool) else self.drift
        if d not in _DRIFTS:
            raise ValueError(f"drift must be one of {sorted(_DRIFTS)} (or a bool), got {self.drift!r}")
        object.__setattr__(self, "drift", d)

    @property
    def label(self) -> str:
        return f"{self.integrator}/{self.solver}/{self.drift}"

    def simulate_kwargs(self) -> dict:
        kw = SOLVERS[self.solver].simulate_kwargs()
        kw["integrator"] = _INTEGRATORS[self.integrator]
        make = _DRIFTS[self.drift]
        kw["drift_control"] = make() if make is not None else None
        return kw


def configs(integrators=("mid", "theta"), solvers=("osqp", "osqp1e-5", "osqp1e-3", "enum", "daqp"),
            drifts=(False, True)) -> list[Config]:
    """The cross product of the given choices."""
    return [Config(i, s, d) for i in integrators for s in solvers for d in drifts]


@dataclass
class Run:
    """One run: its configuration, h, cost and errors.

    ``metrics`` holds the problem's errors (and a few raw figures) by name; ``error`` is
    the primary one (NaN when the run failed).
    """

    problem: str
    config: Config
    h: float
    wall: float
    steps: int
    fallbacks: int
    status: str
    error: float
    metrics: dict = field(default_factory=dict)


def _timed(fn, repeat_below: float = 0.0, repeats: int = 3):
    """(trajectory, wall time, status) of ``fn()``. A run faster than ``repeat_below``
    seconds is repeated (up to ``repeats`` runs in all) and the shortest time kept: the
    runs are deterministic, and on a shared machine the minimum is the cost."""
    best, traj, status = float("inf"), None, "completed"
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        status = "completed"
        try:
            traj = fn()
        except (mo.SolverError, mo.SimulationError) as exc:
            traj, status = exc.trajectory, "failed"
        wall = time.perf_counter() - t0
        best = min(best, wall)
        if wall >= repeat_below:
            break
    return traj, best, status


# ----------------------------------------------------------------------------------------
# problems
# ----------------------------------------------------------------------------------------


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
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, self.t_end), [self.h0], [0.0], h, energy=False, **config.simulate_kwargs()),
            repeat_below=0.5)
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
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, self.t_end), [0.0], [self.omega0], h, energy=False, **config.simulate_kwargs()),
            repeat_below=0.5)
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
        n = round(self.t_end / h)
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, n * h), [self.y0[0]], [self.y0[1]], h, energy=False, **config.simulate_kwargs()),
            repeat_below=0.5)
        m = {}
        if status == "completed" and abs(n * h - self.t_end) < 1e-12:
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
            rec = max(1, int(round(self.record_dt / h)))
            traj, wall, status = _timed(lambda: self.model.simulate(
                self.cycles, h, record_every=rec, energy=False, **config.simulate_kwargs()))
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


# ----------------------------------------------------------------------------------------
# study
# ----------------------------------------------------------------------------------------


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


def _compiles(scene) -> bool:
    """Whether the scene runs in the compiled loop (every part has a kernel)."""
    from moreau.lowering import NotCompilable, lower

    try:
        lower(scene)
    except NotCompilable:
        return False
    return True


def make_problems(quick: bool = False) -> list[Problem]:
    """The study's problems with their ladders and configurations (quick: smaller)."""
    if quick:
        lad = [1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4]
        small = configs(solvers=("osqp", "osqp1e-3", "enum"))
        pist = [Config("mid", "enum", False), Config("mid", "enum", True), Config("theta", "enum", False),
                Config("mid", "osqp", False)]
        plad = [1e-2, 6e-3, 4e-3, 2.5e-3, 1.5e-3]
        return [
            BallProblem(lad, small),
            PendulumWallProblem(lad, small, t_end=6.0),
            SmoothPendulumProblem([0.02, 0.01, 0.005, 0.0025, 0.00125], configs(solvers=("enum",), drifts=(False,))),
            PistonProblem(plad, pist, e=0.0, h_ref=5e-4),
            PistonProblem(plad, pist, e=0.9, h_ref=5e-4),
        ]
    lad = list(np.logspace(-2, -4, 5))  # 1e-2 ... 1e-4, 2 decades: the Python-path solvers
    deep = list(np.logspace(-2, -6, 9))  # 1e-2 ... 1e-6, 4 decades: the compiled loop
    compiled = configs(solvers=("exact",), drifts=("none", "proj", "comb"))
    python = configs(solvers=("osqp", "osqp1e-5", "osqp1e-3", "enum", "daqp"), drifts=("none", "proj"))

    def both(problem_cls, **kw):
        p = problem_cls(deep, compiled + python, **kw)
        # the deep ladder where the scene runs compiled (the ball); a scene with plain
        # Python callables (the pendulum) takes the Python path, 1e-2 ... 1e-4
        fast = _compiles(p.scene)
        p.ladders = {c: (deep if c.solver == "exact" and fast else lad) for c in p.configs}
        return p

    # the piston: every integrator and drift control compiled, down to h = 1e-5 against
    # a reference at h = 1e-6; the Python-path OSQP runs at h >= 1e-4
    plad = list(np.logspace(-2, -5, 7))
    pist = configs(solvers=("exact",), drifts=("none", "proj", "comb")) + [
        Config("mid", "osqp", "none"), Config("mid", "osqp1e-5", "none"), Config("mid", "osqp1e-3", "none")]
    pistons = []
    for e in (0.0, 0.9):
        p = PistonProblem(plad, pist, e=e, h_ref=1e-6, ref_config=Config("mid", "exact", "none"))
        p.ladders = {c: (plad if c.solver == "exact" else [h for h in plad if h >= 1e-4]) for c in pist}
        pistons.append(p)
    chain_ladder = [1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5]  # divisors of 0.01 s
    return [
        both(BallProblem),
        both(PendulumWallProblem, t_end=12.0),
        ChainWallsProblem(chain_ladder, compiled),
        SmoothPendulumProblem([0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125, 4e-4],
                              configs(solvers=("exact",), drifts=(False,))),
        *pistons,
    ]


def run_study(problems: Sequence[Problem], log: Callable[[str], None] | None = None) -> list[Run]:
    """Run every problem's configurations over its ladder; returns the runs in order."""
    runs = []
    for p in problems:
        t0 = time.perf_counter()
        p.prepare()
        if log and getattr(p, "ref_wall", None):
            what = _describe_ref(p.ref) if isinstance(p.ref, dict) else f"{len(p.ref.impacts)} impacts"
            log(f"{p.name}: reference {p.ref_config.label} at h = {p.h_ref:g} took {p.ref_wall:.1f} s: {what}")
        ladders = getattr(p, "ladders", {})
        for c in p.configs:
            for h in ladders.get(c, p.ladder):
                runs.append(p.run(c, h))
        if log:
            log(f"{p.name}: {len(p.configs)} configurations x {len(p.ladder)} steps in "
                f"{time.perf_counter() - t0:.1f} s")
    return runs


def _describe_ref(f: dict) -> str:
    return (f"cycle {f['cycle']}: {f['side_changes']} side changes at "
            f"{' '.join(f'{a:.1f}' for a in f['angles'])} deg, {f['impacts']} impacts, "
            f"{f['rpm']:.3f} rpm, penetration {f['penetration']:.3g} of the clearance")


def fit_orders(runs: Sequence[Run], metric: str | None = None) -> dict[tuple[str, str], float]:
    """Observed order per (problem, configuration label): the least-squares slope of
    log(error) on log(h) (:func:`moreau.diagnostics.convergence_order`) over the runs
    with a finite positive error (NaN when fewer than 3 such runs). ``metric`` names an
    error of ``Run.metrics``; default the primary error."""
    groups: dict[tuple[str, str], list[Run]] = {}
    for r in runs:
        groups.setdefault((r.problem, r.config.label), []).append(r)
    out = {}
    for key, rs in groups.items():
        pts = [(r.h, r.error if metric is None else r.metrics.get(metric, np.nan))
               for r in rs if r.status == "completed"]
        ok = [(h, e) for h, e in pts if np.isfinite(e) and e > 0]
        out[key] = convergence_order(*zip(*ok)) if len(ok) >= 3 else float("nan")
    return out


def drift_cost(runs: Sequence[Run], solver: str | None = None) -> list[dict]:
    """Cost of drift control on the piston: wall time with/without at the same h (same
    integrator and solver), and the penetration each leaves."""
    by = {(r.problem, r.config, r.h): r for r in runs}
    out = []
    for r in runs:
        c = r.config
        if not r.problem.startswith("piston") or c.drift != "none" or c.solver not in (
                (solver,) if solver else ("exact", "enum")):
            continue
        w = by.get((r.problem, Config(c.integrator, c.solver, "comb"), r.h))
        if w is None:
            w = by.get((r.problem, Config(c.integrator, c.solver, "proj"), r.h))
        if w is None:
            continue
        out.append({"problem": r.problem, "integrator": c.integrator, "h": r.h, "wall_none": r.wall,
                    "wall_proj": w.wall, "ratio": w.wall / r.wall,
                    "pen_none": r.metrics.get("penetration_run", np.nan),
                    "pen_proj": w.metrics.get("penetration_run", np.nan),
                    "projections": w.metrics.get("projections", 0), "steps": w.steps})
    return out


def osqp_comparison(problem: PistonProblem, h: float,
                    solvers=("enum", "daqp", "osqp", "osqp1e-5+check", "osqp1e-5", "osqp1e-3+check", "osqp1e-3"),
                    integrator: str = "mid", drift: bool = False) -> list[dict]:
    """The same piston run with each solver: time, fallbacks, impact count, side
    changes and penetration of the last cycle, and their differences to ``enum``."""
    rows = []
    for s in solvers:
        c = Config(integrator, s, drift)
        f, wall, status, stats, _ = problem.simulate(c, h)
        rows.append({"solver": s, "checked": SOLVERS[s].checked, "status": status, "wall": wall,
                     "fallbacks": int(stats.fallbacks), "solves": int(stats.solves),
                     "impacts": f.get("impacts", np.nan), "side_changes": f.get("side_changes", np.nan),
                     "angles": f.get("angles", []), "penetration": f.get("penetration", np.nan),
                     "rpm": f.get("rpm", np.nan)})
    base = next((r for r in rows if r["solver"] == "enum" and r["status"] == "completed"), None)
    for r in rows:
        if base is not None and r["status"] == "completed":
            r["d_impacts"] = r["impacts"] - base["impacts"]
            r["d_impacts_rel"] = r["d_impacts"] / max(1, base["impacts"])
            r["d_penetration"] = r["penetration"] - base["penetration"]
            r["d_angles"] = _angle_distance(r["angles"], base["angles"])
            r["time_ratio"] = r["wall"] / base["wall"]
    return rows


# ----------------------------------------------------------------------------------------
# output
# ----------------------------------------------------------------------------------------


def _fmt(x) -> str:
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return f"{x:.3g}"


def format_table(runs: Sequence[Run], problems: Sequence[Problem]) -> str:
    """One table per problem: configuration, h, wall time, the errors."""
    lines = []
    for p in problems:
        rs = [r for r in runs if r.problem == p.name]
        if not rs:
            continue
        extra = ["impacts"] if p.name in ("ball", "pendulum") else (
            ["impacts_run", "side_changes_run", "penetration_run"] if p.name.startswith("piston") else [])
        cols = list(p.metrics) + extra
        lines.append(f"\n== {p.name}  (primary error: {p.primary}) ==")
        head = f"{'configuration':<24} {'h':>8} {'wall[s]':>8} {'fb':>5}  " + " ".join(f"{c:>12}" for c in cols)
        lines.append(head)
        lines.append("-" * len(head))
        for r in rs:
            vals = " ".join(f"{_fmt(r.metrics.get(c, np.nan)):>12}" for c in cols)
            st = "" if r.status == "completed" else f"  [{r.status}]"
            lines.append(f"{r.config.label:<24} {r.h:8.2g} {r.wall:8.3f} {r.fallbacks:5d}  {vals}{st}")
    return "\n".join(lines)


def cheapest(runs: Sequence[Run], problems: Sequence[Problem], decades: int = 3) -> list[dict]:
    """Per problem and target error: the configuration and h that reach it at the least
    wall time. Targets: the largest primary error of the study, divided by 10, 100, ...
    (``decades`` of them); a configuration reaches a target when one of its runs has a
    primary error at or below it."""
    out = []
    for p in problems:
        rs = [r for r in runs if r.problem == p.name and r.status == "completed" and np.isfinite(r.error)
              and r.error > 0]
        if not rs:
            continue
        top = max(r.error for r in rs)
        for k in range(1, decades + 1):
            target = top / 10.0**k
            ok = [r for r in rs if r.error <= target]
            if not ok:
                continue
            best = min(ok, key=lambda r: r.wall)
            out.append({"problem": p.name, "target": target, "config": best.config.label, "h": best.h,
                        "wall": best.wall, "error": best.error})
    return out


def format_cheapest(rows: Sequence[dict]) -> str:
    head = f"{'problem':<16} {'target error':>12}  {'cheapest configuration':<24} {'h':>8} {'wall[s]':>8} {'error':>10}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['problem']:<16} {r['target']:12.3g}  {r['config']:<24} {r['h']:8.2g} {r['wall']:8.3f} "
                     f"{r['error']:10.3g}")
    return "\n".join(lines)


def format_orders(runs: Sequence[Run], problems: Sequence[Problem]) -> str:
    """Per (problem, configuration): fitted order of each error, total time, best
    primary error."""
    lines = []
    for p in problems:
        rs_p = [r for r in runs if r.problem == p.name]
        if not rs_p:
            continue
        orders = {m: fit_orders(rs_p, m) for m in p.metrics}
        head = (f"{'problem':<16} {'configuration':<24} {'time[s]':>8} {'best err':>9}  "
                + " ".join(f"{'p(' + m + ')':>16}" for m in p.metrics))
        lines += ["", head, "-" * len(head)]
        for c in p.configs:
            key = (p.name, c.label)
            rs = [x for x in rs_p if x.config == c]
            errs = [x.error for x in rs if np.isfinite(x.error)]
            lines.append(f"{p.name:<16} {c.label:<24} {sum(x.wall for x in rs):8.2f} "
                         f"{(min(errs) if errs else float('nan')):9.3g}  "
                         + " ".join(f"{orders[m][key]:16.2f}" for m in p.metrics))
    return "\n".join(lines)


def format_drift(rows: Sequence[dict]) -> str:
    lines = [f"\n{'problem':<12} {'integ':<6} {'h':>8} {'t none[s]':>10} {'t proj[s]':>10} {'ratio':>6} "
             f"{'pen none':>9} {'pen proj':>9}"]
    for d in rows:
        lines.append(f"{d['problem']:<12} {d['integrator']:<6} {d['h']:8.2g} {d['wall_none']:10.2f} "
                     f"{d['wall_proj']:10.2f} {d['ratio']:6.2f} {_fmt(d['pen_none']):>9} {_fmt(d['pen_proj']):>9}")
    return "\n".join(lines)


def format_osqp(rows: Sequence[dict]) -> str:
    lines = [f"\n{'solver':<16} {'checked':>7} {'wall[s]':>8} {'x enum':>7} {'fallbacks':>9} {'impacts':>8} "
             f"{'Δimp':>6} {'sides':>5} {'Δangle':>7} {'pen':>8} {'Δpen':>9}"]
    for r in rows:
        lines.append(f"{r['solver']:<16} {str(r['checked']):>7} {r['wall']:8.2f} {_fmt(r.get('time_ratio')):>7} "
                     f"{r['fallbacks']:9d} {_fmt(r['impacts']):>8} {_fmt(r.get('d_impacts')):>6} "
                     f"{_fmt(r['side_changes']):>5} {_fmt(r.get('d_angles')):>7} {_fmt(r['penetration']):>8} "
                     f"{_fmt(r.get('d_penetration')):>9}"
                     + ("" if r["status"] == "completed" else f"  [{r['status']}]"))
    return "\n".join(lines)


def write_csv(runs: Sequence[Run], orders: dict, path: str) -> None:
    """One row per run: problem, configuration, h, wall time, errors, fitted order."""
    names = []
    for r in runs:
        for k in r.metrics:
            if k not in names and not isinstance(r.metrics[k], (list, tuple)):
                names.append(k)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["problem", "integrator", "solver", "checked", "drift", "h", "wall_s", "steps", "fallbacks",
                    "status", "error", "order", *names])
        for r in runs:
            c = r.config
            w.writerow([r.problem, c.integrator, c.solver, SOLVERS[c.solver].checked, c.drift, f"{r.h:.6g}",
                        f"{r.wall:.4f}", r.steps, r.fallbacks, r.status, f"{r.error:.6g}",
                        f"{orders[(r.problem, c.label)]:.3f}",
                        *[("" if r.metrics.get(k) is None else f"{r.metrics[k]:.6g}") for k in names]])


def plot(runs: Sequence[Run], orders: dict, problems: Sequence[Problem], path: str) -> None:
    """Log–log error against wall time, one panel per problem, one line per
    configuration (colour: solver, line: integrator, marker: drift control); the legend
    gives the fitted order of each line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    colors = {"osqp": "C0", "osqp1e-5": "C1", "osqp1e-3": "C3", "enum": "C2", "daqp": "C4", "exact": "C5"}
    styles = {"mid": "-", "theta": "--"}
    markers = {"none": "o", "proj": "s", "comb": "^"}
    n = len(problems)
    ncol = 3
    nrow = math.ceil((n + 1) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.0 * ncol, 4.6 * nrow))
    axes = np.atleast_1d(axes).ravel()
    for ax, p in zip(axes, problems):
        for c in p.configs:
            rs = [r for r in runs if r.problem == p.name and r.config == c and np.isfinite(r.error) and r.error > 0]
            if not rs:
                continue
            ax.loglog([r.wall for r in rs], [r.error for r in rs], styles[c.integrator], marker=markers[c.drift],
                      color=colors.get(c.solver, "k"), ms=4, lw=1.1, alpha=0.85,
                      label=f"{c.label}  p={orders[(p.name, c.label)]:.2f}")
        ax.set_title(f"{p.name}: {p.primary} error")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel(f"error ({p.primary})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=1 if len(p.configs) <= 8 else 2, loc="best")
    # last panel: piston penetration against h, with and without drift control
    ax = axes[n]
    for p in problems:
        if not p.name.startswith("piston"):
            continue
        for c in p.configs:
            if c.solver not in ("enum", "exact"):
                continue
            rs = [r for r in runs if r.problem == p.name and r.config == c and "penetration_run" in r.metrics]
            if rs:
                ax.loglog([r.h for r in rs], [max(r.metrics["penetration_run"], 1e-6) for r in rs],
                          styles[c.integrator], marker=markers[c.drift], ms=4,
                          label=f"{p.name} {c.label}")
    ax.set_title("piston: max penetration / clearance (last cycle; floor 1e-6)")
    ax.set_xlabel("h (non-dimensional)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    for ax in axes[n + 1:]:
        ax.axis("off")
    handles = [Line2D([], [], color=v, label=k) for k, v in colors.items()]
    handles += [Line2D([], [], color="k", ls=v, label=k) for k, v in styles.items()]
    names = {"none": "no drift control", "proj": "PositionProjection", "comb": "CombinedProjection"}
    handles += [Line2D([], [], color="k", marker=v, ls="", label=names[k]) for k, v in markers.items()]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("moreau work–precision: error against wall time (p = fitted order in h)")
    fig.tight_layout(rect=(0, 0.04, 1, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small ladders and configurations (~2 min)")
    ap.add_argument("--out", default=None, help="directory for work_precision.csv/.png (default: docs/ for the "
                                                "full run, nothing for --quick)")
    ap.add_argument("--problems", default=None,
                    help="comma-separated subset: ball,pendulum,pendulum-smooth,chain,piston-e0,piston-e0.9")
    args = ap.parse_args(argv)

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    t_start = time.perf_counter()
    problems = make_problems(args.quick)
    if args.problems:
        keep = set(args.problems.split(","))
        problems = [p for p in problems if p.name in keep]
    runs = run_study(problems, log)
    orders = fit_orders(runs)
    print(f"work–precision ({'quick' if args.quick else 'full'} run); wall times in s, fb = fallbacks")
    print(format_table(runs, problems))
    print("\nobserved order of the primary error per configuration (fit over the ladder)")
    print(format_orders(runs, problems))
    print("\nwhat buys an accuracy at least cost (primary error; targets 10x, 100x, 1000x below the largest)")
    print(format_cheapest(cheapest(runs, problems)))
    pistons = [p for p in problems if isinstance(p, PistonProblem)]
    for p in pistons:
        print(f"\n{p.name} reference ({p.ref_config.label}, h = {p.h_ref:g}, {p.ref_wall:.0f} s): "
              f"{_describe_ref(p.ref)}")
    if pistons:
        print("\ndrift control on the piston (midpoint/theta, enum): time with/without at the same h")
        print(format_drift(drift_cost(runs)))
        p9 = next((p for p in pistons if p.e == 0.9), None)
        if p9 is not None:
            h_cmp = 1e-3 if args.quick else 1e-4
            print(f"\nOSQP tolerances on the e = 0.9 piston, h = {h_cmp:g}, last cycle (Δ: against enum)")
            print(format_osqp(osqp_comparison(p9, h_cmp)))
    out = args.out if args.out is not None else (None if args.quick else os.path.join(_ROOT, "docs"))
    if out:
        os.makedirs(out, exist_ok=True)
        write_csv(runs, orders, os.path.join(out, "work_precision.csv"))
        plot(runs, orders, problems, os.path.join(out, "work_precision.png"))
        print(f"\nwrote {os.path.join(out, 'work_precision.csv')} and work_precision.png")
    print(f"\ntotal time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
