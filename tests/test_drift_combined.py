"""CombinedProjection: drift control for every restitution (issue: drift control for every e).

- a planar block pressed flat against a wall by a force, two corners in contact, leaves
  the pressed phase without spinning, on a ladder of h (the position-only projection of
  bouncing rows does not: it pumps a rocking that the pressing force feeds);
- a ball with e = 1 gains no energy at any impact and does not drift over 10 000 impacts;
- the compiled and the Python path take the same steps.
"""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

# the block: half-width A, half-height B (m), mass 1 kg, corners (±A, −B) on the wall y = 0
A, B, MASS = 0.2, 0.05, 1.0
INERTIA = MASS * ((2 * A) ** 2 + (2 * B) ** 2) / 12
F0 = 20.0  # N
T_PRESS = 1.0  # s


def _gap(q):
    _, y, p = q
    s, c = np.sin(p), np.cos(p)
    return np.array([y + A * s - B * c, y - A * s - B * c])


def _jac(q):
    _, _, p = q
    s, c = np.sin(p), np.cos(p)
    return np.array([[0.0, 1.0, A * c + B * s], [0.0, 1.0, -A * c + B * s]])


def _force(t, q, v):
    # pressed down off-centre (a torque) until T_PRESS, then pulled away through the centre
    if t < T_PRESS:
        return np.array([0.0, -F0, -0.05 * F0])
    return np.array([0.0, 2.0 * F0, 0.0])


def block(e):
    system = mo.FunctionSystem(np.diag([MASS, MASS, INERTIA]), name="block")
    press = mo.FunctionForce(_force, velocity_dependent=False, name="press")
    corners = mo.Contact(mo.FunctionBarrier(_gap, _jac, nrows=2), mo.NewtonImpact(e), name="corners")
    return mo.Scene(system, [press], [corners], name="block")


def tilt_rate_after_press(e, h, drift_control):
    """Largest |dφ/dt| (rad/s) once the block has left the wall, and the run."""
    phi0 = 0.02  # lands tilted on one corner, sliding at 1 m/s
    q0 = [0.0, B * np.cos(phi0) + A * np.sin(phi0), phi0]
    traj = mo.simulate(block(e), (0.0, T_PRESS + 0.3), q0, [1.0, -0.5, 0.0], h, drift_control=drift_control,
                       backend="python", solver="exact", progress=False)
    assert traj.completed
    left = traj.t[np.flatnonzero(traj.impulses.sum(axis=1) > 0)[-1]]
    assert T_PRESS - 2 * h <= left <= T_PRESS + 0.01  # pressed until the force turned
    flying = traj.t > left + 0.01
    return float(np.abs(traj.v[flying, 2]).max()), traj


@pytest.mark.parametrize("e", [0.5, 0.9])
@pytest.mark.parametrize("h", [1e-3, 3e-4, 1e-4])
def test_block_pressed_on_two_corners_leaves_without_spin(e, h):
    rate, traj = tilt_rate_after_press(e, h, mo.CombinedProjection())
    assert rate < 1e-8, rate
    # and the corners stayed out of the wall: the penetration of a landing, O(h·|U|)
    assert traj.max_penetration.max() < 0.5 * h * 0.5 + 1e-12


def test_position_only_projection_of_bouncing_rows_leaves_the_block_spinning():
    """What the combined projection fixes: positions projected, velocities kept."""
    rate, _ = tilt_rate_after_press(0.9, 1e-3, mo.PositionProjection(max_restitution=1.0))
    assert rate > 1e-4


def test_position_projection_warns_when_it_projects_no_row():
    with pytest.warns(RuntimeWarning, match=r"projects no row .* every row has e > 0"):
        mo.simulate(bouncing_ball(0.5), (0.0, 0.1), [0.1], [0.0], 1e-3, drift_control=mo.PositionProjection(),
                    progress=False)


def test_elastic_ball_gains_no_energy_over_ten_thousand_impacts():
    g, h0, h = 9.81, 1.0, 1e-3
    period = 2.0 * np.sqrt(2.0 * h0 / g)
    T = 10_000 * period + 0.5
    traj = mo.simulate(bouncing_ball(1.0), (0.0, T), [h0], [0.0], h, drift_control=mo.CombinedProjection(),
                       record_every=1000, progress=False)
    imp = traj.impacts
    assert len(imp) >= 10_000
    assert np.all(imp.energy_lost >= -1e-12 * g * h0)  # no impact gains energy
    E0 = g * h0
    drift = np.abs(traj.energy - E0).max() / E0
    assert drift < 1e-9, drift  # round-off only: the elastic midpoint bounce is exact
    assert traj.max_penetration.max() <= h * np.sqrt(2 * g * h0)


@pytest.mark.parametrize("e", [0.0, 0.8])
def test_compiled_and_python_paths_agree(e):
    kw = dict(drift_control=mo.CombinedProjection(), progress=False, solver="exact")
    c = mo.simulate(bouncing_ball(e), (0.0, 3.0), [1.0], [0.0], 1e-3, backend="compiled", **kw)
    p = mo.simulate(bouncing_ball(e), (0.0, 3.0), [1.0], [0.0], 1e-3, backend="python", **kw)
    np.testing.assert_array_equal(c.onsets.step, p.onsets.step)
    np.testing.assert_array_equal(c.onsets.flight, p.onsets.flight)
    np.testing.assert_allclose(c.q, p.q, rtol=0, atol=1e-12)
    assert c.stats.projections == p.stats.projections


def test_combined_projection_validates_memory():
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="memory"):
            mo.CombinedProjection(memory=bad)


def _ball_runs(e, hs, h0s):
    g = 9.81
    for h in hs:
        for h0 in h0s:
            sol = BallSolution(h0, e, g)
            traj = mo.simulate(bouncing_ball(e, g=g), (0.0, 1.2 * sol.zeno_time), [h0], [0.0], h,
                               drift_control=mo.CombinedProjection(), progress=False)
            assert traj.completed
            yield h, sol, traj


def test_ball_impact_times_carry_no_bias_from_bounce_to_bounce():
    """A ball with e = 0.8 under CombinedProjection: the impact times of every bounce the
    step resolves (impact speed > 10 g h) against the analytic ones.

    A row closes in the step in which it reaches the barrier (impact at s ∈ (0, h] into
    the step) and Newton's law acts at the step's midpoint; a bounce then shifts the
    remaining Zeno time by (1 + e)(s − h/2)/e — zero on average, so the impact-time
    error is a random walk of steps ≤ (1 + e)/(2e)·h, standard deviation (1 + e)/(e√12)·h
    per bounce. (With Newton's law on the pre-step velocity every bounce put the ball
    about one step late: the 18th impact 14 steps late at h = 1e-3.) Measured over
    h = 1e-3, 1e-4 and drop heights 0.8, 1, 1.2 m: mean error −0.49 step over 136
    impacts, every impact within 0.37 of the three-sigma bound."""
    e, g = 0.8, 9.81
    errors = []
    for h, sol, traj in _ball_runs(e, (1e-3, 1e-4), (0.8, 1.0, 1.2)):
        ks = [k for k in range(1, len(traj.impacts) + 1) if sol.v1 * e ** (k - 1) > 10 * g * h]
        assert len(ks) >= 15
        err = np.array([(traj.impacts.t[k - 1] - sol.impact_time(k)) / h for k in ks])
        three_sigma = 3 * (1 + e) / (e * np.sqrt(12)) * np.sqrt(np.arange(1, len(ks) + 1)) + 1  # + detection
        assert np.all(np.abs(err) <= three_sigma), (h, sol.h0, err)
        errors.extend(err)
    print(f"mean impact-time error {np.mean(errors):+.2f} steps over {len(errors)} impacts")
    assert abs(np.mean(errors)) < 1.5, np.mean(errors)


@pytest.mark.xfail(strict=True, reason="issue 12 acceptance not met: at rest 6-19 steps before the Zeno time")
def test_ball_at_rest_within_ten_steps_of_the_zeno_time():
    """Issue 12's acceptance: a ball with e = 0.8 and drift control on every row at rest
    within 10 steps of the Zeno time. NOT MET: over h = 3e-3 … 3e-5 and drop heights
    0.8 … 1.2 m it comes to rest 6.1 … 18.8 steps early, without a trend in h (``pytest -s
    --runxfail`` prints each run).

    Why: a time-stepping scheme resolves no flight shorter than about a step. The last
    bounce it resolves leaves at u ≈ g h; the next approach is slower than the smooth
    forces' change in one step and is taken as a persistent contact (e = 0), so the
    bounces that remain — 2 e u / (g (1 − e)) ≈ 8 steps at e = 0.8 — are lost. The
    random walk of the resolved bounces' timing (see the test above) adds ±3 … 4 steps.
    Reaching 10 steps would need the impact instants inside the step (event location)."""
    steps = []  # rest time − Zeno time, in steps (`pytest -s` prints them)
    for h, sol, traj in _ball_runs(0.8, (3e-3, 1e-3, 3e-4, 1e-4, 3e-5), (0.8, 1.0, 1.2)):
        moving = np.flatnonzero(np.abs(traj.v[:, 0]) >= 1e-9)
        steps.append((traj.t[moving[-1]] - sol.zeno_time) / h)
        print(f"h = {h:g}, drop height {sol.h0:g} m: at rest {steps[-1]:+.1f} steps from the Zeno time")
    assert np.all(np.abs(steps) <= 10), steps
