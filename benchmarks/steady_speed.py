"""The engine's own steady speed: run the self-excited piston engine from a given speed
until its cycle-mean speed settles, and compare with the energy-balance estimate.

Two measures of the speed the engine settles at (its pressure curve, brake torque and
losses balance there; the runs start at 2000 rpm, the speed the curve was set for):

* **long run**: cycles are run in chunks, each continuing from the last state, until
  the mean speed of the last 100 cycles differs from that of the 100 before by less than
  ``--criterion`` rpm (default 0.01), or ``--max-cycles``. The per-cycle speeds are fitted
  by a − b·exp(−cycles/τ).
* **energy-balance estimate** from one cycle: with joint damping the only loss that grows
  with speed (W_d ∝ ω per cycle at a fixed crank path; the gas and brake work per cycle do
  not depend on ω), the cycle's energy surplus S = ΔKE over 720° of crank angle moves the
  speed to ω (1 + S / W_d). It is evaluated at the start (after ``--warmup`` cycles) and at
  the end of the long run, and, with ``--check-h``, at another step size.

    python benchmarks/steady_speed.py --e 0 --D 80.04 --rpm0 2000 --h 1e-3
    python benchmarks/steady_speed.py --e 0.9 --D 80.2 --rpm0 1900 --h 1e-3 --check-h 1e-4

One cycle at h = 1e-3 is 12 566 steps (≈ 40 ms compiled); the runs from 2000 and 1900 rpm
take 10 000–20 000 cycles (the relaxation time is ≈ 3 000 cycles). ``--save FILE.npy``
keeps the per-cycle speeds.
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np
from scipy.optimize import curve_fit

import moreau as mo
from moreau.problems.piston import PistonParameters, piston_model

log = logging.getLogger("steady_speed")
CYCLE = 4 * np.pi  # one engine cycle: 720° of crank angle (non-dimensional time at 2000 rpm)
RPM = 2000.0  # non-dimensional speed 1


def _run(model, t0, q0, v0, h, t1, record_every, energy=False, progress=False) -> mo.Trajectory:
    p = model.params
    lim = p.clearance / p.l1  # as the piston job; a continued run may start that deep
    # an exact projection (tol = 0; the main job accepts 1e-4 of the clearance): the
    # steady speeds in docs/piston_accuracy.md were measured with it
    traj = mo.simulate(model.scene, (t0, t1), q0, v0, h, drift_control=mo.CombinedProjection(),
                       record_every=record_every, energy=energy, progress=progress,
                       penetration_limit=lim, initial_penetration=lim)
    if not traj.completed:
        raise RuntimeError(f"run stopped: {traj.message}")
    return traj


def _crossings(traj: mo.Trajectory, k_from: int) -> tuple[np.ndarray, int]:
    """Times at which the crank angle passes 4π k for k >= k_from (linear interpolation
    between records); returns them and the next k."""
    phi, t = traj.q[:, 0], traj.t
    k_to = int(phi[-1] // CYCLE)
    ks = np.arange(k_from, k_to + 1)
    ks = ks[ks * CYCLE >= phi[0]]
    return np.interp(ks * CYCLE, phi, t), (k_to + 1 if ks.size else k_from)


def run_until_settled(model, rpm0: float, h: float, *, criterion: float, max_cycles: int, chunk: int = 1000,
                      per_cycle_records: int = 200) -> tuple[np.ndarray, tuple]:
    """Per-cycle mean speeds (rpm) from ``rpm0`` until settled (see the module docstring);
    returns them and the final (t, q, v)."""
    q, v = model.initial_state(speed=rpm0 / RPM)
    t = 0.0
    stride = max(1, int(round(CYCLE / h / per_cycle_records)))
    ends: list[float] = []
    k_next = 0
    rpm = np.empty(0)
    while True:
        speed = max(v[0], 0.5)
        traj = _run(model, t, q, v, h, t + chunk * CYCLE / speed, stride)
        tc, k_next = _crossings(traj, k_next)
        ends.extend(tc.tolist())
        t, q, v = traj.t[-1], traj.q[-1].copy(), traj.v[-1].copy()
        rpm = RPM * CYCLE / np.diff(ends)
        change = rpm[-100:].mean() - rpm[-200:-100].mean() if rpm.size >= 200 else np.inf
        log.info("%d cycles: last 100 mean %.3f rpm, change per 100 cycles %+.4f", rpm.size,
                 rpm[-100:].mean(), change)
        if abs(change) < criterion or rpm.size >= max_cycles:
            return rpm, (t, q, v)


def energy_balance(model, t0: float, q0, v0, h: float) -> tuple[float, float, float, float]:
    """One engine cycle from (t0, q0, v0) at step h: (cycle-mean rpm, surplus S = ΔKE
    between the two passes of the crank through the same 720° phase, damping work W_d,
    the estimate rpm (1 + S / W_d)); energies in the model's units."""
    phase = np.ceil(q0[0] / CYCLE) * CYCLE  # the next multiple of 720°
    speed = max(v0[0], 0.5)
    traj = _run(model, t0, q0, v0, h, t0 + (phase - q0[0] + 1.05 * CYCLE) / speed, 1, energy=True)
    phi, t, ke = traj.q[:, 0], traj.t, traj.kinetic_energy
    ta, tb = np.interp([phase, phase + CYCLE], phi, t)
    kea, keb = np.interp([ta, tb], t, ke)
    C = next(f for f in model.scene.effects if f.name == "damping").C
    sel = (t >= ta) & (t <= tb)
    pw = np.einsum("ki,ij,kj->k", traj.v[sel], C, traj.v[sel])
    Wd = float(np.trapezoid(pw, t[sel]))
    rpm = RPM * CYCLE / (tb - ta)
    S = float(keb - kea)
    return rpm, S, Wd, rpm * (1 + S / Wd)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--e", type=float, default=0.0)
    ap.add_argument("--D", type=float, default=80.04, help="cylinder diameter (mm)")
    ap.add_argument("--rpm0", type=float, default=2000.0, help="starting speed (rpm)")
    ap.add_argument("--max-cycles", type=int, default=30000)
    ap.add_argument("--criterion", type=float, default=0.01, help="rpm per 100 cycles")
    ap.add_argument("--h", type=float, default=1e-3, help="step in non-dimensional time τ = ωt")
    ap.add_argument("--warmup", type=int, default=5, help="cycles before the first energy-balance estimate")
    ap.add_argument("--check-h", type=float, default=None, help="also estimate at this step")
    ap.add_argument("--iterate", type=int, default=1,
                    help="restart from the estimate and estimate again, this many times in all")
    ap.add_argument("--estimate-only", action="store_true", help="only the energy-balance estimates")
    ap.add_argument("--save", default=None, help="save the per-cycle speeds (.npy)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    model = piston_model(PistonParameters(e=args.e, D=args.D / 1e3))
    head = f"e = {args.e:g}, D = {args.D:g} mm, from {args.rpm0:g} rpm"
    t0 = time.perf_counter()
    for h in [args.h] + ([args.check_h] if args.check_h else []):
        start = args.rpm0
        for _ in range(args.iterate):
            q, v = model.initial_state(speed=start / RPM)
            warm = _run(model, 0.0, q, v, h, args.warmup * CYCLE / max(v[0], 0.5), 100)
            r, S, Wd, est = energy_balance(model, warm.t[-1], warm.q[-1], warm.v[-1], h)
            print(f"{head}, h = {h:g}: started at {start:.2f} rpm, after {args.warmup} cycles {r:.3f} rpm, "
                  f"S = {S:.4g}, W_d = {Wd:.4g}, energy-balance estimate {est:.2f} rpm")
            start += est - r  # the initial speed that gives this cycle-mean speed
    if args.estimate_only:
        return
    rpm, (t, q, v) = run_until_settled(model, args.rpm0, args.h, criterion=args.criterion,
                                       max_cycles=args.max_cycles)
    if args.save:
        np.save(args.save, rpm)
    c = np.arange(rpm.size)
    fit = lambda c, a, b, tau: a - b * np.exp(-c / tau)  # noqa: E731
    try:
        p, _ = curve_fit(fit, c[20:], rpm[20:], p0=(rpm[-1], rpm[-1] - rpm[20], 3000.0), maxfev=20000)
    except (RuntimeError, ValueError, TypeError) as exc:  # a run started at its settled speed: nothing to fit
        log.info("no relaxation fitted: %s", exc)
        p = (np.nan, np.nan, np.nan)
    change = rpm[-100:].mean() - rpm[-200:-100].mean()
    r, S, Wd, est = energy_balance(model, t, q, v, args.h)
    print(f"{head}, h = {args.h:g}: {rpm.size} cycles in {time.perf_counter() - t0:.0f} s")
    print(f"  last 100 cycles {rpm[-100:].mean():.3f} rpm; change per 100 cycles {change:+.4f} rpm "
          f"(criterion {args.criterion}: {'met' if abs(change) < args.criterion else 'NOT met'})")
    print(f"  fit a − b exp(−c/τ): a = {p[0]:.3f} rpm, τ = {p[2]:.0f} cycles, "
          f"rms {np.std(rpm[20:] - fit(c[20:], *p)):.4f} rpm")
    print(f"  energy-balance estimate at the end: {est:.3f} rpm (cycle {r:.3f} rpm, S = {S:.4g}, W_d = {Wd:.4g})")


if __name__ == "__main__":
    main()
