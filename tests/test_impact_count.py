"""Impact counting: one definition (a fast onset after a flight), the raw velocity test
kept beside it, and the piston figures that converge with the default drift control."""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import BallSolution, bouncing_ball
from moreau.problems.piston import PistonParameters, cycle_figures, piston_model


@pytest.mark.parametrize("flight_gap", [0.0, 0.01, 0.1])
def test_ball_impacts_counted_after_flights_above_the_flight_gap(flight_gap):
    """Dropped from 1 m (e = 0.5): impact k + 1 follows the apex e^(2k) m; it counts when
    that apex exceeds the flight gap (the first impact follows the 1 m drop)."""
    e, h = 0.5, 1e-4
    sol = BallSolution(1.0, e)
    traj = mo.simulate(bouncing_ball(e), (0.0, 0.9 * sol.zeno_time), [1.0], [0.0], h, flight_gap=flight_gap,
                       drift_control=mo.CombinedProjection(), progress=False)
    apexes = [1.0] + [sol.apex_height(k) for k in range(1, 40)]
    # the impacts before 0.9 t_Z whose preceding apex exceeds the flight gap
    expected = [k for k, a in enumerate(apexes) if a > flight_gap and sol.impact_time(k + 1) < 0.9 * sol.zeno_time]
    assert len(traj.impacts) == len(expected)
    np.testing.assert_allclose(traj.impacts.t, [sol.impact_time(k + 1) for k in expected], atol=5 * h)
    # the raw velocity test counts every resolved bounce, whatever the flight gap
    assert len(traj.velocity_impacts) >= len(traj.impacts)
    assert np.all(traj.onsets.fast | traj.onsets.flight)


def test_flight_flags_survive_save_and_load(tmp_path):
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 2.0), [1.0], [0.0], 1e-3, flight_gap=0.05, progress=False)
    back = mo.load(traj.save(tmp_path / "ball"))
    np.testing.assert_array_equal(back.onsets.flight, traj.onsets.flight)
    np.testing.assert_array_equal(back.onsets.fast, traj.onsets.fast)
    assert len(back.impacts) == len(traj.impacts) < len(traj.velocity_impacts)


@pytest.mark.parametrize("bad", [-1.0, np.nan, "0.1", True, None, [0.1, 0.2]])
def test_flight_gap_is_validated(bad):
    with pytest.raises(ValueError, match="flight_gap"):
        mo.simulate(bouncing_ball(0.5), (0.0, 0.1), [1.0], [0.0], 1e-3, flight_gap=bad, progress=False)


def _piston(e, h, drift_control, cycles=3):
    params = PistonParameters(e=e)  # D = 80.04 mm: the paper's 40 µm clearance
    model = piston_model(params)
    traj = model.simulate(cycles, h, drift_control=drift_control, record_every=max(1, round(1e-3 / h)),
                          energy=False, progress=False)
    return traj, cycle_figures(traj, params), params


@pytest.mark.slow
@pytest.mark.parametrize("projection", ["engine", "exact"])
@pytest.mark.parametrize("e", [0.0, 0.05, 0.3, 0.9])
def test_piston_at_coarse_step_with_default_drift_control(e, projection):
    """h = 1e-3 with the main job's drift control (``PistonModel.drift_control()``: a
    CombinedProjection accepting 1e-4 of the clearance) and with an exact
    CombinedProjection, against an unprojected run at h = 3e-5: penetration <= 1 % of
    the clearance at every step, impacts per cycle within 10 %, six side changes per
    cycle for e <= 0.3."""
    dc = piston_model(PistonParameters(e=e)).drift_control() if projection == "engine" else mo.CombinedProjection()
    traj, figs, params = _piston(e, 1e-3, dc)
    ref, ref_figs, _ = _piston(e, 3e-5, None)
    clearance = params.clearance / params.l1
    assert traj.completed and not traj.warnings
    assert traj.max_penetration.max() <= 0.01 * clearance
    n, n_ref = np.mean([c.impacts for c in figs]), np.mean([c.impacts for c in ref_figs])
    assert abs(n - n_ref) <= 0.1 * n_ref, (n, n_ref)
    if e <= 0.3:
        assert [c.side_changes for c in figs[1:]] == [6, 6]
        assert [c.side_changes for c in ref_figs[1:]] == [6, 6]
