"""What a run returns: the :class:`~moreau.results.trajectory.Trajectory` with its impact
log and solver statistics, saving and loading, export to xarray/pandas, energy and
convergence diagnostics, and plots.

May import: :mod:`moreau.core`, :mod:`moreau.model`.
"""
