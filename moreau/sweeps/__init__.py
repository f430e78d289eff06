"""Parameter sweeps over a process pool or Dask, recorded point by point and resumable
(:func:`sweep`), and the worker pool shared with the ``moreau`` command.

May import: :mod:`moreau.core` (and calls only the user's function).
"""

from moreau.sweeps.driver import SweepLockedError, grid_points, point_key, read_table, source_digest, sweep

__all__ = ["sweep", "grid_points", "point_key", "read_table", "source_digest", "SweepLockedError"]
