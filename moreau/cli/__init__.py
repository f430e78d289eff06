"""The ``moreau`` command: subcommands registered by entry points (the bundled problems
register ``ball``, ``piston`` and ``sweep``), their shared options and exit codes.

May import: everything else in moreau (it is the outermost layer).
"""

from moreau.cli.command import (  # noqa: F401 - the command-line API
    ENTRY_POINT_GROUP,
    EXIT_FAILED,
    EXIT_OK,
    EXIT_USAGE,
    CLIError,
    Stopped,
    add_backend_option,
    build_parser,
    command_entry_points,
    float_in,
    int_at_least,
    interrupt_exit_code,
    main,
    output_dir,
    positive_int,
    register_compile,
    simulate_and_save,
    write_summary,
)

__all__ = [
    "ENTRY_POINT_GROUP",
    "EXIT_OK",
    "EXIT_FAILED",
    "EXIT_USAGE",
    "CLIError",
    "Stopped",
    "add_backend_option",
    "build_parser",
    "command_entry_points",
    "float_in",
    "int_at_least",
    "interrupt_exit_code",
    "main",
    "register_compile",
    "output_dir",
    "positive_int",
    "simulate_and_save",
    "write_summary",
]
