"""Work–precision study, part 4: the output — tables printed by the command, the
cheapest configuration per target error, the CSV and the figure."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence

import numpy as np
from wp_configs import SOLVERS, Config, Run
from wp_problems import Problem
from wp_study import fit_orders


def _fmt(x) -> str:
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return f"{x:.3g}"


def format_table(runs: Sequence[Run], problems: Sequence[Problem]) -> str:
    """One table per problem: configuration, h, wall time, the errors."""
    lines = []
    for p in problems:
        rs = [r for r in runs if r.problem == p.name]
        if not rs:
            continue
        extra = ["impacts"] if p.name in ("ball", "pendulum") else (
            ["impacts_run", "side_changes_run", "penetration_run"] if p.name.startswith("piston") else [])
        cols = list(p.metrics) + extra
        lines.append(f"\n== {p.name}  (primary error: {p.primary}) ==")
        head = f"{'configuration':<24} {'h':>8} {'wall[s]':>8} {'fb':>5}  " + " ".join(f"{c:>12}" for c in cols)
        lines.append(head)
        lines.append("-" * len(head))
        for r in rs:
            vals = " ".join(f"{_fmt(r.metrics.get(c, np.nan)):>12}" for c in cols)
            st = "" if r.status == "completed" else f"  [{r.status}]"
            lines.append(f"{r.config.label:<24} {r.h:8.2g} {r.wall:8.3f} {r.fallbacks:5d}  {vals}{st}")
    return "\n".join(lines)


def cheapest(runs: Sequence[Run], problems: Sequence[Problem], decades: int = 3) -> list[dict]:
    """Per problem and target error: the configuration and h that reach it at the least
    wall time. Targets: the largest primary error of the study, divided by 10, 100, ...
    (``decades`` of them); a configuration reaches a target when one of its runs has a
    primary error at or below it."""
    out = []
    for p in problems:
        rs = [r for r in runs if r.problem == p.name and r.status == "completed" and np.isfinite(r.error)
              and r.error > 0]
        if not rs:
            continue
        top = max(r.error for r in rs)
        for k in range(1, decades + 1):
            target = top / 10.0**k
            ok = [r for r in rs if r.error <= target]
            if not ok:
                continue
            best = min(ok, key=lambda r: r.wall)
            out.append({"problem": p.name, "target": target, "config": best.config.label, "h": best.h,
                        "wall": best.wall, "error": best.error})
    return out


def step_control_gain(runs: Sequence[Run], problems: Sequence[Problem], decades: int = 3) -> list[dict]:
    """Per problem with step-size control runs and target error (as in :func:`cheapest`):
    the cheapest fixed-step run and the cheapest run with step-size control that reach
    it, and the ratio of their wall times."""
    out = []
    for p in problems:
        rs = [r for r in runs if r.problem == p.name and r.status == "completed" and np.isfinite(r.error)
              and r.error > 0]
        if not any(r.config.adaptive for r in rs):
            continue
        top = max(r.error for r in rs)
        for k in range(1, decades + 1):
            target = top / 10.0**k
            fixed = [r for r in rs if r.error <= target and not r.config.adaptive]
            tol = [r for r in rs if r.error <= target and r.config.adaptive]
            f = min(fixed, key=lambda r: r.wall) if fixed else None
            a = min(tol, key=lambda r: r.wall) if tol else None
            out.append({"problem": p.name, "target": target, "fixed": f, "adaptive": a,
                        "ratio": a.wall / f.wall if a and f else float("nan")})
    return out


def format_gain(rows: Sequence[dict]) -> str:
    head = (f"{'problem':<16} {'target error':>12}  {'cheapest fixed h':<30} {'wall[s]':>8}  "
            f"{'cheapest with StepControl':<28} {'wall[s]':>8} {'ratio':>7}")
    lines = [head, "-" * len(head)]
    for r in rows:
        f, a = r["fixed"], r["adaptive"]
        fs = f"{f.config.label} h={f.h:.2g}" if f else "not reached"
        as_ = f"{a.config.label} tol={a.h:.2g}" if a else "not reached"
        lines.append(f"{r['problem']:<16} {r['target']:12.3g}  {fs:<30} {f.wall if f else float('nan'):8.3f}  "
                     f"{as_:<28} {a.wall if a else float('nan'):8.3f} {r['ratio']:7.3f}")
    return "\n".join(lines)


def format_cheapest(rows: Sequence[dict]) -> str:
    head = f"{'problem':<16} {'target error':>12}  {'cheapest configuration':<24} {'h':>8} {'wall[s]':>8} {'error':>10}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['problem']:<16} {r['target']:12.3g}  {r['config']:<24} {r['h']:8.2g} {r['wall']:8.3f} "
                     f"{r['error']:10.3g}")
    return "\n".join(lines)


def format_orders(runs: Sequence[Run], problems: Sequence[Problem]) -> str:
    """Per (problem, configuration): fitted order of each error, total time, best
    primary error."""
    lines = []
    for p in problems:
        rs_p = [r for r in runs if r.problem == p.name]
        if not rs_p:
            continue
        orders = {m: fit_orders(rs_p, m) for m in p.metrics}
        head = (f"{'problem':<16} {'configuration':<24} {'time[s]':>8} {'best err':>9}  "
                + " ".join(f"{'p(' + m + ')':>16}" for m in p.metrics))
        lines += ["", head, "-" * len(head)]
        for c in p.configs:
            key = (p.name, c.label)
            rs = [x for x in rs_p if x.config == c]
            errs = [x.error for x in rs if np.isfinite(x.error)]
            lines.append(f"{p.name:<16} {c.label:<24} {sum(x.wall for x in rs):8.2f} "
                         f"{(min(errs) if errs else float('nan')):9.3g}  "
                         + " ".join(f"{orders[m][key]:16.2f}" for m in p.metrics))
    return "\n".join(lines)


def format_drift(rows: Sequence[dict]) -> str:
    lines = [f"\n{'problem':<12} {'integ':<6} {'h':>8} {'t none[s]':>10} {'t proj[s]':>10} {'ratio':>6} "
             f"{'pen none':>9} {'pen proj':>9}"]
    for d in rows:
        lines.append(f"{d['problem']:<12} {d['integrator']:<6} {d['h']:8.2g} {d['wall_none']:10.2f} "
                     f"{d['wall_proj']:10.2f} {d['ratio']:6.2f} {_fmt(d['pen_none']):>9} {_fmt(d['pen_proj']):>9}")
    return "\n".join(lines)


def format_osqp(rows: Sequence[dict]) -> str:
    lines = [f"\n{'solver':<16} {'checked':>7} {'wall[s]':>8} {'x enum':>7} {'fallbacks':>9} {'impacts':>8} "
             f"{'Δimp':>6} {'sides':>5} {'Δangle':>7} {'pen':>8} {'Δpen':>9}"]
    for r in rows:
        lines.append(f"{r['solver']:<16} {str(r['checked']):>7} {r['wall']:8.2f} {_fmt(r.get('time_ratio')):>7} "
                     f"{r['fallbacks']:9d} {_fmt(r['impacts']):>8} {_fmt(r.get('d_impacts')):>6} "
                     f"{_fmt(r['side_changes']):>5} {_fmt(r.get('d_angles')):>7} {_fmt(r['penetration']):>8} "
                     f"{_fmt(r.get('d_penetration')):>9}"
                     + ("" if r["status"] == "completed" else f"  [{r['status']}]"))
    return "\n".join(lines)


def write_csv(runs: Sequence[Run], orders: dict, path: str) -> None:
    """One row per run: problem, configuration, h, wall time, errors, fitted order; written
    under a unique temporary name, then renamed into place (an interrupted write leaves the
    last file whole)."""
    names = []
    for r in runs:
        for k in r.metrics:
            if k not in names and not isinstance(r.metrics[k], (list, tuple)):
                names.append(k)
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        # adaptive rows (step-size control): "h" is StepControl's tol, "order" the slope in tol, "h_max"
        # the largest step when the configuration sets it (else the problem's: wp_problems.py), "v_tol"
        # the velocities' tolerance over the coordinates' (empty: the same)
        w.writerow(["problem", "integrator", "solver", "checked", "drift", "adaptive", "h", "wall_s", "steps",
                    "fallbacks", "status", "error", "order", "h_max", "v_tol", *names])
        for r in runs:
            c = r.config
            w.writerow([r.problem, c.integrator, c.solver, SOLVERS[c.solver].checked, c.drift, c.adaptive, f"{r.h:.6g}",
                        f"{r.wall:.4g}", r.steps, r.fallbacks, r.status, f"{r.error:.6g}",
                        f"{orders[(r.problem, c.label)]:.3f}", "" if c.h_max is None else f"{c.h_max:g}",
                        "" if c.v_tol == 1.0 else f"{c.v_tol:g}",
                        *[("" if r.metrics.get(k) is None else f"{r.metrics[k]:.6g}") for k in names]])
    os.replace(tmp, path)


def read_csv(path: str) -> tuple[list[Run], dict]:
    """The runs and fitted orders of a CSV written by :func:`write_csv` (metrics as floats,
    empty ones left out)."""
    runs, orders = [], {}
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            h_max, v_tol = row.pop("h_max", ""), row.pop("v_tol", "")
            c = Config(row.pop("integrator"), row.pop("solver"), row.pop("drift"), row.pop("adaptive") == "True",
                       float(h_max) if h_max else None, float(v_tol) if v_tol else 1.0)
            row.pop("checked")
            r = Run(row.pop("problem"), c, float(row.pop("h")), float(row.pop("wall_s")), int(row.pop("steps")),
                    int(row.pop("fallbacks")), row.pop("status"), float(row.pop("error")))
            orders[(r.problem, c.label)] = float(row.pop("order"))
            r.metrics = {k: float(v) for k, v in row.items() if v != ""}
            runs.append(r)
    return runs, orders


def plot(runs: Sequence[Run], orders: dict, problems: Sequence[Problem], path: str) -> None:
    """Log–log error against wall time, one panel per problem, one line per
    configuration (colour: solver, line: integrator, marker: drift control); the legend
    gives the fitted order of each line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    colors = {"osqp": "C0", "osqp1e-5": "C1", "osqp1e-3": "C3", "enum": "C2", "daqp": "C4", "exact": "C5"}
    styles = {"mid": "-", "theta": "--", "ec": ":"}
    markers = {"none": "o", "proj": "s", "projv": "D", "comb": "^"}
    n = len(problems)
    ncol = 3
    nrow = math.ceil((n + 1) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.0 * ncol, 4.6 * nrow))
    axes = np.atleast_1d(axes).ravel()
    for ax, p in zip(axes, problems):
        for c in p.configs:
            rs = [r for r in runs if r.problem == p.name and r.config == c and np.isfinite(r.error) and r.error > 0]
            if not rs:
                continue
            ax.loglog([r.wall for r in rs], [r.error for r in rs], styles[c.integrator], marker=markers[c.drift],
                      color="k" if c.adaptive else colors.get(c.solver, "k"), ms=4, lw=2.2 if c.adaptive else 1.1,
                      alpha=0.85,
                      label=f"{c.label}  p={orders[(p.name, c.label)]:.2f}")
        ax.set_title(f"{p.name}: {p.primary} error")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel(f"error ({p.primary})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=1 if len(p.configs) <= 8 else 2, loc="best")
    # last panel: piston penetration against h, with and without drift control
    ax = axes[n]
    for p in problems:
        if not p.name.startswith("piston"):
            continue
        for c in p.configs:
            if c.solver not in ("enum", "exact") or c.adaptive:  # (a step-controlled run's ladder is its tol)
                continue
            rs = [r for r in runs if r.problem == p.name and r.config == c and "penetration_run" in r.metrics]
            if rs:
                ax.loglog([r.h for r in rs], [max(r.metrics["penetration_run"], 1e-6) for r in rs],
                          styles[c.integrator], marker=markers[c.drift], ms=4,
                          label=f"{p.name} {c.label}")
    ax.set_title("piston: max penetration / clearance, fixed h (last cycle; floor 1e-6)")
    ax.set_xlabel("h (non-dimensional)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    for ax in axes[n + 1:]:
        ax.axis("off")
    handles = [Line2D([], [], color=v, label=k) for k, v in colors.items()]
    handles += [Line2D([], [], color="k", lw=2.2, label="StepControl(tol): p = slope in tol")]
    handles += [Line2D([], [], color="k", ls=v, label=k) for k, v in styles.items()]
    names = {"none": "no drift control", "proj": "PositionProjection", "projv": "PositionProjection(velocity=True)",
             "comb": "CombinedProjection"}
    handles += [Line2D([], [], color="k", marker=v, ls="", label=names[k]) for k, v in markers.items()]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("moreau work–precision: error against wall time (p = fitted order in h)")
    fig.tight_layout(rect=(0, 0.04, 1, 0.97))
    tmp = f"{path}.{os.getpid()}.tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)
    plt.close(fig)
