"""Case 13 — initial penetration and inconsistent initial velocities, as documented:
a penetrating start is refused with ValueError naming the rows and their gaps (within
the 1e-12 tolerance it is accepted); an approaching velocity on a closed contact is
resolved by the first step's impact.

(``tests/test_api.py`` checks the refusal message for the ball's floor.)
"""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.problems.piston import PistonParameters, piston_model

from .conftest import assert_finite, audit_impacts


def shifted_piston(shift_over_half_clearance, e=0.5, lateral_speed=0.0):
    """The upright piston at firing TDC, its pin moved right by the given multiple of
    the half clearance, moving right at ``lateral_speed`` (non-dimensional)."""
    model = piston_model(PistonParameters(e=e))
    q0, v0 = model.initial_state(0.0)
    lam = model.params.l2 / model.params.l1
    half = 0.5 * model.params.clearance / model.params.l1
    q0[1] = np.arcsin(shift_over_half_clearance * half / lam)  # x_pin = λ sin φ2 at φ1 = 0
    v0[1] += lateral_speed / (lam * np.cos(q0[1]))
    return model, q0, v0


def test_penetrating_piston_refused_naming_rows_and_gaps():
    model, q0, v0 = shifted_piston(1.2)  # 0.2 half clearance = 4 µm = 1e-4 inside the wall
    with pytest.raises(ValueError, match=r"initial state penetrates a barrier \(cylinder\[top-right\]: "
                                         r"g = -0\.0001, cylinder\[bottom-right\]: g = -0\.0001\)"):
        mo.simulate(model.scene, (0.0, 0.01), q0, v0, 1e-3)
    # and on the other side, the left wall's rows
    _, q_left, v_left = shifted_piston(-1.2)
    with pytest.raises(ValueError, match=r"cylinder\[top-left\]: g = -0\.0001, cylinder\[bottom-left\]"):
        mo.simulate(model.scene, (0.0, 0.01), q_left, v_left, 1e-3)


def test_penetration_within_tolerance_is_accepted_and_resolved():
    # a penetration of 1e-13, within penetration_tol = 1e-12: accepted, not projected
    model, q0, v0 = shifted_piston(1.0 + 2e-10)
    g0 = model.scene.gaps(q0)
    assert -1e-12 < g0.min() < 0
    traj = mo.simulate(model.scene, (0.0, 0.2), q0, v0, 1e-3, solver="enum")
    assert traj.completed
    assert_finite(traj)
    audit_impacts(traj)
    np.testing.assert_array_equal(traj.q[0], q0)  # the start is kept as given


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_ball_on_the_floor_moving_down_bounces_in_the_first_step(e):
    h = 1e-3
    traj = mo.simulate(bouncing_ball(e), (0.0, 0.05), [0.0], [-1.0], h, solver="enum")
    assert traj.completed
    audit_impacts(traj)
    imp = traj.impacts
    assert imp.step[0] == 0 and imp.U_before[0] == -1.0
    assert imp.U_after[0] == pytest.approx(e, abs=1e-15)  # Newton: U⁺ = −e U⁻
    assert traj.v[1, 0] == pytest.approx(e, abs=1e-15)
    # the step goes h/2 |v| in before the impact and comes back h/2 e: q⁺ = −h (1 − e)/2
    assert traj.q[1, 0] == pytest.approx(-0.5 * h * (1 - e), abs=1e-15)
    assert traj.q[:, 0].min() >= -0.5 * h  # never deeper than the midpoint
    if e > 0:
        assert traj.q[-1, 0] > 0  # and it flies off


def test_piston_touching_the_wall_and_moving_into_it_bounces_in_the_first_step():
    e, u = 0.5, 0.01
    model, q0, v0 = shifted_piston(1.0, e=e, lateral_speed=u)
    g0, U0 = model.scene.gaps(q0), model.scene.jacobian(q0) @ v0
    assert np.abs(g0[:2]).max() < 1e-12 and np.all(U0[:2] < 0)  # closed and approaching
    traj = mo.simulate(model.scene, (0.0, 0.05), q0, v0, 1e-3, solver="enum")
    assert traj.completed
    assert_finite(traj)
    audit_impacts(traj)
    imp = traj.impacts
    first = imp.select(imp.step == 0)
    assert sorted(first.row.tolist()) == [0, 1]  # both right corners, in the first step
    np.testing.assert_allclose(first.U_after, -e * first.U_before, rtol=1e-9)
    # after the first step the right corners separate (the 1e-3 step: midpoint at h/2 u)
    assert np.all(model.scene.jacobian(traj.q[1])[:2] @ traj.v[1] > 0)
    assert -traj.gaps[:, :2].min() <= 0.5 * 1e-3 * u * (1 + 1e-6)
