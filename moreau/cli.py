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
import csv
import logging
import os
import sys
import tempfile
from collections.abc import Sequence

from ._pool import Terminated, interrupt_exit_code, sigterm_as_interrupt

log = logging.getLogger("moreau.cli")


EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class CLIError(Exception):
    """A problem reported in one line; ``code`` is the exit code (1: a run failed, 2: the
    command could not start)."""

    def __init__(self, message: str, code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        self.code = code


class Stopped(Exception):
    """The command was stopped by Ctrl-C or SIGTERM after saving; ``code`` is 130 or 143."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


def output_dir(path: str, option: str = "--out") -> str:
    """Create the output directory ``path`` (and its parents), or a one-line ``CLIError``
    (exit code 2) naming it: a path that is a file or lies inside a file, no permission."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise CLIError(f"{option} {path!r} is a file, not a directory", EXIT_USAGE)
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"{option} {path!r}: cannot create the directory ({exc.strerror or exc})", EXIT_USAGE) from None
    if not os.access(path, os.W_OK):
        raise CLIError(f"{option} {path!r}: the directory is not writable", EXIT_USAGE)
    return path


def _float_in(lo: float | None = None, hi: float | None = None, lo_open: bool = False):
    def parse(text: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if x != x or (lo is not None and (x < lo or (lo_open and x == lo))) or (hi is not None and x > hi):
            lo_s = "-inf" if lo is None else f"{lo:g}"
            hi_s = "inf" if hi is None else f"{hi:g}"
            raise argparse.ArgumentTypeError(f"{text} is outside {'(' if lo_open else '['}{lo_s}, {hi_s}]")
        return x

    return parse


def _positive_int(text: str) -> int:
    try:
        x = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if x < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {x}")
    return x


def _int_at_least(lo: int):
    def parse(text: str) -> int:
        try:
            x = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if x < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {x}")
        return x

    return parse


def write_summary(rows: list[dict], path: str) -> None:
    """Write rows of a summary to CSV and print them as a table."""
    if not rows:
        return
    keys = list(rows[0])
    fd, tmp = tempfile.mkstemp(prefix=os.path.basename(path) + ".", suffix=".tmp", dir=os.path.dirname(path) or ".")
    try:
        with os.fdopen(fd, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(rows)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    widths = {k: max(len(k), *(len(_fmt(r[k])) for r in rows)) for k in keys}
    print("  ".join(k.rjust(widths[k]) for k in keys))
    for r in rows:
        print("  ".join(_fmt(r[k]).rjust(widths[k]) for k in keys))
    print(f"summary written to {path}")


def _fmt(x) -> str:
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)


# -- ball ---------------------------------------------------------------------------------
def _cmd_ball(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import moreau as mo
    from problems.bouncing_ball import BallSolution, bouncing_ball

    output_dir(args.out)
    for name in ("ball.npz", "ball.partial.npz", "ball.png", "ball_summary.csv"):  # a rerun: nothing old left
        if os.path.exists(os.path.join(args.out, name)):
            os.remove(os.path.join(args.out, name))
    scene = bouncing_ball(args.e)
    sol = BallSolution(args.h0, args.e)
    traj = _run(scene, (0.0, args.t_end), [args.h0], [0.0], args, out_stem=os.path.join(args.out, "ball"),
                record_every=args.record_every)
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
        "us_per_step": traj.stats.us_per_step,
    }
    write_summary([row], os.path.join(args.out, "ball_summary.csv"))
    print(f"figure written to {fig_path}")
    return 0


def _run(scene, t_span, q0, v0, args, out_stem: str, **kw):
    """simulate() that saves the trajectory in every case (completed, failed, interrupted)."""
    import moreau as mo

    try:
        traj = mo.simulate(scene, t_span, q0, v0, args.h, solver=args.solver,
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
    from problems.piston.job import PAPER_CASES, Case, run_cases

    if args.e is None and args.D is None:
        pairs = list(PAPER_CASES)
    else:
        pairs = [(0.0 if args.e is None else args.e, 0.08004 if args.D is None else args.D / 1e3)]
    cases = [Case(e=e, D=D, h=args.h, cycles=args.cycles, transient=args.transient, solver=args.solver,
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
    if stopped is not None:
        raise Stopped(f"{sum(r['status'] == 'completed' for r in rows)} of {len(rows)} case(s) completed; "
                      f"summary in {os.path.join(args.out, 'summary.csv')}", interrupt_exit_code(stopped))
    return EXIT_FAILED if bad else EXIT_OK


# -- sweep --------------------------------------------------------------------------------
_SWEEP_PARAMS = {"e": ("e", 0.0, 1.0, False), "D": ("D_mm", 80.0, 100.0, True)}


def _param_spec(text: str) -> tuple[str, list[float]]:
    """``NAME=start:stop:num`` (numpy.linspace), ``NAME=a,b,c`` or ``NAME=value``."""
    name, sep, spec = text.partition("=")
    name = name.strip()
    if not sep or not spec.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUES, got {text!r}")
    if name not in _SWEEP_PARAMS:
        raise argparse.ArgumentTypeError(f"unknown parameter {name!r}; choose from {', '.join(_SWEEP_PARAMS)}")
    try:
        if ":" in spec:
            parts = spec.split(":")
            if len(parts) != 3:
                raise ValueError
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
            if n < 1:
                raise ValueError
            import numpy as np

            values = [float(x) for x in np.linspace(a, b, n)]
        else:
            values = [float(x) for x in spec.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}={spec}: give start:stop:num (num >= 1 points), "
                                         "a comma list or one number") from None
    _, lo, hi, lo_open = _SWEEP_PARAMS[name]
    for x in values:
        if x != x or x < lo or (lo_open and x == lo) or x > hi:
            interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"
            raise argparse.ArgumentTypeError(f"{name}={spec}: {x:g} is outside {interval}")
    return name, values


def _sweep_out(path: str) -> str:
    """The sweep table's path: its directory is created, the path itself must not be a
    directory (one-line ``CLIError``, exit code 2)."""
    if os.path.isdir(path):
        raise CLIError(f"--out {path!r} is a directory; give the table's file name (.parquet or .csv)", EXIT_USAGE)
    parent = os.path.dirname(os.path.abspath(path))
    if os.path.exists(parent) and not os.path.isdir(parent):
        raise CLIError(f"--out {path!r}: {parent!r} is a file, not a directory", EXIT_USAGE)
    try:
        os.makedirs(parent, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"--out {path!r}: cannot create the directory {parent!r} ({exc.strerror or exc})",
                       EXIT_USAGE) from None
    parts = path + ".parts"
    if os.path.exists(parts) and not os.path.isdir(parts):
        raise CLIError(f"--out {path!r}: {parts!r} (where finished points are kept) is a file", EXIT_USAGE)
    return path


def _cmd_sweep(args) -> int:
    from moreau.sweeps import sweep
    from problems.piston.study import piston_cache_key, piston_point

    try:
        import pandas as pd
    except ImportError:
        raise CLIError("moreau sweep needs pandas: pip install 'moreau[sweeps]'", EXIT_USAGE) from None
    given: dict[str, list[float]] = {}
    for name, values in args.param or []:
        if name in given:
            raise ValueError(f"--param {name} given twice")
        given[name] = values
    if args.dask is not None and ":" not in args.dask:
        raise ValueError(f"--dask {args.dask!r} is not a scheduler address such as tcp://host:8786")
    _sweep_out(args.out)
    grid = {_SWEEP_PARAMS[n][0]: v for n, v in given.items()}
    grid.setdefault("e", [0.0])
    grid.setdefault("D_mm", [80.04])
    grid.update(cycles=args.cycles, transient=args.transient, h=args.h, solver=args.solver,
                drift_control=not args.no_drift_control)
    n = len(grid["e"]) * len(grid["D_mm"])
    where = f"Dask scheduler {args.dask}" if args.dask else f"{args.workers or os.cpu_count()} processes"
    print(f"moreau sweep piston: {n} point(s), {args.transient} transient + {args.cycles} analyzed cycles "
          f"each, h = {args.h:g}, on {where}; table {args.out} (finished points kept in {args.out}.parts/)")
    try:
        df = sweep(piston_point, grid, executor=args.dask or "processes", workers=args.workers,
                   out=args.out, progress=not args.no_progress, cache_key=piston_cache_key())
    except ImportError as exc:
        raise CLIError(str(exc), EXIT_USAGE) from None
    except ConnectionError as exc:  # an unreachable Dask scheduler
        raise CLIError(str(exc), EXIT_USAGE) from None
    except KeyboardInterrupt as exc:
        raise Stopped(f"the finished points are kept in {args.out}.parts/ and the table {args.out} lists every "
                      "point (error 'not computed' for the others); run the same command to resume",
                      interrupt_exit_code(exc)) from None
    cols = ["e", "D_mm", "side_changes_mean", "slaps_mean", "impacts_mean", "energy_lost_J_mean", "rpm",
            "max_penetration_ratio", "error"]
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(df[[c for c in cols if c in df.columns]].to_string(index=False, float_format=lambda x: f"{x:.6g}"))
    print(f"table written to {args.out}")
    bad = int(df["error"].notna().sum())
    if bad:
        print(f"{bad} point(s) failed: see the error column", file=sys.stderr)
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
    parser.add_argument("--solver", choices=available_solvers(), default="enum",
                        help="contact solver (default enum, the fastest exact one here)")
    parser.add_argument("--no-drift-control", action="store_true",
                        help="do not project positions back onto the cylinder after each step")


def build_parser() -> argparse.ArgumentParser:
    from moreau.solvers import available_solvers

    from . import __version__

    p = _Parser(prog="moreau", description="Non-smooth mechanics with the Moreau-Jean midpoint scheme.",
                epilog="exit codes: 0 completed, 1 a run failed, 2 the command could not start "
                       "(options, --out, dependencies), 130/143 stopped by Ctrl-C/SIGTERM after saving")
    p.add_argument("--version", action="version", version=f"moreau {__version__}")
    p.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    b = sub.add_parser("ball", help="bouncing ball against its analytic solution")
    b.add_argument("--e", type=_float_in(0.0, 1.0), default=0.5, help="restitution in [0, 1] (default 0.5)")
    b.add_argument("--h0", type=_float_in(0.0, None, lo_open=True), default=1.0, help="drop height (m)")
    b.add_argument("--h", type=_float_in(0.0, None, lo_open=True), default=1e-4, help="time step (s)")
    b.add_argument("--t-end", type=_float_in(0.0, None, lo_open=True), default=2.0, help="end time (s)")
    b.add_argument("--solver", choices=available_solvers(), default="osqp")
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
