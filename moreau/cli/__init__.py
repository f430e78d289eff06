"""The ``moreau`` command: subcommands registered by entry points (the bundled problems
register ``ball``, ``piston`` and ``sweep``), their shared options and exit codes.

May import: everything else in moreau (it is the outermost layer).
"""

from moreau.cli import command as _command
from moreau.cli.command import *  # noqa: F403 - the command-line API, as listed there

__all__ = list(_command.__all__)
