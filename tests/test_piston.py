"""The piston engine: the scene equals the paper's closed form; effects are the ones asked."""

import numpy as np
import pytest

from moreau.model.barriers import finite_difference_jacobian
from moreau.problems.piston import EFFECTS, PistonParameters, closed_form, groups, piston_model


@pytest.fixture(scope="module")
def model():
    return piston_model(PistonParameters(e=0.3))


def random_states(rng, k=20):
    for _ in range(k):
        phi = rng.uniform(-np.pi, np.pi, 3) * np.array([1.0, 0.3, 0.01])
        dphi = rng.normal(size=3) * np.array([1.0, 0.3, 0.01])
        yield phi, dphi


def test_scene_dynamics_equal_the_papers_closed_form(model, rng):
    ref = closed_form(model.params, model.pressure)
    scene = model.scene
    for phi, dphi in random_states(rng):
        M = scene.system.mass_matrix(phi)
        np.testing.assert_allclose(M, ref["M"](phi), rtol=1e-12, atol=1e-15)
        acc = np.linalg.solve(M, scene.force(0.0, phi, dphi))
        np.testing.assert_allclose(acc, ref["acceleration"](phi, dphi), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(scene.gaps(phi), ref["gaps"](phi), rtol=1e-12, atol=1e-15)
        G = scene.jacobian(phi)
        np.testing.assert_allclose(G, finite_difference_jacobian(scene.gaps, phi), atol=1e-8)


def test_gas_force_and_brake_generalized_components(model, rng):
    G = groups(model.params)
    gas = next(e for e in model.scene.effects if e.name == "gas")
    brake = next(e for e in model.scene.effects if e.name == "brake")
    for phi, dphi in random_states(rng):
        p = model.pressure(phi[0]) / model.params.p_max
        expected = np.array([G.F0 * p * np.sin(phi[0]), G.lambda2 * G.F0 * p * np.sin(phi[1]), 0.0])
        np.testing.assert_allclose(gas.force(0.0, phi, dphi), expected, rtol=1e-12, atol=1e-16)
        np.testing.assert_allclose(brake.force(0.0, phi, dphi), [-G.M0, 0.0, 0.0], rtol=1e-12)


def test_groups_match_the_chain_scaling(model):
    G = groups(model.params)
    M0 = model.scene.system.mass_matrix(np.zeros(3))
    np.testing.assert_allclose(np.diag(M0), [1.0, G.beta2, G.beta3], rtol=1e-12)
    np.testing.assert_allclose([M0[0, 1], M0[0, 2], M0[1, 2]], [G.nu12, G.nu13, G.nu23], rtol=1e-12)
    assert G.Delta - G.delta == pytest.approx(model.params.clearance / model.params.l1, rel=1e-9)


@pytest.mark.parametrize("effects", [(), ("brake",), ("gravity", "damping"), EFFECTS])
def test_scene_holds_only_the_effects_asked_for(effects, rng):
    m = piston_model(effects=effects)
    assert tuple(e.name for e in m.scene.effects) == effects
    assert (m.pressure is None) == ("gas" not in effects)
    ref = closed_form(m.params, m.pressure, **{k: k in effects for k in EFFECTS})
    for phi, dphi in random_states(rng, 5):
        acc = np.linalg.solve(m.scene.system.mass_matrix(phi), m.scene.force(0.0, phi, dphi))
        np.testing.assert_allclose(acc, ref["acceleration"](phi, dphi), rtol=1e-12, atol=1e-14)


def test_initial_state_is_centred_and_consistent(model):
    q0, v0 = model.initial_state(phi1=0.7)
    gaps = model.scene.gaps(q0)
    half = 0.5 * model.params.clearance / model.params.l1
    np.testing.assert_allclose(gaps, half, rtol=1e-9)
    G = model.scene.jacobian(q0)
    np.testing.assert_allclose(G @ v0, 0.0, atol=1e-14)  # no lateral pin velocity


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="D = 0.079 m must exceed the piston diameter d = 0.08 m"):
        PistonParameters(D=0.079)
    with pytest.raises(ValueError, match="m3 must be positive, got -0.4"):
        PistonParameters(m3=-0.4)
    with pytest.raises(ValueError, match="restitution e must be in"):
        piston_model(e=1.2)
    with pytest.raises(ValueError, match="unknown piston effect"):
        piston_model(effects=("gas", "friction"))


def test_short_run_is_stable_and_records_contacts():
    m = piston_model(PistonParameters(e=0.0))
    traj = m.simulate(0.25, 1e-3, solver="enum", record_every=5)
    assert traj.completed and np.all(np.isfinite(traj.q))
    assert traj.impulses.sum() > 0 and traj.stats.fallbacks == 0
    # the crank turns at about the reference speed
    assert traj.v[:, 0].min() > 0.95 and traj.v[:, 0].max() < 1.05


@pytest.mark.parametrize("e", [0.0, 0.9])
def test_side_change_angles_do_not_depend_on_the_record_spacing(e):
    # a change is placed at its landing step from the onset log, not at the record after it
    import moreau as mo
    from moreau.problems.piston import cycle_figures

    model = piston_model(PistonParameters(e=e))
    dc = mo.PositionProjection(velocity=True) if e == 0.0 else None
    every, sparse = (cycle_figures(model.simulate(2, 1e-4, record_every=k, drift_control=dc), model.params)[-1]
                     for k in (1, 50))
    assert every.side_changes == sparse.side_changes >= 6
    # 50 steps of 1e-4 are 0.29° of crank: the records alone would place a change up to that late
    np.testing.assert_allclose(sparse.change_angles_deg, every.change_angles_deg, rtol=0, atol=1e-4)


def test_side_change_angles_are_placed_at_the_crossing_inside_the_landing_step():
    # the onset's t_cross: against h = 1e-4, the e = 0 piston's angles at h = 1e-2 are within
    # 0.1° (measured 0.049°; at the landing step's start: 0.44°, a step is 0.57°) and fall
    # faster than h (measured 0.0038° at h = 10^-2.5)
    import warnings

    import moreau as mo
    from moreau.problems.piston import cycle_figures

    model = piston_model(PistonParameters(e=0.0))

    def angles(h, at_step_start=False):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # (h = 1e-2 is coarse for the clearance)
            traj = model.simulate(2, h, record_every=max(1, round(5e-4 / h)),
                                  drift_control=mo.PositionProjection(velocity=True))
        if at_step_start:
            traj.onsets.t_cross[:] = np.nan  # (as a file saved before t_cross was logged)
        return np.array(cycle_figures(traj, model.params)[-1].change_angles_deg)

    ref = angles(1e-4)
    coarse, finer = angles(1e-2), angles(10**-2.5)
    assert coarse.size == finer.size == ref.size >= 6
    err = np.abs(coarse - ref).max()
    assert err < 0.1
    assert np.abs(finer - ref).max() < err / 5
    assert np.abs(angles(1e-2, at_step_start=True) - ref).max() > 3 * err


def test_step_control_sizes_the_steps_so_h_is_not_checked_against_the_clearance():
    # h = 1e-2 is ten times the clearance's limit for fixed steps; with step control it is only
    # the largest step, and the tolerance resolves the contacts (no warning, no deep corner)
    import warnings

    import moreau as mo

    model = piston_model(PistonParameters(e=0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        traj = model.simulate(0.25, 1e-2, drift_control=mo.PositionProjection(velocity=True),
                              step_control=mo.StepControl(1e-9))
    assert traj.completed and traj.stats.rejected > 0
    assert traj.max_penetration.max() < 0.01 * model.params.clearance / model.params.l1
    with pytest.warns(RuntimeWarning, match="too coarse for the clearance"):
        model.simulate(0.01, 1e-2)


def test_impacts_count_in_the_cycle_in_which_they_cross_the_wall():
    # an impact whose step starts before the 720° boundary but which crosses the wall after it
    # belongs to the next cycle: the cycle figures place impacts by ImpactLog.times()
    import dataclasses

    from moreau.problems.piston import cycle_figures
    from moreau.problems.piston.analysis import crank_angle

    model = piston_model(PistonParameters(e=0.9))
    traj = model.simulate(3, 1e-3, record_every=1)
    before = cycle_figures(traj, model.params)
    imp, phi = traj.onsets, crank_angle(traj)
    first = int(np.flatnonzero(imp.flight & imp.fast & (np.interp(imp.t, traj.t, phi) >= 4 * np.pi))[0])
    i = int(np.searchsorted(phi, 4 * np.pi)) - 1  # the last record of the first cycle
    moved = dataclasses.replace(imp, t=imp.t.copy(), t_cross=imp.t_cross.copy())
    moved.t[first] = traj.t[i]  # the step starts in cycle 0 ...
    moved.t_cross[first] = traj.t[i + 1]  # ... and the wall is crossed in cycle 1
    after = cycle_figures(dataclasses.replace(traj, onsets=moved), model.params)
    assert [c.impacts for c in after] == [c.impacts for c in before]
    moved.t_cross[first] = traj.t[i] - 1e-9  # crossed before the boundary: cycle 0's
    earlier = cycle_figures(dataclasses.replace(traj, onsets=moved), model.params)
    assert earlier[0].impacts == before[0].impacts + 1 and earlier[1].impacts == before[1].impacts - 1
    assert np.array_equal(moved.times()[:first], imp.t_cross[:first])
    old = dataclasses.replace(moved, t_cross=np.full(len(imp), np.nan))  # a file from before t_cross
    assert np.array_equal(old.times(), moved.t)
