"""The event-driven reference (issue 5): exact on the bouncing ball, Newton's reset for a
general mass matrix, and moreau's impact times converging to it at first order."""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import BallSolution, bouncing_ball
from moreau.problems.event_driven import event_driven, moreau_impact_times, pendulum_wall_reference
from moreau.problems.pendulum_wall import pendulum_wall
from moreau.results.diagnostics import convergence_order

G = 9.81


def ball_reference(e, h0=1.0, t_end=10.0, **kw):
    return event_driven(lambda t, y: [y[1], -G], lambda q: q[0], lambda q: np.array([[1.0]]),
                        np.array([[1.0]]), e, (0.0, t_end), [h0, 0.0], **kw)


@pytest.mark.parametrize("e", [0.5, 0.8])
def test_ball_impact_times_apexes_and_zeno_match_the_analytic_solution(e):
    ref = ball_reference(e)
    exact = BallSolution(1.0, e)
    k = np.arange(1, ref.impact_times.size + 1)
    assert ref.impact_times.size > 10
    np.testing.assert_allclose(ref.impact_times, [exact.impact_time(i) for i in k], rtol=0, atol=1e-9)
    # rebound speeds follow Newton's law exactly
    np.testing.assert_allclose(ref.impact_velocities[:, 1], -e * ref.impact_velocities[:, 0], rtol=1e-12)
    # dense output reproduces the parabolas between the impacts
    t = np.linspace(0.0, ref.t_end, 2001)
    q, _ = ref.state(t)
    np.testing.assert_allclose(q[:, 0], exact.position(t), atol=1e-9)
    # the Zeno guard stops just before the accumulation point and says so
    assert ref.status == "zeno"
    assert "rebound speed" in ref.message
    assert 0.0 < exact.zeno_time - ref.t_end < 1e-5


def test_zeno_guard_threshold_and_e_zero():
    coarse = ball_reference(0.5, min_rebound=1e-2)
    fine = ball_reference(0.5, min_rebound=1e-8)
    assert coarse.status == fine.status == "zeno"
    assert coarse.impact_times.size < fine.impact_times.size
    assert ball_reference(0.0).impact_times.size == 1  # e = 0 sticks at the first impact
    capped = ball_reference(0.8, max_impacts=5)
    assert capped.status == "max_impacts" and capped.impact_times.size == 5


def test_unpacks_and_keeps_pre_and_post_impact_states():
    t, q, v, impact_times = ball_reference(0.5, t_end=1.0)
    assert impact_times.size == 2
    i = np.flatnonzero(t == impact_times[0])
    assert i.size == 2  # the impact time appears twice
    assert v[i[0], 0] < 0 < v[i[1], 0]
    assert q.shape == v.shape == (t.size, 1)


def test_newton_reset_with_a_full_mass_matrix():
    """A point mass with a non-diagonal mass matrix hits the inclined floor y >= 0.2 x:
    G v⁺ = −e G v⁻ and M (v⁺ − v⁻) is along Gᵀ (a normal impulse)."""
    M = np.array([[2.0, 0.3], [0.3, 1.0]])
    Minv = np.linalg.inv(M)
    f = np.array([0.0, -9.81 * 2.0])
    Gr = np.array([-0.2, 1.0])

    def rhs(t, y):
        return np.concatenate([y[2:], Minv @ f])

    e = 0.7
    ref = event_driven(rhs, lambda q: q[1] - 0.2 * q[0], lambda q: Gr[None, :], M, e, (0.0, 0.6),
                       [0.0, 1.0, 1.0, 0.0])
    assert ref.impact_times.size == 1
    i = np.flatnonzero(ref.t == ref.impact_times[0])
    v_minus, v_plus = ref.v[i[0]], ref.v[i[1]]
    assert Gr @ v_plus == pytest.approx(-e * (Gr @ v_minus), rel=1e-12)
    impulse = M @ (v_plus - v_minus)
    assert abs(impulse[0] * Gr[1] - impulse[1] * Gr[0]) < 1e-12 * np.linalg.norm(impulse)
    assert impulse @ Gr > 0


def test_pendulum_reference_conserves_energy_with_e_one():
    ref = pendulum_wall_reference(e=1.0, wall_x=0.5, t_end=8.0, theta0=0.0, omega0=4.0, damping=0.0)
    assert ref.status == "completed" and ref.impact_times.size >= 4
    E = 0.5 * ref.v[:, 0] ** 2 - 9.81 * np.cos(ref.q[:, 0])
    assert np.ptp(E) < 1e-9
    # every impact happens at the wall: sin θ = x_w / l
    i = np.searchsorted(ref.t, ref.impact_times)
    np.testing.assert_allclose(np.sin(ref.q[i, 0]), 0.5, atol=1e-12)


def test_refuses_bad_input():
    with pytest.raises(ValueError, match="restitution"):
        ball_reference(1.5)
    with pytest.raises(ValueError, match="penetrates"):
        event_driven(lambda t, y: [y[1], -G], lambda q: q[0], lambda q: [[1.0]], [[1.0]], 0.5, (0, 1), [-0.1, 0])


def test_moreau_impact_times_interpolate_inside_the_step():
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, solver="enum")
    ti = moreau_impact_times(traj)
    exact = BallSolution(1.0, 0.5)
    # free flight is exact for the midpoint scheme: the first impact is off only by the
    # linear interpolation, O(h²) (a step start alone would be off by up to h)
    assert ti[0] == pytest.approx(exact.t1, abs=2 * traj.h**2)
    assert abs(traj.impacts.t[0] - exact.t1) > 10 * abs(ti[0] - exact.t1)
    assert np.all(np.abs(ti - traj.impacts.t) <= traj.h)
    with pytest.raises(ValueError, match="record_every"):
        moreau_impact_times(mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, record_every=2))


# Pendulum hitting the wall x = 0.5 with e = 0.9 and light damping: 10 isolated impacts
# in 15 s. The impact-time error of a time-stepper is O(h) with a factor that depends on
# where each impact falls inside its step; the mean over 10 impacts averages it out.
E, WALL, DAMPING, OMEGA0, T_END = 0.9, 0.5, 0.05, 4.0, 15.0
STEPS = [1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4]


@pytest.fixture(scope="module")
def pendulum_reference():
    ref = pendulum_wall_reference(E, WALL, T_END + 1.0, 0.0, OMEGA0, DAMPING)
    return ref.impact_times[ref.impact_times <= T_END]


@pytest.mark.parametrize("integrator", [mo.MoreauJeanMidpoint, mo.MoreauJeanPredictorCorrector])
def test_moreau_impact_times_converge_to_the_reference_at_first_order(integrator, pendulum_reference):
    scene = pendulum_wall(e=E, wall_x=WALL, damping=DAMPING)
    assert pendulum_reference.size == 10
    errors = []
    for h in STEPS:
        traj = mo.simulate(scene, (0.0, T_END), [0.0], [OMEGA0], h, integrator=integrator, solver="enum",
                           energy=False)
        ti = moreau_impact_times(traj)
        assert ti.size == pendulum_reference.size, f"h = {h}: {ti.size} impacts"
        errors.append(np.abs(ti - pendulum_reference).mean())
    assert errors[-1] < 2e-3
    assert convergence_order(STEPS, errors) == pytest.approx(1.0, abs=0.2)
