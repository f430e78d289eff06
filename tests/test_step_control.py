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


def test_smooth_error_is_proportional_to_the_tolerance(smooth_pendulum):
    """Error over tol within 0.1 … 2 and within a factor 5 of each other for tol = 1e-3 …
    1e-8. Sized by its own error alone, the step grows where the error's leading term changes
    sign, and the error over tol rose as log(1/tol), from 0.45 to 11.7."""
    scene, y_end = smooth_pendulum
    ratios = []
    for tol in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
        traj = mo.simulate(scene, (0.0, 2.0), [1.0], [0.5], 0.1, energy=False, step_control=mo.StepControl(tol))
        ratios.append(max(abs(traj.q[-1, 0] - y_end[0]), abs(traj.v[-1, 0] - y_end[1])) / tol)
    assert 0.1 <= min(ratios) and max(ratios) <= 2.0 and max(ratios) / min(ratios) <= 5.0, ratios


@pytest.fixture(scope="module")
def woodpecker_scene():
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    return woodpecker(), GLOCKER_STATE


def test_a_contact_that_opens_late_in_a_step_is_resolved(woodpecker_scene):
    """The woodpecker's sleeve, held on the rod by friction, leaves it at t = 0.06702 s. In a
    step whose three midpoints all lie before, every answer holds the contact and they agree;
    its force falling through zero in the step's last quarter is the error of the late
    release. At tol = 1e-7, for nine largest steps 8e-4 … 1.2e-3, the sleeve's angular
    velocity at 0.07 s within 1e-3 rad/s of an h = 1e-7 run (at most 1.8e-4; unseen, three
    of the nine were 3.2e-3 … 4.4e-3 off)."""
    scene, (q0, v0) = woodpecker_scene
    ref = mo.simulate(scene, (0.0, 0.07), q0, v0, 1e-7, energy=False, record_every=100)
    assert ref.active[np.searchsorted(ref.t, 0.06)].any() and not ref.active[-1].any()
    for h in np.linspace(8e-4, 1.2e-3, 9):
        traj = mo.simulate(scene, (0.0, 0.07), q0, v0, h, energy=False, step_control=mo.StepControl(1e-7))
        assert abs(traj.v[-1, 1] - ref.v[-1, 1]) <= 1e-3, (h, traj.v[-1, 1] - ref.v[-1, 1])


def test_a_contact_held_at_rest_is_extrapolated(woodpecker_scene):
    """The sleeve sliding on the rod (0 … 0.02 s, its row closed and at rest): the fine and
    coarse answers differ only along the rod, the step is as smooth as a free one and is
    extrapolated. At tol = 1e-5 the sleeve's speed at 0.02 s within 1e-6 of an h = 1e-7 run
    (2.6e-7; as a first-order contact step, not extrapolated: 8.7e-6)."""
    scene, (q0, v0) = woodpecker_scene
    ref = mo.simulate(scene, (0.0, 0.02), q0, v0, 1e-7, energy=False, record_every=100)
    traj = mo.simulate(scene, (0.0, 0.02), q0, v0, 1e-3, energy=False, step_control=mo.StepControl(1e-5))
    assert traj.active[1:, 1].all() and np.all(traj.v[1:, 0] < 0.0)  # in contact, sliding
    assert abs(traj.v[-1, 0] - ref.v[-1, 0]) <= 1e-6, traj.v[-1, 0] - ref.v[-1, 0]


def test_stick_to_slip_is_a_switching_point(monkeypatch):
    """A closed row whose tangential impulse reaches mu times its normal one (it slips) in
    the second fine step, having stuck at the start and in the other two steps, makes the
    step switching (kind 2); the same row sticking throughout is persistent contact (1).
    (The parts as Python: ``py_func``.)"""
    from types import SimpleNamespace

    from moreau.compiled import local_error

    monkeypatch.setattr(local_error, "_slip_of", local_error._slip_of.py_func)
    closed = np.array([True])
    sn = SimpleNamespace(closed_c=closed, closed_f=closed, closed0=closed, in_contact=closed,
                         slip0=np.zeros(1), slip_c=np.zeros(1), slip_f=np.zeros(1))
    P = np.array([2.0])
    for PT, kind in ((-0.6, 2), (-0.3, 1)):
        fr = SimpleNamespace(PT=np.array([PT]), mu=np.array([0.3]))
        assert local_error._kind.py_func(1, closed, sn, 0, 0, P, fr) == kind


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
    for tol, words in (([1e-6, -1e-6], r"positive in every component, got \[1e-06, -1e-06\]"),
                       ("1e-6", "a number or a sequence"), ([], "positive in every component")):
        with pytest.raises(ValueError, match=words):
            mo.StepControl(tol)
    with pytest.raises(ValueError, match=r"3 components, the state \(q, v\) of this scene 2 \(n = 1"):
        mo.simulate(scene, (0.0, 0.1), [1.0], [0.0], 1e-3, step_control=mo.StepControl([1e-6] * 3))


def _inclined(scale: float):
    """The README's point on an inclined floor with its x coordinate in units 1/scale as
    large (q = (scale x, y)): M = diag(m / scale², m), the gap's Jacobian (−0.2 / scale, 1)."""
    m = 2.0
    return mo.Scene(mo.FunctionSystem(np.diag([m / scale**2, m])), [mo.ConstantForce([0.0, -9.81 * m])],
                    [mo.Contact(mo.FunctionBarrier(gap=lambda q: np.array([q[1] - 0.2 * q[0] / scale]),
                                                   jacobian=lambda q: np.array([[-0.2 / scale, 1.0]])),
                                mo.NewtonImpact(0.7))])


def test_a_tolerance_per_component_follows_the_units():
    """A coordinate in other units with its tolerances in the same units takes the same
    steps: scaled by 2^10 (exact in floating point) the run is the unscaled one scaled, bit
    for bit; one tolerance for both coordinates takes other steps."""
    s, tol = 1024.0, (1e-5, 1e-5, 1e-4, 1e-4)
    run = lambda scale, tol: mo.simulate(_inclined(scale), (0.0, 2.0), [0.0, 1.0], [scale * 1.0, 0.0], 1e-2,  # noqa: E731
                                          energy=False, step_control=mo.StepControl(tol))
    base = run(1.0, tol)
    scaled = run(s, (tol[0] * s, tol[1], tol[2] * s, tol[3]))
    assert base.status == "completed" and len(base.impacts) >= 4 and base.stats.rejected > 0
    np.testing.assert_array_equal(scaled.t, base.t)
    np.testing.assert_array_equal(scaled.q, base.q * [s, 1.0])
    np.testing.assert_array_equal(scaled.v, base.v * [s, 1.0])
    np.testing.assert_array_equal(scaled.impacts.t, base.impacts.t)
    assert run(s, 1e-5).stats.steps != base.stats.steps  # (x's error s times larger in its units)


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
def test_woodpecker_return_times_follow_the_tolerance(woodpecker_scene):
    """The returns to Glocker's state within 3x tol of an h = 1e-7 run for tol = 1e-4, 1e-5,
    1e-6 (over 40 tolerances 1e-3 … 1e-6 the largest error is 1.5 tol): a barrier crossed
    inside a step counts as the state error of its late impact, not as its depth alone, which
    let the sleeve's impacts come 5e-6 s late at tol = 1e-5 (error 5x tol)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    from wp_friction import _returns

    scene, (q0, v0) = woodpecker_scene
    ref = _returns(mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-7, energy=False, record_every=10))
    for tol in (1e-4, 1e-5, 1e-6):
        got = _returns(mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-3, energy=False, step_control=mo.StepControl(tol)))
        assert got.shape == ref.shape
        assert np.abs(got[:, 0] - ref[:, 0]).max() <= 3 * tol, tol


@pytest.mark.slow
def test_piston_side_changes_follow_the_tolerance():
    """The e = 0 piston with PositionProjection(velocity=True), tol = 1e-10, three largest
    steps: the last cycle's side-change angles within 0.003 deg of an h = 1e-5 run. A
    landing both answers cross is put back on the wall by the projection: its depth before,
    not after, is the crossing rule's measure (after: 0.0036 … 0.014 deg over the largest
    steps 0.0094 … 0.0106)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    from wp_problems import _angle_distance

    from moreau.problems.piston.analysis import cycle_figures
    from moreau.problems.piston.model import piston_model
    from moreau.problems.piston.params import PistonParameters

    params = PistonParameters(e=0.0)
    model = piston_model(params)

    def angles(h, **kw):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            traj = model.simulate(2, h, energy=False, drift_control=mo.PositionProjection(velocity=True),
                                  progress=False, **kw)
        return cycle_figures(traj, params)[-1].change_angles_deg

    ref = angles(1e-5, record_every=100)
    for h in (0.0094, 0.01, 0.0106):
        assert _angle_distance(angles(h, step_control=mo.StepControl(1e-10)), ref) <= 3e-3, h


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


@pytest.mark.parametrize("case", ["smooth", "impacts"])
def test_an_accepted_attempt_is_the_fixed_steps_it_takes(case, ball):
    """With every attempt accepted at H (``StepControl(1e6)``), each step of the run is what
    fixed-step runs from its start give: one step of H (x_c) and two of H/2 (x_f) combined as
    the module says: x_f + (x_f − x_c)/3 in a smooth phase of the undamped pendulum (the
    midpoint step of order 2), x_f across the ball's impacts (a switching step, never
    extrapolated; its flights are exact, x_f = x_c)."""
    from moreau.problems.pendulum_wall import pendulum_wall

    H = 1e-2
    scene, x0, T = ((pendulum_wall(wall_x=None, damping=0.0), (1.0, 0.5), 0.3) if case == "smooth"
                    else (ball[0], (1.0, 0.0), 1.2))
    traj = mo.simulate(scene, (0.0, T), [x0[0]], [x0[1]], H, energy=False, step_control=mo.StepControl(1e6))
    assert traj.stats.rejected == 0 and np.allclose(np.diff(traj.t), H)
    if case == "impacts":
        assert len(traj.impacts.t) >= 2

    def end(k, h):  # the state after fixed steps of h from the run's k-th step
        with warnings.catch_warnings():  # an impact step ends inside the floor: the run's last step here
            warnings.simplefilter("ignore", RuntimeWarning)
            run = mo.simulate(scene, (traj.t[k], traj.t[k] + H), traj.q[k], traj.v[k], h, energy=False,
                              initial_penetration=1.0)
        assert run.stats.steps == round(H / h)
        return np.concatenate([run.q[-1], run.v[-1]])

    apart = 0  # steps whose two answers differ: where extrapolating or not is seen
    for k in range(len(traj.t) - 1):
        coarse, fine = end(k, H), end(k, H / 2)
        expected = fine + (fine - coarse) / 3 if case == "smooth" else fine
        apart += np.abs(fine - coarse).max() > 1e-6
        got = np.concatenate([traj.q[k + 1], traj.v[k + 1]])
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-13, err_msg=f"step {k}")
    assert apart == len(traj.t) - 1 if case == "smooth" else apart >= 2  # every smooth step; the impacts


def _runs_of_the_loop_variants():
    """One short run per variant of the loop and its features, with and without step
    control: (label, a function returning the trajectory)."""
    from moreau.problems.four_bar import four_bar
    from moreau.problems.piston import piston_model
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    piston, wp, fb = piston_model(e=0.0), woodpecker(), four_bar(stop=0.75, e=0.5)
    fq, fv = fb.initial_state(0.3, 5.0)
    projv = mo.PositionProjection(velocity=True)
    return [
        ("piston, step control, projection", lambda: piston.simulate(2, 0.1, record_every=1, energy=False,
                                                                    drift_control=projv,
                                                                    step_control=mo.StepControl(1e-6))),
        ("piston, fixed h, projection", lambda: piston.simulate(1, 1e-2, drift_control=projv)),
        ("woodpecker, step control", lambda: mo.simulate(wp, (0.0, 0.15), *GLOCKER_STATE, 4e-3,
                                                         step_control=mo.StepControl(0.03))),
        ("woodpecker, fixed h", lambda: mo.simulate(wp, (0.0, 0.05), *GLOCKER_STATE, 1e-4,
                                                    integrator=mo.MoreauJeanPredictorCorrector,
                                                    drift_control=mo.CombinedProjection())),
        ("four-bar, step control", lambda: mo.simulate(fb.scene, (0.0, 1.0), fq, fv, 1e-2,
                                                       integrator=mo.MoreauJeanPredictorCorrector,
                                                       drift_control=mo.CombinedProjection(),
                                                       step_control=mo.StepControl(1e-6))),
    ]


def test_no_run_reads_a_work_array_before_writing_it(monkeypatch):
    """Every array a run allocates with np.empty is written before it is read: the same
    runs with that memory filled with 0, 1e300 and NaN are equal bit for bit. (The judge of
    an attempt once read the Jacobian of the last step that closed a row, or none, for a
    barrier crossed in a free step: the e = 0 piston under step control then differed from
    run to run, 512, 515 or 514 records.)"""
    empty = np.empty
    runs = _runs_of_the_loop_variants()
    for _, run in runs:
        run()  # loaded or compiled with numpy's own empty
    results = {}
    for fill in (0.0, 1e300, np.nan):
        def filled(*args, fill=fill, **kw):
            a = empty(*args, **kw)
            if a.dtype.kind == "f":
                a.fill(fill)
            return a

        monkeypatch.setattr(np, "empty", filled)
        results[fill] = [run() for _, run in runs]
        monkeypatch.setattr(np, "empty", empty)
    for (label, _), *trajs in zip(runs, *results.values()):
        first = trajs[0]
        assert first.status == "completed", label
        for traj in trajs[1:]:
            assert traj.t.shape == first.t.shape, label
            assert np.array_equal(traj.q, first.q) and np.array_equal(traj.v, first.v), label


def test_a_users_jacobian_failing_where_a_crossing_is_judged_stops_the_run_by_name():
    """A barrier crossed inside a step is judged with the Jacobian at the step's midpoint;
    a user's Jacobian that raises there stops the run naming it, and the run keeps the last
    accepted state (free fall, exact for the midpoint step: y = 1 - g t^2 / 2)."""
    undefined = {"below": 0.05}

    def jacobian(q):  # a dict lookup: called back, not compiled
        if q[0] < undefined["below"]:
            raise ValueError("the Jacobian is undefined this close to the floor")
        return np.array([[1.0]])

    floor = mo.FunctionBarrier(lambda q: np.array([q[0]]), jacobian)
    scene = mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.ConstantForce([-9.81])], [mo.Contact(floor, 0.5, name="floor")])
    with pytest.raises(mo.SimulationError, match="user Jacobian 'floor' raised ValueError: the Jacobian is undefined"
                       ) as info:
        mo.simulate(scene, (0.0, 1.0), [1.0], [0.0], 0.1, step_control=mo.StepControl(1e-3), check_jacobian=False)
    traj = info.value.trajectory
    assert traj.status == "failed" and 0.0 < traj.t[-1] < 0.45
    assert traj.q[-1, 0] == pytest.approx(1.0 - 0.5 * 9.81 * traj.t[-1] ** 2, abs=1e-12)
