"""The kernels of the equality rows (moreau.contact.equality) against dense linear algebra."""

import numpy as np

from moreau.contact.equality import eq_basis, eq_free, eq_impulses, eq_particular, eq_reduce_rows, eq_velocity


def _basis(M, G):
    n, me = M.shape[0], G.shape[0]
    L = np.linalg.cholesky(M)
    Q, R, piv = np.empty((n, n)), np.empty((n, me)), np.zeros(me, dtype=np.int64)
    rank = eq_basis(L, np.ascontiguousarray(G), 0, me, Q, R, piv, np.empty(n))
    return L, Q, R, piv, rank


def test_bilateral_reduced_problem_equals_the_kkt_system():
    """A random SPD M, two equality rows and one contact row held active: the reduced
    problem's answer, mapped back, solves the full KKT system (M v − b = G_Eᵀ P_E + g P,
    G_E v = c_E, g v = c) to 1e-12, and the impulses of the equality rows match."""
    rng = np.random.default_rng(3)
    n = 5
    A = rng.normal(size=(n, n))
    M = A @ A.T + n * np.eye(n)
    GE = rng.normal(size=(2, n))
    g = rng.normal(size=(1, n))
    b, cE, c = rng.normal(size=n), rng.normal(size=2), rng.normal(size=1)
    L, Q, R, piv, rank = _basis(M, GE)
    assert rank == 2
    y, x, by = np.zeros(n), np.empty(n), np.empty(n)
    assert eq_particular(R, piv, rank, 2, cE, y) == -1
    eq_free(L, Q, rank, b, y, by, x)
    gy, cy = g.copy(), c.copy()
    eq_reduce_rows(L, Q, rank, gy, 0, 1, cy, y, x)
    # the contact row active: the reduced QP with M = I, its row held at its bound
    p = (cy[0] - gy[0] @ by) / (gy[0] @ gy[0])
    ysol = by + gy[0] * p
    v = np.empty(n)
    eq_velocity(L, Q, ysol, v)
    PE = np.empty(2)
    eq_impulses(L, Q, R, piv, rank, 2, M @ v - b - g[0] * p, PE, x)
    K = np.block([[M, -GE.T, -g.T], [GE, np.zeros((2, 3))], [g, np.zeros((1, 3))]])
    ref = np.linalg.solve(K, np.concatenate([b, cE, c]))
    np.testing.assert_allclose(v, ref[:n], rtol=0, atol=1e-12)
    np.testing.assert_allclose(PE, ref[n:n + 2], rtol=0, atol=1e-12)
    assert abs(p - ref[-1]) <= 1e-12


def test_bilateral_redundant_rows_consistent_or_named():
    """Three rows of rank 2 (the third the sum of the first two): a consistent bound gives
    rank 2 and no complaint; an inconsistent one names the redundant row."""
    M = np.diag([1.0, 2.0, 3.0])
    G = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, -1.0], [1.0, 1.0, 0.0]])
    L, Q, R, piv, rank = _basis(M, G)
    assert rank == 2
    y = np.zeros(3)
    assert eq_particular(R, piv, rank, 3, np.array([0.3, -0.2, 0.1]), y) == -1
    bad = eq_particular(R, piv, rank, 3, np.array([0.3, -0.2, 0.5]), y)
    assert bad == piv[2] and bad in (0, 1, 2)
