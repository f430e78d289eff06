"""Work–precision study: what accuracy costs in time (issue 5).

For a ladder of step sizes, each integrator (:class:`~moreau.MoreauJeanMidpoint`,
:class:`~moreau.MoreauJeanPredictorCorrector`), each contact solver (OSQP at its default eps 1e-9
with polishing and at loose tolerances, the exact ``enum`` and ``daqp``) and with and
without drift control (:class:`~moreau.PositionProjection`), measure the wall time of the
run and its error against an independent reference; fit the observed order of
convergence per configuration (:func:`moreau.results.diagnostics.convergence_order`).

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
``block``
    A block sliding to rest on a floor with Coulomb friction (mu = 0.3, v0 = 2 m/s) over
    1 s, against its analytic motion (:class:`BlockProblem`): the position in L∞ and the
    stop position v0²/(2 mu g).
``woodpecker``
    The woodpecker toy (:mod:`moreau.problems.woodpecker`, friction and impacts) from
    Glocker's state on its limit cycle over three periods, against the compiled midpoint
    run at h = 1e-6 (:class:`WoodpeckerProblem`): the instants and velocities of the
    returns through φ_S = −0.2788.
``piston-e0``, ``piston-e0.9``
    The engine of :mod:`moreau.problems.piston` over 2 cycles from its standard start, against a
    run at h = 1e-6 (midpoint, exact solver; for e = 0 with ``PositionProjection(velocity=True)``,
    whose corners leave the wall on time, for e = 0.9 without drift control, see
    :class:`PistonProblem`): structural figures of the last cycle, not pointwise states —
    the crank angles of the side changes (largest distance between the two sets of angles,
    degrees; each change timed at its landing step from the onset log), the mean speed (rpm), impacts per cycle, the
    largest penetration (fraction of the clearance). For e = 0.9 the impact count is
    not a convergent figure: it grows like log(1/h) (each burst of bounces is resolved
    down to normal speeds ~ h a), so its "error" only measures the distance in h.

Impact times of a moreau run are read from the impact log as the crossing time of the
step in which the impact happened, ``t_k + g(q_k)/(−G v_k)`` (:func:`impact_times`):
the start of the step alone would add an O(h) quantization noise that hides the order.

Step-size control (``mo.StepControl``, the configurations labelled ``/tol``) runs the
midpoint step over a ladder of tolerances instead of steps, on every problem but the
chain (its error is read on a uniform grid of records); its "order" is the slope of the
error in tol (1: the error proportional to tol), and a table compares the cheapest run
with it and without it at each target error. The e = 0 piston's fixed runs with
``PositionProjection(velocity=True)``, the configuration its step-control runs use, go up
to their largest step 0.1.

Loose OSQP tolerances are run *unchecked* (``fallback=None`` and no KKT acceptance
test): with moreau's default checks (``tol=1e-6``, fallback ``enum``) a loose answer is
rejected and re-solved exactly, which costs time but no accuracy; the comparison on the
e = 0.9 piston (:func:`osqp_comparison`) shows both.

Run::

    python benchmarks/work_precision.py --quick      # ~2 min: prints the tables
    python benchmarks/work_precision.py --replot     # the figure again from docs/work_precision.csv
    python benchmarks/work_precision.py              # full study (~20 min), writes
                                                     # docs/work_precision.{csv,png}

Absolute times on a shared machine drift; ratios measured in one run hold better. Each wall
time is the best of up to ten runs within 0.5 s (``wp_configs._timed``).
The functions are importable from this script (``run_study``, ``fit_orders``,
``drift_cost``, ``osqp_comparison``, ``format_table``, ...); they live in its parts beside
it: ``wp_configs.py`` (configurations, runs, timing), ``wp_problems.py`` (the problems and
their references), ``wp_study.py`` (the study's ladders, running it, orders and
comparisons) and ``wp_report.py`` (tables, CSV, figure).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

_HERE = os.path.dirname(os.path.abspath(__file__))
_ROOT = os.path.dirname(_HERE)
for _p in (_ROOT, _HERE):  # `python benchmarks/work_precision.py` from anywhere; the wp_* parts beside it
    if _p not in sys.path:
        sys.path.insert(0, _p)

# the study's parts, re-exported here: `work_precision.Config`, `.run_study`, ... as before
from wp_configs import SOLVERS, Config, Run, SolverSpec, configs  # noqa: E402
from wp_friction import BlockProblem, WoodpeckerProblem  # noqa: E402
from wp_problems import (  # noqa: E402
    BallProblem,
    ChainWallsProblem,
    PendulumWallProblem,
    PistonProblem,
    Problem,
    SmoothPendulumProblem,
    _angle_distance,  # noqa: E402, F401 (tests/test_work_precision.py checks it here)
    impact_times,
)
from wp_report import (  # noqa: E402
    cheapest,
    format_cheapest,
    format_drift,
    format_gain,
    format_orders,
    format_osqp,
    format_table,
    plot,
    read_csv,
    step_control_gain,
    write_csv,
)
from wp_study import (  # noqa: E402
    _describe_ref,
    drift_cost,
    fit_orders,
    make_problems,
    osqp_comparison,
    run_study,
)

__all__ = [
    "SolverSpec", "Config", "Run", "Problem", "BallProblem", "PendulumWallProblem",
    "SmoothPendulumProblem", "PistonProblem", "ChainWallsProblem", "BlockProblem", "WoodpeckerProblem", "SOLVERS",
    "impact_times", "configs",
    "make_problems", "run_study", "fit_orders", "drift_cost", "osqp_comparison",
    "format_table", "format_orders", "format_drift", "format_osqp", "cheapest", "format_cheapest", "write_csv",
    "read_csv",
    "plot", "main",
]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small ladders and configurations (~2 min)")
    ap.add_argument("--out", default=None, help="directory for work_precision.csv/.png (default: docs/ for the "
                                                "full run, nothing for --quick)")
    ap.add_argument("--problems", default=None,
                    help="comma-separated subset: ball,pendulum,pendulum-smooth,chain,block,woodpecker,"
                         "piston-e0,piston-e0.9")
    ap.add_argument("--replot", action="store_true", help="draw work_precision.png again from the CSV in --out "
                                                             "(default docs/), running nothing")
    args = ap.parse_args(argv)
    if args.replot:
        out = args.out or os.path.join(_ROOT, "docs")
        runs, orders = read_csv(os.path.join(out, "work_precision.csv"))
        names = {r.problem for r in runs}
        problems = [p for p in make_problems(False) if p.name in names]
        plot(runs, orders, problems, os.path.join(out, "work_precision.png"))
        print(f"redrew {os.path.join(out, 'work_precision.png')} from its CSV")
        return 0

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    t_start = time.perf_counter()
    problems = make_problems(args.quick)
    if args.problems:
        keep = set(args.problems.split(","))
        problems = [p for p in problems if p.name in keep]
    runs = run_study(problems, log, freeze=True)
    orders = fit_orders(runs)
    print(f"work–precision ({'quick' if args.quick else 'full'} run); wall times in s, fb = fallbacks")
    print(format_table(runs, problems))
    print("\nobserved order of the primary error per configuration (fit over the ladder)")
    print(format_orders(runs, problems))
    print("\nwhat buys an accuracy at least cost (primary error; targets 10x, 100x, 1000x below the largest)")
    print(format_cheapest(cheapest(runs, problems)))
    print("\nstep-size control against fixed steps: the cheapest run of each reaching a target, and the ratio")
    print(format_gain(step_control_gain(runs, problems)))
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
