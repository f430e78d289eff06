"""Matplotlib helpers: each takes ``ax=None`` and returns the Axes; none calls ``show()``.

matplotlib is imported when a function is called, not when moreau is imported.
"""

from __future__ import annotations

import numpy as np

from moreau.results.trajectory import Trajectory

__all__ = ["plot_coordinates", "plot_gaps", "plot_energy", "new_axes"]


def new_axes(ax=None, **fig_kw):
    """Return ``ax`` or a fresh Axes on a new figure (Agg-safe)."""
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    _, ax = plt.subplots(**fig_kw)
    return ax


def plot_coordinates(traj: Trajectory, index: int = 0, ax=None, label: str | None = None, **kw):
    """q[:, index] against t."""
    ax = new_axes(ax)
    ax.plot(traj.t, traj.q[:, index], label=label or f"q[{index}]", **kw)
    ax.set_xlabel("t")
    return ax


def plot_gaps(traj: Trajectory, ax=None, **kw):
    """Every contact row's gap against t, with impacts marked."""
    ax = new_axes(ax)
    for j, name in enumerate(traj.row_names):
        ax.plot(traj.t, traj.gaps[:, j], label=name, **kw)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("t")
    ax.set_ylabel("gap g(q)")
    if traj.row_names:
        ax.legend(loc="best", fontsize="small")
    return ax


def plot_energy(traj: Trajectory, ax=None, **kw):
    """Mechanical energy against t, with the impacts' losses marked."""
    ax = new_axes(ax)
    if traj.energy is None:
        raise ValueError("this trajectory has no energy (simulate(..., energy=True))")
    ax.plot(traj.t, traj.energy, **kw)
    if len(traj.impacts):
        ax.plot(traj.impacts.t, np.interp(traj.impacts.t, traj.t, traj.energy), "x", ms=4, label="impacts")
        ax.legend(loc="best", fontsize="small")
    ax.set_xlabel("t")
    ax.set_ylabel("energy (J)")
    return ax
