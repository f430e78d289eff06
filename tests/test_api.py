"""Front door behaviour: bad inputs, recording, saving, failures that keep results."""

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.problems.pendulum_wall import pendulum_wall


def free_scene():
    return mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([0.0, -9.81])], name="free")


# -- bad inputs --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(q0=[np.nan], v0=[0.0]), "q0 has non-finite"),
        (dict(q0=[1.0], v0=[np.inf]), "v0 has non-finite"),
        (dict(q0=[1.0, 2.0], v0=[0.0]), r"q0 must have shape \(1,\)"),
        (dict(q0=[[1.0]], v0=[0.0]), "q0 must be one-dimensional"),
        (dict(h=0.0), "step size h must be finite and positive, got 0.0"),
        (dict(h=-1e-3), "step size h must be finite and positive, got -0.001"),
        (dict(h=np.nan), "step size h"),
        (dict(t_span=(1.0, 0.0)), r"t1 > t0, got t_span = \(1.0, 0.0\)"),
        (dict(t_span=(0.0, np.inf)), "t_span must be finite"),
        (dict(q0=[-0.1]), r"penetrates a barrier \(floor: g = -0.1\)"),
        (dict(solver="gurobi-ish"), "unknown solver 'gurobi-ish'"),
        (dict(record_every=0), "record_every must be a positive integer, got 0"),
    ],
)
def test_bad_inputs_raise_value_error_naming_the_value(kwargs, match):
    args = dict(t_span=(0.0, 0.1), q0=[1.0], v0=[0.0], h=1e-3)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        mo.simulate(bouncing_ball(0.5), args.pop("t_span"), args.pop("q0"), args.pop("v0"), args.pop("h"), **args)


@pytest.mark.parametrize("e", [-0.1, 1.5, np.nan, "x"])
def test_restitution_outside_unit_interval(e):
    with pytest.raises(ValueError, match="restitution e must be"):
        mo.NewtonImpact(e)
    with pytest.raises(ValueError, match="restitution e must be"):
        bouncing_ball(e)


def test_mass_matrix_not_spd_or_not_symmetric():
    with pytest.raises(ValueError, match="not positive definite"):
        mo.FunctionSystem([[1.0, 0.0], [0.0, -2.0]])
    with pytest.raises(ValueError, match="negative|positive"):
        bouncing_ball(0.5, mass=-1.0)
    with pytest.raises(ValueError, match="not symmetric"):
        mo.FunctionSystem([[1.0, 0.5], [0.0, 1.0]])
    # a callable mass that is not SPD is caught at the initial state
    sysm = mo.FunctionSystem(lambda q: np.array([[1.0, 2.0], [2.0, 1.0]]), ndof=2)
    with pytest.raises(ValueError,
                       match=r"mass matrix at the initial state is not positive definite \(smallest eigenvalue -1"):
        mo.simulate(mo.Scene(sysm), (0, 1), [0, 0], [0, 0], 0.1)


def test_wrong_shapes_from_user_callables_are_named():
    sysm = mo.FunctionSystem(np.eye(2))
    bad_force = mo.FunctionForce(lambda t, q, v: np.zeros(3), name="wind")
    with pytest.raises(ValueError,
                       match=r"force of effect 'wind' at the initial state has shape \(3,\), expected \(2,\)"):
        mo.simulate(mo.Scene(sysm, [bad_force]), (0, 1), [0, 0], [0, 0], 0.1)
    bad_jac = mo.FunctionBarrier(lambda q: np.array([q[1]]), lambda q: np.zeros((2, 2)))
    with pytest.raises(ValueError,
                       match=r"Jacobian of contact 'floor' at the initial state has shape \(2, 2\), expected \(1, 2\)"):
        mo.simulate(mo.Scene(sysm, contacts=[mo.Contact(bad_jac, 0.5, name="floor")]), (0, 1), [0, 1], [0, 0], 0.1)
    nan_gap = mo.FunctionBarrier(lambda q: np.array([np.nan]), lambda q: np.zeros((1, 2)))
    with pytest.raises(ValueError, match="gap of contact 'floor' at the initial state is not finite"):
        mo.simulate(mo.Scene(sysm, contacts=[mo.Contact(nan_gap, 0.5, name="floor")]), (0, 1), [0, 1], [0, 0], 0.1)


# -- what a scene asks for ---------------------------------------------------------------
class CountingSolver(mo.EnumerationSolver):
    name = "counting"
    calls = 0

    def solve(self, *a):
        CountingSolver.calls += 1
        return super().solve(*a)


def test_scene_without_barriers_never_calls_the_contact_solver():
    CountingSolver.calls = 0
    traj = mo.simulate(free_scene(), (0.0, 1.0), [0.0, 1.0], [1.0, 0.0], 1e-3, solver=CountingSolver())
    assert CountingSolver.calls == 0
    assert traj.stats.solves == 0 and traj.gaps.shape == (1001, 0)
    # and with a barrier it does
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, solver=CountingSolver())
    assert CountingSolver.calls == traj.stats.solves > 0


def test_scene_evaluates_only_its_effects():
    calls = {"damping": 0}

    def damping(t, q, v):
        calls["damping"] += 1
        return -0.1 * v

    sysm = mo.FunctionSystem(np.eye(1))
    grav = mo.ConstantForce([-9.81])
    mo.simulate(mo.Scene(sysm, [grav]), (0, 0.1), [0.0], [0.0], 1e-3)
    assert calls["damping"] == 0
    mo.simulate(mo.Scene(sysm, [grav, mo.FunctionForce(damping, name="damping")]), (0, 0.1), [0.0], [0.0], 1e-3)
    # one per step, one for the initial check, 4 n for the differences of the explicit step's
    # stability limit (constant M: moreau.model.stability.explicit_limit_message)
    assert calls["damping"] == 100 + 1 + 4


# -- recording, saving -------------------------------------------------------------------
def test_record_every_sums_impulses_and_keeps_every_impact():
    full = mo.simulate(bouncing_ball(0.8), (0.0, 3.0), [1.0], [0.0], 1e-3, solver="enum")
    sparse = mo.simulate(bouncing_ball(0.8), (0.0, 3.0), [1.0], [0.0], 1e-3, solver="enum", record_every=7)
    assert len(sparse) == 3000 // 7 + 2
    np.testing.assert_allclose(sparse.q, full.q[np.r_[0:3001:7, 3000]], atol=1e-14)
    assert sparse.impulses.sum() == pytest.approx(full.impulses.sum(), rel=1e-12)
    np.testing.assert_array_equal(sparse.impacts.t, full.impacts.t)
    assert sparse.t[-1] == pytest.approx(3.0)


def test_save_load_roundtrip(tmp_path):
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3)
    path = traj.save(tmp_path / "ball")
    back = mo.load(path)
    for name in ("t", "q", "v", "gaps", "impulses", "active", "energy"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))
    np.testing.assert_array_equal(back.impacts.energy_lost, traj.impacts.energy_lost)
    assert back.stats == traj.stats
    assert back.h == 1e-3 and back.scene["contacts"][0]["restitution"] == [0.5]
    # a built-in scene runs compiled, with the exact dual active-set solver by default
    assert back.stats.solver == "exact" and back.stats.backend == "compiled"
    assert back.version == mo.__version__


def test_load_rejects_corrupt_files(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="cannot read trajectory file"):
        mo.load(bad)
    with pytest.raises(ValueError, match="no trajectory file"):
        mo.load(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", x=np.arange(3))
    with pytest.raises(ValueError, match="cannot read|not a moreau trajectory"):
        mo.load(tmp_path / "other.npz")


# -- failures keep what was computed ------------------------------------------------------
def test_nan_mid_run_stops_with_error_and_keeps_the_trajectory():
    def force(t, q, v):
        return np.array([np.nan]) if t > 0.5 else np.array([-9.81])

    scene = mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.FunctionForce(force, name="bad")])
    with pytest.raises(mo.SimulationError, match=r"non-finite at step 500 \(t = 0.5\)") as info:
        mo.simulate(scene, (0.0, 1.0), [10.0], [0.0], 1e-3, record_every=3)
    traj = info.value.trajectory
    assert traj.status == "failed"
    assert traj.t[-1] == pytest.approx(0.5)  # the last good state, though not on the record grid
    assert np.all(np.isfinite(traj.q))
    assert traj.q[-1, 0] == pytest.approx(10.0 - 0.5 * 9.81 * 0.5**2, rel=1e-9)


def test_keyboard_interrupt_propagates_with_the_partial_trajectory():
    def force(t, q, v):
        if t > 0.3:
            raise KeyboardInterrupt
        return np.array([-9.81])

    scene = mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.FunctionForce(force)])
    with pytest.raises(KeyboardInterrupt) as info:
        mo.simulate(scene, (0.0, 1.0), [10.0], [0.0], 1e-3)
    traj = info.value.trajectory
    assert traj.status == "interrupted" and "interrupted" in traj.message
    assert traj.t[-1] == pytest.approx(0.3, abs=2e-3)


def test_user_exception_mid_run_is_wrapped_with_step_and_trajectory():
    def gap(q):
        if q[0] < 5.0:
            raise RuntimeError("sensor broke")
        return np.array([q[0]])

    barrier = mo.FunctionBarrier(gap, lambda q: np.array([[1.0]]))
    scene = mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.ConstantForce([-9.81])], [mo.Contact(barrier, 0.5, "floor")])
    with pytest.raises(mo.SimulationError, match="raised RuntimeError: sensor broke") as info:
        mo.simulate(scene, (0.0, 2.0), [10.0], [0.0], 1e-3)
    assert info.value.trajectory.q[-1, 0] >= 5.0 - 0.01


def test_integrator_usable_step_by_step():
    scene = pendulum_wall(e=0.8)
    integ = oracle.MoreauJeanMidpoint(scene, 1e-3, solver="enum")
    integ.init(0.0, [-0.5], [0.0])
    traj = mo.simulate(scene, (0.0, 0.5), [-0.5], [0.0], 1e-3, solver="enum")
    for _ in range(500):
        integ.step()
    assert integ.k == 500 and integ.t == pytest.approx(0.5)
    np.testing.assert_allclose(integ.q, traj.q[-1], atol=1e-15)
