"""Figures like the paper's Figs 2–4: one 720° cycle against the crank angle."""

from __future__ import annotations

import numpy as np

import moreau as mo

from .analysis import FOUR_PI, crank_angle, cycle_index, lateral_position, pin_position, side_changes, tilt
from .model import CORNERS
from .params import PistonParameters

__all__ = ["plot_cycle"]


def plot_cycle(traj: mo.Trajectory, params: PistonParameters, cycle: int, title: str | None = None, fig=None):
    """Four panels against the crank angle φ1 (0–720° from firing TDC) for one cycle:
    the pin's lateral position x_O3 (in half-clearances), its height y_O3 (in l1), the
    piston tilt φ3, and which corners carry a contact impulse; side changes are marked.

    Returns the matplotlib Figure (never shown).
    """
    import matplotlib.pyplot as plt

    sel = cycle_index(traj) == cycle
    if not sel.any():
        raise ValueError(f"cycle {cycle} is not in the trajectory (cycles {np.unique(cycle_index(traj)).tolist()})")
    deg = np.degrees(crank_angle(traj)[sel] - FOUR_PI * cycle)
    x = lateral_position(traj, params)[sel]
    _, y = pin_position(traj, params)
    y = y[sel]
    phi3 = tilt(traj)[sel]
    P = traj.impulses[sel]
    idx, new_side = side_changes(traj)
    keep = cycle_index(traj)[idx] == cycle
    ch_deg = np.degrees(crank_angle(traj)[idx[keep]] - FOUR_PI * cycle)

    if fig is None:
        fig = plt.figure(figsize=(8, 8))
    axes = fig.subplots(4, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2, 2, 1.6]})
    axes[0].plot(deg, x, lw=0.9)
    axes[0].axhline(1.0, color="k", lw=0.5, ls="--")
    axes[0].axhline(-1.0, color="k", lw=0.5, ls="--")
    axes[0].set_ylabel("x_O3 / ((D−d)/2)")
    axes[1].plot(deg, y, lw=0.9)
    axes[1].set_ylabel("y_O3 / l1")
    axes[2].plot(deg, 1e3 * phi3, lw=0.9)
    axes[2].set_ylabel("φ3 (mrad)")
    for j in range(len(CORNERS)):
        on = P[:, j] > 0
        axes[3].fill_between(deg, j - 0.4, j + 0.4, where=on, step="mid", color=f"C{j}", lw=0)
    axes[3].set_yticks(range(4), CORNERS, fontsize="small")
    axes[3].set_ylim(-0.6, 3.6)
    axes[3].set_ylabel("contact")
    axes[3].set_xlabel("crank angle φ1 (deg from firing TDC)")
    axes[3].set_xlim(0, 720)
    axes[3].set_xticks(np.arange(0, 721, 90))
    for ax in axes:
        for a in ch_deg:
            ax.axvline(a, color="gray", lw=0.6, ls=":")
        ax.grid(alpha=0.25)
    axes[0].set_title(title or f"cycle {cycle}: {keep.sum()} side changes")
    fig.align_ylabels(axes)
    fig.tight_layout()
    return fig
