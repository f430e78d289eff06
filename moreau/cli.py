"""The ``moreau`` command.

    moreau piston [--e E] [--D MM] [--cycles N] [--transient N] [--h H] [--solver S] [--out DIR]
    moreau ball [--e E] [--h H] [--t-end T] [--solver S] [--out DIR]
    moreau sweep piston --param e=0:1:21 [--param D=80.04] [--cycles N] [--out FILE] [--dask ADDRESS]
    moreau --version

Each subcommand writes its figures (PNG), a summary (CSV, also printed) and the
trajectory (``.npz``) into ``--out``; a rerun first removes the files an earlier run left
there for the same cases. Errors end the command with a one-line message. Ctrl-C and
SIGTERM are handled alike: what was computed is saved first (``*.partial.npz``, the
summary with every case's status, the sweep's finished points).

Exit codes (the same for every subcommand)
------------------------------------------
0
    Every run completed.
1
    A run failed (solver or simulation error, a case or sweep point that failed, an
    output that could not be written); what it computed is saved.
2
    The command could not start: a bad option or value, an unusable ``--out``, a missing
    optional dependency, an unreachable Dask scheduler.
130, 143
    Stopped by Ctrl-C (SIGINT: 130 = 128 + 2) or SIGTERM (143 = 128 + 15), after saving.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence

from ._cli_common import (
    EXIT_FAILED,
    EXIT_OK,
    EXIT_USAGE,
    CLIError,
    Stopped,
    _float_in,
    _int_at_least,
    _positive_int,
    output_dir,
    write_summary,
)
from ._cli_sweep import _cmd_sweep, _param_spec
from ._pool import Terminated, interrupt_exit_code, sigterm_as_interrupt

log = logging.getLogger("moreau.cli")


# -- ball ---------------------------------------------------------------------------------
def _cmd_ball(args) -> int:
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
    traj = _run(scene, (0.0, args.t_end), [args.h0], [0.0], args, out_stem=os.path.join(args.out, "ball"),
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
    fig.savefig(fig_path, dpi=120)
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
        return 1
    return 0


def _run(scene, t_span, q0, v0, args, out_stem: str, **kw):
    """simulate() that saves the trajectory in every case (completed, failed, interrupted)."""
    import moreau as mo

    try:
        traj = mo.simulate(scene, t_span, q0, v0, args.h, solver=args.solver, backend=args.backend,
                           progress=not args.no_progress, **kw)
    except (mo.SolverError, mo.SimulationError) as exc:
        path = exc.trajectory.save(out_stem + ".partial.npz")
        raise CLIError(f"{exc} (the {len(exc.trajectory)} records computed are saved in {path})") from None
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM, the partial run attached (or None)
        traj = getattr(exc, "trajectory", None)
        if traj is None:
            raise Stopped("nothing computed to save", interrupt_exit_code(exc)) from None
        path = traj.save(out_stem + ".partial.npz")
        raise Stopped(f"{traj.message or 'interrupted'}; the {len(traj)} records computed are saved in {path}",
                      interrupt_exit_code(exc)) from None
    path = traj.save(out_stem + (".npz" if traj.completed else ".partial.npz"))
    if traj.status == "interrupted":
        raise Stopped(f"{traj.message}; the {len(traj)} records computed are saved in {path}", interrupt_exit_code())
    if not traj.completed:
        raise CLIError(f"{traj.message}; the {len(traj)} records computed are saved in {path}")
    log.info("trajectory saved to %s", path)
    return traj


# -- piston -------------------------------------------------------------------------------
def _cmd_piston(args) -> int:
    from moreau.problems.piston.job import PAPER_CASES, Case, run_cases

    if args.e is None and args.D is None:
        pairs = list(PAPER_CASES)
    else:
        pairs = [(0.0 if args.e is None else args.e, 0.08004 if args.D is None else args.D / 1e3)]
    cases = [Case(e=e, D=D, h=args.h, cycles=args.cycles, transient=args.transient, solver=args.solver,
                  backend=args.backend,
                  drift_control=not args.no_drift_control, record_every=args.record_every)
             for e, D in pairs]
    output_dir(args.out)
    print(f"moreau piston: {len(cases)} case(s), {args.transient} transient + {args.cycles} analyzed "
          f"cycles each, h = {args.h:g} (non-dimensional time), solver {args.solver}; output in {args.out}/")
    stopped = None
    try:
        rows = run_cases(cases, args.out, progress=not args.no_progress, workers=args.workers)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: every case's row is attached
        rows, stopped = getattr(exc, "rows", None), exc
        if rows is None:
            raise
    write_summary(rows, os.path.join(args.out, "summary.csv"))
    bad = [r for r in rows if r["status"] != "completed"]
    for r in bad:
        saved = "partial trajectory saved" if r["status"] in ("failed", "interrupted") else "nothing saved"
        print(f"case e={r['e']}, D={r['D_mm']} mm {r['status']}: {saved}", file=sys.stderr)
    warned = [r for r in rows if r.get("warnings")]
    for r in warned:  # never reported as clean
        print(f"case e={r['e']}, D={r['D_mm']} mm completed WITH WARNINGS: {r['warnings']}", file=sys.stderr)
    bad += [r for r in warned if r not in bad]
    if stopped is not None:
        raise Stopped(f"{sum(r['status'] == 'completed' for r in rows)} of {len(rows)} case(s) completed; "
                      f"summary in {os.path.join(args.out, 'summary.csv')}", interrupt_exit_code(stopped))
    return EXIT_FAILED if bad else EXIT_OK


# -- entry point --------------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line (``moreau piston: error: ...``), exit code 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _engine_run_args(parser: argparse.ArgumentParser, cycles: int, h: float) -> None:
    """The options of a piston run shared by ``piston`` and ``sweep``."""
    from moreau.solvers import available_solvers

    parser.add_argument("--cycles", type=_positive_int, default=cycles,
                        help=f"engine cycles analyzed (default {cycles})")
    parser.add_argument("--transient", type=_int_at_least(0), default=1, help="cycles discarded first (default 1)")
    parser.add_argument("--h", type=_float_in(0.0, 0.05, lo_open=True), default=h,
                        help=f"time step in non-dimensional time τ = ωt (default {h:g})")
    parser.add_argument("--solver", choices=available_solvers(), default="exact",
                        help="contact solver (default exact: the dual active-set method, which runs "
                             "compiled; osqp, daqp and quadprog run on the Python path)")
    _backend_arg(parser)
    parser.add_argument("--no-drift-control", action="store_true",
                        help="do not project positions back onto the cylinder after each step")


def _backend_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--backend", choices=("auto", "compiled", "python"), default="auto",
                        help="where the time loop runs: compiled (numba), python (the reference "
                             "path, to compare), auto (compiled when the scene and solver allow; default)")


def build_parser() -> argparse.ArgumentParser:
    from moreau.solvers import available_solvers

    from . import __version__

    p = _Parser(prog="moreau", description="Non-smooth mechanics with the Moreau-Jean midpoint scheme.",
                epilog="exit codes: 0 completed, 1 a run failed or completed with warnings, 2 the command could not start "
                       "(options, --out, dependencies), 130/143 stopped by Ctrl-C/SIGTERM after saving")
    p.add_argument("--version", action="version", version=f"moreau {__version__}")
    p.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    b = sub.add_parser("ball", help="bouncing ball against its analytic solution")
    b.add_argument("--e", type=_float_in(0.0, 1.0), default=0.5, help="restitution in [0, 1] (default 0.5)")
    b.add_argument("--h0", type=_float_in(0.0, None, lo_open=True), default=1.0, help="drop height (m)")
    b.add_argument("--h", type=_float_in(0.0, None, lo_open=True), default=1e-4, help="time step (s)")
    b.add_argument("--t-end", type=_float_in(0.0, None, lo_open=True), default=2.0, help="end time (s)")
    b.add_argument("--solver", choices=available_solvers(), default="exact",
                   help="contact solver (default exact, compiled)")
    _backend_arg(b)
    b.add_argument("--record-every", type=_positive_int, default=1, metavar="K",
                   help="keep every K-th step (default 1; raise it for long runs)")
    b.add_argument("--out", default="ball-out", help="output directory")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    b.set_defaults(func=_cmd_ball)

    pi = sub.add_parser("piston", help="the paper's piston engine: figures, summary, trajectories",
                        description="Simulate the piston - connecting rod - crankshaft engine (the paper's "
                                    "three cases, or the one given by --e/--D), discard the transient, and "
                                    "write figures, summary.csv and the trajectories into --out.")
    pi.add_argument("--e", type=_float_in(0.0, 1.0), default=None, help="restitution in [0, 1]")
    pi.add_argument("--D", type=_float_in(80.0, 100.0, lo_open=True), default=None,
                    help="cylinder diameter in mm, > 80 (the piston's); paper: 80.04 and 80.2")
    _engine_run_args(pi, cycles=3, h=1e-4)
    pi.add_argument("--workers", type=_positive_int, default=None, help="parallel processes (default: one per case, up to the cores)")
    pi.add_argument("--record-every", type=_positive_int, default=None, metavar="K",
                    help="keep every K-th step (default: about one record per 0.1 degree of crank angle)")
    pi.add_argument("--out", default="piston-out", help="output directory (default piston-out); "
                    "a rerun first removes the files an earlier run left there for the same cases")
    pi.add_argument("--no-progress", action="store_true", help="no progress bars")
    pi.set_defaults(func=_cmd_piston)

    sw = sub.add_parser("sweep", help="a parameter sweep of the piston engine (parallel, resumable)",
                        description="Run the piston engine over a grid of restitutions e and cylinder "
                                    "diameters D (cartesian product) on a local process pool or a Dask "
                                    "cluster; one row per point in --out. An interrupted sweep resumes: "
                                    "run the same command again.")
    sw.add_argument("problem", choices=["piston"], help="the system to sweep")
    sw.add_argument("--param", type=_param_spec, action="append", metavar="NAME=VALUES",
                    help="e=start:stop:num (numpy.linspace), e=0,0.5,0.9 or e=0.9; names: e, D (mm); "
                         "defaults e=0, D=80.04")
    _engine_run_args(sw, cycles=5, h=3e-4)
    sw.add_argument("--out", default="sweep-out/piston_sweep.parquet", help="table, .parquet or .csv "
                    "(default sweep-out/piston_sweep.parquet)")
    sw.add_argument("--dask", metavar="ADDRESS", default=None, help="run on this Dask scheduler (tcp://host:8786)")
    sw.add_argument("--workers", type=_positive_int, default=None, help="local processes (default: the cores)")
    sw.add_argument("--no-progress", action="store_true", help="no progress bar")
    sw.set_defaults(func=_cmd_sweep)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; returns its exit code (see the module docstring)."""
    parser = build_parser()
    args = parser.parse_args(argv)  # bad options: argparse prints one line, exit 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    name = f"moreau {args.command}"
    with sigterm_as_interrupt():
        try:
            return args.func(args)
        except Stopped as exc:
            what = "terminated (SIGTERM)" if exc.code == 143 else "interrupted"
            print(f"{name}: {what}: {exc}", file=sys.stderr)
            return exc.code
        except KeyboardInterrupt as exc:
            print(f"{name}: {'terminated (SIGTERM)' if isinstance(exc, Terminated) else 'interrupted'}",
                  file=sys.stderr)
            return interrupt_exit_code(exc)
        except CLIError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr)
            return exc.code
        except ValueError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr)
            return EXIT_USAGE
        except ImportError as exc:
            print(f"{name}: error: a dependency is missing: {exc} (pip install -e \".[dev]\")", file=sys.stderr)
            return EXIT_USAGE
        except OSError as exc:  # e.g. the disk filled up while writing the results
            print(f"{name}: error: {exc}", file=sys.stderr)
            return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
