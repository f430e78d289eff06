"""The compiled path (issue 10): same answers as the Python reference path, a scene
compiles to exactly its effects, user @njit callables run compiled, clear errors for
what does not compile, and a new process loads the loop from numba's cache."""

import os
import subprocess
import sys
import textwrap
import warnings

import numba
import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.compiled.lowering import lower
from moreau.core import kernels as K
from moreau.model.chain import ChainGravity, JointDamping, Link, PendulumChain, PointLineBarrier, PointLineRow
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.problems.chain_walls import chain_walls
from moreau.problems.piston import piston_model


def triple_with_walls():
    scene, q0, v0 = chain_walls()
    return scene, q0, v0, 1e-3


def piston_case(e, drift):
    model = piston_model(e=e)
    q0, v0 = model.initial_state()
    return model.scene, q0, v0, 1e-4, (mo.PositionProjection() if drift else None)


def both(scene, q0, v0, h, steps, **kw):
    runs = {b: oracle.simulate(scene, (0.0, steps * h), q0, v0, h, backend=b, solver="exact", **kw)
            for b in ("compiled", "python")}
    assert runs["compiled"].stats.backend == "compiled" and runs["python"].stats.backend == "python"
    return runs["compiled"], runs["python"]


def assert_same(c, p, rtol=1e-9):
    assert c.completed and p.completed and len(c) == len(p)
    scale = np.abs(p.q).max(axis=0) + np.abs(p.v).max(axis=0)
    assert np.all(np.abs(c.q - p.q) <= rtol * scale) and np.all(np.abs(c.v - p.v) <= rtol * scale)
    np.testing.assert_array_equal(c.active, p.active)  # the same contact decisions
    np.testing.assert_array_equal(c.impacts.step, p.impacts.step)
    np.testing.assert_array_equal(c.impacts.row, p.impacts.row)
    np.testing.assert_allclose(c.impacts.impulse, p.impacts.impulse, rtol=1e-7)
    np.testing.assert_allclose(c.max_penetration, p.max_penetration, rtol=1e-6, atol=1e-15)
    for key in ("forces", "contacts"):
        assert c.work[key] == pytest.approx(p.work[key], rel=1e-7, abs=1e-12)
    assert (c.stats.solves, c.stats.contact_steps) == (p.stats.solves, p.stats.contact_steps)


@pytest.mark.parametrize("name", ["ball", "pendulum-wall", "triple-chain"])
def test_compiled_equals_python_over_10000_steps(name):
    if name == "ball":
        c, p = both(bouncing_ball(0.5), [1.0], [0.0], 3e-4, 10_000)  # through the Zeno point
    elif name == "pendulum-wall":
        chain = PendulumChain([Link.rod(m=1.0, l=1.0)])  # the pendulum against a wall, built in
        wall = PointLineBarrier(chain, [PointLineRow(0, (1.0, 0.0), line_point=(0.5, 0.0), normal=(-1.0, 0.0))])
        scene = mo.Scene(chain, [ChainGravity(chain), JointDamping(chain, [0.05])],
                         [mo.Contact(wall, 0.8, name="wall")])
        c, p = both(scene, [-1.2], [0.0], 1e-3, 10_000)
    else:
        scene, q0, v0, h = triple_with_walls()
        c, p = both(scene, q0, v0, h, 10_000)
    assert len(c.impacts) > 3  # the comparison covers impacts
    assert_same(c, p)
    np.testing.assert_allclose(c.energy, p.energy, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c.gaps, p.gaps, rtol=0, atol=1e-9)  # lengths ~1: the states' 1e-9


@pytest.mark.parametrize("e, drift", [(0.0, True), (0.0, False), (0.9, True), (0.9, False)])
def test_compiled_equals_python_on_the_piston_over_10000_steps(e, drift):
    scene, q0, v0, h, dc = piston_case(e, drift)
    c, p = both(scene, q0, v0, h, 10_000, drift_control=dc, record_every=10)
    assert c.stats.contact_steps > 1000
    assert_same(c, p)
    assert c.stats.projections == p.stats.projections


@pytest.mark.parametrize("e", [0.0, 0.9])
def test_compiled_equals_python_on_the_piston_with_the_engines_drift_control(e):
    """The main job's drift control (a CombinedProjection accepting 1e-4 of the
    clearance): the same projections, contact decisions and states on both paths."""
    model = piston_model(e=e)
    q0, v0 = model.initial_state()
    c, p = both(model.scene, q0, v0, 1e-4, 10_000, drift_control=model.drift_control(), record_every=10)
    assert model.drift_control().tol > 0
    assert c.stats.contact_steps > 1000 and c.stats.projections > 0
    assert_same(c, p)
    assert c.stats.projections == p.stats.projections


@pytest.mark.slow  # the Python path: 4 x 50 000 steps, ~1 min
# without drift control the plastic piston sinks a clearance deep at this h, and both paths say so
@pytest.mark.filterwarnings("ignore:row 'cylinder:RuntimeWarning")
@pytest.mark.parametrize("e, drift", [(0.0, "exact"), (0.0, "none"), (0.9, "exact"), (0.9, "none"),
                                      (0.0, "engine"), (0.9, "engine")])
def test_piston_structural_figures_after_4_cycles_are_identical_on_both_paths(e, drift):
    """Side changes and their angles, impacts per cycle, penetration and speed of every
    cycle of a 4-cycle run (h = 1e-3; an exact CombinedProjection, the main job's drift
    control, which accepts 1e-4 of the clearance, or none)."""
    from moreau.problems.piston.analysis import cycle_figures

    model = piston_model(e=e)
    dc = {"exact": mo.CombinedProjection(), "engine": model.drift_control(), "none": None}[drift]
    c, p = (oracle.run_piston(model, 4, 1e-3, backend=b, solver="exact", drift_control=dc, record_every=1)
            for b in ("compiled", "python"))
    assert c.warnings == p.warnings
    fc, fp = cycle_figures(c, model.params), cycle_figures(p, model.params)
    assert len(fc) == len(fp) == 4
    assert sum(f.impacts for f in fc) > 10
    for a, b in zip(fc, fp):
        assert (a.side_changes, a.impacts) == (b.side_changes, b.impacts)
        np.testing.assert_allclose(a.change_angles_deg, b.change_angles_deg, rtol=0, atol=1e-6)
        assert a.mean_rpm == pytest.approx(b.mean_rpm, rel=1e-9)
        assert a.max_penetration == pytest.approx(b.max_penetration, rel=1e-6, abs=1e-9)
        assert a.energy_lost == pytest.approx(b.energy_lost, rel=1e-6, abs=1e-12)


def test_theta_integrator_compiled_equals_python():
    scene, q0, v0, h = triple_with_walls()
    runs = [oracle.simulate(scene, (0.0, 2.0), q0, v0, h, backend=b, solver="exact",
                        integrator=mo.MoreauJeanPredictorCorrector) for b in ("compiled", "python")]
    assert_same(*runs)


def test_a_scene_compiles_to_exactly_its_effects():
    model = piston_model(effects=("gas", "brake"))
    cs = lower(model.scene)
    assert sorted(cs.ekind.tolist()) == sorted([K.FOURIER_PT, K.CONST])  # no gravity, no damping
    assert cs.ints[1] == 4 and cs.bkind.tolist() == [K.BAR_TRIG]
    free = lower(mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([0.0, -9.81])]))
    assert free.ints[1] == 0 and free.bkind.size == 0 and free.ekind.tolist() == [K.CONST]
    assert free.ints[8] == 0  # no kernel needs cos q, sin q: none evaluated


def test_compiled_scene_parameters_are_the_objects_own():
    """The lowering reads each component's own parameter array: the kernels the Python
    objects call are fed the very same numbers."""
    model = piston_model()
    cs = lower(model.scene)
    for e, off in zip(model.scene.effects, cs.eoff):
        p = e.kernel()[1][0]
        np.testing.assert_array_equal(cs.pool[off:off + p.size], p)


@numba.njit
def _mass(q):
    return np.array([[2.0 + 0.1 * np.cos(q[1]), 0.0], [0.0, 1.0]])


@numba.njit
def _bias(q, v):  # −Ṁv + ½∇(vᵀMv) of _mass (simulate checks it)
    return np.array([0.1 * np.sin(q[1]) * v[0] * v[1], -0.05 * np.sin(q[1]) * v[0] ** 2])


@numba.njit
def _force(t, q, v):
    return np.array([-0.3 * v[0], -9.81])


@numba.njit
def _gap(q):
    return np.array([q[1] - 0.1 * q[0]])


@numba.njit
def _jac(q):
    return np.array([[-0.1, 1.0]])


def user_scene(compiled=True):
    wrap = (lambda f: f) if compiled else (lambda f: f.py_func)
    system = mo.FunctionSystem(wrap(_mass), ndof=2, bias=wrap(_bias))
    return mo.Scene(system, [mo.FunctionForce(wrap(_force))],
                    [mo.Contact(mo.FunctionBarrier(wrap(_gap), wrap(_jac)), 0.6, name="floor")])


def test_user_njit_callables_run_compiled_with_the_same_answers():
    c = mo.simulate(user_scene(), (0.0, 2.0), [0.0, 1.0], [1.0, 0.0], 1e-3)
    assert c.stats.backend == "compiled"
    p = oracle.simulate(user_scene(), (0.0, 2.0), [0.0, 1.0], [1.0, 0.0], 1e-3, backend="python", solver="exact")
    assert len(c.impacts) >= 3
    assert_same(c, p)


def test_plain_python_callables_run_compiled_with_the_njit_answers():
    plain = mo.simulate(user_scene(compiled=False), (0.0, 2.0), [0.0, 1.0], [1.0, 0.0], 1e-3)
    jit = mo.simulate(user_scene(), (0.0, 2.0), [0.0, 1.0], [1.0, 0.0], 1e-3)
    assert plain.stats.backend == "compiled" and len(plain.impacts) >= 3
    np.testing.assert_array_equal(plain.q, jit.q)  # numba compiled the same functions
    assert lower(mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.FunctionForce(lambda t, q, v: -q)])).user.callbacks == ()
    # OSQP is called from the loop (moreau.compiled.callbacks.SolverCallback), its answers checked
    osqp = mo.simulate(bouncing_ball(), (0, 1.0), [1.0], [0.0], 1e-3, solver="osqp")
    exact = mo.simulate(bouncing_ball(), (0, 1.0), [1.0], [0.0], 1e-3)
    assert osqp.stats.backend == "compiled" and osqp.stats.solver == "osqp" and osqp.stats.fallbacks == 0
    np.testing.assert_allclose(osqp.q, exact.q, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="backend must be"):
        oracle.simulate(bouncing_ball(), (0, 0.1), [1.0], [0.0], 1e-3, backend="fast")


def test_compiled_failures_keep_the_run_and_name_the_step():
    @numba.njit
    def mass(q):  # stops being positive definite below q = 0.5
        return np.array([[q[0] - 0.5]])

    @numba.njit
    def bias(q, v):  # −½ M'(q) v², M' = 1
        return np.array([-0.5 * v[0] ** 2])

    scene = mo.Scene(mo.FunctionSystem(mass, ndof=1, bias=bias), [mo.ConstantForce([-1.0])])
    with pytest.raises(mo.SimulationError, match="stopped being symmetric positive definite at step") as info:
        mo.simulate(scene, (0.0, 5.0), [1.0], [0.0], 1e-3)
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.stats.backend == "compiled"
    assert np.all(traj.q[:-1, 0] > 0.5)  # every state before the failing step is good
    assert f"at step {traj.stats.steps} " in str(info.value)


def test_a_new_process_loads_the_loop_from_the_cache():
    code = textwrap.dedent("""
        import time, moreau as mo
        from moreau.compiled import loop
        from moreau.problems.piston import piston_model
        m = piston_model(e=0.9)
        t = time.perf_counter()
        traj = m.simulate(0.01, 1e-4, drift_control=mo.PositionProjection())
        assert traj.stats.backend == "compiled"
        st = loop._run_chunk.stats  # the one entry point, for every scene
        print(sum(st.cache_hits.values()), sum(st.cache_misses.values()), time.perf_counter() - t)
    """)
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    for _ in range(2):  # the first run may compile (a fresh clone); the second must not
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=900)
        assert out.returncode == 0, out.stderr[-2000:]
    hits, misses, seconds = out.stdout.split()
    assert int(hits) >= 1 and int(misses) == 0  # machine code loaded, nothing compiled


# -- run-level checks (issue 11 A) ---------------------------------------------------------
def floor_scene(jac):
    return mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.ConstantForce([-9.81])],
                    [mo.Contact(mo.FunctionBarrier(lambda q: np.array([q[0]]), jac), 0.0, name="floor")])


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_jacobian_of_the_wrong_sign_is_refused_naming_the_row(backend):
    scene = floor_scene(lambda q: np.array([[-1.0]]))  # the gap is +q: its Jacobian is +1
    with pytest.raises(ValueError, match=r"Jacobian of contact row 'floor' \(row 0\) does not match"):
        oracle.simulate(scene, (0.0, 1.0), [1.0], [0.0], 1e-3, backend="python" if backend == "python" else "auto")
    # opting out runs it, and the penetration check then reports what happened
    with pytest.warns(RuntimeWarning, match="penetrated"):
        traj = mo.simulate(scene, (0.0, 1.0), [1.0], [0.0], 1e-3, check_jacobian=False, penetration_limit=1e-3)
    assert traj.warnings and -traj.gaps.min() > 1.0


def test_a_penetration_beyond_the_limit_warns_and_is_kept_by_save_load(tmp_path):
    with pytest.warns(RuntimeWarning, match="row 'floor' penetrated"):
        traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-2, penetration_limit=1e-3)
    assert traj.completed and len(traj.warnings) == 1
    assert traj.max_penetration[0] > 1e-3
    back = mo.load(traj.save(tmp_path / "run.npz"))
    assert back.warnings == traj.warnings
    clean = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-4)  # default: h·|U⁻|
    assert clean.warnings == [] and 0 < clean.max_penetration[0] <= 1e-4 * 4.5


def test_the_piston_within_its_clearance_has_no_warnings():
    """No drift control (PositionProjection() would project none of its e = 0.9 rows, and says
    so): the penetration stays within the clearance and nothing warns, of any kind."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        traj = piston_model(e=0.9).simulate(0.05, 1e-4, drift_control=None)
    assert traj.warnings == [] and traj.max_penetration.max() > 0


def test_python_path_raises_where_the_mass_matrix_stops_being_positive_definite():
    scene = mo.Scene(mo.FunctionSystem(lambda q: np.array([[q[0] - 0.5]]), ndof=1), [mo.ConstantForce([-1.0])])
    with pytest.raises(mo.SimulationError, match="stopped being symmetric positive definite at step") as info:
        oracle.simulate(scene, (0.0, 5.0), [1.0], [0.0], 1e-3, backend="python")
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.stats.backend == "python"
    # every step kept used a positive M (at its midpoint); the last state is the failing step's start
    assert np.all(traj.q[:-1, 0] > 0.5)
    assert f"at step {traj.stats.steps} " in str(info.value)


def test_ball_command_with_an_absurd_step_is_not_reported_clean(tmp_path):
    """`moreau ball --h 1 --t-end 1` once exited 0 with the ball 3.9 m inside the floor."""
    env = dict(os.environ, MPLBACKEND="Agg")
    out = subprocess.run([sys.executable, "-m", "moreau", "ball", "--h", "1", "--t-end", "1", "--no-progress",
                          "--out", str(tmp_path / "o")], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 1, out.stderr[-500:]
    assert "completed WITH WARNINGS" in out.stderr and "penetrated 3.9" in out.stderr
    assert "penetrated" in (tmp_path / "o" / "ball_summary.csv").read_text()


@numba.njit
def _force_raising(t, q, v):
    if t > 0.5:
        raise ValueError("the force table ends at t = 0.5 s")
    return np.array([0.0, -9.81])


@numba.njit
def _gap_raising_with_a_value(q):  # a dynamic exception: its message built at run time
    if q[1] < 0.3:
        raise ValueError("no table below y =", q[1])
    return np.array([q[1]])


@numba.njit
def _gap_changing(q):  # 1 row, then 3 once the ball is below 0.5 m
    return np.array([q[1]]) if q[1] > 0.5 else np.array([q[1], q[1], q[1]])


@numba.njit
def _jac_ball(q):
    return np.array([[0.0, 1.0]])


def test_user_callables_that_go_wrong_mid_run_stop_it_by_name_on_the_compiled_path():
    system = mo.FunctionSystem(np.eye(2))
    raising = mo.Scene(system, [mo.FunctionForce(_force_raising, name="table")],
                       [mo.Contact(mo.FunctionBarrier(_gap, _jac), 0.6, name="floor")])
    with pytest.raises(mo.SimulationError, match=r"user force 'table' raised ValueError: the force table ends "
                                                 r"at t = 0.5 s at step 500 \(t = 0.5\)") as info:
        mo.simulate(raising, (0.0, 2.0), [0.0, 1.0], [0.0, 0.0], 1e-3, backend="compiled")
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.stats.steps == 500 and traj.t[-1] == pytest.approx(0.5)
    changing = mo.Scene(system, [mo.ConstantForce([0.0, -9.81])],
                        [mo.Contact(mo.FunctionBarrier(_gap_changing, _jac_ball), 0.6, name="floor")])
    with pytest.raises(mo.SimulationError, match="user gap function 'floor' returned an array of the wrong shape"):
        mo.simulate(changing, (0.0, 2.0), [0.0, 1.0], [0.0, 0.0], 1e-3, backend="compiled")
    dynamic = mo.Scene(system, [mo.ConstantForce([0.0, -9.81])],
                       [mo.Contact(mo.FunctionBarrier(_gap_raising_with_a_value, _jac_ball), 0.6, name="floor")])
    for _ in range(2):  # the wrapper's error path leaves the process able to run again
        with pytest.raises(mo.SimulationError, match="user gap function 'floor' raised ValueError") as info:
            mo.simulate(dynamic, (0.0, 2.0), [0.0, 1.0], [0.0, 0.0], 1e-3, backend="compiled")
        assert info.value.trajectory.status == "failed" and 0.3 < info.value.trajectory.q[-1, 1] < 0.32


@numba.njit
def _gap_shrinking(q):  # 1 row, then none once the ball is below 0.5 m
    return np.array([q[1]]) if q[1] > 0.5 else np.zeros(0)


@numba.njit
def _mass_growing(q):  # 2 x 2, then 3 x 3 below 0.5 m
    return np.eye(2) if q[1] > 0.5 else np.eye(3)


@numba.njit
def _gap_ball(q):
    return np.array([q[1]])


@pytest.mark.parametrize("backend", ["python", "compiled"])
@pytest.mark.parametrize("case", ["longer gap", "shorter gap", "mass"])
def test_a_shape_change_mid_run_stops_it_with_the_trajectory_on_both_paths(backend, case):
    gap = {"longer gap": _gap_changing, "shorter gap": _gap_shrinking, "mass": _gap_ball}[case]
    system = mo.FunctionSystem(_mass_growing, ndof=2) if case == "mass" else mo.FunctionSystem(np.eye(2))
    scene = mo.Scene(system, [mo.ConstantForce([0.0, -9.81])],
                     [mo.Contact(mo.FunctionBarrier(gap, _jac_ball), 0.6, name="floor")])
    with pytest.raises(mo.SimulationError, match=r"(shape|wrong shape) at step 319 \(t = 0.319\)|"
                                                 r"at step 319 \(t = 0.319\) has shape") as info:
        oracle.simulate(scene, (0.0, 2.0), [0.0, 1.0], [0.0, 0.0], 1e-3, backend=backend)
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.stats.steps == 319
    assert np.all(traj.q[:, 1] > 0.5)  # every state kept is from before the change
