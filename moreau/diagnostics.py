"""Measurements on trajectories shared by tests, benchmarks and notebooks."""

from __future__ import annotations

import numpy as np

from .result import Trajectory

__all__ = ["convergence_order", "max_penetration", "impact_energy_audit"]


def convergence_order(h, errors) -> float:
    """Observed order p of ``error ≈ C h^p``: least-squares slope of log(error) on log(h).

    Parameters
    ----------
    h, errors : array_like, shape (k,)
        Step sizes and the errors measured with them (k >= 2, all positive).
    """
    h = np.asarray(h, dtype=float)
    err = np.asarray(errors, dtype=float)
    if h.shape != err.shape or h.shape[0] < 2:
        raise ValueError(f"need at least two (h, error) pairs of equal length, got {h.shape} and {err.shape}")
    if np.any(h <= 0) or np.any(err <= 0) or not np.all(np.isfinite(err)):
        raise ValueError(f"steps and errors must be positive and finite, got h={h.tolist()}, errors={err.tolist()}")
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])


def max_penetration(traj: Trajectory) -> float:
    """Largest penetration ``max(0, -min g)`` over the recorded states (gap units)."""
    if traj.gaps.size == 0:
        return 0.0
    return max(0.0, -float(np.nanmin(traj.gaps)))


def impact_energy_audit(traj: Trajectory) -> float:
    """Smallest kinetic energy lost at any logged impact (J); negative means a gain."""
    if len(traj.impacts) == 0:
        return 0.0
    return float(traj.impacts.energy_lost.min())
