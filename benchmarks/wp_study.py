"""Work–precision study, part 3: the study's problems and ladders, running them, and
what is read off the runs (fitted orders, the cost of drift control, the solvers
compared on the piston)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
from wp_configs import SOLVERS, Config, Run, configs, settle
from wp_friction import BlockProblem, WoodpeckerProblem
from wp_problems import (
    BallProblem,
    ChainWallsProblem,
    PendulumWallProblem,
    PistonProblem,
    Problem,
    SmoothPendulumProblem,
    _angle_distance,
)

from moreau.results.diagnostics import convergence_order


def _with_step_control(problem: Problem, tols: Sequence[float], drift: str = "none",
                       h_max: float | None = None, v_tol: float = 1.0) -> Problem:
    """The problem with one more configuration, the midpoint step with step-size control
    (the exact solver, drift control ``drift``, largest step ``h_max`` or the problem's,
    the velocities' tolerance ``v_tol`` times the coordinates'), over the tolerances ``tols``."""
    c = Config("mid", "exact", drift, adaptive=True, h_max=h_max, v_tol=v_tol)
    problem.configs.append(c)
    problem.ladders = {**getattr(problem, "ladders", {}), c: [float(t) for t in tols]}
    return problem


def make_problems(quick: bool = False) -> list[Problem]:
    """The study's problems with their ladders and configurations (quick: smaller); the
    midpoint step with step-size control on every problem but the chain (whose error is
    read on a uniform grid of records)."""
    if quick:
        lad = [1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4]
        small = configs(solvers=("osqp", "osqp1e-3", "enum"))
        pist = [Config("mid", "enum", False), Config("mid", "enum", True), Config("theta", "enum", False),
                Config("mid", "osqp", False)]
        plad = [1e-2, 6e-3, 4e-3, 2.5e-3, 1.5e-3]
        return [
            _with_step_control(BallProblem(lad, small), [1e-3, 1e-4, 1e-5]),
            PendulumWallProblem(lad, small, t_end=6.0),
            _with_step_control(SmoothPendulumProblem([0.02, 0.01, 0.005, 0.0025, 0.00125],
                                                     configs(solvers=("enum",), drifts=(False,))), [1e-3, 1e-4, 1e-5]),
            BlockProblem(lad, configs(solvers=("osqp", "enum"), drifts=(False,))),  # OSQP: Tresca, 5 s a run
            _with_step_control(WoodpeckerProblem([1e-3, 5e-4, 2e-4], configs(solvers=("exact", "enum"),
                                                                            drifts=(False,)), h_ref=2e-5),
                               [1e-3, 1e-4]),
            PistonProblem(plad, pist, e=0.0, h_ref=5e-4),
            PistonProblem(plad, pist, e=0.9, h_ref=5e-4),
        ]
    lad = list(np.logspace(-2, -4, 5))  # 1e-2 ... 1e-4, 2 decades: the Python-path solvers
    deep = list(np.logspace(-2, -6, 9))  # 1e-2 ... 1e-6, 4 decades: the compiled loop
    compiled = configs(solvers=("exact",), drifts=("none", "proj", "comb"))
    python = configs(solvers=("osqp", "osqp1e-5", "osqp1e-3", "enum", "daqp"), drifts=("none", "proj"))

    def both(problem_cls, **kw):
        p = problem_cls(deep, compiled + python, **kw)
        # the deep ladder for the compiled solver (every scene runs compiled), 1e-2 ... 1e-4
        # for the Python path's solvers
        p.ladders = {c: (deep if c.solver == "exact" else lad) for c in p.configs}
        return p

    # the piston: every integrator and drift control compiled, down to h = 1e-5 against
    # a reference at h = 1e-6; the Python-path OSQP runs at h >= 1e-4. e = 0: also drift
    # control with velocity=True, which the reference runs (its corners leave the wall on
    # time: docs/guide/accuracy.md, "Leaving a curved barrier")
    plad = list(np.logspace(-2, -5, 7))
    pistons = []
    for e in (0.0, 0.9):
        pist = configs(solvers=("exact",), drifts=("none", "proj", "comb") + (("projv",) if e == 0.0 else ())) + [
            Config("mid", "osqp", "none"), Config("mid", "osqp1e-5", "none"), Config("mid", "osqp1e-3", "none")]
        ref = Config("mid", "exact", "projv" if e == 0.0 else "none")
        p = PistonProblem(plad, pist, e=e, h_ref=1e-6, ref_config=ref)
        p.ladders = {c: (plad if c.solver == "exact" else [h for h in plad if h >= 1e-4]) for c in pist}
        if e == 0.0:  # the configuration step control runs, also fixed up to its largest step 0.1
            p.ladders[Config("mid", "exact", "projv")] = [1e-1, 10**-1.5] + plad
        pistons.append(p)
    chain_ladder = [1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5]  # divisors of 0.01 s
    tols = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7]
    # q is (crank, rod, tilt) in rad: the 40 µm clearance spans 2.7e-4 rad of the rod (l2 = 0.15 m), and the
    # side changes ask for much smaller tolerances than the crank alone would (docs/guide/accuracy.md)
    pistons[0] = _with_step_control(_with_step_control(pistons[0], [1e-4, 1e-5, 1e-6]), [1e-8, 1e-9, 1e-10, 1e-11],
                                    drift="projv")
    # the coarse errors: steps up to 0.1 (100x the h = 1e-3 the clearance allows a fixed
    # step) where the contacts do not switch
    pistons[0] = _with_step_control(pistons[0], [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9], drift="projv", h_max=0.1)
    # a tolerance per component: the velocities' 30x the coordinates' (of 10, 30 and 100 the
    # cheapest for the side-change angles: benchmarks/step_control.py --piston)
    pistons[0] = _with_step_control(pistons[0], [1e-5, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 1e-9], drift="projv",
                                    h_max=0.1, v_tol=30.0)
    return [
        _with_step_control(both(BallProblem), tols),
        _with_step_control(both(PendulumWallProblem, t_end=12.0), tols),
        # the energy-consistent step where its terms act: configuration-dependent M, damping
        ChainWallsProblem(chain_ladder, compiled + configs(integrators=("ec",), solvers=("exact",),
                                                           drifts=("none", "comb"))),
        _with_step_control(SmoothPendulumProblem([0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125, 4e-4],
                                                 configs(integrators=("mid", "theta", "ec"), solvers=("exact",),
                                                         drifts=(False,))), tols + [1e-8]),
        _with_step_control(both(BlockProblem), tols[:4]),
        # the woodpecker's coarse errors: the largest step near the stability limit (4.4e-3:
        # ω = 458 rad/s at Glocker's state) and looser tolerances
        _with_step_control(_with_step_control(both(WoodpeckerProblem), tols[:4]), [1e-1, 3e-2, 1e-2], h_max=4e-3),
        *pistons,
    ]


def run_study(problems: Sequence[Problem], log: Callable[[str], None] | None = None,
              freeze: bool = False) -> list[Run]:
    """Run every problem's configurations over its ladder; returns the runs in order.
    ``freeze``: after each problem's reference, :func:`wp_configs.settle` (for the study's
    own process: it freezes every object alive then)."""
    runs = []
    for p in problems:
        t0 = time.perf_counter()
        p.prepare()
        if freeze:
            settle()  # (the reference compiled what this problem's runs use)
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
    log(error) on log(h) (:func:`moreau.results.diagnostics.convergence_order`) over the runs
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
        if not r.problem.startswith("piston") or c.drift != "none" or c.adaptive or c.solver not in (
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
