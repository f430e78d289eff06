"""Do the piston's structural figures converge in h with the default scheme?

For e ∈ {0, 0.05, 0.3, 0.9} at D = 80.04 mm (the paper's 40 µm clearance), runs three
engine cycles at h = 1e-3 … 1e-5 with the main job's drift control
(``PistonModel.drift_control()``: :class:`moreau.CombinedProjection` accepting 1e-4 of
the clearance; ``--tol`` sets another fraction), and once without drift control at the finest h,
and prints per h the figures of the two cycles after the first: side changes per cycle
and their crank angles, impacts per cycle (fast onsets after a flight of 2 % of the
clearance), the raw count of the velocity test, the kinetic energy lost at the impacts
(J per cycle) and the largest penetration (% of the clearance, every step).

    python benchmarks/piston_convergence.py            # ~3 min on one core
    python benchmarks/piston_convergence.py --quick    # h >= 1e-4, ~20 s
    python benchmarks/piston_convergence.py --tol 0 --out /tmp/exact.csv  # an exact projection
    python benchmarks/piston_convergence.py --locate --out docs/piston_convergence_located.csv

Writes the table to ``docs/piston_convergence.csv`` (``--out`` to change).
"""

from __future__ import annotations

import argparse
import csv
import logging
import os
import time

import numpy as np

import moreau as mo
from moreau.problems.piston import PistonParameters, cycle_figures, piston_model
from moreau.problems.piston.model import PROJECTION_FRACTION

log = logging.getLogger("piston_convergence")

ES = (0.0, 0.05, 0.3, 0.9)
HS = (1e-3, 3e-4, 1e-4, 3e-5, 1e-5)
CYCLES = 3  # the first is the transient from the upright start


def figures(e: float, h: float, drift: bool, tol: float | None = None, locate: bool = False) -> dict:
    params = PistonParameters(e=e)
    model = piston_model(params)
    if not drift:
        dc = None
    elif tol is None and not locate:
        dc = model.drift_control()
    else:
        frac = PROJECTION_FRACTION if tol is None else tol
        dc = (mo.CombinedProjection(tol=frac * params.clearance / params.l1, locate_impacts=True, memory=0)
              if locate else mo.CombinedProjection(tol=frac * params.clearance / params.l1))
    t0 = time.perf_counter()
    traj = model.simulate(CYCLES, h, drift_control=dc,
                          record_every=max(1, round(1e-3 / h)), energy=False, progress=False)
    wall = time.perf_counter() - t0
    figs = cycle_figures(traj, params)[1:]
    vel_phi = np.interp(traj.velocity_impacts.t, traj.t, traj.q[:, 0])
    n_vel = int(np.sum(vel_phi >= 4 * np.pi)) / len(figs)
    return {
        "e": e, "h": h, "drift_control": ("located" if locate else "combined") if drift else "none",
        "side_changes": "/".join(str(c.side_changes) for c in figs),
        "angles_deg": " ".join(f"{a:.0f}" for a in figs[-1].change_angles_deg),
        "impacts_per_cycle": float(np.mean([c.impacts for c in figs])),
        "velocity_onsets_per_cycle": n_vel,
        "energy_lost_J": float(np.mean([c.energy_lost for c in figs])),
        "max_penetration_pct": 100.0 * float(traj.max_penetration.max()) / (params.clearance / params.l1),
        "wall_s": round(wall, 2),
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="h >= 1e-4 only")
    ap.add_argument("--tol", type=float, default=None,
                    help="CombinedProjection's accepted penetration, as a fraction of the clearance "
                         "(default: the engine's drift control, PROJECTION_FRACTION = 1e-4)")
    ap.add_argument("--locate", action="store_true",
                    help="CombinedProjection(locate_impacts=True, memory=0): Newton's law at the located "
                         "impact instant")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "docs", "piston_convergence.csv"))
    args = ap.parse_args(argv)
    if args.tol is not None and not (np.isfinite(args.tol) and 0.0 <= args.tol < 1.0):
        ap.error(f"--tol must be a fraction of the clearance in [0, 1), got {args.tol}")
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    hs = [h for h in HS if h >= 1e-4] if args.quick else list(HS)
    rows = [figures(e, h, True, args.tol, args.locate) for e in ES for h in hs]
    rows += [figures(e, hs[-1], False) for e in ES]
    head = ("e", "h", "drift_control", "side_changes", "angles_deg", "impacts_per_cycle",
            "velocity_onsets_per_cycle", "energy_lost_J", "max_penetration_pct", "wall_s")
    widths = (5, 7, 9, 8, 44, 8, 9, 9, 9, 7)
    log.info(" ".join(f"{h[:w]:>{w}}" for h, w in zip(head, widths)))
    for r in sorted(rows, key=lambda r: (r["e"], r["drift_control"], -r["h"])):
        cells = [f"{r['e']:g}", f"{r['h']:g}", r["drift_control"], r["side_changes"], r["angles_deg"],
                 f"{r['impacts_per_cycle']:.1f}", f"{r['velocity_onsets_per_cycle']:.0f}",
                 f"{r['energy_lost_J']:.4f}", f"{r['max_penetration_pct']:.2g}", f"{r['wall_s']:.1f}"]
        log.info(" ".join(f"{c:>{w}}" for c, w in zip(cells, widths)))
    out = os.path.abspath(args.out)
    tmp = f"{out}.{os.getpid()}.tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=head)
        w.writeheader()
        w.writerows(rows)
    os.replace(tmp, out)
    log.info("wrote %s", out)


if __name__ == "__main__":
    main()
