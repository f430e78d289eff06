"""The compiled exact contact solver (dual active set, moreau.lcp) against OSQP and
enumeration on random one-step problems: redundant rows, ill-scaled mass matrices, up to 30
active rows. v⁺ is unique (M is SPD) and is what is compared; P is not unique when rows
are redundant."""

import numpy as np
import pytest

import moreau as mo
from moreau.onestep import kkt_residuals


def random_problem(rng, k_max=30, scaled=True):
    n = int(rng.integers(2, 13))
    k = int(rng.integers(1, k_max + 1))
    A = rng.normal(size=(n, n))
    M = A @ A.T + n * np.eye(n)
    S = np.diag(10.0 ** rng.uniform(-2, 2, n) if scaled else np.ones(n))  # units of very different size
    M = S @ M @ S
    G = rng.normal(size=(k, n)) @ np.linalg.inv(S)
    if k >= 3 and rng.random() < 0.4:  # redundant rows: a duplicate and a multiple
        G[-1] = G[0]
        G[-2] = 2.0 * G[1]
    b = M @ rng.normal(size=n)
    v_ok = rng.normal(size=n)  # a feasible velocity, so that the problem has a solution
    c = np.minimum(rng.normal(size=k), G @ v_ok - 0.01 * rng.random(k))
    return M, b, G, c


def rel(a, b):
    return float(np.max(np.abs(a - b)) / max(1e-300, np.max(np.abs(b))))


def test_exact_solver_agrees_with_enumeration_and_osqp_on_1000_random_problems():
    rng = np.random.default_rng(20261122)
    exact, enum = mo.ExactSolver(), mo.EnumerationSolver()
    worst_enum = worst_osqp = 0.0
    n_enum = n_enum_failed = n_osqp = n_osqp_failed = n_redundant = max_rows = 0
    for i in range(2000):  # odd: M diagonally scaled over 1e-4 … 1e4; even: as drawn
        M, b, G, c = random_problem(rng, scaled=bool(i % 2))
        k = G.shape[0]
        rows = np.arange(k)
        v, P = exact.solve(M, b, G, c, rows)
        assert kkt_residuals(M, b, G, c, v, P).worst <= 1e-6  # the engine's acceptance (tol)
        if k <= 10:
            try:
                ve, _ = enum.solve(M, b, G, c, rows)
            except mo.solvers.SolveFailed:  # no active set passes at round-off (near-dependent rows)
                n_enum_failed += 1
            else:
                worst_enum = max(worst_enum, rel(v, ve))
                n_enum += 1
        n_redundant += bool(k >= 3 and np.array_equal(G[-1], G[0]))
        max_rows = max(max_rows, k)
        if i % 2:  # OSQP on ill-scaled M is issue 11 B: measured, 354 of 2000 not converged or
            continue  # rejected by the check, and accepted answers off by up to 5e-7
        osqp = mo.OSQPSolver()
        osqp.setup(M.shape[0], k)
        try:
            vo, Po = osqp.solve(M, b, G, c, rows)
        except mo.solvers.SolveFailed:  # ADMM did not converge in 20 000 iterations
            n_osqp_failed += 1
            continue
        if kkt_residuals(M, b, G, c, vo, Po).worst > 1e-6:  # the engine would reject it and fall back
            n_osqp_failed += 1
            continue
        worst_osqp = max(worst_osqp, rel(v, vo))
        n_osqp += 1
    print(f"enum: {n_enum} compared, {n_enum_failed} failed; osqp: {n_osqp} compared, {n_osqp_failed} "
          f"not converged or rejected by the check; worst v+ difference {worst_enum:.2g} / {worst_osqp:.2g}")
    assert n_enum > 300 and n_redundant > 100 and max_rows == 30
    assert n_enum_failed <= 0.02 * n_enum, n_enum_failed
    assert n_osqp >= 950, n_osqp_failed  # OSQP answered (and passed the check)
    assert worst_enum <= 1e-9, worst_enum
    assert worst_osqp <= 1e-9, worst_osqp
    assert n_osqp_failed < 0.05 * n_osqp, n_osqp_failed


@pytest.mark.parametrize("scale", [1e-4, 1e4])
def test_a_light_coordinate_is_solved_exactly_and_a_wrong_one_is_caught(scale):
    """A coordinate 1e4 times lighter (or heavier) than the others: the check, measured per
    coordinate, catches a 1e-6 relative error in that coordinate's velocity alone."""
    rng = np.random.default_rng(1)
    M, b, G, c = random_problem(rng, k_max=4)
    n = M.shape[0]
    S = np.ones(n)
    S[0] = scale
    M = M * np.outer(S, S)
    G = G / S
    b = b * S
    v, P = mo.ExactSolver().solve(M, b, G, c, np.arange(G.shape[0]))
    assert kkt_residuals(M, b, G, c, v, P).worst <= 1e-9
    wrong = v.copy()  # 1e-6 of that coordinate's velocity scale in the step (v⁺ or v_free)
    wrong[0] += 1e-6 * max(abs(v[0]), abs(np.linalg.solve(M, b)[0]))
    assert kkt_residuals(M, b, G, c, wrong, P).stationarity > 5e-7


def test_osqp_projection_solves_pass_the_check_without_fallbacks():
    """Drift-control projections are QPs with data of 1e-10 (b = 0, c = −g): OSQP solves them
    in units where they are O(1). Before, 7794 of 11324 steps fell back (0.1 cycle)."""
    from moreau.problems.piston import piston_model

    traj = piston_model(e=0.0).simulate(0.1, 1e-4, solver="osqp", backend="python",
                                        drift_control=mo.PositionProjection())
    assert traj.completed and traj.stats.projections > 10_000
    assert traj.stats.fallbacks == 0
