"""``moreau sweep piston``: the piston engine over a grid of e, D and the skirt friction mu; registered by
:func:`moreau.problems.commands.register_sweep`."""

from __future__ import annotations

import argparse
import os
import sys

from moreau.cli import (
    EXIT_FAILED,
    EXIT_OK,
    EXIT_USAGE,
    CLIError,
    Stopped,
    interrupt_exit_code,
    output_dir,
    progress_mode,
)

__all__ = ["param_spec", "run_sweep"]

#: name on the command line: (point argument, lowest, highest, lowest excluded)
_SWEEP_PARAMS = {"e": ("e", 0.0, 1.0, False), "D": ("D_mm", 80.0, 100.0, True), "mu": ("mu", 0.0, 10.0, False)}


def param_spec(text: str) -> tuple[str, list[float]]:
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
    try:  # the sweep writes there first: an unusable --out stops it before any point runs
        os.makedirs(parts, exist_ok=True)
        output_dir(parts, "--out")
    except OSError as exc:
        raise CLIError(f"--out {path!r}: cannot write {parts!r} ({exc.strerror or exc})", EXIT_USAGE) from None
    return path


def run_sweep(args: argparse.Namespace) -> int:
    """Run the sweep and print its table; exit code 1 when a point failed."""
    from moreau.problems.piston.study import piston_cache_key, piston_point
    from moreau.sweeps import sweep

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
    grid.setdefault("mu", [0.0])
    grid.update(cycles=args.cycles, transient=args.transient, h=args.h, solver=args.solver, backend=args.backend,
                drift_control=not args.no_drift_control)
    n = len(grid["e"]) * len(grid["D_mm"]) * len(grid["mu"])
    where = f"Dask scheduler {args.dask}" if args.dask else f"{args.workers or os.cpu_count()} processes"
    print(f"moreau sweep piston: {n} point(s), {args.transient} transient + {args.cycles} analyzed cycles "
          f"each, h = {args.h:g} τ, on {where}; table {args.out} (finished points kept in {args.out}.parts/)")
    import moreau as mo
    from moreau.problems.piston.model import piston_model
    from moreau.problems.piston.params import PistonParameters

    # here, once, the variants the points run (with friction where some mu > 0): the workers load them
    bars, report = progress_mode(args)  # off a terminal a line per finished point
    mo.ensure_compiled(*(piston_model(PistonParameters(mu=mu)).scene for mu in {min(grid["mu"]), max(grid["mu"])}))
    try:
        df = sweep(piston_point, grid, executor=args.dask or "processes", workers=args.workers,
                   out=args.out, progress=bars, cache_key=piston_cache_key(),
                   dask_timeout=args.dask_timeout, report=report)
    except ImportError as exc:
        raise CLIError(str(exc), EXIT_USAGE) from None
    except ConnectionError as exc:  # an unreachable Dask scheduler
        raise CLIError(str(exc), EXIT_USAGE) from None
    except KeyboardInterrupt as exc:
        raise Stopped(f"the finished points are kept in {args.out}.parts/ and the table {args.out} lists every "
                      "point (error 'not computed' for the others); run the same command to resume",
                      interrupt_exit_code(exc)) from None
    cols = ["e", "D_mm", "mu", "side_changes_mean", "slaps_mean", "impacts_mean", "energy_lost_J_mean",
            "friction_loss_J_mean", "mean_speed_rpm", "settled_speed_rpm", "max_penetration_ratio", "error"]
    if not any(grid["mu"]):  # a frictionless sweep: its table as before
        cols = [c for c in cols if c not in ("mu", "friction_loss_J_mean")]
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(df[[c for c in cols if c in df.columns]].to_string(index=False, float_format=lambda x: f"{x:.6g}"))
    print(f"table written to {args.out}")
    bad = int(df["error"].notna().sum())
    if bad:
        print(f"{bad} point(s) failed: see the error column", file=sys.stderr)
    return EXIT_FAILED if bad else EXIT_OK
