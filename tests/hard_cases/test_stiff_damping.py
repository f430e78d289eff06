"""Case 11 — stiff damping and large torques.

The midpoint scheme treats velocity-dependent forces explicitly (f at v_k), so viscous
damping f = −C v has the step limit of explicit Euler: every mode of M⁻¹C with eigenvalue
λ is multiplied by (1 − h λ) per step, stable for h λ < 2. Inside the limit the runs are
stable (tests below); outside it the stiffest mode oscillates with growing amplitude
|1 − h λ|^n: a free system overflows (SimulationError, the run kept up to the last good
step), and ``simulate`` warns before the run (constant M: the energy check cannot see it);
in the piston the walls bound the positions, and the energy check stops the run (without
it the run "completes" with garbage: tilt rates of 10³, penetrations of hundreds of
clearances).
"""

import numpy as np
import pytest
from scipy.linalg import eigh

import moreau as mo
from moreau.model.chain import ChainGravity, JointStop, Link, LinkTorque, PendulumChain
from moreau.problems.piston import PistonParameters, piston_model
from moreau.problems.piston.analysis import max_penetration_ratio

from .conftest import assert_finite, audit_impacts


def damped_1dof(hc):
    """M = 2, C = c: one explicit-Euler mode with h λ = h c / M = hc."""
    M, h = 2.0, 1e-2
    system = mo.FunctionSystem([[M]])
    return mo.Scene(system, [mo.LinearDamping([[hc * M / h]])]), h


@pytest.mark.parametrize("hc", [0.5, 1.0, 1.9, 1.999])
def test_damping_inside_the_step_limit_decays_exactly_as_predicted(hc):
    scene, h = damped_1dof(hc)
    traj = mo.simulate(scene, (0.0, 2.0), [0.0], [1.0], h)
    n = np.arange(len(traj))
    np.testing.assert_allclose(traj.v[:, 0], (1 - hc) ** n, rtol=1e-12, atol=1e-300)
    assert np.all(np.abs(traj.v[1:, 0]) < 1.0)  # decays (oscillating for h λ > 1)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.parametrize("hc", [2.05, 2.2])
def test_damping_outside_the_step_limit_grows_and_overflows(hc):
    # slow growth (|1 − h λ|² = 1.1, 1.44 a step in kinetic energy, below the runaway test's
    # e^0.4 = 1.49): the state overflows
    scene, h = damped_1dof(hc)
    with pytest.raises(mo.SimulationError, match="state became non-finite") as info, \
            pytest.warns(RuntimeWarning, match=rf"h·ρ = {hc:g} > 2, and that motion grows without bound"):
        mo.simulate(scene, (0.0, 1e6 * h), [0.0], [1.0], h, record_every=100)
    traj = info.value.trajectory
    assert traj.status == "failed" and np.all(np.isfinite(traj.v))
    # the last good state is where |1 − h λ|^n reaches the float range (~1.8e308)
    n = round(traj.t[-1] / h)
    assert n == pytest.approx(np.log(np.finfo(float).max) / np.log(hc - 1), rel=0.01)


def test_damping_far_outside_the_step_limit_is_stopped_as_a_runaway():
    scene, h = damped_1dof(2.5)  # 2.25 a step in kinetic energy
    with pytest.raises(mo.SimulationError, match=r"rose above its largest so far by a factor of 2.25 a step") as info, \
            pytest.warns(RuntimeWarning, match=r"h·ρ = 2.5 > 2"):
        mo.simulate(scene, (0.0, 1e6 * h), [0.0], [1.0], h, record_every=1)
    traj = info.value.trajectory  # up to the last check that passed: the start (the first check found it)
    assert traj.status == "failed" and traj.t[-1] == 0.0 and "at h = 0.01" in str(info.value)


def piston_damping_factor(factor):
    """The piston with its joint damping multiplied by ``factor`` (the same 2000 rpm gas
    pressure; the engine slows down) and h·λ_max of M⁻¹C at the start."""
    pressure = piston_model(PistonParameters()).pressure
    model = piston_model(PistonParameters(e=0.0, c1=0.00432 * factor), pressure=pressure)
    C = next(e for e in model.scene.effects if e.name == "damping").C
    q0, _ = model.initial_state(0.0)
    lam = eigh(C, model.scene.system.mass_matrix(q0), eigvals_only=True).max()
    return model, lam


@pytest.mark.slow
def test_piston_damping_times_1000_is_stable():
    h = 1e-3
    model, lam = piston_damping_factor(1000)
    assert h * lam < 0.01  # the stiffest mode (piston tilt, λ ≈ 4.3) is far inside h λ < 2
    traj = model.simulate(1.0, h, solver="enum", record_every=10)
    assert traj.completed and traj.stats.fallbacks == 0
    assert_finite(traj)
    audit_impacts(traj)
    # the damping takes 25 % of the crank speed in one cycle (measured 0.733), monotonically
    # enough that the crank keeps turning forward
    assert 0.5 < traj.v[-1, 0] < 0.9 and traj.v[:, 0].min() > 0
    # penetration: the drift law h·l1 at speed <= 1 (see test_coarse_step.py)
    assert max_penetration_ratio(traj, model.params) * model.params.clearance <= 1.5 * h * model.params.l1


@pytest.mark.parametrize("factor, stable", [(4e5, True), (6e5, False)])
def test_piston_damping_step_limit(factor, stable):
    """At h = 1e-3 the limit h λ < 2 is crossed between 4e5 (h λ = 1.73) and 6e5
    (h λ = 2.59) times the paper's damping; beyond it the energy check stops the run."""
    h = 1e-3
    model, lam = piston_damping_factor(factor)
    assert (h * lam < 2) == stable
    if not stable:
        # the tilt mode grows by |1 − h λ| = 1.59 per step: without the energy check the run
        # completed with garbage (tilt rate 1.3e3, penetration 577 clearances); now it stops,
        # naming a smaller step, with the trajectory up to there finite
        with pytest.raises(mo.SimulationError, match="energy grew") as info:
            model.simulate(0.1, h, solver="enum")
        assert "h = 0.001" in str(info.value) and "about h = " in str(info.value)
        assert_finite(info.value.trajectory)
        traj = model.simulate(0.1, h, solver="enum", energy_growth=None)
        assert traj.completed
        assert np.abs(traj.v[:, 2]).max() > 100.0 and max_penetration_ratio(traj, model.params) > 10.0
        return
    traj = model.simulate(0.1, h, solver="enum")
    assert_finite(traj)
    tilt_rate = np.abs(traj.v[:, 2]).max()
    pen = max_penetration_ratio(traj, model.params)
    assert tilt_rate < 1.0 and pen * model.params.clearance <= 1.5 * h * model.params.l1
    assert not any("energy grew" in w for w in traj.warnings)


@pytest.mark.slow
def test_piston_brake_times_100_is_stable():
    """A brake 100 times the paper's drives the engine backwards and presses the piston
    hard on its walls: finite, and the penetration stays at the drift law."""
    h = 1e-3
    pressure = piston_model(PistonParameters()).pressure
    model = piston_model(PistonParameters(e=0.0, M0=980.7), pressure=pressure)
    traj = model.simulate(1.0, h, solver="enum", record_every=10)
    assert traj.completed and traj.stats.fallbacks == 0
    assert_finite(traj)
    audit_impacts(traj)
    assert traj.v[-1, 0] < traj.v[0, 0]  # the brake wins
    assert max_penetration_ratio(traj, model.params) * model.params.clearance <= 1.5 * h * model.params.l1


def test_chain_pressed_on_a_joint_stop_by_a_large_torque():
    """A double pendulum whose second joint rests on a stop and is driven into it by a
    torque 10⁴ times gravity's: the stop (a linear gap in the angles) holds to round-off,
    and the contact impulse of each step balances the torque (τ h).

    (Started away from the stop, such a torque carries the joint 1.3 rad in the first
    step, far through the stop: no time-stepper sees a contact it jumps over; the step
    must resolve the motion, h·|v| small against the gap.)"""
    chain = PendulumChain([Link.rod(1.0, 0.5), Link.rod(1.0, 0.5)])
    tau = 1e4 * 9.81 * 0.5
    stop = JointStop(chain, 1, upper=0.3, relative_to=0)
    scene = mo.Scene(chain, [ChainGravity(chain), LinkTorque(chain, [-tau, tau])],
                     [mo.Contact(stop, 0.0, name="stop")])
    h = 1e-3
    traj = mo.simulate(scene, (0.0, 1.0), [0.0, 0.3], [0.0, 0.0], h, solver="enum")
    assert traj.completed and traj.stats.fallbacks == 0
    assert_finite(traj)
    audit_impacts(traj)
    rel = traj.q[:, 1] - traj.q[:, 0]
    assert rel.max() <= 0.3 + 1e-12  # the stop holds (no drift: its gap is linear in q)
    assert traj.active[1:, 0].all()  # pressed at every step
    # torque τ on the joint, impulse P on the stop row (−1, 1)·q: P ≈ τ h per step (the
    # gravity and centrifugal torques are 1e-4 of it and vary slowly)
    np.testing.assert_allclose(traj.impulses[-100:, 0], tau * h, rtol=1e-3)
