"""The engine's own steady speed: run the self-excited piston engine for thousands of
cycles from a given speed and print its cycle-mean speed, its change per 100 cycles and
the fitted relaxation a − b·exp(−cycles/τ).

    python benchmarks/steady_speed.py --e 0 --D 80.04 --rpm0 2000 --cycles 12000 --h 1e-3

(12 000 cycles at h = 1e-3 are 150 M steps: 2.5–12 min on one core.) ``--save FILE.npy``
keeps the per-cycle speeds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import curve_fit

import moreau as mo
from moreau.problems.piston import PistonParameters, piston_model


def cycle_speeds(e: float, D_mm: float, rpm0: float, cycles: int, h: float) -> tuple[np.ndarray, mo.Trajectory]:
    """Cycle-mean speeds (rpm), one per completed engine cycle (720° of crank angle)."""
    model = piston_model(PistonParameters(e=e, D=D_mm / 1e3))
    q0, v0 = model.initial_state(speed=rpm0 / 2000.0)  # non-dimensional speed 1 = 2000 rpm
    per_cycle = 4 * np.pi / h
    p = model.params
    traj = mo.simulate(model.scene, (0.0, 4 * np.pi * cycles * 2000.0 / rpm0), q0, v0, h,
                       drift_control=mo.CombinedProjection(), record_every=max(1, int(round(per_cycle / 50))),
                       energy=False, progress=True, penetration_limit=p.clearance / p.l1)  # as the piston job
    phi, t = traj.q[:, 0], traj.t
    ends = np.interp(4 * np.pi * np.arange(1, int(phi[-1] // (4 * np.pi)) + 1), phi, t)
    return 2000.0 * 4 * np.pi / np.diff(np.concatenate([[0.0], ends])), traj


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--e", type=float, default=0.0)
    ap.add_argument("--D", type=float, default=80.04, help="cylinder diameter (mm)")
    ap.add_argument("--rpm0", type=float, default=2000.0, help="starting speed (rpm)")
    ap.add_argument("--cycles", type=int, default=12000)
    ap.add_argument("--h", type=float, default=1e-3, help="step in non-dimensional time τ = ωt")
    ap.add_argument("--save", default=None, help="save the per-cycle speeds (.npy)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rpm, traj = cycle_speeds(args.e, args.D, args.rpm0, args.cycles, args.h)
    if args.save:
        np.save(args.save, rpm)
    c = np.arange(rpm.size)
    fit = lambda c, a, b, tau: a - b * np.exp(-c / tau)  # noqa: E731
    p, _ = curve_fit(fit, c[20:], rpm[20:], p0=(rpm[-1], rpm[-1] - rpm[20], 3000.0), maxfev=20000)
    print(f"e = {args.e:g}, D = {args.D:g} mm, from {args.rpm0:g} rpm, h = {args.h:g}: {rpm.size} cycles in "
          f"{time.perf_counter() - t0:.0f} s ({traj.stats.us_per_step:.2f} µs/step)")
    print(f"last cycle {rpm[-1]:.3f} rpm; mean of the last 100 {rpm[-100:].mean():.3f} rpm; change per 100 "
          f"cycles {rpm[-100:].mean() - rpm[-200:-100].mean():+.4f} rpm (criterion: < 0.01)")
    print(f"fit a − b exp(−c/τ): settled speed a = {p[0]:.3f} rpm, τ = {p[2]:.0f} cycles, "
          f"rms {np.std(rpm[20:] - fit(c[20:], *p)):.4f} rpm")


if __name__ == "__main__":
    main()
