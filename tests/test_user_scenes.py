"""A user's own scene in the compiled loop (issue 41): plain numpy callables compiled by numba as
they are, callables numba cannot compile called back into Python, friction on a user barrier,
and the result's slip velocities computed in one compiled pass."""

import logging
import re

import numba
import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.compiled.lowering import lower
from moreau.problems.bouncing_ball import bouncing_ball

G0 = 9.81


def inclined(gap, jac):
    """The README's first example: a point mass bouncing on the floor y >= 0.2 x."""
    m = 2.0
    system = mo.FunctionSystem(m * np.eye(2))
    gravity = mo.ConstantForce([0.0, -G0 * m], name="gravity")
    floor = mo.FunctionBarrier(gap=gap, jacobian=jac)
    return mo.Scene(system, [gravity], [mo.Contact(floor, mo.NewtonImpact(0.7), name="floor")])


def plain_gap(q):
    return np.array([q[1] - 0.2 * q[0]])


def plain_jac(q):
    return np.array([[-0.2, 1.0]])


def run(scene, t_end=2.0, **kw):
    return mo.simulate(scene, (0.0, t_end), q0=[0.0, 1.0], v0=[1.0, 0.0], h=1e-3, progress=False, **kw)


def test_the_readme_example_compiles_its_lambdas_and_equals_the_njit_scene():
    scene = inclined(lambda q: np.array([q[1] - 0.2 * q[0]]), lambda q: np.array([[-0.2, 1.0]]))
    assert lower(scene).user.callbacks == ()  # numba compiled both lambdas: no callback
    plain = run(scene)
    jit = run(inclined(numba.njit(plain_gap), numba.njit(plain_jac)))
    assert plain.stats.backend == "compiled" and plain.completed
    assert len(plain.impacts) == len(jit.impacts) >= 3
    np.testing.assert_array_equal(plain.q, jit.q)  # the same machine code path: bit for bit
    np.testing.assert_array_equal(plain.impacts.t, jit.impacts.t)


def test_lambdas_binding_values_as_default_arguments_are_compiled_too():
    slope = np.array([-0.2, 1.0])  # bound as `n=slope`, the idiom for a value fixed in a loop
    scene = inclined(lambda q, n=slope: np.array([n @ q]), lambda q, n=slope: n.reshape(1, 2).copy())
    assert lower(scene).user.callbacks == ()  # not a callback: numba takes the default as a constant
    bound = run(scene)
    jit = run(inclined(numba.njit(plain_gap), numba.njit(plain_jac)))
    assert bound.completed and len(bound.impacts) == len(jit.impacts) >= 3
    np.testing.assert_allclose(bound.q, jit.q, rtol=0, atol=1e-12)


def test_a_gap_numba_cannot_compile_is_called_back_logged_by_name_with_the_same_answers(caplog):
    offsets = {"floor": 0.0}

    def gap(q):  # a dict lookup: numba cannot type it
        return np.array([q[1] - 0.2 * q[0] + offsets["floor"]])

    with caplog.at_level(logging.WARNING, logger="moreau.run.simulation"):
        back = run(inclined(gap, plain_jac))
    lines = [r.getMessage() for r in caplog.records if "Python callback" in r.getMessage()]
    assert len(lines) == 1 and "gap function 'floor'" in lines[0] and "dict" in lines[0]
    jit = run(inclined(numba.njit(plain_gap), numba.njit(plain_jac)))
    assert back.stats.backend == "compiled" and len(back.impacts) == len(jit.impacts) >= 3
    np.testing.assert_allclose(back.q, jit.q, rtol=0, atol=1e-12)


def test_results_returned_as_tuples_or_lists_are_compiled_with_the_array_answers():
    m = 2.0
    system = mo.FunctionSystem(m * np.eye(2))
    floor = mo.FunctionBarrier(gap=lambda q: (q[1] - 0.2 * q[0],), jacobian=lambda q: ((-0.2, 1.0),))
    gravity = mo.FunctionForce(lambda t, q, v: (0.0, -G0 * m), name="gravity")
    tuples = mo.Scene(system, [gravity], [mo.Contact(floor, mo.NewtonImpact(0.7), name="floor")])
    listed = inclined(lambda q: [q[1] - 0.2 * q[0]], lambda q: [[-0.2, 1.0]])
    assert lower(tuples).user.callbacks == () and lower(listed).user.callbacks == ()
    jit = run(inclined(numba.njit(plain_gap), numba.njit(plain_jac)))
    for traj in (run(tuples), run(listed)):
        assert traj.completed and len(traj.impacts) == len(jit.impacts) >= 3
        np.testing.assert_array_equal(traj.q, jit.q)

    def with_mass(mass):  # a mass matrix M(q) given by a callable
        contact = mo.Contact(mo.FunctionBarrier(gap=plain_gap, jacobian=plain_jac), mo.NewtonImpact(0.7), name="floor")
        return mo.Scene(mo.FunctionSystem(mass, ndof=2), [mo.ConstantForce([0.0, -G0 * m])], [contact])

    rows = with_mass(lambda q: [[m, 0.0], [0.0, m]])
    assert lower(rows).user.callbacks == ()
    np.testing.assert_array_equal(run(rows).q, run(with_mass(lambda q: m * np.eye(2))).q)


def test_a_callable_returning_what_the_loop_cannot_take_is_called_back_with_its_type_named(caplog):
    # numba compiles the lambda; its slot cannot take a 1-D Jacobian, and the check then names the shape
    with caplog.at_level(logging.WARNING, logger="moreau.run.simulation"):
        with pytest.raises(ValueError, match=r"has shape \(2,\), expected \(1, 2\)"):
            run(inclined(plain_gap, lambda q: np.array([-0.2, 1.0])))
    lines = [r.getMessage() for r in caplog.records if "Python callback" in r.getMessage()]
    assert len(lines) == 1, lines
    assert "Jacobian 'floor'" in lines[0]
    assert "it returns array(float64, 1d, C), and the loop takes an array of shape (m, n)" in lines[0]


def test_a_list_of_rows_of_the_wrong_length_mid_run_stops_it_by_name():
    jac = lambda q: [[-0.2, 1.0]] if q[1] > 0.5 else [[-0.2, 1.0, 0.0]]  # noqa: E731 - a row grows below y = 0.5
    with pytest.raises(mo.SimulationError, match=r"user Jacobian 'floor' returned an array of the wrong shape "
                                                 r"at step (\d+)") as exc:
        run(inclined(plain_gap, jac))
    step = int(re.search(r"at step (\d+)", str(exc.value)).group(1))
    kept = exc.value.trajectory  # the Jacobian is evaluated near the floor: the run up to that step is kept
    assert step > 300 and kept.status == "failed" and len(kept) == step + 1 and np.all(np.isfinite(kept.q))


def test_a_plain_callable_is_compiled_again_when_a_value_it_reads_changes():
    shift = 0.0  # a closure cell holding a float: numba freezes its value

    def gap(q):
        return np.array([q[1] - 0.2 * q[0] - shift])

    first = run(inclined(gap, plain_jac), t_end=0.6)
    shift = 0.3  # noqa: F841 - read by gap through its closure
    second = run(inclined(gap, plain_jac), t_end=0.6)
    assert second.impacts.t[0] < first.impacts.t[0]  # the floor moved up: the first impact comes earlier


def test_a_scene_built_again_with_the_same_values_reuses_its_compiled_callables():
    def make(slope):
        return inclined(lambda q: np.array([q[1] - slope * q[0]]), lambda q: np.array([[-slope, 1.0]]))

    first = lower(make(0.2)).user
    assert lower(make(0.2)).user is first  # new lambdas, the same code and values: not compiled again
    assert lower(make(0.25)).user is not first  # another value: compiled for it
    np.testing.assert_array_equal(run(make(0.2)).q, run(inclined(plain_gap, plain_jac)).q)


def test_a_zero_of_the_other_sign_is_another_value_to_a_compiled_callable():
    from moreau.compiled.callbacks import fingerprint

    def make(c):
        return lambda q: np.array([np.copysign(1.0, c) * q[1]])

    assert fingerprint(make(0.0)) == fingerprint(make(0.0))
    assert fingerprint(make(0.0)) != fingerprint(make(-0.0))


def test_a_callback_calls_the_functions_of_its_own_scene():
    offsets = {"floor": 0.0}

    def make():
        def gap(q):  # a dict lookup: called back
            return np.array([q[1] - 0.2 * q[0] + offsets["floor"]])
        return gap

    gaps = [make(), make()]  # the same code and values, two functions
    users = [lower(inclined(g, plain_jac)).user for g in gaps]
    assert users[0] is not users[1]
    assert [u.callbacks[0].fns[0] for u in users] == gaps


def test_a_callback_that_raises_stops_the_run_naming_it_and_keeps_the_states():
    calls = {"n": 0}

    def gap(q):
        calls["n"] += 1
        if calls["n"] > 300:
            raise RuntimeError("sensor offline")
        return np.array([q[1] - 0.2 * q[0]])

    with pytest.raises(mo.SimulationError, match="user gap function 'floor' raised RuntimeError: sensor offline "
                                                 r"at step \d+") as info:
        run(inclined(gap, plain_jac), check_jacobian=False)
    assert isinstance(info.value.__cause__, RuntimeError)  # the exception the callback caught
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.stats.backend == "compiled" and len(traj) > 1


def test_ctrl_c_inside_a_callback_interrupts_the_run_and_keeps_what_was_computed():
    calls = {"n": 0}

    def gap(q):
        calls["n"] += 1
        if calls["n"] == 500:
            raise KeyboardInterrupt
        return np.array([q[1] - 0.2 * q[0]])

    with pytest.raises(KeyboardInterrupt) as info:
        run(inclined(gap, plain_jac), check_jacobian=False)
    traj = info.value.trajectory
    assert traj.status == "interrupted" and 0.0 < traj.t[-1] < 2.0
    again = run(inclined(gap, plain_jac), check_jacobian=False)  # the flag was cleared
    assert again.completed


def sliding_rod(mu=(0.1, 0.9), L=1.0, m=1.0):
    """A rod (x, y, φ) lying on the floor y = 0 on its two ends, friction per end."""
    h2 = 0.5 * L

    def gap(q):
        return np.array([q[1] - h2 * np.sin(q[2]), q[1] + h2 * np.sin(q[2])])

    def jac(q):
        c = h2 * np.cos(q[2])
        return np.array([[0.0, 1.0, -c], [0.0, 1.0, c]])

    def tangent(q):  # the ends' velocities along the floor
        s = h2 * np.sin(q[2])
        return np.array([[1.0, 0.0, s], [1.0, 0.0, -s]])

    ends = mo.FunctionBarrier(gap, jac, nrows=2, tangent_jacobian=tangent)
    system = mo.FunctionSystem(np.diag([m, m, m * L * L / 12.0]))
    return mo.Scene(system, [mo.ConstantForce([0.0, -m * G0, 0.0], name="gravity")],
                    [mo.Contact(ends, mo.NewtonImpactFriction(0.0, mu), name="ends")])


def test_friction_on_a_user_barrier_runs_compiled_and_stops_where_coulomb_says():
    mu, v0 = (0.1, 0.9), 2.0
    scene = sliding_rod(mu)
    traj = mo.simulate(scene, (0.0, 0.6), [0.0, 0.0, 0.0], [v0, 0.0, 0.0], 1e-4, progress=False)
    assert traj.stats.backend == "compiled" and traj.completed
    # equal normal loads m g / 2 at the ends: deceleration g (mu1 + mu2) / 2
    expected = v0 ** 2 / (G0 * sum(mu))
    assert abs(traj.q[-1, 0] - expected) <= 5e-3 * expected
    assert abs(traj.v[-1, 0]) < 1e-9 and abs(traj.q[-1, 2]) < 1e-9
    # the slip velocities are the ends' tangential velocities T(q) v at every record
    T = np.array([np.array([[1.0, 0.0, 0.5 * np.sin(x[2])], [1.0, 0.0, -0.5 * np.sin(x[2])]]) @ v
                  for x, v in zip(traj.q, traj.v)])
    np.testing.assert_allclose(traj.slip_velocity, T, rtol=0, atol=1e-12)
    # sliding, each end on its cone's edge; at rest the net tangential impulse vanishes (its
    # split between the ends of a rigid rod is not unique: Coulomb's law admits any that fits)
    i = len(traj) // 4
    np.testing.assert_allclose(np.abs(traj.tangential_impulses[i]), np.array(mu) * traj.impulses[i], rtol=1e-9)
    assert not traj.sticking[i].any() and abs(traj.tangential_impulses[-1].sum()) < 1e-15


def test_the_free_velocity_of_a_frictional_contact_step_leaves_out_the_friction_impulses():
    """The impact log's 'faster than the smooth forces' rule compares U⁻ with the free
    normal velocity G (v_k + h M⁻¹ f): a tilted rod sliding on one end, whose friction
    turns it (the tangential impulse changes the end's normal velocity)."""
    phi, h = 0.05, 1e-3
    scene = sliding_rod((0.5, 0.5))
    integ = oracle.MoreauJeanMidpoint(scene, h, solver="exact")
    integ.init(0.0, [0.0, 0.5 * np.sin(phi), phi], [2.0, 0.0, 0.0])
    integ.step()
    assert integ.active[0] and integ.PT[0] != 0.0
    q_m = integ.q - 0.5 * h * integ.v
    G = scene.jacobian(q_m)[[0]]
    v_free = np.array([2.0, 0.0, 0.0]) + h * np.linalg.solve(scene.system.mass_matrix(q_m),
                                                               scene.force(0.5 * h, q_m, np.zeros(3)))
    details = integ.last_contact_details(np.array([0]))
    np.testing.assert_allclose(details.U_free, G @ v_free, rtol=0, atol=1e-14)


def block_on_floor(tangent):
    floor = mo.FunctionBarrier(lambda q: np.array([q[1]]), lambda q: np.array([[0.0, 1.0]]),
                               tangent_jacobian=tangent)
    return mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([5.0, -G0], name="push and gravity")],
                    [mo.Contact(floor, mo.NewtonImpactFriction(0.0, 0.3), name="floor")])


def test_a_zero_tangent_row_on_the_osqp_route_prints_nothing(capfd):
    scene = block_on_floor(lambda q: np.array([[0.0, 0.0]]))  # a frictionless floor written as a zero row
    traj = oracle.simulate(scene, (0.0, 0.2), [0.0, 0.0], [0.0, 0.0], 1e-3, backend="python", solver="osqp",
                       progress=False)
    assert traj.completed and "Polishing" not in capfd.readouterr().out
    assert traj.v[-1, 0] == pytest.approx(1.0, rel=1e-9)  # no friction force: x'' = 5


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_non_finite_tangent_jacobian_is_named_with_the_step(backend):
    def tangent(q):
        return np.array([[np.nan if q[0] > 0.05 else 1.0, 0.0]])

    kw = {"solver": "osqp"} if backend == "python" else {}
    with pytest.raises(mo.SimulationError, match=r"floor.*(tangent|non-finite|not finite).* at step \d+") as info:
        oracle.simulate(block_on_floor(tangent), (0.0, 1.0), [0.0, 0.0], [0.0, 0.0], 1e-3, backend=backend,
                    progress=False, **kw)
    assert "OSQPException" not in str(info.value)
    assert info.value.trajectory.q[-1, 0] <= 0.06


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_row_that_penetrates_without_any_impulse_warns_naming_it(backend):
    """A Jacobian that vanishes near the floor (g = q, G = 0 below 0.01): the ball falls
    through, and the run says so although the row never logged an impact."""
    floor = mo.FunctionBarrier(lambda q: np.array([q[0]]),
                               lambda q: np.array([[1.0 if q[0] >= 0.01 else 0.0]]))
    scene = mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.ConstantForce([-G0])],
                     [mo.Contact(floor, 0.5, name="floor")])
    with pytest.warns(RuntimeWarning, match="row 'floor' penetrated .* without any contact impulse"):
        traj = oracle.simulate(scene, (0.0, 2.0), [1.0], [0.0], 1e-3, backend=backend, progress=False)
    assert len(traj.impacts) == 0 and traj.max_penetration[0] > 10.0
    assert any("never enforced" in w for w in traj.warnings)


def test_a_row_crossed_in_the_last_step_warns_that_the_final_state_penetrates():
    """One step of h = 0.01 from 1 mm above the floor at 0.15 m/s: its midpoint is above the
    floor, its end 1 mm below, and the run ends there: not a vanishing Jacobian."""
    with pytest.warns(RuntimeWarning, match="row 'floor' penetrated .* in the run's last step") as record:
        traj = mo.simulate(bouncing_ball(0.5), (0.0, 0.01), [0.001], [-0.15], 0.01, progress=False)
    assert traj.max_penetration[0] > 5e-4 and len(traj.impacts) == 0
    assert not any("never enforced" in str(w.message) for w in record)


def test_a_row_never_enforced_warns_beside_rows_that_bounce():
    """The vanishing Jacobian of the test above on a second coordinate, beside a floor the
    first one bounces on: the bounces' step scale h·|U⁻| does not hide the row that fell through."""
    floor = mo.FunctionBarrier(lambda q: np.array([q[0]]), lambda q: np.array([[1.0, 0.0]]))
    bad = mo.FunctionBarrier(lambda q: np.array([q[1]]), lambda q: np.array([[0.0, 1.0 if q[1] >= 0.01 else 0.0]]))
    scene = mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([-G0, -G0])],
                     [mo.Contact(floor, 0.5, name="floor"), mo.Contact(bad, 0.5, name="bad")])
    with pytest.warns(RuntimeWarning, match="row 'bad' penetrated .* without any contact impulse"):
        traj = mo.simulate(scene, (0.0, 2.0), [1.0, 1.0], [0.0, 0.0], 1e-3, progress=False)
    assert len(traj.impacts) > 0 and set(traj.impacts.row.tolist()) == {0}
    assert not any("'floor'" in w for w in traj.warnings)


def test_the_drift_of_a_sliding_contact_is_named_as_such_not_blamed_on_the_step():
    """A point dropped into a circular bowl (e = 0) lands once and slides. Without drift
    control the midpoint step leaves G v⁺ = (h/2) vᵀ∇²g v on the curved barrier, so its
    penetration grows in contact, first order in h. The warning names that drift and what
    holds it, not the landing's resolution; with the engine's drift control there is none."""
    bowl = mo.FunctionBarrier(lambda q: np.array([1.0 - np.hypot(q[0], q[1])]),
                              lambda q: -np.array([[q[0], q[1]]]) / np.hypot(q[0], q[1]))
    scene = mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([0.0, -G0])],
                     [mo.Contact(bowl, 0.0, name="bowl")])
    pen = []
    for h in (1e-3, 5e-4):
        with pytest.warns(RuntimeWarning, match="row 'bowl' penetrated .* the drift of a persistent contact"):
            traj = mo.simulate(scene, (0.0, 2.0), [0.6, 0.0], [0.0, 0.0], h, progress=False)
        assert len(traj.impacts) == 1 and traj.max_penetration_t[0] - traj.impacts.t[0] > 1.0
        pen.append(traj.max_penetration[0])
    assert 1.7 < pen[0] / pen[1] < 2.3  # first order in h
    # sliding from the start under a given limit: no impact to measure from
    with pytest.warns(RuntimeWarning, match=r"beyond the given limit \(1e-06\): with no impact, in contact: the drift"):
        mo.simulate(scene, (0.0, 2.0), [0.0, -1.0], [1.0, 0.0], 1e-3, progress=False, penetration_limit=1e-6)
    held = mo.simulate(scene, (0.0, 2.0), [0.6, 0.0], [0.0, 0.0], 1e-3, progress=False,
                       drift_control=mo.CombinedProjection())
    assert held.warnings == [] and held.max_penetration[0] < 1e-12


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_rough_floor_redundant_with_a_rail_warns_naming_both(backend):
    """A block held on y = 0 by a rail and standing on a rough floor y >= 0: the normal load
    may go to either row, and friction on the floor is not determined. The run says so,
    naming the floor and the rail (not Painlevé's paradox)."""
    floor = mo.FunctionBarrier(lambda q: np.array([q[1]]), lambda q: np.array([[0.0, 1.0]]),
                               tangent_jacobian=lambda q: np.array([[1.0, 0.0]]))
    rail = mo.Bilateral(mo.FunctionBarrier(lambda q: np.array([q[1]]), lambda q: np.array([[0.0, 1.0]])), "rail")
    scene = mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([1.0, -G0])],
                     [mo.Contact(floor, mo.NewtonImpactFriction(0.0, 0.5), name="floor")], constraints=[rail])
    with pytest.warns(RuntimeWarning, match=r"contact row 'floor' \(mu = 0.5\) is redundant with the bilateral "
                                            r"rows \['rail'\]"):
        traj = oracle.simulate(scene, (0.0, 0.1), [0.0, 0.0], [0.0, 0.0], 1e-3, backend=backend, progress=False,
                           **({"solver": "exact"} if backend == "python" else {}))
    assert any("redundant" in w for w in traj.warnings) and not any("Painlevé" in w for w in traj.warnings)
    # the same floor without the rail carries the load, and friction holds the block (mu g > 1)
    alone = mo.Scene(scene.system, scene.effects, scene.contacts)
    held = oracle.simulate(alone, (0.0, 0.1), [0.0, 0.0], [0.0, 0.0], 1e-3, backend=backend, progress=False)
    assert not any("redundant" in w for w in held.warnings) and abs(held.q[-1, 0]) < 1e-12


def test_a_built_in_part_whose_method_a_user_replaced_runs_the_users_method():
    """A subclass of a built-in part that overrides a method its kernel computes (a
    ConstantForce whose force grows with t, a LinearBarrier whose gap is raised), or an
    instance given its own gap, runs through the user's method: never the stale kernel."""

    class Wind(mo.ConstantForce):
        def force(self, t, q, v):
            return np.array([6.0 * t, 0.0])

    free = mo.Scene(mo.FunctionSystem(np.eye(2)), [Wind([0.0, 0.0], name="wind")], [])
    traj = mo.simulate(free, (0.0, 1.0), [0.0, 0.0], [0.0, 0.0], 1e-3)
    assert traj.q[-1, 0] == pytest.approx(1.0, abs=1e-5)  # x = t^3 under a force 6 t on a unit mass

    class Raised(mo.LinearBarrier):
        def gap(self, q):
            return super().gap(q) - 0.5

    floor = mo.LinearBarrier([0.0, 1.0])
    floor.gap = lambda q: np.array([q[1] - 0.25])  # this instance's own gap
    gravity = mo.ConstantForce([0.0, -9.81])
    for barrier, height in ((Raised([0.0, 1.0]), 0.5), (floor, 0.25)):
        scene = mo.Scene(mo.FunctionSystem(np.eye(2)), [gravity], [mo.Contact(barrier, 0.0)])
        traj = mo.simulate(scene, (0.0, 1.0), [0.0, 1.0], [0.0, 0.0], 1e-3)
        assert len(traj.impacts) == 1 and traj.q[-1, 1] == pytest.approx(height, abs=5e-3)
