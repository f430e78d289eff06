"""The bundled problems' ``moreau`` commands: ``ball``, ``piston`` and ``sweep``.

Each ``register_*`` function is a ``moreau.commands`` entry point (``pyproject.toml``; the
protocol is described in :mod:`moreau.cli`): it adds its parser to the ``moreau`` command
and names its handler. Registration only describes options; the handlers import the
problems and plotting when they run.

Units
-----
Every option names its unit in ``--help``. A step ``--h`` is in the time unit of the
model it runs: seconds for the ball; for the piston (``piston`` and ``sweep`` alike) the
non-dimensional crank-angle time τ = ω t of the paper's model, ω = 2π·2000/60 rad/s, so
that h = 1e-4 is 1e-4 rad of crank angle (0.48 µs) at the reference speed — the model is
integrated in τ because its mass matrix and forces are O(1) there. Lengths on the command
line and in the tables are in mm (``--D``, ``D_mm``); the Python API takes SI (``Case.D``,
``PistonParameters.D`` in m).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from moreau.cli import (
    EXIT_FAILED,
    EXIT_OK,
    Stopped,
    add_backend_option,
    add_progress_options,
    float_in,
    int_at_least,
    interrupt_exit_code,
    output_dir,
    positive_int,
    progress_mode,
    save_figure,
    simulate_and_save,
    write_summary,
)

__all__ = ["register_ball", "register_piston", "register_sweep"]


def _solver_option(parser: argparse.ArgumentParser, help: str) -> None:
    from moreau.contact.solvers import SOLVER_NAMES  # (a back-end not installed is refused by the run)

    parser.add_argument("--solver", choices=SOLVER_NAMES, default="exact", help=help)


# -- ball ---------------------------------------------------------------------------------
def register_ball(subparsers: Any) -> None:
    """``moreau ball``: the bouncing ball against its analytic solution."""
    b = subparsers.add_parser("ball", help="bouncing ball against its analytic solution")
    b.add_argument("--e", type=float_in(0.0, 1.0), default=0.5,
                   help="restitution in [0, 1] (dimensionless; default 0.5)")
    b.add_argument("--h0", type=float_in(0.0, None, lo_open=True), default=1.0, metavar="METRES",
                   help="drop height (m; default 1)")
    b.add_argument("--h", type=float_in(0.0, None, lo_open=True), default=1e-4, metavar="SECONDS",
                   help="time step (s; default 1e-4)")
    b.add_argument("--t-end", type=float_in(0.0, None, lo_open=True), default=2.0, metavar="SECONDS",
                   help="end time (s; default 2)")
    _solver_option(b, "contact solver (default exact, compiled)")
    add_backend_option(b)
    b.add_argument("--record-every", type=positive_int, default=1, metavar="K",
                   help="keep every K-th step (steps; default 1; raise it for long runs)")
    b.add_argument("--out", default="ball-out", help="output directory")
    add_progress_options(b, "bar")
    b.set_defaults(func=run_ball)


def run_ball(args: argparse.Namespace) -> int:
    """Simulate the ball, write its figure, summary and trajectory into ``args.out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import moreau as mo
    from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

    output_dir(args.out)
    for name in ("ball.npz", "ball.partial.npz", "ball.png", "ball_summary.csv"):  # a rerun: nothing old left
        if os.path.exists(os.path.join(args.out, name)):
            os.remove(os.path.join(args.out, name))
    scene = bouncing_ball(args.e)
    sol = BallSolution(args.h0, args.e)
    traj = simulate_and_save(scene, (0.0, args.t_end), [args.h0], [0.0], args.h,
                             out_stem=os.path.join(args.out, "ball"), solver=args.solver, backend=args.backend,
                             progress=False if args.no_progress else (args.progress or None),  # None: on a terminal
                             record_every=args.record_every, penetration_limit=0.01 * args.h0)  # 1 % of the drop
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(traj.t, traj.q[:, 0], label=f"moreau, h = {args.h:g} s")
    ax.plot(traj.t, sol.position(traj.t), "--", lw=1, label="analytic")
    if np.isfinite(sol.zeno_time):
        ax.axvline(sol.zeno_time, color="gray", lw=0.6, ls=":", label="Zeno time")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("height y (m)")
    ax.set_title(f"Bouncing ball, e = {args.e:g}")
    ax.legend()
    fig.tight_layout()
    fig_path = os.path.join(args.out, "ball.png")
    try:
        save_figure(fig, fig_path, dpi=120)
    finally:
        plt.close(fig)
    row = {
        "e": args.e, "h": args.h, "impacts": len(traj.impacts),
        "zeno_time_analytic": sol.zeno_time,
        "max_penetration": mo.diagnostics.max_penetration(traj),
        "fallbacks": traj.stats.fallbacks, "wall_time_s": traj.stats.wall_time,
        "us_per_step": traj.stats.us_per_step, "warnings": "; ".join(traj.warnings),
    }
    write_summary([row], os.path.join(args.out, "ball_summary.csv"))
    print(f"figure written to {fig_path}")
    if traj.warnings:  # never reported as a clean run
        print(f"moreau ball: completed WITH WARNINGS: {'; '.join(traj.warnings)}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


# -- piston -------------------------------------------------------------------------------
def _engine_run_args(parser: argparse.ArgumentParser, cycles: int, h: float) -> None:
    """The options of a piston run shared by ``piston`` and ``sweep``."""
    parser.add_argument("--cycles", type=positive_int, default=cycles, metavar="N",
                        help=f"engine cycles analyzed (cycles of 720° crank angle; default {cycles})")
    parser.add_argument("--transient", type=int_at_least(0), default=1, metavar="N",
                        help="engine cycles discarded first (cycles of 720° crank angle; default 1)")
    parser.add_argument("--h", type=float_in(0.0, 0.05, lo_open=True), default=h, metavar="TAU",
                        help=f"time step (τ: the model's non-dimensional crank-angle time τ = ω t, "
                             f"ω = 2π·2000/60 rad/s, so 1e-4 τ = 1e-4 rad of crank angle = 0.48 µs; "
                             f"default {h:g})")
    _solver_option(parser, "contact solver (default exact: the dual active-set method, the loop's own; "
                           "osqp, daqp and quadprog are called from the compiled loop)")
    add_backend_option(parser)
    parser.add_argument("--no-drift-control", action="store_true",
                        help="do not project positions back onto the cylinder after each step")


def register_piston(subparsers: Any) -> None:
    """``moreau piston``: the paper's engine cases, figures, summary and trajectories."""
    pi = subparsers.add_parser("piston", help="the paper's piston engine: figures, summary, trajectories",
                               description="Simulate the piston - connecting rod - crankshaft engine (the paper's "
                                           "three cases, or the one given by --e/--D), discard the transient, and "
                                           "write figures, summary.csv and the trajectories into --out.",
                               epilog="summary.csv: e, D_mm (mm), h (τ), mean_speed_rpm (rev/min, mean over the "
                                      "analyzed cycles), settled_speed_rpm (rev/min, energy-balance "
                                      "estimate of the speed the engine settles at), side_change_angles_deg "
                                      "(crank angle, °), energy_lost_per_cycle_J "
                                      "(J, at impacts), friction_loss_per_cycle_J (J, skirt friction, "
                                      "with --mu), max_slap_impulse_Ns (N s), max_penetration_over_clearance "
                                      "(dimensionless), wall_time_s (s), us_per_step (µs). The trajectories "
                                      "(.npz) are in the model's non-dimensional units; traj.units names them and "
                                      "gives the scales to SI.")
    pi.add_argument("--e", type=float_in(0.0, 1.0), default=None,
                    help="restitution in [0, 1] (dimensionless)")
    pi.add_argument("--D", type=float_in(80.0, 100.0, lo_open=True), default=None, metavar="MM",
                    help="cylinder diameter (mm), > 80 (the piston's); paper: 80.04 and 80.2")
    pi.add_argument("--mu", type=float_in(0.0, None), default=0.0, metavar="MU",
                    help="Coulomb friction of the skirt at the cylinder wall (dimensionless, >= 0; default 0, "
                         "the paper's frictionless wall)")
    _engine_run_args(pi, cycles=3, h=1e-4)
    pi.add_argument("--workers", type=positive_int, default=None,
                    help="parallel processes (default: one per case, up to the cores)")
    pi.add_argument("--record-every", type=positive_int, default=None, metavar="K",
                    help="keep every K-th step (steps; default: about one record per 0.1° of crank angle)")
    pi.add_argument("--out", default="piston-out", help="output directory (default piston-out); "
                    "a rerun first removes the files an earlier run left there for the same cases")
    add_progress_options(pi, "bars")
    pi.set_defaults(func=run_piston)


def run_piston(args: argparse.Namespace) -> int:
    """Run the engine cases, write the summary; exit code 1 when a case failed or warned."""
    from moreau.problems.piston.job import PAPER_CASES, Case, case_files, run_cases

    if args.e is None and args.D is None:
        pairs = list(PAPER_CASES)
    else:
        pairs = [(0.0 if args.e is None else args.e, 0.08004 if args.D is None else args.D / 1e3)]
    cases = [Case(e=e, D=D, h=args.h, cycles=args.cycles, transient=args.transient, solver=args.solver,
                  backend=args.backend, mu=args.mu,
                  drift_control=not args.no_drift_control, record_every=args.record_every)
             for e, D in pairs]
    output_dir(args.out)
    print(f"moreau piston: {len(cases)} case(s), {args.transient} transient + {args.cycles} analyzed "
          f"cycles each, h = {args.h:g} τ (non-dimensional crank-angle time), solver {args.solver}; "
          f"output in {args.out}/")
    stopped = None
    try:
        bars, report = progress_mode(args)  # off a terminal a line per case ends, not the bars' cursor codes
        rows = run_cases(cases, args.out, progress=bars, workers=args.workers, report=report)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: every case's row is attached
        attached = getattr(exc, "rows", None)
        if attached is None:
            raise
        rows, stopped = attached, exc
    write_summary(rows, os.path.join(args.out, "summary.csv"))
    bad = [r for r in rows if r["status"] != "completed"]
    for r, case in zip(rows, cases):
        if r not in bad:
            continue
        partial = case_files(case, args.out)[1]
        saved = f"partial trajectory saved in {partial}" if os.path.exists(partial) else "no trajectory saved"
        if r.get("warnings"):  # why: a worker that died, a file that could not be written
            saved = f"{r['warnings']}; {saved}"
        print(f"case e={r['e']}, D={r['D_mm']} mm {r['status']}: {saved}", file=sys.stderr)
    warned = [r for r in rows if r.get("warnings") and r["status"] == "completed"]
    for r in warned:  # never reported as clean
        print(f"case e={r['e']}, D={r['D_mm']} mm completed WITH WARNINGS: {r['warnings']}", file=sys.stderr)
    bad += [r for r in warned if r not in bad]
    if stopped is not None:
        raise Stopped(f"{sum(r['status'] == 'completed' for r in rows)} of {len(rows)} case(s) completed; "
                      f"summary in {os.path.join(args.out, 'summary.csv')}", interrupt_exit_code(stopped))
    return EXIT_FAILED if bad else EXIT_OK


# -- sweep --------------------------------------------------------------------------------
def register_sweep(subparsers: Any) -> None:
    """``moreau sweep piston``: the engine over a grid of e, D and mu (see :mod:`.sweep_command`)."""
    from .sweep_command import param_spec, run_sweep

    sw = subparsers.add_parser("sweep", help="a parameter sweep of the piston engine (parallel, resumable)",
                               description="Run the piston engine over a grid of restitutions e, cylinder "
                                           "diameters D and skirt frictions mu (cartesian product) on a local "
                                           "process pool or a Dask cluster; one row per point in --out. An "
                                           "interrupted sweep resumes: "
                                           "run the same command again.",
                               epilog="table columns: e, D_mm (mm), clearance_um (µm), mean_speed_rpm and "
                                      "settled_speed_rpm (rev/min), "
                                      "energy_lost_J_mean and friction_loss_J_mean (J per cycle), "
                                      "max_impulse_Ns (N s), wall_time_s (s); "
                                      "counts per cycle (side_changes_mean, slaps_mean, impacts_mean); h is in τ "
                                      "(see --h). See moreau.problems.piston.study.piston_point.")
    sw.add_argument("problem", choices=["piston"], help="the system to sweep")
    sw.add_argument("--param", type=param_spec, action="append", metavar="NAME=VALUES",
                    help="e=start:stop:num (numpy.linspace), e=0,0.5,0.9 or e=0.9; names: e (restitution, "
                         "dimensionless), D (cylinder diameter, mm), mu (Coulomb friction of the skirt, "
                         "dimensionless, in [0, 10]); defaults e=0, D=80.04, mu=0")
    _engine_run_args(sw, cycles=5, h=3e-4)
    sw.add_argument("--out", default="sweep-out/piston_sweep.parquet", help="table, .parquet or .csv "
                    "(default sweep-out/piston_sweep.parquet)")
    sw.add_argument("--dask", metavar="ADDRESS", default=None, help="run on this Dask scheduler (tcp://host:8786)")
    sw.add_argument("--dask-timeout", type=float_in(0.0, None, lo_open=True), default=10.0, metavar="SECONDS",
                    help="how long to wait for the Dask scheduler to answer (default 10 s)")
    sw.add_argument("--workers", type=positive_int, default=None, help="local processes (default: the cores)")
    add_progress_options(sw, "bar")
    sw.set_defaults(func=run_sweep)
