"""Contact solvers agree, are checked, and fall back (issue 2 acceptance)."""

import warnings

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.contact.problem import OneStepProblem, kkt_residuals
from moreau.contact.solvers import SolveFailed
from moreau.problems.bouncing_ball import bouncing_ball


def random_problem(rng):
    """A feasible one-step QP with redundant rows and strictly satisfied rows."""
    n = int(rng.integers(1, 6))
    m = int(rng.integers(1, 6))
    A = rng.normal(size=(n, n))
    M = A @ A.T + 0.1 * np.eye(n)
    b = rng.normal(size=n)
    G = rng.normal(size=(m, n))
    redundant = m >= 2 and rng.random() < 0.5
    if redundant:  # a duplicated (or scaled) row, with a consistent bound below
        G[1] = G[0] * (1.0 if rng.random() < 0.5 else 2.0)
    v0 = rng.normal(size=n)
    slack = np.abs(rng.normal(size=m)) * (rng.random(m) < 0.5)
    c = G @ v0 - slack  # feasible at v0
    # some rows strictly satisfied by the unconstrained solution
    v_free = np.linalg.solve(M, b)
    loose = rng.random(m) < 0.3
    c[loose] = np.minimum(c[loose], G[loose] @ v_free - 1.0)
    if redundant:
        c[1] = c[0] * (G[1, 0] / G[0, 0])
    rows = np.flatnonzero(rng.random(m) < 0.8)
    if rows.size == 0:
        rows = np.arange(m)
    return M, b, G, c, rows


def test_osqp_and_exact_backends_agree_on_random_problems(rng):
    exact = {"enum": mo.EnumerationSolver(), "daqp": mo.make_solver("daqp")}
    checked = 0
    for _ in range(250):
        M, b, G, c, rows = random_problem(rng)
        m, n = G.shape
        osqp = mo.OSQPSolver()
        osqp.setup(n, m, None)
        v_o, P_o = osqp.solve(M, b, G, c, rows)
        for name, s in exact.items():
            s.setup(n, m, None)
            v_e, P_e = s.solve(M, b, G, c, rows)
            assert kkt_residuals(M, b, G[rows], c[rows], v_e, P_e).worst < 1e-9, name
            np.testing.assert_allclose(v_o, v_e, atol=1e-8, rtol=0, err_msg=name)
            # impulses may differ on redundant rows; the generalized impulse may not
            np.testing.assert_allclose(G[rows].T @ P_o, G[rows].T @ P_e, atol=1e-7, rtol=0)
        checked += 1
    assert checked == 250


def test_a_sparse_qpsolvers_backend_gets_csc_matrices_and_warns_nothing(rng):
    """qpsolvers' OSQP takes sparse matrices; given dense ones it converts them and warns
    (``SparseConversionWarning``) in every run of a user's scene. Ours are converted before,
    with the same answers as the dense ones converted by qpsolvers."""
    from qpsolvers.warnings import SparseConversionWarning

    problems = [random_problem(rng) for _ in range(30)]
    T = np.array([[1.0, 0.0]])  # friction: box QPs (its Tresca problems)
    landing = (np.eye(2), np.array([1.0, -1.0]), np.array([[0.0, 1.0]]), np.zeros(1), T, np.array([0.5]),
               np.array([0]))

    def answers(solver):
        out = []
        for M, b, G, c, rows in problems:
            solver.setup(G.shape[1], G.shape[0], None)
            out.append(solver.solve(M, b, G, c, rows)[0])
        solver.setup(2, 1, None)
        return out, solver.solve_friction(*landing)[0]

    dense = mo.make_solver("qpsolvers:osqp")
    dense._matrix = np.asarray  # as before: qpsolvers converts (and warns)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # only its answers are compared
        v_dense, slide_dense = answers(dense)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        v_sparse, slide = answers(mo.make_solver("qpsolvers:osqp"))
    assert not [w for w in seen if issubclass(w.category, SparseConversionWarning)]
    for a, b in zip(v_sparse, v_dense):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(slide, slide_dense)
    # lands (P_N = 1) and slides: |P_T| = mu P_N takes 0.5 of the tangential 1 (OSQP's tolerance)
    np.testing.assert_allclose(slide, [0.5, 0.0], atol=1e-3)


def test_osqp_is_set_up_once_and_updated(monkeypatch):
    import osqp

    calls = {"setup": 0, "update": 0}
    real_setup, real_update = osqp.OSQP.setup, osqp.OSQP.update

    def setup(self, *a, **k):
        calls["setup"] += 1
        return real_setup(self, *a, **k)

    def update(self, *a, **k):
        calls["update"] += 1
        return real_update(self, *a, **k)

    monkeypatch.setattr(osqp.OSQP, "setup", setup)
    monkeypatch.setattr(osqp.OSQP, "update", update)
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, solver="osqp")
    assert calls["setup"] == 1
    assert calls["update"] == traj.stats.solves > 0


def test_osqp_setup_loads_the_refinement_for_the_solves_argument_types(rng):
    """The refinement's kernels are loaded (or compiled) at setup, for exactly the argument
    types of the solves: no solve compiles them again (a first OSQP run otherwise waits ~7 s
    inside its first solve, and ``moreau compile`` would not have warmed it)."""
    from moreau.contact import refine

    osqp = mo.OSQPSolver()
    M, b, G, c, rows = random_problem(rng)
    osqp.setup(M.shape[0], G.shape[0])
    kernels = (refine._normalized, refine._exact_from_proposed_set, refine._upper_solve)
    before = [set(k.overloads) for k in kernels]
    assert all(before)
    for _ in range(3):
        osqp.solve(M, b, G, c, rows)
        M, b, G, c, rows = random_problem(rng)
        osqp.setup(M.shape[0], G.shape[0])
    assert [set(k.overloads) for k in kernels] == before


def test_osqp_prints_nothing(capfd):
    mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, solver="osqp")
    out, err = capfd.readouterr()
    assert out == ""
    assert "Polishing" not in err


class WrongSolver(mo.ContactSolver):
    """Returns the unconstrained velocity on chosen calls: a wrong answer that looks fine."""

    name = "wrong"

    def __init__(self, bad_calls):
        self.bad_calls = set(bad_calls)
        self.calls = 0
        self.inner = mo.EnumerationSolver()

    def setup(self, ndof, nrows, mass=None):
        self.inner.setup(ndof, nrows, mass)

    def solve(self, M, b, G, c, rows):
        self.calls += 1
        if self.calls in self.bad_calls:
            return np.linalg.solve(M, b), np.zeros(rows.shape[0])
        return self.inner.solve(M, b, G, c, rows)


class FailingSolver(mo.ContactSolver):
    name = "failing"

    def solve(self, M, b, G, c, rows):
        raise SolveFailed("always fails")


def test_wrong_answers_are_caught_and_fallback_counted():
    ref = mo.simulate(bouncing_ball(0.5), (0.0, 1.5), [1.0], [0.0], 1e-3, solver="enum")
    wrong = WrongSolver(bad_calls=range(1, 10_000, 7))
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.5), [1.0], [0.0], 1e-3, solver=wrong)
    expected = len([k for k in range(1, wrong.calls + 1) if k in wrong.bad_calls])
    assert traj.stats.fallbacks == expected > 0
    np.testing.assert_allclose(traj.q, ref.q, atol=1e-12)


def test_all_backends_failing_raises_solver_error_with_context():
    with pytest.raises(mo.SolverError) as info:
        mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3,
                    solver=FailingSolver(), fallback=None)
    exc = info.value
    assert exc.rows == ["floor"]
    assert exc.step == int(round(exc.t / 1e-3))
    assert 0.44 < exc.t < 0.46  # the first impact
    assert "failing" in exc.residuals and "always fails" in str(exc)
    assert exc.trajectory.status == "failed"
    assert exc.trajectory.t[-1] == pytest.approx(exc.t)  # kept up to the last good step


def test_lcp_form_matches_qp_form(rng):
    for _ in range(50):
        M, b, G, c, rows = random_problem(rng)
        s = mo.EnumerationSolver()
        s.setup(*G.shape[::-1], None)
        v, P = s.solve(M, b, G, c, rows)
        W, w = OneStepProblem(M, b, G[rows], c[rows]).lcp()
        slack = w + W @ P
        assert slack.min() > -1e-9 and P.min() >= 0
        assert np.abs(P * slack).max() < 1e-9


def test_the_fallback_is_never_the_main_solver_and_every_backends_failure_is_kept():
    """Issue 11 B: an integrator built by hand with ``solver="enum"`` took ``"enum"`` as its
    fallback too (the default), and the error of a step both failed kept only one of the
    two failures (both keyed "enum"). Now the default fallback is ``"exact"`` for enum,
    a fallback of the main solver's name is refused, and a failed step names both."""
    integ = oracle.MoreauJeanMidpoint(bouncing_ball(0.5), 1e-3, solver="enum")
    assert (integ.solver.name, integ.fallback.name) == ("enum", "exact")
    for main, fallback in (("enum", "enum"), (mo.OSQPSolver(), mo.OSQPSolver()), ("exact", mo.ExactSolver())):
        with pytest.raises(ValueError, match="fallback must be another solver than the main one"):
            oracle.MoreauJeanMidpoint(bouncing_ball(0.5), 1e-3, solver=main, fallback=fallback)
    with pytest.raises(ValueError, match="fallback must be another solver than the main one, got 'osqp' twice"):
        mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, solver=mo.OSQPSolver(),
                    fallback=mo.OSQPSolver())
    other = FailingSolver()
    other.name = "failing too"
    with pytest.raises(mo.SolverError) as info:
        mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, solver=FailingSolver(), fallback=other)
    assert set(info.value.residuals) == {"failing", "failing too"}


def test_auto_solver_is_the_loops_exact_solver_choosing_by_size():
    """``solver="auto"`` runs the loop's exact solver (which picks its method by the
    problem's size): a 12-link chain landing on a floor, with up to 12 rows closed (block
    pivoting from 8), gives the same trajectory bit for bit, and the result names it."""
    from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow

    N = 12
    chain = PendulumChain([Link.rod(m=1.0 / N, l=1.0 / N) for _ in range(N)])
    floor = PointLineBarrier(chain, [PointLineRow(i, (1.0 / N, 0.0), line_point=(0.0, -0.02), normal=(0.0, 1.0))
                                     for i in range(N)])
    scene = mo.Scene(chain, [ChainGravity(chain)], [mo.Contact(floor, 0.0, name="floor")])
    q0 = np.full(N, np.pi / 2)
    runs = [mo.simulate(scene, (0.0, 0.3), q0, np.zeros(N), 1e-3, solver=s) for s in ("auto", "exact")]
    assert all(r.completed for r in runs) and runs[0].stats.solver == "exact"
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].impulses, runs[1].impulses)
    assert runs[0].active.sum(axis=1).max() >= 8  # the many-row path was taken


@pytest.mark.parametrize("name", ["exact", "enum"])
def test_the_compiled_solvers_called_from_python_take_numbas_fast_dispatch(name, rng, monkeypatch):
    """Every argument of the compiled solve is given: numba's dispatch then finds the
    compiled code from its C fast path, not by typing the 21-array workspace in Python on
    every call (0.3 ms a solve when two arguments were left to their defaults)."""
    from numba.core.dispatcher import Dispatcher

    M, b, G, c, rows = random_problem(rng)
    solver = mo.make_solver(name)
    solver.solve(M, b, G, c, rows)  # load or compile
    typed = []
    original = Dispatcher._compile_for_args
    monkeypatch.setattr(Dispatcher, "_compile_for_args",
                        lambda self, *a, **k: typed.append(self.py_func.__name__) or original(self, *a, **k))
    v, P = solver.solve(M, b, G, c, rows)
    assert typed == []
    assert kkt_residuals(M, b, G, c, v, P).worst < 1e-8


def test_an_instance_of_the_loops_own_solver_runs_as_its_name_does(monkeypatch):
    """``solver=mo.ExactSolver()`` is the loop's own method, as ``"exact"`` is, not a call
    back into the same code from the loop (16x the piston's step): the same trajectory bit
    for bit and the instance's ``solve`` never called. An enumeration with other settings
    than the name's is still called back."""
    from moreau.contact.exact import _CompiledLCPSolver

    calls = []
    original = _CompiledLCPSolver.solve
    monkeypatch.setattr(_CompiledLCPSolver, "solve", lambda self, *a: calls.append(self.name) or original(self, *a))
    scene, q0, v0 = bouncing_ball(0.5), [1.0], [0.0]
    for name, instance in (("exact", mo.ExactSolver()), ("enum", mo.EnumerationSolver())):
        fallback = "exact" if name == "enum" else "enum"
        by_name, by_instance = (mo.simulate(scene, (0.0, 1.0), q0, v0, 1e-3, solver=s, fallback=fallback)
                                for s in (name, instance))
        assert by_instance.stats.solver == name and by_instance.stats.solves == by_name.stats.solves > 0
        assert np.array_equal(by_name.q, by_instance.q) and np.array_equal(by_name.v, by_instance.v)
    assert calls == []
    mo.simulate(scene, (0.0, 1.0), q0, v0, 1e-3, solver=mo.EnumerationSolver(max_rows=4), fallback="exact")
    assert calls and set(calls) == {"enum"}
