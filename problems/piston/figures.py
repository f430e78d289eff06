"""Figures of the piston engine: one 720° cycle against the crank angle like the paper's
Figs 2–4 (:func:`plot_cycle`), and the figures of parameter sweeps of
:func:`~moreau.problems.piston.study.piston_point` and
:func:`~moreau.problems.piston.study.bifurcation_samples` (:func:`plot_sweep`,
:func:`plot_section`, :func:`plot_side_change_angles`; also importable from
:mod:`moreau.problems.piston.study`)."""

from __future__ import annotations

import numpy as np

import moreau as mo

from .analysis import FOUR_PI, crank_angle, cycle_index, lateral_position, pin_position, side_changes, tilt
from .model import CORNERS
from .params import PistonParameters

__all__ = ["plot_cycle", "plot_sweep", "plot_section", "plot_side_change_angles"]


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


# -- figures of sweeps ----------------------------------------------------------------------
def _per_cycle(ax, df, x: str, col: str, label: str, color: str) -> None:
    """Each analyzed cycle as a dot, the mean as a line, against parameter ``x``."""
    xs = np.concatenate([[r[x]] * len(r[col]) for _, r in df.iterrows()]) if len(df) else []
    ys = np.concatenate([list(r[col]) for _, r in df.iterrows()]) if len(df) else []
    ax.plot(xs, ys, "o", ms=3, alpha=0.35, color=color, label="one cycle")
    ax.plot(df[x], [np.mean(v) for v in df[col]], "-", color=color, lw=1.4, label="mean")
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)


def _log_counts(ax) -> None:
    """A log y axis labelled 1, 2, 5, 10, 20, ... in plain numbers."""
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    ax.set_yscale("log")
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(ScalarFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())


def plot_sweep(df, x: str = "e", xlabel: str = "restitution e", title: str | None = None, log_x: bool = False):
    """Four panels of a :func:`~moreau.problems.piston.study.piston_point` sweep against one parameter: side changes,
    impacts and energy dissipated at the impacts per cycle (every cycle a dot, the mean
    a line), and the crank speed (mean over the analyzed cycles, and the energy-balance estimate of
    the settled speed when the table has it) with the largest penetration / clearance.

    Returns the matplotlib Figure (never shown).
    """
    import matplotlib.pyplot as plt

    ok = df[df["error"].isna()].sort_values(x)
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 9.5), sharex=True)
    _per_cycle(axes[0], ok, x, "side_changes", "side changes / cycle", "C0")
    axes[0].axhline(6, color="k", lw=0.6, ls="--", label="the paper's six")
    axes[0].legend(fontsize="small", loc="upper left")
    if len(ok) and max(max(v) for v in ok["side_changes"]) > 20:  # a rattling piston: hundreds
        _log_counts(axes[0])
    _per_cycle(axes[1], ok, x, "slaps", "slaps / cycle\n(impulse ≥ 1 % of max)", "C1")
    axes[1].plot(ok[x], ok["impacts_mean"], "--", color="0.5", lw=1, label="all logged impacts (mean)")
    axes[1].legend(fontsize="small", loc="upper left")
    counts = [x for v in ok["impacts"] for x in v if x > 0] if len(ok) else []
    if counts and max(counts) > 10 * min(counts):  # counts spanning decades
        _log_counts(axes[1])
    _per_cycle(axes[2], ok, x, "energy_lost_J", "energy lost at\nimpacts / cycle (J)", "C3")
    axes[3].plot(ok[x], ok["mean_speed_rpm"], "o-", ms=3, color="C2", label="mean over the cycles")
    if "settled_speed_rpm" in ok:  # tables recorded before the estimate existed lack it
        axes[3].plot(ok[x], ok["settled_speed_rpm"], "^--", ms=3, color="C2", label="settled (energy balance)")
        axes[3].legend(fontsize="small", loc="lower left")
    axes[3].set_ylabel("crank speed (rpm)", color="C2")
    axes[3].ticklabel_format(axis="y", useOffset=False, style="plain")
    axes[3].grid(alpha=0.3)
    tw = axes[3].twinx()
    tw.plot(ok[x], ok["max_penetration_ratio"], "s:", ms=3, color="C7")
    tw.set_ylabel("max penetration\n/ clearance", color="C7")
    tw.set_ylim(bottom=0)
    axes[3].set_xlabel(xlabel)
    if log_x:
        axes[3].set_xscale("log")
    if title:
        axes[0].set_title(title)
    fig.align_ylabels(axes)
    fig.tight_layout()
    return fig


def plot_section(long, x: str = "e", xlabel: str = "restitution e", title: str | None = None,
                 log_x: bool = False):
    """Bifurcation-like diagram: x_O3 and φ3 sampled once per cycle (rows of
    :func:`~moreau.problems.piston.study.section_long`) against a parameter, one colour per crank angle.

    Returns the matplotlib Figure (never shown).
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True)
    for j, (angle, g) in enumerate(long.groupby("angle_deg", sort=True)):
        kw = {"s": 5, "alpha": 0.6, "color": f"C{j}", "lw": 0, "label": f"φ1 = {angle:g}° (mod 720°)"}
        axes[0].scatter(g[x], g["x_O3"], **kw)
        axes[1].scatter(g[x], g["phi3_mrad"], **kw)
    for v in (-1.0, 1.0):
        axes[0].axhline(v, color="k", lw=0.5, ls="--")
    axes[0].set_ylabel("x_O3 / ((D−d)/2)")
    axes[1].set_ylabel("tilt φ3 (mrad)")
    axes[1].set_xlabel(xlabel)
    axes[0].legend(fontsize="small", markerscale=2)
    for ax in axes:
        ax.grid(alpha=0.3)
    if log_x:
        axes[1].set_xscale("log")
    if title:
        axes[0].set_title(title)
    fig.tight_layout()
    return fig


def plot_side_change_angles(df, x: str = "e", xlabel: str = "restitution e", title: str | None = None,
                            log_x: bool = False):
    """Crank angles (0–720°) of the side changes of the last analyzed cycle against a
    parameter, over the strokes; with the crank angle spent in flight per cycle.

    Returns the matplotlib Figure (never shown).
    """
    import matplotlib.pyplot as plt

    ok = df[df["error"].isna()].sort_values(x)
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7.5, 7), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    for _, r in ok.iterrows():
        ax.plot([r[x]] * len(r["side_change_angles_deg"]), r["side_change_angles_deg"], "o", ms=3.5, color="C0")
    for a, name in ((0, "expansion"), (180, "exhaust"), (360, "intake"), (540, "compression")):
        ax.axhspan(a, a + 180, color="0.5", alpha=0.08 if a % 360 == 0 else 0.0)
        ax.text(1.01, (a + 90) / 720, name, transform=ax.transAxes, rotation=90, va="center", fontsize="small")
    ax.set_ylim(0, 720)
    ax.set_yticks(np.arange(0, 721, 90))
    ax.set_ylabel("crank angle of a side change\n(deg from firing TDC)")
    ax.grid(alpha=0.3)
    _per_cycle(ax2, ok, x, "flight_deg", "in flight\n(deg / cycle)", "C4")
    ax2.set_xlabel(xlabel)
    if log_x:
        ax2.set_xscale("log")
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return fig
