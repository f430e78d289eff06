"""Issue 11 A on the Python path: the shapes of M, f, g and G are checked at every call
(a model function that returns another shape mid-run stops the run with an error naming
it, the expected and the received shape, and the run up to it is kept), and the step
factorizes a configuration-dependent M once (Cholesky) and solves with that factor."""

import numpy as np
import oracle
import oracle.base
import pytest

import moreau as mo
from moreau.model.chain import ChainGravity, JointDamping, Link, PendulumChain


def switching(good, bad, after):
    """A callable that behaves like ``good`` for ``after`` calls, then like ``bad``."""
    calls = [0]

    def fun(*args):
        calls[0] += 1
        return good(*args) if calls[0] <= after else bad(*args)
    return fun


def point_on_floor(gap=None, jacobian=None, mass=None, force=None, wall_gap=None):
    """A 1-DOF point falling onto a floor at q = 0 (e = 0.5), from plain callables; with
    ``wall_gap`` a second contact (a ceiling at q = 2)."""
    gap = gap or (lambda q: np.array([q[0]]))
    jacobian = jacobian or (lambda q: np.array([[1.0]]))
    mass = mass or (lambda q: np.eye(1))
    force = force or (lambda t, q, v: np.array([-9.81]))
    contacts = [mo.Contact(mo.FunctionBarrier(gap, jacobian), 0.5, name="floor")]
    if wall_gap is not None:
        contacts.append(mo.Contact(mo.FunctionBarrier(wall_gap, lambda q: np.array([[-1.0]])), 0.5, name="ceiling"))
    return mo.Scene(mo.FunctionSystem(mass, ndof=1), [mo.FunctionForce(force, name="push")], contacts)


CASES = {
    "gap of two rows": (dict(gap=switching(lambda q: np.array([q[0]]), lambda q: np.array([q[0], q[0]]), 300)),
                        r"gap of contact 'floor' at step \d+ \(t = [0-9.e-]+\) has shape \(2,\), expected \(1,\)"),
    "gap as a column": (dict(gap=switching(lambda q: np.array([q[0]]), lambda q: np.array([[q[0]]]), 300)),
                        r"gap of contact 'floor' at step \d+ .* has shape \(1, 1\), expected \(1,\)"),
    # a scalar gap once ran to "completed" without a word
    "gap as a scalar": (dict(gap=switching(lambda q: np.array([q[0]]), lambda q: q[0], 300)),
                        r"gap of contact 'floor' at step \d+ .* has shape \(\), expected \(1,\)"),
    "Jacobian too wide": (dict(jacobian=switching(lambda q: np.array([[1.0]]), lambda q: np.array([[1.0, 0.0]]), 100)),
                          r"Jacobian of contact 'floor' at step \d+ .* has shape \(1, 2\), expected \(1, 1\)"),
    "force as a column": (dict(force=switching(lambda t, q, v: np.array([-9.81]), lambda t, q, v: np.array([[-9.81]]),
                                               300)),
                          r"force of effect 'push' at step \d+ .* has shape \(1, 1\), expected \(1,\)"),
    "mass matrix too large": (dict(mass=switching(lambda q: np.eye(1), lambda q: np.eye(2), 300)),
                              r"mass matrix at step \d+ .* has shape \(2, 2\), expected \(1, 1\)"),
    "second contact's gap": (dict(wall_gap=switching(lambda q: np.array([2.0 - q[0]]),
                                                     lambda q: np.array([2.0 - q[0], 1.0]), 300)),
                             r"gap of contact 'ceiling' at step \d+ .* has shape \(2,\), expected \(1,\)"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_model_function_that_changes_shape_mid_run_stops_it_by_name_and_keeps_the_run(case):
    parts, message = CASES[case]
    scene = point_on_floor(**parts)
    with pytest.raises(mo.SimulationError, match=message) as info:
        oracle.simulate(scene, (0.0, 1.0), [0.2], [0.0], 1e-3, backend="python", solver="exact",
                    check_jacobian=False)
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.stats.backend == "python"
    assert traj.stats.steps >= 100 and len(traj.t) == traj.stats.steps + 1  # every good step kept
    assert f"at step {traj.stats.steps} " in str(info.value)  # the step that got the bad shape
    assert traj.t[-1] == pytest.approx(traj.stats.steps * 1e-3)


def test_the_predictor_corrector_checks_every_call_too():
    scene = point_on_floor(force=switching(lambda t, q, v: np.array([-9.81 - 0.1 * v[0]]),
                                           lambda t, q, v: np.array([-9.81, -0.1 * v[0]]), 500))
    with pytest.raises(mo.SimulationError, match=r"force of effect 'push' at step \d+ .* has shape \(2,\)"):
        oracle.simulate(scene, (0.0, 1.0), [0.2], [0.0], 1e-3, backend="python", solver="exact",
                    integrator=mo.MoreauJeanPredictorCorrector, check_jacobian=False)


def pendulum_chain():
    chain = PendulumChain([Link.rod(m=1.0, l=0.5), Link.rod(m=0.8, l=0.45)])
    return mo.Scene(chain, [ChainGravity(chain, g=9.81), JointDamping(chain, [0.01, 0.005])])


def test_a_configuration_dependent_mass_matrix_is_factorized_once_per_step(monkeypatch):
    """The step factorizes M(q_m) (Cholesky: a matrix that stops being SPD raises there)
    and solves with that factor; it used to solve with M again (np.linalg.solve: a
    second, LU, factorization every step). The answer is the same to round-off: the
    compiled path, which always used the factor, agrees to 1e-12."""
    scene = pendulum_chain()
    q0, v0, h, steps = [1.0, -0.5], [0.0, 0.0], 1e-3, 500
    calls = {"cholesky": 0, "solve": 0}
    real_cholesky, real_solve = oracle.base._cholesky, np.linalg.solve

    def cholesky(*a):
        calls["cholesky"] += 1
        return real_cholesky(*a)

    def solve(*a):
        calls["solve"] += 1
        return real_solve(*a)

    monkeypatch.setattr(oracle.base, "_cholesky", cholesky, raising=False)
    monkeypatch.setattr(np.linalg, "solve", solve)
    py = oracle.simulate(scene, (0.0, steps * h), q0, v0, h, backend="python", solver="exact", check_jacobian=False)
    monkeypatch.undo()
    assert py.completed and py.stats.steps == steps
    assert calls == {"cholesky": steps, "solve": 0}
    comp = mo.simulate(scene, (0.0, steps * h), q0, v0, h, backend="compiled")
    scale = np.abs(py.q).max(axis=0) + np.abs(py.v).max(axis=0)
    assert np.all(np.abs(comp.q - py.q) <= 1e-12 * scale) and np.all(np.abs(comp.v - py.v) <= 1e-12 * scale)


def test_the_jacobian_check_has_no_false_alarm_at_a_large_crank_angle():
    """After a thousand engine cycles the crank angle is 12 566 rad: a finite-difference
    step relative to it (1e-2 rad) is too coarse for the corners' gaps, and the check
    falls back to absolute steps instead of refusing a correct Jacobian."""
    from moreau.problems.piston import piston_model
    from moreau.run.trust import check_jacobians

    model = piston_model(e=0.0)
    q0, _ = model.initial_state()
    q = q0 + np.array([4 * np.pi * 1000, 0.0, 0.0])
    # the piston's corner gaps as a user's barrier: a built-in barrier is not checked at run time
    own = [mo.Contact(mo.FunctionBarrier(c.barrier.gap, c.barrier.jacobian, nrows=c.barrier.nrows), 0.0, name=c.name)
           for c in model.scene.contacts]
    check_jacobians(mo.Scene(model.scene.system, [], own), q)
    bad = mo.FunctionBarrier(lambda q: np.array([1.0 + np.sin(q[0])]), lambda q: np.array([[-np.cos(q[0])]]))
    with pytest.raises(ValueError, match="does not match its gap"):  # a wrong sign is still caught there
        check_jacobians(mo.Scene(mo.FunctionSystem(np.eye(1)), [], [mo.Contact(bad, 0.0)]), np.array([1e4]))


def test_a_run_checks_the_jacobians_of_user_barriers_only(monkeypatch):
    """A built-in barrier's Jacobian is its kernel's, tested at random states
    (tests/test_chain.py): a run does not difference its gaps again; a user's barrier in
    the same scene still is, and a wrong Jacobian of it is refused."""
    import moreau.run.trust as trust
    from moreau.problems.piston import piston_model

    model = piston_model(e=0.9)
    q0, v0 = model.initial_state()
    differenced, real = [], trust.finite_difference_jacobian
    monkeypatch.setattr(trust, "finite_difference_jacobian",
                        lambda f, q, **kw: differenced.append(f) or real(f, q, **kw))
    assert mo.simulate(model.scene, (0.0, 1e-3), q0, v0, 1e-4).completed
    assert differenced == []
    row = np.eye(model.scene.ndof)[:1]
    wrong = mo.FunctionBarrier(lambda q: 10.0 + row @ q, lambda q: -row)  # open, its Jacobian's sign wrong
    scene = mo.Scene(model.scene.system, model.scene.effects,
                     [*model.scene.contacts, mo.Contact(wrong, 0.0, name="own stop")])
    with pytest.raises(ValueError, match="own stop"):
        mo.simulate(scene, (0.0, 1e-3), q0, v0, 1e-4)
    assert differenced and all(f is wrong.gap for f in differenced)  # its gaps only


def test_the_initial_state_check_evaluates_the_users_parts_only(monkeypatch):
    """Built-in parts (a kernel of moreau's own) are checked when built; the start
    evaluates the parts a user gives, and names the one that is not finite there."""
    calls, built_in = [], mo.ConstantForce.force
    monkeypatch.setattr(mo.ConstantForce, "force", lambda self, t, q, v: calls.append(t) or built_in(self, t, q, v))
    system = mo.FunctionSystem(np.eye(2))
    floor = mo.LinearBarrier([0.0, 1.0])
    ok = mo.Scene(system, [mo.ConstantForce([0.0, -9.81], name="gravity")], [mo.Contact(floor, 0.5)])
    ok.check_state(0.0, np.array([0.0, 1.0]), np.zeros(2))
    assert calls == []
    bad = mo.FunctionForce(lambda t, q, v: np.array([0.0, np.nan]), name="wind")
    with pytest.raises(ValueError, match="force of effect 'wind' at the initial state is not finite"):
        mo.simulate(mo.Scene(system, [mo.ConstantForce([0.0, -9.81]), bad], [mo.Contact(floor, 0.5)]), (0.0, 0.01),
                    [0.0, 1.0], [0.0, 0.0], 1e-3)


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_run_continues_from_a_slightly_penetrating_state_only_when_asked(backend):
    """The state a run ended in may lie inside a barrier by round-off or by the midpoint's
    impact step; ``initial_penetration`` accepts it explicitly, the default refuses it."""
    from moreau.problems.bouncing_ball import bouncing_ball

    scene = bouncing_ball(0.5)
    with pytest.raises(ValueError, match="penetrates a barrier"):
        oracle.simulate(scene, (0.0, 0.01), [-1e-8], [-1.0], 1e-3, backend=backend)
    traj = oracle.simulate(scene, (0.0, 0.01), [-1e-8], [-1.0], 1e-3, backend=backend, initial_penetration=1e-6)
    assert traj.completed and traj.v[1, 0] > 0  # the first step resolves the approach
    for bad in (-1e-9, True, "1e-6", float("nan")):
        with pytest.raises(ValueError, match="initial_penetration"):
            oracle.simulate(scene, (0.0, 0.01), [1.0], [0.0], 1e-3, backend=backend, initial_penetration=bad)
