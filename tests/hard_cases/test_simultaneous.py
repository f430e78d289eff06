"""Case 6 — simultaneous impacts: redundant floors, a rod landing flat on two supports,
and the piston slapping a wall with both corners of a side at once.

(``tests/test_ball.py`` compares two identical floors with one over three bounces; here
through the whole Zeno accumulation and the resting contact that follows.)
"""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import BallSolution, bouncing_ball
from moreau.problems.piston import PistonParameters, piston_model

from .conftest import assert_finite, audit_impacts

SOLVERS = ["enum", "osqp", "daqp"]
# tolerances on states compared between runs: the exact backends reproduce the one-floor
# run to round-off; OSQP's answers are exact to its eps = 1e-9 (relative, polished), which
# over a run leaves up to ~1e-10 (measured) in q and v
TOL = {"enum": 1e-12, "daqp": 1e-12, "osqp": 1e-9}


ZENO_E, ZENO_H = 0.9, 5e-4
ZENO_END = 1.2 * BallSolution(1.0, ZENO_E).zeno_time  # the accumulation, then rest


@pytest.fixture(scope="module")
def one_floor():
    return mo.simulate(bouncing_ball(ZENO_E), (0.0, ZENO_END), [1.0], [0.0], ZENO_H, solver="enum")


@pytest.mark.parametrize("solver", SOLVERS)
def test_two_identical_floors_through_zeno_and_rest(solver, one_floor):
    one = one_floor
    two = mo.simulate(bouncing_ball(ZENO_E, floors=2), (0.0, ZENO_END), [1.0], [0.0], ZENO_H, solver=solver)
    assert two.completed
    assert_finite(two)
    audit_impacts(two)
    np.testing.assert_allclose(two.q, one.q, atol=TOL[solver], rtol=0)
    np.testing.assert_allclose(two.v, one.v, atol=TOL[solver], rtol=0)
    # the generalized impulse Gᵀ P = P0 + P1 equals the single floor's, in flight, at the
    # impacts and in the resting contact (the split between the floors is not unique)
    np.testing.assert_allclose(two.impulses.sum(axis=1), one.impulses[:, 0], atol=10 * TOL[solver], rtol=0)
    # the same impact events (a solver may load one floor or both: rows differ, steps not)
    assert set(two.impacts.step.tolist()) == set(one.impacts.step.tolist())
    assert len(one.impacts) >= 50


# -- a rigid rod (x, y, θ) falling flat onto two supports under its ends ---------------------
M_ROD, L_ROD = 2.0, 1.0
J_ROD = M_ROD * L_ROD**2 / 12


def rod_scene(e):
    system = mo.FunctionSystem(np.diag([M_ROD, M_ROD, J_ROD]), name="rod")
    gravity = mo.ConstantForce([0.0, -9.81 * M_ROD, 0.0])

    def gap(q):  # heights of the two ends above the floor y = 0
        s = 0.5 * L_ROD * np.sin(q[2])
        return np.array([q[1] - s, q[1] + s])

    def jacobian(q):
        c = 0.5 * L_ROD * np.cos(q[2])
        return np.array([[0.0, 1.0, -c], [0.0, 1.0, c]])

    supports = mo.FunctionBarrier(gap, jacobian, nrows=2, ndof=3)
    assert mo.check_jacobian(supports, [0.1, 0.5, 0.3]).ok(1e-8)
    return mo.Scene(system, [gravity], [mo.Contact(supports, e, name="supports")], name="rod")


@pytest.mark.parametrize("solver", SOLVERS)
def test_rod_lands_flat_on_two_supports(solver):
    e, h, y0 = 0.5, 1e-3, 0.3
    traj = mo.simulate(rod_scene(e), (0.0, 1.0), [0.0, y0, 0.0], [0.2, 0.0, 0.0], h, solver=solver)
    assert traj.completed
    assert_finite(traj)
    audit_impacts(traj)
    imp = traj.impacts
    assert len(imp) >= 8
    # both ends hit in the same step, with equal impulses (to round-off)
    steps, counts = np.unique(imp.step, return_counts=True)
    assert np.all(counts == 2)
    P = imp.impulse.reshape(-1, 2)
    np.testing.assert_allclose(P[:, 0], P[:, 1], rtol=1e-12, atol=0)
    # no spurious rotation: θ and ω stay at round-off (1000 steps of ulps of O(1) terms)
    assert np.abs(traj.q[:, 2]).max() < 1e-12 and np.abs(traj.v[:, 2]).max() < 1e-12
    # and the rod's height is that of a ball of the same mass and restitution
    ball = mo.simulate(bouncing_ball(e, mass=M_ROD), (0.0, 1.0), [y0], [0.0], h, solver="enum")
    np.testing.assert_allclose(traj.q[:, 1], ball.q[:, 0], atol=TOL[solver], rtol=0)
    np.testing.assert_allclose(traj.q[:, 0], 0.2 * traj.t, atol=1e-12, rtol=0)  # sliding freely


# -- the piston slapping a wall with its top and bottom corners at once ------------------------
def piston_slap(solver):
    """Engine at rest (no forces), piston upright and centred, the pin moving sideways:
    both right corners approach the wall with the same normal speed."""
    model = piston_model(PistonParameters(e=0.5), effects=())
    lam = model.params.l2 / model.params.l1
    phi1 = np.pi / 2
    q0 = np.array([phi1, -np.arcsin(np.sin(phi1) / lam), 0.0])
    u = 0.01  # lateral pin velocity (non-dimensional): 50 steps across the half clearance
    v0 = np.array([0.0, u / (lam * np.cos(q0[1])), 0.0])
    scene = model.scene
    np.testing.assert_allclose(scene.jacobian(q0) @ v0, [-u, -u, u, u], rtol=1e-12)
    return mo.simulate(scene, (0.0, 0.1), q0, v0, 1e-3, solver=solver)


def test_piston_top_and_bottom_corners_close_in_the_same_step():
    runs = {s: piston_slap(s) for s in SOLVERS}
    for traj in runs.values():
        assert traj.completed and traj.stats.fallbacks == 0
        assert_finite(traj)
        audit_impacts(traj)
        imp = traj.impacts
        # one slap: top-right and bottom-right, in the same step
        assert imp.row.tolist() == [0, 1] and imp.step[0] == imp.step[1]
        assert np.all(imp.impulse > 0)
        # Newton's law on both rows: U⁺ = −e U⁻, so the impact does not create rotation
        # beyond e times the (tiny) pre-impact mismatch of the corners' normal velocities
        np.testing.assert_allclose(imp.U_after, -0.5 * imp.U_before, rtol=1e-10)
        dU_before = imp.U_before[0] - imp.U_before[1]
        dU_after = imp.U_after[0] - imp.U_after[1]
        assert abs(dU_after) <= 0.5 * abs(dU_before) * (1 + 1e-6) + 1e-15
        # the tilt stays far below the geometric limit (D − d)/s = 5e-4 rad
        assert np.abs(traj.q[:, 2]).max() < 1e-3 * 5e-4
    # the same step on all backends (v to 1e-8: OSQP's eps is 1e-9 relative)
    for solver in ("osqp", "daqp"):
        np.testing.assert_allclose(runs[solver].v, runs["enum"].v, atol=1e-8, rtol=0)
