"""Cost of one time step (µs) for free-flight and contact steps with each backend.

Prints a table, and the ratio of OSQP set up once and updated each step to OSQP rebuilt
every step through ``qpsolvers.solve_qp``. Absolute times on a shared 2-core machine are
noisy: read the ratios, which are measured in the same run.

    python benchmarks/step_cost.py [--steps N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import moreau as mo
from problems.bouncing_ball import bouncing_ball
from problems.pendulum_wall import pendulum_wall
from problems.piston import PistonParameters, piston_model


def three_dof_four_rows() -> tuple[mo.Scene, np.ndarray, np.ndarray]:
    """A 3-DOF body pressed by a force into a corner of 4 planes (2 active): the size of
    the piston's contact problem."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 3))
    M = A @ A.T + 3 * np.eye(3)
    G = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.3], [-1.0, 0.1, 0.0], [0.0, -1.0, 0.2]])
    barrier = mo.LinearBarrier(G, [0.0, 0.0, 1.0, 1.0])
    push = mo.ConstantForce(-(G[0] + G[1]), name="push")
    scene = mo.Scene(mo.FunctionSystem(M), [push], [mo.Contact(barrier, 0.5, name="walls")], name="3dof-4rows")
    return scene, np.zeros(3), np.zeros(3)


def cases():
    ball = bouncing_ball(0.5)
    yield "free flight (pendulum, n=1)", pendulum_wall(wall_x=None), [0.3], [0.0]
    yield "contact (ball at rest, n=1, m=1)", ball, [0.0], [0.0]
    scene, q0, v0 = three_dof_four_rows()
    yield "contact (n=3, m=4, 2 active)", scene, q0, v0
    piston = piston_model(PistonParameters(e=0.0))
    q0, v0 = piston.initial_state(phi1=np.radians(60.0))  # adjoining the left wall, sliding
    yield "piston sliding (n=3, m=4, config. M)", piston.scene, q0, v0


def time_case(scene, q0, v0, solver, steps, h=1e-4):
    traj = mo.simulate(scene, (0.0, steps * h), q0, v0, h, solver=solver, energy=False, fallback="enum")
    return traj.stats.us_per_step, traj.stats.fallbacks


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20_000, help="steps per measurement")
    args = ap.parse_args(argv)
    solvers = {
        "osqp (update)": lambda: mo.OSQPSolver(),
        "qpsolvers:osqp (rebuild)": lambda: mo.QpsolversSolver("osqp", eps_abs=1e-9, eps_rel=1e-9, polish=True),
        "enum": lambda: mo.EnumerationSolver(),
        "daqp": lambda: mo.make_solver("daqp"),
        "quadprog": lambda: mo.make_solver("quadprog"),
    }
    rows = []
    for label, scene, q0, v0 in cases():
        for sname, make in solvers.items():
            steps = args.steps if "rebuild" not in sname else max(1000, args.steps // 10)
            t0 = time.perf_counter()
            us, fb = time_case(scene, q0, v0, make(), steps)
            rows.append((label, sname, us, fb))
            del t0
    w = max(len(r[0]) for r in rows)
    print(f"{'case':<{w}}  {'solver':<26} {'µs/step':>9} {'fallbacks':>9}")
    for label, sname, us, fb in rows:
        print(f"{label:<{w}}  {sname:<26} {us:9.1f} {fb:9d}")
    # drift control on the piston: same steps with and without the position projection
    piston = piston_model(PistonParameters(e=0.0))
    q0, v0 = piston.initial_state(phi1=np.radians(60.0))
    cost = {}
    for dc in (None, mo.PositionProjection()):
        traj = mo.simulate(piston.scene, (0.0, args.steps * 1e-4), q0, v0, 1e-4, solver="enum",
                           energy=False, drift_control=dc)
        cost[dc is not None] = traj.stats.us_per_step
    print(f"piston sliding, enum: {cost[False]:.1f} µs/step plain, {cost[True]:.1f} with drift control "
          f"(ratio {cost[True] / cost[False]:.2f})")
    by = {(r[0], r[1]): r[2] for r in rows}
    for label in dict.fromkeys(r[0] for r in rows):
        if not label.startswith("free"):
            ratio = by[(label, "qpsolvers:osqp (rebuild)")] / by[(label, "osqp (update)")]
            print(f"ratio rebuild/update for {label}: {ratio:.1f}x")


if __name__ == "__main__":
    main()
