"""Leaving a curved barrier: drift control with and without ``velocity=True``.

Prints, in one run, for ``mo.PositionProjection()`` and ``mo.PositionProjection(velocity=True)``:

1. a particle sliding off a frictionless circle of radius R = 1 m from its top at
   v0 = 0.5 m/s (g = 9.81 m/s², e = 0): the angle of the last record on the circle
   against the analytic lift-off angle, cos θ = (2 + v0²/(g R)) / 3 (47.533°), and the
   largest error of the normal force read from the records (impulse / h) before it,
   against N = m (g cos θ − v²/R), v² = v0² + 2 g R (1 − cos θ);
2. the e = 0 piston over 2 cycles: the side-change angles of the last cycle
   (``problems.piston.analysis.cycle_figures``) against a run with ``velocity=True`` at
   h = 1e-5, and the wall time (best of up to ten runs within 0.5 s).

    python benchmarks/leaving_barrier.py      # about 15 s on 2 cores
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

sys.path[:0] = [str(Path(__file__).parent), str(Path(__file__).parents[1])]
from wp_configs import _timed  # noqa: E402
from wp_problems import _angle_distance  # noqa: E402

import moreau as mo  # noqa: E402

R, G0, M, V0 = 1.0, 9.81, 1.0, 0.5


def circle_scene() -> mo.Scene:
    """A point mass (x, y) outside the circle |q| >= R under gravity, e = 0."""
    system = mo.FunctionSystem(M * np.eye(2))
    gravity = mo.ConstantForce([0.0, -G0 * M], name="gravity")
    circle = mo.FunctionBarrier(gap=lambda q: np.array([np.hypot(q[0], q[1]) - R]),
                                jacobian=lambda q: np.array([[q[0], q[1]]]) / np.hypot(q[0], q[1]))
    return mo.Scene(system, [gravity], [mo.Contact(circle, mo.NewtonImpact(0.0), name="circle")])


def liftoff_deg() -> float:
    """The analytic lift-off angle from the top (degrees)."""
    return float(np.degrees(np.arccos((2.0 + V0**2 / (G0 * R)) / 3.0)))


def circle_errors(traj: mo.Trajectory, h: float) -> tuple[float, float]:
    """(angle of the last record on the circle − the analytic lift-off angle (deg), the
    largest |impulse/h − N| before it (N))."""
    on = np.flatnonzero(traj.gaps[:, 0] <= 1e-12)
    theta = np.arctan2(traj.q[:, 0], traj.q[:, 1])
    last = float(np.degrees(theta[on[-1]]))
    before = np.flatnonzero(np.degrees(theta) < liftoff_deg() - 5.0)[1:]
    c = np.cos(theta[before])
    normal = M * (G0 * c - (V0**2 + 2.0 * G0 * R * (1.0 - c)) / R)
    return last - liftoff_deg(), float(np.abs(traj.impulses[before, 0] / h - normal).max())


def circle() -> None:
    scene = circle_scene()
    print(f"\n1. Particle off a circle (R = {R} m, v0 = {V0} m/s): lift-off at {liftoff_deg():.3f} deg")
    print(f"  {'drift control':<34} {'h':>7} {'angle error (deg)':>18} {'normal force error (N)':>23}")
    for velocity in (False, True):
        for h in (1e-2, 1e-3, 1e-4):
            traj = mo.simulate(scene, (0.0, 1.2), [0.0, R], [V0, 0.0], h, energy=False,
                               drift_control=mo.PositionProjection(velocity=velocity))
            da, dn = circle_errors(traj, h)
            print(f"  {f'PositionProjection(velocity={velocity})':<34} {h:7.0e} {da:+18.4f} {dn:23.3g}")


def piston() -> None:
    from problems.piston.analysis import cycle_figures
    from problems.piston.model import piston_model
    from problems.piston.params import PistonParameters

    params = PistonParameters(e=0.0)
    model = piston_model(params)

    def run(h, velocity):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _timed(lambda: model.simulate(2, h, energy=False, record_every=1,
                                                 drift_control=mo.PositionProjection(velocity=velocity)),
                          repeat_below=0.5)

    angles = lambda traj: cycle_figures(traj, params)[-1].change_angles_deg  # noqa: E731
    ref = angles(run(1e-5, True)[0])
    print("\n2. Piston e = 0, 2 cycles: side-change angles of the last cycle against velocity=True at h = 1e-5")
    print(f"  {'drift control':<34} {'h':>9} {'error (deg)':>12} {'wall (s)':>9}")
    for velocity in (False, True):
        for h in (1e-3, 3.16e-4, 1e-4):
            traj, wall, _ = run(h, velocity)
            err = _angle_distance(angles(traj), ref)
            print(f"  {f'PositionProjection(velocity={velocity})':<34} {h:9.3g} {err:12.4f} {wall:9.3f}")


def main() -> None:
    circle()
    piston()


if __name__ == "__main__":
    main()
