"""Helpers of the ``moreau`` command: exit codes, one-line errors, option parsers, output
paths and the summary table."""

from __future__ import annotations

import argparse
import csv
import os
import tempfile

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
