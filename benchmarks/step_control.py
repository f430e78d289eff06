"""What step-size control (``mo.StepControl``) costs against fixed steps, at the same error.

Prints, in one run (wall times: the best of up to ten runs within 0.5 s, `wp_configs._timed`; compare within
one table, absolute times on a shared 2-core machine are noisy):

1. the bouncing ball (e = 0.8, from 1 m, 4.5 s): the largest error of the first 6 impact
   times against the analytic ones (``BallSolution``), fixed h against ``StepControl(tol)``
   (h = 1e-2 the largest step), and each run's time over that of fixed h = 1e-6;
2. the damped pendulum without a wall (damping 0.5, 2 s): the final state's error against
   DOP853 at rtol = atol = 1e-13, per tol, the sum of the accepted steps' local errors
   (each against DOP853 from its start) over tol; and the extrapolated step at fixed H (every
   step accepted, ``StepControl(1e6)``), with its observed order;
3. the woodpecker (Glocker's state, 0.45 s): the error of the three returns' times, ydot
   and phidot against fixed h = 1e-6 (``benchmarks/wp_friction.py``'s metrics); the
   reference's own distance from an h = 1e-7 run; the return-time error over tol against
   the h = 1e-7 run for ten tolerances 1e-3 … 1e-6 (its scatter); and the cost of the
   ``simulate()`` call itself, over one step;
4. with ``--piston``: the e = 0 piston over 2 cycles with ``PositionProjection(velocity=True)``,
   the side-change angles of the last cycle against fixed h = 1e-6 (``benchmarks/wp_problems.py``'s
   metric), ``StepControl(tol)`` with the largest step 1e-2, and coarse tolerances with the largest step 0.1
   (one tolerance, and one per component); at the coarse end fixed h = 10^-1.5 against largest steps
   0.1 … 0.5; and the error at tol = 1e-10 and 2e-11 for five largest steps 0.0094 … 0.0106 (its scatter);
5. an attempt's own cost: the woodpecker over 0.45 s with ``StepControl(1e6)`` at H = 2e-5 (every
   attempt accepted, 22 500 attempts of one step of H and two of H/2) against fixed H plus fixed H/2,
   best of 15 runs each, taken in turn; the difference over the attempts is what the controller adds;
6. the woodpecker at the study's 1/100 target: ``StepControl(0.03)`` with the largest step 4e-3
   against the study's cheapest fixed run there (predictor–corrector, ``CombinedProjection``,
   h = 1e-4), best of 30 in turn, the ratio of the ``simulate()`` calls (issue 45 asks <= 1/3).

    python benchmarks/step_control.py [--piston]
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from wp_configs import _timed, settle  # noqa: E402
from wp_friction import _returns  # noqa: E402
from wp_problems import _angle_distance  # noqa: E402

import moreau as mo  # noqa: E402


def _row(label, err, traj, wall, base):
    st = traj.stats
    print(f"  {label:<22} {err:10.3e} {st.steps:9d} {st.rejected:8d} {st.velocity_updates:10d} {wall:9.4f} "
          f"{wall / base:8.4f}")


def _header(what):
    print(f"  {'run':<22} {what:>10} {'steps':>9} {'rejected':>8} {'updates':>10} {'wall (s)':>9} {'/ fixed':>8}")


def _warm(run, h):
    """One untimed run of a problem's scene with a fixed step and one with step control: what
    a first call loads (the loop, the driver, the scene's lowering) is not in the timed runs,
    whose first would not be repeated when it takes over 0.5 s."""
    run(h)
    run(h, step_control=mo.StepControl(1e-3))


def ball():
    from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

    scene, sol = bouncing_ball(0.8), BallSolution(1.0, 0.8)
    t_ref = np.array([sol.impact_time(k) for k in range(1, 7)])
    from moreau.problems.event_driven import moreau_impact_times

    print("\n1. Bouncing ball e = 0.8, 4.5 s: error of the first 6 impact times (s); '/ fixed': wall / fixed h = 1e-6")
    _header("error")
    run = lambda h, **kw: _timed(lambda: mo.simulate(scene, (0.0, 4.5), [1.0], [0.0], h, energy=False, **kw),  # noqa: E731
                                 repeat_below=0.5)
    _warm(run, 1e-2)
    ref, base, _ = run(1e-6)
    rows = [(f"fixed h = {h:g}", *run(h)[:2], moreau_impact_times) for h in (1e-4, 1e-5)]
    rows.append(("fixed h = 1e-06", ref, base, moreau_impact_times))
    rows += [(f"tol = {tol:g}", *run(1e-2, step_control=mo.StepControl(tol))[:2], lambda t: t.impacts.t)
             for tol in (1e-3, 1e-4, 1e-5, 1e-6)]
    for label, traj, wall, times in rows:
        _row(label, float(np.abs(times(traj)[:6] - t_ref).max()), traj, wall, base)


def pendulum():
    from scipy.integrate import solve_ivp

    from moreau.problems.pendulum_wall import pendulum_rhs, pendulum_wall

    scene = pendulum_wall(wall_x=None, damping=0.5)
    y = solve_ivp(pendulum_rhs(damping=0.5), (0, 2.0), (1.0, 0.5), method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
    run = lambda h, **kw: _timed(lambda: mo.simulate(scene, (0.0, 2.0), [1.0], [0.5], h, energy=False, **kw),  # noqa: E731
                                 repeat_below=0.5)
    err = lambda t: max(abs(t.q[-1, 0] - y[0]), abs(t.v[-1, 0] - y[1]))  # noqa: E731
    print("\n2. Damped pendulum, 2 s: error of the final state against DOP853; '/ fixed': wall / fixed h = 1e-4")
    _header("error")
    _warm(run, 1e-2)
    ref, base, _ = run(1e-4)
    _row("fixed h = 1e-4", err(ref), ref, base, base)
    rhs, sums = pendulum_rhs(damping=0.5), []
    for tol in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
        traj, wall, _ = run(0.1, step_control=mo.StepControl(tol))
        _row(f"tol = {tol:g}", err(traj), traj, wall, base)
        if tol >= 1e-7:  # the accepted steps' local errors, each against DOP853 from the step's start
            loc = 0.0
            for i in range(len(traj.t) - 1):
                z = solve_ivp(rhs, (traj.t[i], traj.t[i + 1]), (traj.q[i, 0], traj.v[i, 0]), method="DOP853",
                              rtol=1e-13, atol=1e-14).y[:, -1]
                loc += max(abs(z[0] - traj.q[i + 1, 0]), abs(z[1] - traj.v[i + 1, 0]))
            sums.append(loc / tol)
    print("   sum of the accepted steps' local errors / tol for tol = 1e-3 ... 1e-7: "
          + " ".join(f"{x:.3g}" for x in sums))
    print("   extrapolated at fixed H (every step accepted):")
    last = None
    for h in (4e-2, 2e-2, 1e-2, 5e-3):
        traj, wall, _ = run(h, step_control=mo.StepControl(1e6))
        e = err(traj)
        order = "" if last is None else f"   order {math.log2(last / e):.2f}"
        print(f"  H = {h:<14g} {e:10.3e}{order}")
        last = e


def woodpecker():
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    scene, (q0, v0) = woodpecker(), GLOCKER_STATE
    run = lambda h, **kw: _timed(lambda: mo.simulate(scene, (0.0, 0.45), q0, v0, h, energy=False, **kw),  # noqa: E731
                                 repeat_below=0.5)
    ref = _returns(run(1e-6)[0])
    print("\n3. Woodpecker, 0.45 s: error of the returns' times (s) [ydot, phidot] against h = 1e-6; "
          "'/ fixed': wall / fixed h = 1e-5")
    _header("time error")
    rows = [(f"fixed h = {h:g}", *run(h)[:2]) for h in (1e-4, 3e-5, 1e-5)]
    base = rows[-1][2]
    rows += [(f"tol = {tol:g}", *run(1e-3, step_control=mo.StepControl(tol))[:2]) for tol in (1e-3, 1e-4, 1e-5)]
    for label, traj, wall in rows:
        d = np.abs(_returns(traj) - ref).max(axis=0)
        _row(label, float(d[0]), traj, wall, base)
        print(f"  {'':<22} [{d[1]:.2e}, {d[2]:.2e}]")
    # the call's own cost: a third of the cheapest fixed run at a coarse target is below it
    def call(kw):
        return min(_timed(lambda: mo.simulate(scene, (0.0, 1e-3), q0, v0, 1e-3, energy=False, **kw), repeats=1)[1]
                   for _ in range(30))

    calls = {"fixed h": call({}), "StepControl": call({"step_control": mo.StepControl(0.03)})}
    print("  the simulate() call over one step of 1e-3 (best of 30): "
          + ", ".join(f"{k} {1e3 * w:.2f} ms" for k, w in calls.items()))
    finer = _returns(mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-7, energy=False, record_every=10))
    print(f"  the reference itself against h = 1e-7: return times {np.abs(ref - finer)[:, 0].max():.2e} s")
    ladder = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6)
    ratios = [float(np.abs(_returns(mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-3, energy=False,
                                                step_control=mo.StepControl(tol))) - finer)[:, 0].max()) / tol
              for tol in ladder]  # (untimed: one run each; against h = 1e-7, finer than the tolerances)
    print("  return-time error / tol against h = 1e-7 over tol = " + ", ".join(f"{t:g}" for t in ladder) + ":\n  "
          + " ".join(f"{r:.2g}" for r in ratios))


def piston():
    from moreau.problems.piston.analysis import cycle_figures
    from moreau.problems.piston.model import piston_model
    from moreau.problems.piston.params import PistonParameters

    params = PistonParameters(e=0.0)
    model = piston_model(params)

    def run(h, **kw):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _timed(lambda: model.simulate(2, h, energy=False, drift_control=mo.PositionProjection(velocity=True),
                                                 **kw), repeat_below=0.5)

    angles = lambda t: cycle_figures(t, params)[-1].change_angles_deg  # noqa: E731
    _warm(run, 1e-2)
    ref = angles(run(1e-6, record_every=500)[0])  # (side changes are timed from the onset log, not the records)
    print("\n4. Piston e = 0, 2 cycles, PositionProjection(velocity=True): side-change angles of the last cycle (deg) "
          "against h = 1e-6; '/ fixed': wall / fixed h = 1e-4")
    _header("angles")
    rows = [(f"fixed h = {h:g}", *run(h, record_every=max(1, round(5e-4 / h)))[:2])
            for h in (1e-2, 1e-3, 3.2e-4, 1e-4, 3.2e-5)]
    base = rows[3][2]
    rows += [(f"tol = {tol:g}", *run(1e-2, step_control=mo.StepControl(tol))[:2]) for tol in (1e-8, 1e-9, 1e-10, 1e-11)]
    # coarse tolerances pay only with a larger largest step: at most 1e-2, no run is cheaper than fixed h = 1e-2
    rows += [(f"H = 0.1, tol = {tol:g}", *run(0.1, step_control=mo.StepControl(tol))[:2])
             for tol in (1e-6, 1e-7, 1e-8)]
    # a tolerance per component: tol for the coordinates (rad), k tol for the velocities
    rows += [(f"H = 0.1, {tol:g}, v{k}x", *run(0.1, step_control=mo.StepControl((tol,) * 3 + (k * tol,) * 3))[:2])
             for k in (10, 30, 100) for tol in (3e-7, 1e-7, 3e-8)]
    # the coarse end: the cheapest fixed run there, and largest steps beyond 0.1
    rows += [("fixed h = 0.0316", *run(10**-1.5, record_every=1)[:2])]
    rows += [(f"H = {hm:g}, 1e-05, v30x", *run(hm, step_control=mo.StepControl((1e-5,) * 3 + (3e-4,) * 3))[:2])
             for hm in (0.1, 0.2, 0.3, 0.5)]
    for label, traj, wall in rows:
        _row(label, _angle_distance(angles(traj), ref), traj, wall, base)
    for tol in (1e-10, 2e-11):  # the same tolerance, slightly different largest steps
        errs = [_angle_distance(angles(run(hm, step_control=mo.StepControl(tol))[0]), ref)
                for hm in (0.0094, 0.0097, 0.01, 0.0103, 0.0106)]
        print(f"  tol = {tol:g}, largest step 0.0094 ... 0.0106: " + " ".join(f"{e:.2g}" for e in errs))


def attempt_cost(rounds: int = 15) -> None:
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    scene, (q0, v0), H, T = woodpecker(), GLOCKER_STATE, 2e-5, 0.45
    runs = {"fixed H": (H, {}), "fixed H/2": (H / 2, {}),
            "StepControl(1e6), H": (H, {"step_control": mo.StepControl(1e6)})}
    best = dict.fromkeys(runs, float("inf"))
    stats = {}
    for _ in range(rounds):  # in turn, so that a slow phase of the machine falls on all three
        for label, (h, kw) in runs.items():
            traj, wall, _ = _timed(lambda h=h, kw=kw: mo.simulate(scene, (0.0, T), q0, v0, h, energy=False, **kw),
                                   repeats=1)
            best[label], stats[label] = min(best[label], wall), traj.stats
    print(f"\n5. An attempt's own cost: woodpecker, {T} s, H = {H:g} (best of {rounds}, in turn)")
    for label in runs:
        st = stats[label]
        print(f"  {label:<22} {1e3 * best[label]:9.2f} ms  {st.steps:7d} steps  {st.rejected:4d} rejected")
    attempts = stats["StepControl(1e6), H"].steps + stats["StepControl(1e6), H"].rejected
    extra = best["StepControl(1e6), H"] - best["fixed H"] - best["fixed H/2"]
    print(f"  controller's own cost: {1e6 * extra / attempts:.2f} µs an attempt over {attempts} attempts")


def coarse_pair(rounds: int = 30) -> None:
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    scene, (q0, v0) = woodpecker(), GLOCKER_STATE
    runs = {"fixed theta/comb h = 1e-4": (1e-4, {"integrator": mo.MoreauJeanPredictorCorrector,
                                                  "drift_control": mo.CombinedProjection()}),
            "StepControl(0.03), H = 4e-3": (4e-3, {"step_control": mo.StepControl(0.03)})}
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(rounds):  # in turn, as in attempt_cost
        for label, (h, kw) in runs.items():
            _, wall, _ = _timed(lambda h=h, kw=kw: mo.simulate(scene, (0.0, 0.45), q0, v0, h, energy=False, **kw),
                                repeats=1)
            best[label] = min(best[label], wall)
    fixed, ctl = best.values()
    print(f"\n6. Woodpecker, 0.45 s, the study's 1/100 target (best of {rounds}, in turn): "
          + ", ".join(f"{k} {1e3 * w:.2f} ms" for k, w in best.items()) + f"; ratio {ctl / fixed:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--piston", action="store_true", help="also the e = 0 piston (about 90 s more)")
    args = ap.parse_args()
    mo.ensure_compiled()  # the loop's variants and step-size control's judges
    settle()
    ball()
    pendulum()
    woodpecker()
    if args.piston:
        piston()
    attempt_cost()
    coarse_pair()


if __name__ == "__main__":
    main()
