"""Order of convergence in smooth phases against scipy's DOP853 (issue 2 acceptance)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import moreau as mo
from moreau.problems.pendulum_wall import pendulum_rhs, pendulum_wall
from moreau.results.diagnostics import convergence_order

STEPS = [0.02, 0.01, 0.005, 0.0025, 0.00125]


def errors_against_dop853(damping):
    T, y0 = 1.0, [1.0, 0.5]
    ref = solve_ivp(pendulum_rhs(damping=damping), (0, T), y0, method="DOP853", rtol=1e-13, atol=1e-13)
    assert ref.success
    scene = pendulum_wall(wall_x=None, damping=damping)
    errs = []
    for h in STEPS:
        traj = mo.simulate(scene, (0.0, T), [y0[0]], [y0[1]], h)
        errs.append(max(abs(traj.q[-1, 0] - ref.y[0, -1]), abs(traj.v[-1, 0] - ref.y[1, -1])))
    return np.array(errs)


def test_position_only_forces_constant_mass_second_order():
    scene = pendulum_wall(wall_x=None)
    assert scene.system.constant_mass and not scene.velocity_dependent
    assert convergence_order(STEPS, errors_against_dop853(0.0)) == pytest.approx(2.0, abs=0.15)


def test_viscous_damping_first_order():
    assert pendulum_wall(wall_x=None, damping=0.5).velocity_dependent
    assert convergence_order(STEPS, errors_against_dop853(0.5)) == pytest.approx(1.0, abs=0.15)


def test_convergence_order_fit_recovers_known_slopes():
    h = np.array(STEPS)
    assert convergence_order(h, 3 * h**1.5) == pytest.approx(1.5, abs=1e-12)
    with pytest.raises(ValueError, match="positive"):
        convergence_order(h, np.zeros_like(h))
