"""The ``moreau`` command and how packages add their own subcommands to it.

    moreau --version
    moreau [-v] COMMAND [options]      # moreau --help lists the commands installed

The core defines no problem-specific command. Every subcommand — the bundled ``piston``,
``ball`` and ``sweep`` as well as a user's own — is found through the Python entry-point
group ``moreau.commands`` (``ENTRY_POINT_GROUP``), so the library never imports a
problem, and any installed package can add ``moreau <name>``.

Adding a command
----------------
Declare an entry point whose name is the command's name and whose object is a
*registration function*; in ``pyproject.toml``::

    [project.entry-points."moreau.commands"]
    hello = "mypackage.cli:register_hello"

The function receives argparse's subparsers object, adds **one** parser with the entry
point's name, and sets its handler as the default ``func``; the handler receives the parsed
arguments and returns the exit code::

    def register_hello(subparsers):
        p = subparsers.add_parser("hello", help="say hello")
        p.add_argument("--name", default="world", help="who to greet")
        p.set_defaults(func=run_hello)

    def run_hello(args) -> int:
        print(f"hello, {args.name}")
        return 0

Registration runs on every ``moreau`` call (``--help`` lists every command), so it should
only describe options: import heavy modules inside the handler. A registration function
that fails, or adds no parser of its name, is skipped with a logged warning; the other
commands still work. When two packages register the same name, the first one found is
used and the other is named in a warning.

The handler's exceptions are reported in one line by ``main``: ``CLIError``
(its ``code``), ``Stopped`` (130/143), ``ValueError`` (2), ``ImportError`` (2: a
missing optional dependency), ``OSError`` (1); Ctrl-C and SIGTERM are handled alike. The
helpers a command needs are exported here: ``output_dir``, ``write_summary``, ``save_figure``,
``simulate_and_save``, the option types ``float_in``, ``positive_int``,
``int_at_least``, ``add_backend_option``, ``add_progress_options`` with
``progress_mode``, and ``interrupt_exit_code`` (the exit
code of a Ctrl-C or SIGTERM, for ``Stopped``).

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
import sys
from collections.abc import Callable, Sequence
from importlib.metadata import EntryPoint, entry_points
from typing import Any, NoReturn

from moreau.cli.common import (
    EXIT_FAILED,
    EXIT_OK,
    EXIT_USAGE,
    CLIError,
    Stopped,
    add_backend_option,
    add_progress_options,
    float_in,
    int_at_least,
    output_dir,
    positive_int,
    progress_mode,
    save_figure,
    simulate_and_save,
    write_summary,
)
from moreau.sweeps.pool import Terminated, interrupt_exit_code, sigterm_as_interrupt

__all__ = [
    "ENTRY_POINT_GROUP", "EXIT_OK", "EXIT_FAILED", "EXIT_USAGE", "CLIError", "Stopped",
    "add_backend_option", "add_progress_options", "build_parser", "command_entry_points", "float_in", "int_at_least",
    "interrupt_exit_code", "main", "register_compile",
    "output_dir", "positive_int", "progress_mode", "save_figure", "simulate_and_save", "write_summary",
]

log = logging.getLogger("moreau.cli")

#: the entry-point group in which packages register ``moreau`` subcommands
ENTRY_POINT_GROUP = "moreau.commands"

Handler = Callable[[argparse.Namespace], int]


class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line (``moreau piston: error: ...``), exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def command_entry_points() -> list[EntryPoint]:
    """The registered commands' entry points, one per name (the first found), by name."""
    chosen: dict[str, EntryPoint] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in chosen:
            if ep.value != chosen[ep.name].value:
                log.warning("moreau command %r is registered twice (%s and %s); using the first",
                            ep.name, _origin(chosen[ep.name]), _origin(ep))
            continue
        chosen[ep.name] = ep
    return [chosen[name] for name in sorted(chosen)]


def _origin(ep: EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return f"{ep.value} from {dist.name}" if dist is not None else ep.value


def _register(ep: EntryPoint, sub: Any) -> None:
    """Call one registration function; skip it (warning) when it fails or adds nothing."""
    try:
        register = ep.load()
        register(sub)
    except Exception as exc:  # noqa: BLE001 - a broken plug-in must not break every command
        log.warning("moreau command %r (%s) could not be registered: %s: %s",
                    ep.name, _origin(ep), type(exc).__name__, exc)
        _drop(sub, ep.name)
        return
    parser = sub.choices.get(ep.name)
    if parser is None:
        log.warning("moreau command %r (%s) added no parser named %r; skipped", ep.name, _origin(ep), ep.name)
    elif parser.get_default("func") is None:
        log.warning("moreau command %r (%s) set no handler (set_defaults(func=...)); skipped", ep.name, _origin(ep))
        _drop(sub, ep.name)


def _drop(sub: Any, name: str) -> None:
    """Remove a command's parser and its line in ``--help``."""
    sub.choices.pop(name, None)
    sub._choices_actions[:] = [a for a in sub._choices_actions if a.dest != name]


def build_parser() -> argparse.ArgumentParser:
    """The ``moreau`` parser with every registered command."""
    from moreau.core.version import __version__

    p = _Parser(prog="moreau", description="Non-smooth mechanics with the Moreau-Jean midpoint scheme.",
                epilog="exit codes: 0 completed, 1 a run failed or completed with warnings, 2 the command could "
                       "not start (options, --out, dependencies), 130/143 stopped by Ctrl-C/SIGTERM after saving")
    p.add_argument("--version", action="version", version=f"moreau {__version__}")
    p.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="COMMAND")
    eps = command_entry_points()
    if not eps:
        log.warning("no moreau commands are registered (entry-point group %r): is the moreau-jean "
                    "distribution installed? (pip install -e .)", ENTRY_POINT_GROUP)
    for ep in eps:
        _register(ep, sub)
    return p


def register_compile(subparsers: Any) -> None:
    """``moreau compile``: load the compiled time loop, or compile it into numba's cache."""
    p = subparsers.add_parser(
        "compile", help="compile the time loop into numba's cache now (e.g. for a container image or a "
                        "cluster's shared environment; NUMBA_CACHE_DIR chooses where)")
    p.set_defaults(func=_run_compile)


def _run_compile(args: argparse.Namespace) -> int:
    from moreau.core.jitcache import cache_dir
    from moreau.run.simulation import ensure_compiled

    seconds = ensure_compiled()  # everything a run can load: warms a cache once
    print(f"moreau compile: the time loop is in {cache_dir() or 'no cache (not writable)'} "
          f"({seconds:.1f} s to load or compile)")
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; returns its exit code (see the module docstring)."""
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    parser = build_parser()
    args = parser.parse_args(argv)  # bad options: argparse prints one line, exit 2
    if args.verbose:
        logging.getLogger().setLevel(logging.INFO)
    name = f"moreau {args.command}"
    func: Handler = args.func
    with sigterm_as_interrupt():
        try:
            return func(args)
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
