"""Drift control and the θ = ½ variant: what they change, and what they leave alone."""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.problems.pendulum_wall import pendulum_wall


def bead_in_circle(e=0.0):
    """A point mass pressed by gravity against the inside of a circle of radius 1: a curved
    barrier g = 1 − |p| >= 0 on which the midpoint scheme drifts outward."""
    barrier = mo.FunctionBarrier(
        gap=lambda q: np.array([1.0 - np.hypot(q[0], q[1])]),
        jacobian=lambda q: -np.atleast_2d(q / np.hypot(q[0], q[1])),
        ndof=2,
    )
    return mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([0.0, -9.81])],
                    [mo.Contact(barrier, e, name="circle")], name="bead")


def test_projection_removes_the_drift_on_a_curved_barrier():
    scene = bead_in_circle()
    q0, v0 = [0.0, -1.0], [3.0, 0.0]  # sliding along the bottom of the circle
    plain = mo.simulate(scene, (0.0, 2.0), q0, v0, 1e-2, solver="enum")
    proj = mo.simulate(scene, (0.0, 2.0), q0, v0, 1e-2, solver="enum", drift_control=mo.PositionProjection())
    drift = -plain.gaps.min()
    assert drift > 1e-3  # the scheme's drift is real: O(h) over the run
    assert -proj.gaps.min() < 1e-6 * drift  # and the projection removes it
    assert proj.stats.projections > 0 and plain.stats.projections == 0


def test_projection_changes_nothing_without_penetration():
    scene = pendulum_wall(e=0.8)
    a = mo.simulate(scene, (0.0, 0.3), [-0.2], [0.0], 1e-3)  # never reaches the wall
    b = mo.simulate(scene, (0.0, 0.3), [-0.2], [0.0], 1e-3, drift_control=mo.PositionProjection())
    np.testing.assert_array_equal(a.q, b.q)
    assert b.stats.projections == 0


def test_projection_on_a_flat_floor_is_exact_for_the_ball():
    # a flat floor has no curvature: the projection only removes the impact-step penetration
    traj = mo.simulate(bouncing_ball(0.0), (0.0, 1.0), [1.0], [0.0], 1e-3, drift_control=mo.PositionProjection())
    assert traj.q[:, 0].min() >= -1e-15


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_projection_rejects_bad_iterations(bad):
    with pytest.raises(ValueError, match="max_iter must be a positive integer"):
        mo.PositionProjection(max_iter=bad)


def test_theta_equals_midpoint_without_velocity_dependent_forces():
    scene = pendulum_wall(e=0.8)
    assert not scene.velocity_dependent
    a = mo.simulate(scene, (0.0, 1.0), [-0.5], [2.0], 1e-3)
    b = mo.simulate(scene, (0.0, 1.0), [-0.5], [2.0], 1e-3, integrator=mo.MoreauJeanPredictorCorrector)
    np.testing.assert_array_equal(a.q, b.q)


def test_theta_with_damping_and_impacts_loses_no_energy_at_impacts():
    scene = pendulum_wall(e=0.8, damping=0.3)
    traj = mo.simulate(scene, (0.0, 3.0), [-0.5], [3.0], 1e-3, integrator=mo.MoreauJeanPredictorCorrector,
                       solver="enum")
    assert len(traj.impacts) >= 2  # the pendulum swings back to the wall once in 3 s
    assert traj.impacts.energy_lost.min() > 0
    np.testing.assert_allclose(traj.impacts.U_after, -0.8 * traj.impacts.U_before, rtol=0.02)


def test_projection_leaves_bouncing_rows_alone_so_they_come_to_rest():
    # projecting an e > 0 contact without touching its velocity kept it bouncing at ~h g
    ball = bouncing_ball(0.8)
    plain = mo.simulate(ball, (0.0, 6.0), [1.0], [0.0], 1e-3, solver="enum")
    proj = mo.simulate(ball, (0.0, 6.0), [1.0], [0.0], 1e-3, solver="enum", drift_control=mo.PositionProjection())
    assert len(proj.impacts) == len(plain.impacts)
    assert np.abs(proj.v[-500:, 0]).max() < 1e-9  # at rest at the end
    every = mo.simulate(ball, (0.0, 6.0), [1.0], [0.0], 1e-3, solver="enum",
                        drift_control=mo.PositionProjection(max_restitution=1.0))
    assert len(every.impacts) > 5 * len(plain.impacts)  # the behaviour the default avoids


def test_former_name_of_the_predictor_corrector_still_works():
    assert mo.MoreauJeanTheta is mo.MoreauJeanPredictorCorrector
    assert "MoreauJeanTheta" not in mo.__all__
