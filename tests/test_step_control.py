"""Step-size control (mo.StepControl): errors against analytic and reference solutions,
the order of the extrapolated step, and runs cut into chunks equal to uncut ones."""

import warnings

import numpy as np
import pytest

import moreau as mo
from moreau.compiled import runner


@pytest.fixture(scope="module")
def ball():
    from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

    sol = BallSolution(1.0, 0.8)
    return bouncing_ball(0.8), np.array([sol.impact_time(k) for k in range(1, 7)])


@pytest.fixture(scope="module")
def smooth_pendulum():
    from scipy.integrate import solve_ivp

    from moreau.problems.pendulum_wall import pendulum_rhs, pendulum_wall

    ref = solve_ivp(pendulum_rhs(damping=0.5), (0, 2.0), (1.0, 0.5), method="DOP853", rtol=1e-13, atol=1e-13)
    return pendulum_wall(wall_x=None, damping=0.5), ref.y[:, -1]


def test_ball_impact_times_follow_the_tolerance(ball):
    """The first 6 impact times of the e = 0.8 ball (analytic) within 10x tol, and the
    error falls with tol; steps shrink only around impacts."""
    scene, t_ref = ball
    errors = []
    for tol in (1e-3, 1e-4, 1e-5, 1e-6):
        traj = mo.simulate(scene, (0.0, 4.5), [1.0], [0.0], 1e-2, energy=False, step_control=mo.StepControl(tol))
        assert traj.status == "completed" and traj.t[-1] == 4.5
        err = np.abs(traj.impacts.t[:6] - t_ref).max()
        assert err <= 10 * tol, (tol, err)
        errors.append(err)
        assert traj.stats.steps < 5000  # against 4.5e6 steps of h = 1e-6 for an error of 2.6e-6
        assert np.diff(traj.t).max() == pytest.approx(1e-2)  # the largest step in flight
    assert errors[-1] < errors[1] < errors[0]


def test_ball_never_crosses_the_floor_deeper_than_tol(ball):
    scene, _ = ball
    traj = mo.simulate(scene, (0.0, 2.0), [1.0], [0.0], 1e-2, energy=False, step_control=mo.StepControl(1e-5))
    assert traj.gaps.min() >= -1.01e-5


def test_extrapolated_steps_are_second_order(smooth_pendulum):
    """The damped pendulum (velocity-dependent force: the midpoint step is first order): with
    every step accepted at H (a tolerance never met) the extrapolated step is second order."""
    scene, y_end = smooth_pendulum
    err = []
    for h in (2e-2, 1e-2, 5e-3):
        traj = mo.simulate(scene, (0.0, 2.0), [1.0], [0.5], h, energy=False, step_control=mo.StepControl(1e6))
        assert traj.stats.steps == round(2.0 / h) and traj.stats.rejected == 0
        err.append(max(abs(traj.q[-1, 0] - y_end[0]), abs(traj.v[-1, 0] - y_end[1])))
    orders = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    assert orders.min() > 1.9, orders


def test_smooth_error_falls_with_the_tolerance(smooth_pendulum):
    """Error against DOP853 within 20x tol over five decades, and falling with it."""
    scene, y_end = smooth_pendulum
    errors = []
    for tol in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7):
        traj = mo.simulate(scene, (0.0, 2.0), [1.0], [0.5], 0.1, energy=False, step_control=mo.StepControl(tol))
        errors.append(max(abs(traj.q[-1, 0] - y_end[0]), abs(traj.v[-1, 0] - y_end[1])))
        assert errors[-1] <= 20 * tol, (tol, errors[-1])
    assert all(b < a for a, b in zip(errors, errors[1:])), errors


@pytest.mark.parametrize("control", [None, mo.StepControl(1e-6)], ids=["fixed", "adaptive"])
def test_a_run_cut_into_chunks_equals_the_uncut_run(ball, monkeypatch, control):
    """The runner resumes the loop chunk after chunk (Ctrl-C is honoured between them): a run
    cut after 1, 3, 7, ... steps equals the run in one chunk, bit for bit."""
    scene, _ = ball
    run = lambda: mo.simulate(scene, (0.0, 1.5), [1.0], [0.0], 1e-3, step_control=control)  # noqa: E731
    whole = run()
    monkeypatch.setattr(runner, "FIRST_CHUNK", 1)
    cut = run()
    for name in ("t", "q", "v", "impulses", "gaps"):
        np.testing.assert_array_equal(getattr(cut, name), getattr(whole, name))
    np.testing.assert_array_equal(cut.impacts.t, whole.impacts.t)
    assert (cut.stats.steps, cut.stats.rejected) == (whole.stats.steps, whole.stats.rejected)


def test_step_control_refuses_bad_values(ball):
    scene, _ = ball
    for kwargs, word in (({"tol": 0.0}, "tol"), ({"tol": 1e-6, "rtol": -1.0}, "rtol"),
                         ({"tol": float("nan")}, "tol"), ({"tol": 1e-6, "h_min": 0.0}, "h_min")):
        with pytest.raises(ValueError, match=word):
            mo.StepControl(**kwargs)
    with pytest.raises(ValueError, match="h_min"):
        mo.simulate(scene, (0.0, 0.1), [1.0], [0.0], 1e-3, step_control=mo.StepControl(1e-6, h_min=1e-2))
    with pytest.raises(ValueError, match="step_control"):
        mo.simulate(scene, (0.0, 0.1), [1.0], [0.0], 1e-3, step_control=1e-6)


@pytest.mark.slow
def test_friction_and_impacts_follow_the_tolerance():
    """The woodpecker (friction, impacts, the full loop variant): the times of its returns
    to Glocker's state within 3x tol of a fixed h = 1e-6 run, in fewer steps than h = 1e-4."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    from wp_friction import _returns

    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    scene, (q0, v0) = woodpecker(), GLOCKER_STATE
    ref = _returns(mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-6, energy=False))
    traj = mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-3, energy=False, step_control=mo.StepControl(1e-5))
    got = _returns(traj)
    assert got.shape == ref.shape
    assert np.abs(got[:, 0] - ref[:, 0]).max() <= 3e-5
    assert traj.stats.steps < 4500


@pytest.mark.slow
def test_a_closed_loop_with_a_stop_under_step_control_stays_closed():
    """The four-bar with a stop (bilateral rows, an impact through the loop, drift control,
    the predictor–corrector): the loop stays closed to 1e-10, the energy lost is the
    contact work to 1e-3 of it, and the stop holds to the tolerance."""
    from moreau.problems.four_bar import four_bar

    fb = four_bar(stop=0.75, e=0.5)
    q0, v0 = fb.initial_state(0.3, 5.0)
    traj = mo.simulate(fb.scene, (0.0, 3.0), q0, v0, 1e-2, energy=True, integrator=mo.MoreauJeanPredictorCorrector,
                       drift_control=mo.CombinedProjection(), step_control=mo.StepControl(1e-6))
    assert traj.completed and len(traj.impacts) >= 2
    assert np.abs(traj.constraint_residuals).max() <= 1e-10
    lost = traj.energy[0] - traj.energy[-1]
    assert traj.work["contacts"] < 0 and abs(lost + traj.work["contacts"]) <= 1e-3 * abs(traj.work["contacts"])
    assert traj.gaps.min() >= -1e-6


def test_the_impact_log_names_accepted_steps(ball):
    """With step control the log's step is the index of the accepted step (the record it
    starts from at record_every=1), and its time lies in that step."""
    scene, _ = ball
    traj = mo.simulate(scene, (0.0, 2.0), [1.0], [0.0], 1e-2, energy=False, step_control=mo.StepControl(1e-5))
    im = traj.impacts
    assert len(im) >= 2 and im.step.max() < traj.stats.steps
    assert np.all(traj.t[im.step] <= im.t) and np.all(im.t < traj.t[im.step + 1])


def test_an_error_floor_near_the_tolerance_does_not_stall_the_step():
    """The e = 0 piston's step-doubling estimate has a round-off floor (about 2.7e-11 in one
    velocity after t = 5.66, whatever H): at tol = 3e-11 every accepted step sat at 0.9 of
    the tolerance at h_min, shrinking instead of growing, and the 2 cycles took 5.5 million
    steps (tol = 4.4e-11: 36 000). A step accepted within the tolerance whose error did not
    grow with H is grown through the floor."""
    from moreau.problems.piston.model import piston_model
    from moreau.problems.piston.params import PistonParameters

    model = piston_model(PistonParameters(e=0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (steps forced at h_min where the floor is above tol: warned)
        traj = model.simulate(2, 0.3, energy=False, drift_control=mo.PositionProjection(velocity=True),
                              step_control=mo.StepControl(3e-11), progress=False)
    assert traj.status == "completed"
    assert traj.stats.steps < 200_000, traj.stats


def test_steps_forced_at_h_min_are_counted_and_warned_with_the_remedy(ball):
    """An h_min too large to resolve the ball's impacts to tol: the steps accepted there
    above the tolerance are counted, and the warning names the causes and what to change."""
    scene, _ = ball
    with pytest.warns(RuntimeWarning, match="lower h_min, or raise tol"):
        traj = mo.simulate(scene, (0.0, 1.0), [1.0], [0.0], 1e-2, energy=False,
                           step_control=mo.StepControl(1e-6, h_min=5e-3))
    assert traj.stats.forced > 0 and any("h_min" in w for w in traj.warnings)
