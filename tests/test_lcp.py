"""The compiled exact contact solver (dual active set, moreau.contact.lcp) against OSQP and
enumeration on random one-step problems: redundant rows, ill-scaled mass matrices, up to 30
active rows. v⁺ is unique (M is SPD) and is what is compared; P is not unique when rows
are redundant."""

import numpy as np
import pytest

import moreau as mo
from moreau.contact.problem import kkt_residuals


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


def test_exact_solver_agrees_with_enumeration_and_osqp_on_2000_random_problems():
    """Half of them with M diagonally scaled over 1e-4 … 1e4 (condition numbers up to 1e8):
    OSQP, solving in mass-normalized units and exact on the active set it finds, answers
    every one, passes the engine's check on every one (no fallback), and agrees with the
    exact solver to 1e-9. Before (issue 11 B): 354 of those 1000 not converged or rejected
    by the check, and accepted answers off by up to 5e-7."""
    rng = np.random.default_rng(20261122)
    exact, enum = mo.ExactSolver(), mo.EnumerationSolver()
    worst_enum = 0.0
    worst_osqp = [0.0, 0.0]  # as drawn, scaled
    n_osqp = [0, 0]
    osqp_failed = []
    n_enum = n_enum_failed = n_redundant = max_rows = 0
    max_cond = 0.0
    for i in range(2000):  # odd: M diagonally scaled over 1e-4 … 1e4; even: as drawn
        scaled = i % 2
        M, b, G, c = random_problem(rng, scaled=bool(scaled))
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
        if scaled:
            max_cond = max(max_cond, np.linalg.cond(M))
        osqp = mo.OSQPSolver()
        osqp.setup(M.shape[0], k)
        try:
            vo, Po = osqp.solve(M, b, G, c, rows)
        except mo.solvers.SolveFailed as exc:
            osqp_failed.append((i, str(exc)))
            continue
        res = kkt_residuals(M, b, G, c, vo, Po)
        if res.worst > 1e-6:  # the engine would reject it and fall back
            osqp_failed.append((i, res.as_dict()))
            continue
        worst_osqp[scaled] = max(worst_osqp[scaled], rel(v, vo))
        n_osqp[scaled] += 1
    print(f"enum: {n_enum} compared, {n_enum_failed} failed; osqp: {n_osqp} compared (as drawn, scaled), "
          f"{len(osqp_failed)} not converged or rejected by the check; worst v+ difference {worst_enum:.2g} / "
          f"{worst_osqp}; largest cond(M) of the scaled ones {max_cond:.2g}")
    assert n_enum > 300 and n_redundant > 100 and max_rows == 30 and max_cond > 1e8
    assert n_enum_failed <= 0.02 * n_enum, n_enum_failed
    assert worst_enum <= 1e-9, worst_enum
    assert osqp_failed == [] and n_osqp == [1000, 1000]
    assert max(worst_osqp) <= 1e-9, worst_osqp


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

    traj = piston_model(e=0.0).simulate(0.1, 1e-4, solver="osqp",
                                        drift_control=mo.PositionProjection())
    assert traj.completed and traj.stats.projections > 10_000
    assert traj.stats.fallbacks == 0


def test_osqp_passes_the_check_without_fallbacks_where_the_plastic_piston_slides():
    """300 steps with OSQP (called back from the loop) and drift control from the state the compiled loop
    reaches at step 53 700 of the first cycle (e = 0, h = 1e-4), where the piston slides
    along the wall: before (issue 11 B), 68 of the contact and projection solves fell back
    (OSQP's answers off by 1.1e-6 … 1.5e-6 in the check's stationarity)."""
    from moreau.problems.piston import piston_model

    model = piston_model(e=0.0)
    q0, v0 = model.initial_state()
    h, k0 = 1e-4, 53_700
    pre = mo.simulate(model.scene, (0.0, k0 * h), q0, v0, h, drift_control=mo.PositionProjection(),
                      record_every=k0)
    assert pre.stats.backend == "compiled" and pre.completed
    traj = mo.simulate(model.scene, (pre.t[-1], pre.t[-1] + 300 * h), pre.q[-1], pre.v[-1], h,
                       solver="osqp", drift_control=mo.PositionProjection(),
                       penetration_limit=model.params.clearance / model.params.l1)
    assert traj.completed and traj.stats.solves > 100 and traj.stats.projections > 100
    assert traj.stats.fallbacks == 0


@pytest.mark.slow  # OSQP called back at every contact and projection solve
def test_osqp_runs_a_whole_piston_cycle_with_drift_control_without_fallbacks():
    """One engine cycle (e = 0, h = 1e-4, 125 664 steps) with OSQP (called back from the loop) and
    drift control: every contact and projection solve passes the check. Before (issue 11 B):
    7 fallbacks (steps 53 819 … 53 838, stationarity 1.1e-6 … 1.5e-6)."""
    from moreau.problems.piston import piston_model

    traj = piston_model(e=0.0).simulate(1.0, 1e-4, solver="osqp",
                                        drift_control=mo.PositionProjection())
    assert traj.completed and traj.stats.solves > 100_000 and traj.stats.projections > 100_000
    assert traj.stats.fallbacks == 0


@pytest.mark.parametrize("k", [8, 20, 60])
def test_many_row_lcps_match_nonnegative_least_squares(k):
    """From ``BLOCK_MIN`` rows the dual method is started by block principal pivoting, which
    gives up on hard problems. On positive definite W (condition up to 1e6, random
    eigenvectors) with about half the rows active, and with every row pushed (w < 0), P
    equals the independent answer of scipy's NNLS: min |R P + R⁻ᵀ w| over P >= 0 for
    W = RᵀR is the same LCP."""
    from scipy.optimize import nnls

    from moreau.contact.active_set import BLOCK_MIN, lcp_dual_active_set
    from moreau.contact.one_step import workspace

    assert k >= BLOCK_MIN
    rng = np.random.default_rng(k)
    for trial in range(20):
        Q, _ = np.linalg.qr(rng.normal(size=(k, k)))
        W = Q @ np.diag(10.0 ** rng.uniform(-3, 3, k)) @ Q.T
        W = 0.5 * (W + W.T)
        w = -np.abs(rng.normal(size=k)) if trial % 4 == 0 else rng.normal(size=k)
        ws = workspace(1, k)
        P = np.empty(k)
        assert lcp_dual_active_set(W, w, P, k, 1e-12, ws.s, ws.A, ws.inA, ws.rhs, ws.r, ws.sub, ws.fac) == 0
        R = np.linalg.cholesky(W).T
        ref, _ = nnls(R, -np.linalg.solve(R.T, w), maxiter=50 * k)
        assert rel(P, ref) <= 1e-8
        slack = w + W @ P
        assert P.min() >= 0.0 and slack.min() >= -1e-10 * np.abs(w).max()
        assert np.abs(P * slack).max() <= 1e-10 * np.abs(P).max() * np.abs(w).max()


@pytest.mark.parametrize("N", [8, 20, 40])
def test_a_chain_on_a_floor_is_solved_by_block_pivoting_alone(N, monkeypatch):
    """The one-step problems of an N-link chain lying on a floor, shaken (random angles
    and velocities: from none to all rows pushed into the floor): block pivoting alone
    solves each (its Python form; no fallback to the dual method), and agrees with
    scipy's NNLS."""
    from scipy.optimize import nnls

    from moreau.contact import active_set
    from moreau.contact.active_set import _block_pivoting
    from moreau.contact.one_step import workspace
    from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow

    # the Python form calls its inlined helper as Python too (it has no Python entry)
    monkeypatch.setattr(active_set, "_solve_active", active_set._solve_active.py_func)

    chain = PendulumChain([Link.rod(m=1.0 / N, l=1.0 / N) for _ in range(N)])
    floor = PointLineBarrier(chain, [PointLineRow(i, (1.0 / N, 0.0), line_point=(0.0, 0.0), normal=(0.0, 1.0))
                                     for i in range(N)])
    gravity = ChainGravity(chain)
    rng = np.random.default_rng(N)
    for trial in range(10):
        q = np.pi / 2 + 0.05 * rng.normal(size=N)
        M, G = chain.mass_matrix(q), floor.jacobian(q)
        W = G @ np.linalg.solve(M, G.T)
        w = G @ (0.3 * trial / 9 * rng.normal(size=N) + 1e-3 * np.linalg.solve(M, gravity.force(0.0, q, 0 * q)))
        ws = workspace(1, N)
        P = np.empty(N)
        assert _block_pivoting.py_func(W, w, P, N, 1e-12, ws.s, ws.A, ws.inA, ws.rhs, ws.r, ws.sub, ws.fac)
        R = np.linalg.cholesky(W).T
        ref, _ = nnls(R, -np.linalg.solve(R.T, w), maxiter=50 * N)
        assert rel(P, ref) <= 1e-10


def test_many_dependent_rows_fall_back_to_the_dual_method(monkeypatch):
    """Sixteen rows on four coordinates (W = G M⁻¹ Gᵀ of rank 4), nine pushed: block
    pivoting gives up (its Python form says so); the dual method solves, and the engine's
    check passes."""
    from moreau.contact import active_set
    from moreau.contact.one_step import workspace

    rng = np.random.default_rng(7)
    n, k = 4, 16
    A = rng.normal(size=(n, n))
    M = A @ A.T + n * np.eye(n)
    G = rng.normal(size=(k, n))
    b = M @ rng.normal(size=n)
    c = G @ rng.normal(size=n) - 0.1  # feasible: some velocity clears every row
    W, w = G @ np.linalg.solve(M, G.T), G @ np.linalg.solve(M, b) - c
    ws = workspace(n, k)
    monkeypatch.setattr(active_set, "_solve_active", active_set._solve_active.py_func)
    assert (w < 0).sum() > n and not active_set._block_pivoting.py_func(
        W, w, np.empty(k), k, 1e-12 * np.abs(w).max(), ws.s, ws.A, ws.inA, ws.rhs, ws.r, ws.sub, ws.fac)
    v, P = mo.ExactSolver().solve(M, b, G, c, np.arange(k))
    assert kkt_residuals(M, b, G, c, v, P).worst <= 1e-9
    assert (P > 0).sum() >= 2


@pytest.mark.parametrize("seed, index", [(1, 347), (1, 2761), (5, 2705), (5, 2915)])
def test_nearly_dependent_active_rows_are_refined_to_the_checks_tolerance(seed, index):
    """Scaled random problems whose active rows are nearly dependent (cond(W_AA) 6.6e11 …
    2.4e13): one step of iterative refinement left the exact solver's answers off their
    bounds by complementarity residuals of 5e-6 … 3e-5, which the engine's check rejects;
    refinement repeated while it halves the residual passes it, as OSQP's answer does."""
    rng = np.random.default_rng(seed)
    for i in range(index + 1):
        M, b, G, c = random_problem(rng, scaled=bool(i % 2))
    rows = np.arange(G.shape[0])
    v, P = mo.ExactSolver().solve(M, b, G, c, rows)
    assert kkt_residuals(M, b, G, c, v, P).worst <= 1e-9
    osqp = mo.OSQPSolver()
    osqp.setup(M.shape[0], G.shape[0])
    vo, Po = osqp.solve(M, b, G, c, rows)
    assert kkt_residuals(M, b, G, c, vo, Po).worst <= 1e-9
    assert rel(v, vo) <= 1e-9


def test_the_checks_round_off_floor_is_kept_through_a_steps_passes():
    """kkt_residuals_kernel with ``keep`` (a step's later passes: the same M) gives the
    residuals of a check that forms √(M⁻¹)_jj afresh, bit for bit, and those are √ of the
    inverse's diagonal; without ``keep`` a new M is never checked against the last one's."""
    from moreau.contact.kkt import kkt_residuals_kernel
    from moreau.core.kernels import cholesky

    rng = np.random.default_rng(5)
    M, b, G, c = random_problem(rng)
    n, k = M.shape[0], G.shape[0]
    L = np.empty((n, n))
    assert cholesky(M, L, n) == -1
    v = np.linalg.solve(M, b) * (1.0 + 1e-9 * rng.normal(size=n))  # off by 1e-9: the floor is formed
    P = np.zeros(k)
    work = [np.empty(max(n, k)) for _ in range(5)]
    X, rd = np.empty((n, n)), np.zeros(n + 1)
    no_chain = (np.empty(0), 0, np.empty(0), np.empty(0), np.empty((4, 0)), False)  # the dense M's check
    first, again = np.empty(4), np.empty(4)
    kkt_residuals_kernel(M, L, b, G, c, v, P, k, first, *work, X, rd, False, *no_chain)
    assert rd[n] == 1.0  # formed
    np.testing.assert_allclose(rd[:n], np.sqrt(np.diag(np.linalg.inv(M))), rtol=1e-12)
    kkt_residuals_kernel(M, L, b, G, c, v, P, k, again, *work, X, rd, True, *no_chain)
    assert np.array_equal(first, again) and first[3] > 0.0
    M2 = 4.0 * M  # another M: without keep its floor is formed again (√ of a quarter)
    L2 = 2.0 * L
    kkt_residuals_kernel(M2, L2, b, G, c, v, P, k, again, *work, X, rd, False, *no_chain)
    np.testing.assert_allclose(rd[:n], 0.5 * np.sqrt(np.diag(np.linalg.inv(M))), rtol=1e-12)
