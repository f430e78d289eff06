"""The package's version, read from the installed distribution's metadata."""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

__all__ = ["DISTRIBUTION", "__version__"]

#: the distribution's name on the package index; the import name is ``moreau``
DISTRIBUTION = "moreau-jean"

try:
    __version__ = _version(DISTRIBUTION)
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
