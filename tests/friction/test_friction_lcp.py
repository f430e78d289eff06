"""Lemke's method and the one-step problem with planar Coulomb friction, against
independent checks: complementarity of random LCPs, the enumeration of contact states
with a different mu per contact, and the single step of a block on a floor."""

import numpy as np
import pytest

from moreau.contact.friction import friction_one_step, friction_residuals
from moreau.contact.friction_enum import friction_enumerate
from moreau.contact.lemke import OK, RAY, lcp_lemke


def lemke(A, q):
    k = len(q)
    z = np.empty(k)
    st = lcp_lemke(np.asarray(A, float), np.asarray(q, float), z, k, np.empty((k, 2 * k + 2)),
                   np.empty(k, np.int64), np.empty(k))
    return st, z


@pytest.mark.parametrize("degenerate", [False, True])
def test_lemke_solves_random_positive_definite_lcps(rng, degenerate):
    """Non-symmetric positive definite A (a P-matrix: a unique solution): Lemke ends
    with z >= 0, w = A z + q >= 0, z ⟂ w to round-off, also with zeros in q (ties)."""
    worst = 0.0
    for _ in range(300):
        k = int(rng.integers(1, 9))
        B, S = rng.normal(size=(k, k)), rng.normal(size=(k, k))
        A = B @ B.T + 0.1 * np.eye(k) + (S - S.T)
        q = rng.normal(size=k)
        if degenerate:
            q[rng.random(k) < 0.5] = 0.0
        st, z = lemke(A, q)
        assert st == OK
        w = A @ z + q
        scale = max(np.abs(q).max(), 1e-3)
        worst = max(worst, -z.min() * np.abs(A).max() / scale, -w.min() / scale,
                    np.abs(z * w).max() * np.abs(A).max() / scale**2)
    assert worst < 1e-12


def test_lemke_reports_a_secondary_ray():
    """Two LCPs without a solution, and Lemke says so: w = −z − 1 < 0 for every z >= 0;
    and A = [[1, −2], [−2, 1]], q = (−1, −1) (z1 > 0 alone gives w2 < 0, z2 alone w1 < 0,
    both positive needs z1 = z2 = −1)."""
    st, _ = lemke([[-1.0]], [-1.0])
    assert st == RAY
    st, _ = lemke([[1.0, -2.0], [-2.0, 1.0]], [-1.0, -1.0])
    assert st == RAY


def check_solution(A, q, z, tol=1e-9):
    w = A @ z + q
    scale = max(np.abs(q).max(), np.abs(A @ z).max(), 1e-300)
    assert z.min() >= 0.0 and w.min() >= -tol * scale and np.abs(z * w).max() <= tol * scale * max(z.max(), 1e-300)


def test_lemke_keeps_a_ray_met_with_z0_at_round_off_when_it_solves_the_problem():
    """A degenerate LCP (rank-2 PSD A with a duplicated row) on which Lemke meets a ray
    while z0 is basic at 3.5e-17: the basic point solves it and is returned (it was
    thrown away as RAY); then 3000 such problems, each with a solution by construction."""
    A = np.array([[0.1835894103769278, 0.307668427127939, -0.47072942092897757, 0.262096397074904,
                   -0.47072942092897757],
                  [0.307668427127939, 0.5748721476786668, -1.1015887085000315, 0.78855485676294,
                   -1.1015887085000315],
                  [-0.47072942092897757, -1.1015887085000315, 2.857016870247749, -2.5152156685394353,
                   2.857016870247749],
                  [0.262096397074904, 0.78855485676294, -2.5152156685394353, 2.433114754539224,
                   -2.5152156685394353],
                  [-0.47072942092897757, -1.1015887085000315, 2.857016870247749, -2.5152156685394353,
                   2.857016870247749]])
    q = np.array([-0.11695814574276459, -0.12881411413058913, -0.05464527780863815, 0.22905604855177664,
                  0.267874033091363])
    st, z = lemke(A, q)
    assert st == OK
    check_solution(A, q, z)
    rng = np.random.default_rng(0)
    for _ in range(3000):
        k = int(rng.integers(3, 12))
        G = rng.standard_normal((k, int(rng.integers(1, k))))
        G[rng.integers(0, k)] = G[rng.integers(0, k)]  # a duplicated row
        A = G @ G.T
        x = np.maximum(rng.standard_normal(k), 0.0) * (rng.random(k) < 0.5)  # a solution: z = x, w
        w = np.maximum(rng.standard_normal(k), 0.0) * (x == 0.0) * (rng.random(k) < 0.5)
        q = w - A @ x
        st, z = lemke(A, q)
        assert st == OK
        check_solution(A, q, z)


def body_on_floor(points, m=2.0, J=0.3):
    """A rigid body q = (x, y, θ) at θ = 0 touching a floor at body points (rx, ry):
    M, normal rows (0, 1, rx) and tangent rows (1, 0, −ry)."""
    M = np.diag([m, m, J])
    GA = np.array([[0.0, 1.0, rx] for rx, _ in points])
    TA = np.array([[1.0, 0.0, -ry] for _, ry in points])
    return M, GA, TA


def delassus(M, GA, TA, muA, b, cA):
    fidx = np.flatnonzero(muA > 0)
    G = np.vstack([GA, TA[fidx]])
    W = G @ np.linalg.solve(M, G.T)
    w = G @ np.linalg.solve(M, b) - np.concatenate([cA, np.zeros(len(fidx))])
    return W, w, fidx


def test_friction_lcp_matches_state_enumeration_with_different_mu_per_contact(rng):
    """One to three contacts with different mu on a system of 6 coordinates with a random
    mass matrix and random rows (a regular W: one answer): Lemke's impulses equal those
    of the enumeration of open/stick/slip states (which builds no LCP matrix), and pass
    the law check. The pitfall this guards: each contact's own mu multiplies its own
    normal impulse; with one mu for all contacts an index mix-up would be invisible."""
    for trial in range(300):
        k = 1 + trial % 3
        B = rng.normal(size=(6, 6))
        M = B @ B.T + 0.5 * np.eye(6)
        GA, TA = rng.normal(size=(k, 6)), rng.normal(size=(k, 6))
        muA = rng.uniform(0.05, 1.0, size=k)
        v = rng.normal(size=6)
        b = M @ v + 0.1 * rng.normal(size=6)
        cA = -rng.uniform(0, 1, k) * (GA @ v)
        st, vn, PN, PT = friction_one_step(M, b, GA, cA, TA, muA)
        assert st == OK
        res = friction_residuals(M, b, GA, cA, TA, muA, vn, PN, PT)
        assert res.max() < 1e-9, res
        W, w, fidx = delassus(M, GA, TA, muA, b, cA)
        Pe = friction_enumerate(W, w, muA, fidx)
        assert Pe is not None
        pscale = np.abs(w).max() / np.diag(W).max()
        np.testing.assert_allclose(np.concatenate([PN, PT]), Pe, rtol=0, atol=1e-9 * max(np.abs(Pe).max(), pscale))


def test_rigid_body_on_two_and_three_contacts(rng):
    """A rigid body on a floor at two or three points (redundant rows: the impulses are
    not unique, the velocities are): Lemke's post-step contact velocities equal the
    enumeration's, and its answer passes the law check."""
    for trial in range(100):
        npts = 2 + trial % 2
        pts = [(rng.uniform(-1, 1), rng.uniform(-0.5, 0.0)) for _ in range(npts)]
        M, GA, TA = body_on_floor(pts)
        muA = rng.uniform(0.05, 0.8, size=npts)
        v = rng.normal(size=3) + np.array([0.0, -1.0, 0.0])
        b = M @ v + 1e-2 * np.array([rng.normal(), -19.62, rng.normal()])
        cA = -rng.uniform(0, 1, npts) * (GA @ v)
        st, vn, PN, PT = friction_one_step(M, b, GA, cA, TA, muA)
        assert st == OK
        res = friction_residuals(M, b, GA, cA, TA, muA, vn, PN, PT)
        assert res.max() < 1e-9, res
        W, w, fidx = delassus(M, GA, TA, muA, b, cA)
        Pe = friction_enumerate(W, w, muA, fidx)
        assert Pe is not None
        np.testing.assert_allclose(W @ np.concatenate([PN, PT[fidx]]) + w, W @ Pe + w,
                                   atol=1e-9 * np.abs(w).max())


def test_swapped_mu_gives_another_answer():
    """A body sliding on two contacts with mu = (0.1, 0.6): the answer for (0.6, 0.1) is
    different, and each matches its own enumeration."""
    M, GA, TA = body_on_floor([(-0.5, -0.2), (0.7, -0.2)])
    v = np.array([2.0, -0.5, 0.3])
    b = M @ v + 1e-3 * np.array([0.0, -19.62, 0.0])
    cA = np.zeros(2)
    answers = []
    for mu in ([0.1, 0.6], [0.6, 0.1]):
        mu = np.array(mu)
        st, vn, PN, PT = friction_one_step(M, b, GA, cA, TA, mu)
        W, w, fidx = delassus(M, GA, TA, mu, b, cA)
        Pe = friction_enumerate(W, w, mu, fidx)
        np.testing.assert_allclose(np.concatenate([PN, PT]), Pe, atol=1e-12)
        answers.append(vn)
    assert np.abs(answers[0] - answers[1]).max() > 1e-3


@pytest.mark.parametrize("v0", [1.0, -1.0, 1e-3, 0.0])
def test_block_single_step(v0):
    """A block (m = 2 kg) resting on a floor, mu = 0.3, h = 1e-3: sliding faster than
    mu g h loses exactly mu g h of speed; slower, it sticks (v⁺ = 0) with |P_T| < mu P_N."""
    m, h, g, mu = 2.0, 1e-3, 9.81, 0.3
    M = m * np.eye(2)
    b = M @ np.array([v0, 0.0]) + h * np.array([0.0, -m * g])
    st, vn, PN, PT = friction_one_step(M, b, np.array([[0.0, 1.0]]), np.zeros(1), np.array([[1.0, 0.0]]),
                                       np.array([mu]))
    assert st == OK
    assert PN[0] == pytest.approx(m * g * h, rel=1e-14)
    if abs(v0) > mu * g * h:
        assert vn[0] == pytest.approx(v0 - np.sign(v0) * mu * g * h, rel=1e-13)
        assert PT[0] == pytest.approx(-np.sign(v0) * mu * PN[0], rel=1e-13)
    else:
        assert abs(vn[0]) < 1e-15
        assert abs(PT[0]) <= mu * PN[0]
    assert abs(vn[1]) < 1e-15
