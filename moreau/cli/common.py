"""Helpers of the ``moreau`` command and of the commands registered with it: exit codes,
one-line errors, option parsers, output paths, the summary table and a run that saves its
trajectory whatever happens. Re-exported by :mod:`moreau.cli`, which documents them."""

from __future__ import annotations

import argparse
import csv
import logging
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from moreau.sweeps.pool import interrupt_exit_code

if TYPE_CHECKING:
    from moreau.model.scene import Scene
    from moreau.results.trajectory import Trajectory

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2

log = logging.getLogger("moreau.cli")


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
    try:  # a file can be made there (os.access misses read-only mounts for root, ACLs)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise CLIError(f"{option} {path!r}: the directory is not writable ({exc.strerror or exc})",
                       EXIT_USAGE) from None
    return path


def float_in(lo: float | None = None, hi: float | None = None, lo_open: bool = False) -> Callable[[str], float]:
    """An argparse ``type`` for a float in [lo, hi] ((lo, hi] with ``lo_open``); a value
    outside, NaN or a non-number is an error naming it (``2 is outside [0, 1]``)."""

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


def positive_int(text: str) -> int:
    """An argparse ``type`` for an integer >= 1."""
    try:
        x = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if x < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {x}")
    return x


def int_at_least(lo: int) -> Callable[[str], int]:
    """An argparse ``type`` for an integer >= ``lo``."""

    def parse(text: str) -> int:
        try:
            x = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if x < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {x}")
        return x

    return parse


def write_summary(rows: list[dict[str, Any]], path: str) -> None:
    """Print rows of a summary as a table, then write them to CSV (through a temporary
    file renamed into place). An ``OSError`` names the file; the table was printed."""
    if not rows:
        return
    keys = list(rows[0])
    widths = {k: max(len(k), *(len(_fmt(r[k])) for r in rows)) for k in keys}
    print("  ".join(k.rjust(widths[k]) for k in keys))
    for r in rows:
        print("  ".join(_fmt(r[k]).rjust(widths[k]) for k in keys))
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=os.path.basename(path) + ".", suffix=".tmp",
                                   dir=os.path.dirname(path) or ".")
        with os.fdopen(fd, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(rows)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes it 0600; the user's default, as every other output
        os.replace(tmp, path)
    except OSError as exc:
        if tmp is not None and os.path.exists(tmp):
            os.remove(tmp)
        raise OSError(exc.errno, f"could not write the summary {path}: {exc.strerror or exc}") from exc
    except BaseException:
        if tmp is not None and os.path.exists(tmp):
            os.remove(tmp)
        raise
    print(f"summary written to {path}")


def save_figure(fig: Any, path: str, dpi: int = 110) -> None:
    """Save a matplotlib figure under a unique temporary name, then rename it into place;
    an ``OSError`` names ``path`` (a full disk says "[Errno 28] ...: 'out/ball.png'")."""
    tmp = f"{path}.{os.getpid()}.tmp.png"
    try:
        fig.savefig(tmp, dpi=dpi)
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.remove(tmp)
        if isinstance(exc, OSError) and exc.filename in (None, tmp):
            raise OSError(exc.errno, exc.strerror or str(exc), path) from exc
        raise


def _umask() -> int:
    """The process's file-creation mask (read without changing it where /proc tells it)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)  # elsewhere: the classic read-and-restore
    os.umask(mask)
    return mask


def _fmt(x: object) -> str:
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)


def add_progress_options(parser: argparse.ArgumentParser, what: str = "bar") -> None:
    """``--no-progress`` (no progress ``what``) and ``--progress`` (also where the output is
    not a terminal; by default only on one)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--no-progress", action="store_true", help=f"no progress {what}")
    group.add_argument("--progress", action="store_true",
                       help=f"progress {what} also where the output is not a terminal (a file, a pipe)")


def progress_mode(args: argparse.Namespace) -> tuple[bool, Callable[[str], None] | None]:
    """``(bars, report)`` of :func:`add_progress_options`' flags: bars on a terminal (or with
    ``--progress``); elsewhere ``report`` prints one line at a time, at once (a log sees each
    as it ends), unless ``--no-progress``."""
    bars = bool(args.progress) or (not args.no_progress and sys.stderr.isatty())
    return bars, (None if bars or args.no_progress else _said)


def _said(line: str) -> None:
    print(line, flush=True)


def add_backend_option(parser: argparse.ArgumentParser) -> None:
    """``--backend auto|compiled|python`` (see :func:`moreau.simulate`)."""
    parser.add_argument("--backend", choices=("auto", "compiled", "python"), default="auto",
                        help="kept for existing scripts: every run is compiled (numba); 'python' is "
                             "deprecated and runs compiled too")


def simulate_and_save(scene: Scene, t_span: tuple[float, float], q0: Sequence[float], v0: Sequence[float],
                      h: float, out_stem: str, **kwargs: Any) -> Trajectory:
    """:func:`moreau.simulate` that saves the trajectory in every case: ``out_stem.npz``
    when it completed, ``out_stem.partial.npz`` otherwise.

    Raises
    ------
    CLIError
        The run failed (solver or simulation error, or it stopped early); what it computed
        is saved and the message says where.
    Stopped
        Ctrl-C or SIGTERM stopped it (exit code 130 or 143), after saving.
    """
    import moreau as mo

    try:
        traj = mo.simulate(scene, t_span, q0, v0, h, **kwargs)
    except (mo.SolverError, mo.SimulationError) as exc:
        if exc.trajectory is None:
            raise CLIError(f"{exc} (nothing computed to save)") from None
        path = exc.trajectory.save(out_stem + ".partial.npz")
        raise CLIError(f"{exc} (the {len(exc.trajectory)} records computed are saved in {path})") from None
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM, the partial run attached (or None)
        partial: Trajectory | None = getattr(exc, "trajectory", None)
        if partial is None:
            raise Stopped("nothing computed to save", interrupt_exit_code(exc)) from None
        path = partial.save(out_stem + ".partial.npz")
        raise Stopped(f"{partial.message or 'interrupted'}; the {len(partial)} records computed are saved in {path}",
                      interrupt_exit_code(exc)) from None
    path = traj.save(out_stem + (".npz" if traj.completed else ".partial.npz"))
    if traj.completed and os.path.exists(out_stem + ".partial.npz"):  # an earlier, stopped run's
        os.remove(out_stem + ".partial.npz")
    if traj.status == "interrupted":
        raise Stopped(f"{traj.message}; the {len(traj)} records computed are saved in {path}", interrupt_exit_code())
    if not traj.completed:
        raise CLIError(f"{traj.message}; the {len(traj)} records computed are saved in {path}")
    log.info("trajectory saved to %s", path)
    return traj
