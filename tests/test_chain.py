"""The planar pendulum chain (issue 3): mass matrix, equations of motion, effects,
barriers, impacts, and the triple pendulum with walls."""

import numpy as np
import pytest

import moreau as mo
from moreau.core import kernels
from moreau.model.barriers import check_jacobian, finite_difference_jacobian
from moreau.model.chain import (
    ChainGravity,
    JointDamping,
    JointSprings,
    JointStop,
    Link,
    LinkTorque,
    PendulumChain,
    PointForce,
    PointLineBarrier,
    PointLineRow,
)
from moreau.model.system import check_spd

# The paper's engine (Awrejcewicz & Kudra, section 3): crank, connecting rod, piston.
PISTON = dict(
    m=[10.0, 1.0, 0.4], J=[1.0, 0.0075, 0.001], l=[0.04, 0.15, 0.0], com=[0.0, 0.12, 0.01]
)


# ----------------------------------------------------------------------------------------
# helpers: an independent, loop-based model of the chain (no shared code with moreau.model.chain)
# ----------------------------------------------------------------------------------------
def random_chain(rng, n, orientation="hanging", lateral=False, pivot=None):
    return PendulumChain.from_arrays(
        m=rng.uniform(0.1, 5.0, n),
        J=rng.uniform(1e-3, 0.5, n),
        l=rng.uniform(0.05, 1.0, n),
        com=rng.uniform(-0.2, 0.8, n),
        com_lateral=rng.uniform(-0.3, 0.3, n) if lateral else None,
        pivot=rng.uniform(-1, 1, 2) if pivot is None else pivot,
        orientation=orientation,
    )


def unit(phi, orientation):
    """Link direction e(φ) and its derivative de/dφ, written out from the definitions."""
    if orientation == "hanging":
        return np.array([np.sin(phi), -np.cos(phi)]), np.array([np.cos(phi), np.sin(phi)])
    return np.array([np.sin(phi), np.cos(phi)]), np.array([np.cos(phi), -np.sin(phi)])


def com_states(chain, q, v):
    """Positions and velocities of the centres of mass by explicit loops."""
    pos, vel = [], []
    for k, link in enumerate(chain.links):
        p = np.array(chain.pivot, dtype=float)
        pv = np.zeros(2)
        for i in range(k):
            e, de = unit(q[i], chain.orientation)
            p = p + chain.links[i].l * e
            pv = pv + chain.links[i].l * v[i] * de
        e, de = unit(q[k], chain.orientation)
        p = p + link.com * e + link.com_lateral * de
        # d/dt(de/dφ) = −e φ̇ in both orientations
        pv = pv + v[k] * (link.com * de - link.com_lateral * e)
        pos.append(p)
        vel.append(pv)
    return np.array(pos), np.array(vel)


def kinetic_energy_loops(chain, q, v):
    _, vel = com_states(chain, q, v)
    return sum(0.5 * lk.m * vc @ vc + 0.5 * lk.J * vk**2 for lk, vc, vk in zip(chain.links, vel, v))


def paper_groups(m, J, l, e):
    """ν_ij (i < j), β_i and M_11 of eq. (2.1) from the physical parameters."""
    n = len(m)
    tail = [sum(m[k] for k in range(i + 1, n)) for i in range(n)]  # mass beyond link i
    diag = [J[i] + m[i] * e[i] ** 2 + l[i] ** 2 * tail[i] for i in range(n)]
    M11 = diag[0]
    nu = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            nu[i, j] = nu[j, i] = l[i] * (m[j] * e[j] + l[j] * tail[j]) / M11
    return nu, np.array(diag) / M11, M11


# ----------------------------------------------------------------------------------------
# construction and validation
# ----------------------------------------------------------------------------------------
def test_link_and_chain_validation():
    with pytest.raises(ValueError, match="zero links"):
        PendulumChain([])
    with pytest.raises(ValueError, match=r"link 2: .*J.*nan"):
        PendulumChain.from_arrays(m=[1, 1, 1], J=[1, 1, np.nan], l=[1, 1, 1], com=[0.5] * 3)
    with pytest.raises(ValueError, match=r"link 1: .*mass.*-0.5"):
        PendulumChain.from_arrays(m=[1, -0.5], J=[1, 1], l=[1, 1], com=[0.5, 0.5])
    with pytest.raises(ValueError, match=r"link 0: .*length.*-1"):
        PendulumChain([dict(m=1, J=1, l=-1, com=0)])
    with pytest.raises(ValueError, match="must be > 0"):
        Link(m=1.0, J=0.0, l=1.0, com=0.5)
    with pytest.raises(ValueError, match="orientation"):
        PendulumChain([Link.rod(1, 1)], orientation="sideways")
    chain = PendulumChain([Link.rod(1, 1)] * 3)
    with pytest.raises(ValueError, match="index 3 is out of range"):
        chain.point_position(np.zeros(3), 3, (0, 0))
    with pytest.raises(ValueError, match="row 1: link index 7"):
        PointLineBarrier(chain, [(0, (1, 0), (2, 0), (-1, 0)), (7, (1, 0), (2, 0), (-1, 0))])
    with pytest.raises(ValueError, match="row 0: the normal of the line must be non-zero"):
        PointLineBarrier(chain, PointLineRow(2, (1, 0), (2, 0), (0, 0)))
    with pytest.raises(ValueError, match="lower must be < upper"):
        JointStop(chain, 1, lower=0.5, upper=0.1)
    with pytest.raises(ValueError, match="relative_to link index 5"):
        JointStop(chain, 1, lower=0.0, relative_to=5)


# ----------------------------------------------------------------------------------------
# mass matrix, bias terms, kinetic energy
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("orientation", ["hanging", "inverted"])
@pytest.mark.parametrize("lateral", [False, True])
def test_mass_matrix_spd_for_random_chains(rng, orientation, lateral):
    for n in range(1, 7):
        for _ in range(5):
            chain = random_chain(rng, n, orientation, lateral)
            for _ in range(5):
                M = chain.mass_matrix(rng.uniform(-np.pi, np.pi, n))
                assert M.shape == (n, n)
                assert np.array_equal(M, M.T)
                check_spd(M)
                # the inertia of each link alone bounds M from below: M - diag(J) is PSD
                assert np.linalg.eigvalsh(M - np.diag(chain.inertias))[0] > -1e-12 * np.abs(M).max()


@pytest.mark.parametrize("n", [3, 9])
def test_point_line_gaps_from_the_joints_match_the_points_positions(rng, n):
    """The gaps and Jacobian of points on a chain against lines (from the joints' positions
    in O(n + m), ``kernels.gaps_chain_point``, on 8 links or more; else from A and B; rows
    on any links in any order, points off the link's axis, tilted lines) against the
    points' positions and Jacobians (PendulumChain), and against the dense form
    g0 + A cos q + B sin q."""
    chain = PendulumChain([Link.rod(m=0.1 * (i + 1), l=0.15 + 0.05 * i) for i in range(n)], pivot=(0.3, -0.2))
    rows = [PointLineRow(int(k), tuple(rng.normal(size=2) * 0.1), tuple(rng.normal(size=2)), tuple(rng.normal(size=2)))
            for k in rng.permutation(np.arange(7) % n)]
    barrier = PointLineBarrier(chain, rows)
    assert barrier.kernel()[0] == (kernels.BAR_CHAIN_POINT if n >= 8 else kernels.BAR_TRIG)
    for q in rng.uniform(-np.pi, np.pi, size=(5, chain.ndof)):
        want = [barrier.normals[i] @ (chain.point_position(q, r.link, r.local) - np.asarray(r.line_point))
                for i, r in enumerate(rows)]
        np.testing.assert_allclose(barrier.gap(q), want, rtol=0, atol=1e-14)
        np.testing.assert_allclose(barrier.gap(q), barrier._g0 + barrier._A @ np.cos(q) + barrier._B @ np.sin(q),
                                   rtol=0, atol=1e-14)
        J = np.array([barrier.normals[i] @ chain.point_jacobian(q, r.link, r.local) for i, r in enumerate(rows)])
        np.testing.assert_allclose(barrier.jacobian(q), J, rtol=0, atol=1e-14)


@pytest.mark.parametrize("lateral", [False, True])
def test_linear_time_chain_kernels_match_the_dense_matrix(rng, lateral):
    """M x, the centrifugal terms, the Cholesky factor and M⁻¹ b from the O(n) generators
    (moreau.core.kernels.chain) against the dense ν ∘ cos + ν^s ∘ sin forms (N(q) of the
    paper's eq. (2.2), numpy's Cholesky and solve), up to chains of 60 links."""
    from moreau.core import kernels as k

    for n in (1, 2, 3, 7, 24, 60):
        chain = random_chain(rng, n, lateral=lateral)
        for _ in range(3):
            q = rng.uniform(-np.pi, np.pi, n)
            x = rng.normal(size=n)
            c, s = k.cos_sin(q)
            M = chain.mass_matrix(q)
            Mx = np.empty(n)
            k.chain_product(chain._pm, 0, c, s, x, Mx)
            np.testing.assert_allclose(Mx, M @ x, rtol=0, atol=1e-13 * np.abs(M).sum(axis=1).max() * np.abs(x).max())
            q2 = q + rng.normal(scale=0.1, size=n)  # two configurations in one sweep: each as chain_product
            c2, s2 = k.cos_sin(q2)
            Mx2, pair, pair2 = np.empty(n), np.empty(n), np.empty(n)
            k.chain_product(chain._pm, 0, c2, s2, x, Mx2)
            k.chain_product_pair(chain._pm, 0, c, s, c2, s2, x, pair, pair2)
            assert np.array_equal(pair, Mx) and np.array_equal(pair2, Mx2)
            bias = chain.bias_force(q, x)
            ref = -chain.n_matrix(q) @ x**2
            np.testing.assert_allclose(bias, ref, rtol=0, atol=1e-13 * np.abs(chain.n_matrix(q)).sum(axis=1).max()
                                       * np.max(x**2))
            L, gen = np.full((n, n), np.nan), np.empty((4, n))
            assert k.chain_factor(chain._pm, 0, c, s, gen, L) == -1
            assert not np.triu(L, 1).any()
            Lref = np.linalg.cholesky(M)
            assert np.abs(L - Lref).max() <= 1e-12 * np.linalg.cond(M) * np.abs(Lref).max()
            assert np.abs(L @ L.T - M).max() <= 1e-14 * n * np.abs(M).max()
            sol = x.copy()
            k.chain_solve(chain._pm, 0, c, s, gen, sol, sol)  # in place, from the generators alone
            ref = np.linalg.solve(M, x)
            assert np.abs(sol - ref).max() <= 1e-14 * np.linalg.cond(M) * np.abs(ref).max()
            B = rng.normal(size=(n, 5))  # five right-hand sides side by side: each as chain_solve alone
            X = B.copy()
            k.chain_solve_columns(chain._pm, 0, c, s, gen, X, 4, np.empty(5), np.empty(5))
            for j in range(4):
                one = np.empty(n)
                k.chain_solve(chain._pm, 0, c, s, gen, B[:, j].copy(), one)
                assert np.array_equal(X[:, j], one)
            assert np.array_equal(X[:, 4], B[:, 4])  # only the first k columns
            rd = np.empty(n)  # √ of M⁻¹'s diagonal (the KKT check's round-off floor), O(n)
            k.chain_inverse_diagonal_sqrt(chain._pm, 0, c, s, gen, rd)
            ref = np.sqrt(np.diag(np.linalg.inv(M)))
            assert np.abs(rd / ref - 1.0).max() <= 1e-14 * np.linalg.cond(M)
    broken = chain._pm.copy()
    broken[2 * n * n + 5] = -1.0  # M_55 < 0: the factor names the first non-positive pivot
    assert k.chain_factor(broken, 0, c, s, np.empty((4, n)), np.empty((n, n))) == 5


@pytest.mark.parametrize("orientation", ["hanging", "inverted"])
def test_triple_pendulum_matches_paper_closed_form(rng, orientation):
    chain = PendulumChain.from_arrays(**PISTON, orientation=orientation)
    nu, beta, M11 = paper_groups(PISTON["m"], PISTON["J"], PISTON["l"], PISTON["com"])
    assert chain.has_bias and not chain.constant_mass
    for _ in range(20):
        q, v = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-5, 5, 3)
        c = lambda i, j: np.cos(q[i] - q[j])  # noqa: E731, B023 - called in this iteration
        s = lambda i, j: np.sin(q[i] - q[j])  # noqa: E731, B023 - called in this iteration
        M_paper = np.array([
            [1.0, nu[0, 1] * c(0, 1), nu[0, 2] * c(0, 2)],
            [nu[0, 1] * c(0, 1), beta[1], nu[1, 2] * c(1, 2)],
            [nu[0, 2] * c(0, 2), nu[1, 2] * c(1, 2), beta[2]],
        ])
        N_paper = np.array([
            [0.0, nu[0, 1] * s(0, 1), nu[0, 2] * s(0, 2)],
            [-nu[0, 1] * s(0, 1), 0.0, nu[1, 2] * s(1, 2)],
            [-nu[0, 2] * s(0, 2), -nu[1, 2] * s(1, 2), 0.0],
        ])
        np.testing.assert_allclose(chain.mass_matrix(q) / M11, M_paper, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(chain.n_matrix(q) / M11, N_paper, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(chain.bias_force(q, v) / M11, -N_paper @ v**2, rtol=1e-12, atol=1e-13)
    nd = chain.nondimensional()
    assert nd.units.length == 0.04 and nd.units.mass == pytest.approx(M11 / 0.04**2, rel=1e-14)
    np.testing.assert_allclose(nd.beta, beta, rtol=1e-12)
    np.testing.assert_allclose(nd.nu - np.diag(nd.beta), nu, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(nd.lam, [1.0, 0.15 / 0.04, 0.0], rtol=1e-14)
    q = rng.uniform(-np.pi, np.pi, 3)
    np.testing.assert_allclose(nd.chain.mass_matrix(q), chain.mass_matrix(q) / M11, rtol=1e-12, atol=1e-15)
    assert nd.chain.mass_matrix(q)[0, 0] == pytest.approx(1.0, rel=1e-14)


@pytest.mark.parametrize("orientation", ["hanging", "inverted"])
def test_kinetic_energy_from_point_velocities(rng, orientation):
    for n in (1, 2, 3, 5):
        chain = random_chain(rng, n, orientation, lateral=True)
        for _ in range(10):
            q, v = rng.uniform(-np.pi, np.pi, n), rng.uniform(-3, 3, n)
            T_points = sum(
                0.5 * lk.m * np.sum(chain.point_velocity(q, v, k, (lk.com, lk.com_lateral)) ** 2)
                + 0.5 * lk.J * v[k] ** 2
                for k, lk in enumerate(chain.links)
            )
            T_loops = kinetic_energy_loops(chain, q, v)
            T = chain.kinetic_energy(q, v)
            assert T == pytest.approx(T_points, rel=1e-12)
            assert T == pytest.approx(T_loops, rel=1e-12)
            pos, _ = com_states(chain, q, v)
            np.testing.assert_allclose(chain.com_positions(q), pos, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("lateral", [False, True])
def test_lagrangian_residual_by_finite_differences(rng, lateral):
    """d/dt(∂T/∂φ̇) − ∂T/∂φ from finite differences of the loop-based T(q, v) equals
    M φ̈ − bias along a path with acceleration φ̈."""
    n = 4
    chain = random_chain(rng, n, "inverted", lateral)
    T = lambda q, v: kinetic_energy_loops(chain, q, v)  # noqa: E731
    dv, dq, dt = 1e-3, 1e-5, 1e-4
    I = np.eye(n)
    for _ in range(5):
        q, v, a = rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)

        def momentum(t):  # ∂T/∂v at (q(t), v(t)); central differences are exact in v (T is quadratic)
            qt, vt = q + v * t + 0.5 * a * t * t, v + a * t  # noqa: B023 - used in this iteration
            return np.array([(T(qt, vt + dv * I[i]) - T(qt, vt - dv * I[i])) / (2 * dv)
                             for i in range(n)])

        dpdt = (momentum(dt) - momentum(-dt)) / (2 * dt)
        dTdq = np.array([(T(q + dq * I[i], v) - T(q - dq * I[i], v)) / (2 * dq) for i in range(n)])
        lhs = dpdt - dTdq
        rhs = chain.mass_matrix(q) @ a - chain.bias_force(q, v)
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-6 * np.abs(rhs).max())


def energy_error_order(chain, q0, hs, t_end=1.0):
    scene = mo.Scene(chain, [ChainGravity(chain)])
    assert scene.conservative
    errs = []
    for h in hs:
        traj = mo.simulate(scene, (0.0, t_end), q0, np.zeros(chain.ndof), h, solver="enum")
        errs.append(np.max(np.abs(traj.energy - traj.energy[0])))
    return np.polyfit(np.log(hs), np.log(errs), 1)[0], errs


def test_energy_conserved_to_second_order_for_one_link(rng):
    """A single link has a constant mass matrix and no bias terms: the midpoint scheme is
    Störmer–Verlet and the energy error is O(h²)."""
    chain = random_chain(rng, 1, lateral=True)
    assert not chain.has_bias
    order, errs = energy_error_order(chain, [1.2], [4e-3, 2e-3, 1e-3, 5e-4])
    assert errs[-1] < 1e-4 * chain.kinetic_energy([0.0], [1.0]) + 1e-12
    assert order == pytest.approx(2.0, abs=0.2)


def test_energy_error_of_triple_pendulum_is_first_order(rng):
    """With N >= 2 links the centrifugal terms −N(q)φ̇² are velocity dependent and the
    midpoint step evaluates them at v_k: the scheme is first order in smooth phases, and
    so is its energy error (design notes §2). This pins that known property; a θ = ½
    integrator would make the order 2."""
    chain = random_chain(rng, 3)
    order, errs = energy_error_order(chain, [0.8, 0.8, 0.8], [4e-3, 2e-3, 1e-3, 5e-4])
    assert order == pytest.approx(1.0, abs=0.2)
    assert errs[-1] < 1e-2 * max(1.0, abs(ChainGravity(chain).potential(np.zeros(3))))


# ----------------------------------------------------------------------------------------
# kinematics, effects, barriers against finite differences
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("orientation", ["hanging", "inverted"])
def test_point_kinematics(rng, orientation):
    chain = random_chain(rng, 4, orientation, lateral=True)
    for _ in range(5):
        q, v = rng.uniform(-np.pi, np.pi, 4), rng.uniform(-2, 2, 4)
        link, local = int(rng.integers(4)), rng.uniform(-1, 1, 2)
        Jp = chain.point_jacobian(q, link, local)
        Jfd = finite_difference_jacobian(lambda x: chain.point_position(x, link, local), q)  # noqa: B023
        np.testing.assert_allclose(Jp, Jfd, atol=1e-8)
        np.testing.assert_allclose(chain.point_velocity(q, v, link, local), Jp @ v, rtol=1e-14, atol=1e-14)
        same = PendulumChain(chain.links, chain.pivot, orientation=(chain.axis, chain.lateral))
        np.testing.assert_array_equal(same.point_position(q, link, local), chain.point_position(q, link, local))
        joints = chain.joint_positions(q)
        assert joints.shape == (5, 2)
        np.testing.assert_allclose(joints[0], chain.pivot)
        for k in range(4):
            np.testing.assert_allclose(
                joints[k + 1], chain.point_position(q, k, (chain.links[k].l, 0.0)), atol=1e-14
            )


@pytest.mark.parametrize("orientation", ["hanging", "inverted"])
def test_barrier_jacobians(rng, orientation):
    chain = random_chain(rng, 4, orientation, lateral=True)
    rows = [
        PointLineRow(int(rng.integers(4)), rng.uniform(-1, 1, 2), rng.uniform(-2, 2, 2), rng.normal(size=2))
        for _ in range(5)
    ]
    barrier = PointLineBarrier(chain, rows)
    stops = [
        JointStop(chain, 2, lower=-0.3, upper=0.4),
        JointStop(chain, 3, upper=1.0, relative_to=2),
        JointStop(chain, 0, lower=-1.0),
    ]
    for _ in range(10):
        q = rng.uniform(-np.pi, np.pi, 4)
        for b in [barrier, *stops]:
            chk = check_jacobian(b, q)
            assert chk.max_abs_error < 1e-8 * max(1.0, np.abs(chk.numeric).max()), type(b).__name__
        expected = [
            np.asarray(r.normal) / np.linalg.norm(r.normal) @ (chain.point_position(q, r.link, r.local) - r.line_point)
            for r in rows
        ]
        np.testing.assert_allclose(barrier.gap(q), expected, atol=1e-13)
        th = q[3] - q[2]
        np.testing.assert_allclose(stops[1].gap(q), [1.0 - th], atol=1e-15)
        np.testing.assert_allclose(stops[0].gap(q), [q[2] + 0.3, 0.4 - q[2]], atol=1e-15)
    assert all(s.constant_jacobian for s in stops)
    assert barrier.row_names("wall") == [f"wall[{i}]" for i in range(5)]


@pytest.mark.parametrize("orientation", ["hanging", "inverted"])
def test_point_force_is_virtual_work_gradient(rng, orientation):
    chain = random_chain(rng, 3, orientation, lateral=True)
    link, local, F = 2, rng.uniform(-1, 1, 2), rng.normal(size=2)
    const = PointForce(chain, link, local, F)
    state = PointForce(chain, link, local, lambda t, q, v: F * (1.0 + np.sin(q[0])),
                       time_dependent=False, velocity_dependent=False)
    assert const.has_potential and not state.has_potential and not state.velocity_dependent
    for _ in range(10):
        q, v = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-1, 1, 3)
        work = lambda x: np.array([F @ chain.point_position(x, link, local)])  # noqa: E731
        Q_fd = finite_difference_jacobian(work, q)[0]
        np.testing.assert_allclose(const.force(0.0, q, v), Q_fd, atol=1e-8)
        np.testing.assert_allclose(state.force(0.0, q, v), (1.0 + np.sin(q[0])) * Q_fd, atol=1e-8)
        np.testing.assert_allclose(
            const.force(0.0, q, v), chain.point_jacobian(q, link, local).T @ F, rtol=1e-13, atol=1e-14
        )
        assert const.potential(q) == pytest.approx(-work(q)[0], abs=1e-13)


def test_conservative_effects_are_potential_gradients(rng):
    chain = random_chain(rng, 4, "inverted", lateral=True)
    effects = [
        ChainGravity(chain, g=9.81, direction=rng.normal(size=2)),
        JointSprings(chain, rng.uniform(0, 3, 4), rest=rng.uniform(-1, 1, 4)),
        LinkTorque(chain, rng.normal(size=4)),
        PointForce(chain, 1, (0.3, -0.1), rng.normal(size=2)),
    ]
    for _ in range(5):
        q = rng.uniform(-np.pi, np.pi, 4)
        for eff in effects:
            assert eff.has_potential and not eff.velocity_dependent
            grad = finite_difference_jacobian(lambda x: np.array([eff.potential(x)]), q)[0]  # noqa: B023
            np.testing.assert_allclose(eff.force(0.0, q, np.zeros(4)), -grad, atol=1e-7, err_msg=eff.name)
    # gravity's potential is Σ m g · height of the centres of mass (downward gravity)
    g = ChainGravity(chain, g=9.81)
    q = rng.uniform(-np.pi, np.pi, 4)
    assert g.potential(q) == pytest.approx(9.81 * chain.masses @ chain.com_positions(q)[:, 1], rel=1e-12)


def test_joint_damping_is_the_papers_tridiagonal_matrix(rng):
    chain = PendulumChain.from_arrays(**PISTON, orientation="inverted")
    c1, c21, c31 = 0.00432, 0.2, 0.2
    damping = JointDamping(chain, c1 * np.array([1.0, c21, c31]))
    C_paper = c1 * np.array([[1 + c21, -c21, 0], [-c21, c21 + c31, -c31], [0, -c31, c31]])
    np.testing.assert_allclose(damping.C, C_paper, rtol=1e-14)
    assert damping.velocity_dependent
    v = rng.normal(size=3)
    np.testing.assert_allclose(damping.force(0.0, np.zeros(3), v), -C_paper @ v, rtol=1e-13)
    # dissipated power = Σ c_i (relative joint velocity)²
    rel = np.array([v[0], v[1] - v[0], v[2] - v[1]])
    assert -damping.power(0.0, np.zeros(3), v) == pytest.approx(c1 * np.array([1, c21, c31]) @ rel**2)
    torque = LinkTorque(chain, lambda t, q, v: np.array([-9.807, 0.0, 0.0]), time_dependent=False)
    assert torque.velocity_dependent and not torque.time_dependent and not torque.has_potential


def test_nondimensional_scene_reproduces_the_physical_run(rng):
    """Scaling lengths, masses and time and converting the effects with Units gives the
    same motion in τ = t / T."""
    chain = random_chain(rng, 3, "hanging", lateral=True)
    T = 0.37
    nd = chain.nondimensional(time_scale=T)
    u = nd.units
    c = np.array([0.05, 0.02, 0.01])
    phys = mo.Scene(chain, [ChainGravity(chain), JointDamping(chain, c)])
    scaled = mo.Scene(nd.chain, [ChainGravity(nd.chain, g=9.81 / u.acceleration),
                                 JointDamping(nd.chain, c / u.damping)])
    q0, v0 = np.array([0.9, -0.4, 1.3]), np.array([0.5, 0.0, -1.0])
    h = 1e-3
    a = mo.simulate(phys, (0.0, 0.5), q0, v0, h, solver="enum")
    b = mo.simulate(scaled, (0.0, 0.5 / T), q0, v0 * T, h / T, solver="enum")
    np.testing.assert_allclose(b.q, a.q, atol=1e-10)
    np.testing.assert_allclose(b.v / T, a.v, atol=1e-9)
    np.testing.assert_allclose(b.energy * u.energy, a.energy, rtol=1e-10)


def test_piston_corners_and_gas_force_match_the_paper(rng):
    """Eq. (2.3): the four piston corners against the walls x = ±D/2, and the gas force
    at the pin O3 giving f_e = [F sin φ1, λ2 F sin φ2, 0] (times l1), as in eq. (2.1)."""
    chain = PendulumChain.from_arrays(**PISTON, orientation="inverted")
    l1, l2 = PISTON["l"][:2]
    D, d, s, hp = 0.08004, 0.08, 0.08, 0.04  # bore, piston diameter and height, pin depth
    corners = PointLineBarrier(chain, [
        PointLineRow(2, (hp, d / 2), (D / 2, 0.0), (-1.0, 0.0), "top right"),
        PointLineRow(2, (hp - s, d / 2), (D / 2, 0.0), (-1.0, 0.0), "bottom right"),
        PointLineRow(2, (hp, -d / 2), (-D / 2, 0.0), (1.0, 0.0), "top left"),
        PointLineRow(2, (hp - s, -d / 2), (-D / 2, 0.0), (1.0, 0.0), "bottom left"),
    ])
    lam2, eta, sigma, delta, Delta = l2 / l1, hp / l1, s / l1, d / l1, D / l1
    F = 1234.5
    gas = PointForce(chain, 2, (0.0, 0.0), (0.0, -F))  # along the cylinder axis, towards the crank
    for _ in range(10):
        f1, f2, f3 = q = rng.uniform(-np.pi, np.pi, 3)
        x = np.sin(f1) + lam2 * np.sin(f2)
        h_paper = [
            Delta / 2 - x - eta * np.sin(f3) - delta / 2 * np.cos(f3),
            Delta / 2 - x + (sigma - eta) * np.sin(f3) - delta / 2 * np.cos(f3),
            Delta / 2 + x + eta * np.sin(f3) - delta / 2 * np.cos(f3),
            Delta / 2 + x - (sigma - eta) * np.sin(f3) - delta / 2 * np.cos(f3),
        ]
        np.testing.assert_allclose(corners.gap(q) / l1, h_paper, rtol=0, atol=1e-13)
        np.testing.assert_allclose(gas.force(0.0, q, q) / l1, [F * np.sin(f1), lam2 * F * np.sin(f2), 0.0],
                                   rtol=1e-13, atol=1e-10)
    assert corners.row_names("piston")[1] == "piston[bottom right]"


# ----------------------------------------------------------------------------------------
# impacts
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("n_links", [1, 2])
def test_impact_dissipates_the_newton_energy(n_links):
    """At an isolated impact U_after = −e U_before and the logged energy loss is the
    contact's share of the step's kinetic energy balance, −½ P (U_before + U_after) with
    P = (U_after − U_free)/W (W = G M⁻¹ Gᵀ, U_free the contact-free post-step velocity):
    ½ (1 − e²) U_before²/W up to the O(h) smooth change U_free − U_before."""
    e, h = 0.8, 1e-4
    chain = PendulumChain([Link.rod(1.0, 0.6), Link(m=0.5, J=0.004, l=0.3, com=0.2)][:n_links])
    tip = (chain.links[-1].l, 0.0)
    # the wall x <= -0.15 leans the pendulum: gravity swings it back into the wall again and again
    wall = PointLineBarrier(chain, PointLineRow(n_links - 1, tip, line_point=(-0.15, 0.0), normal=(-1.0, 0.0)))
    gravity = ChainGravity(chain)
    scene = mo.Scene(chain, [gravity], [mo.Contact(wall, e, "wall")])
    q0 = np.full(n_links, -0.9)
    traj = mo.simulate(scene, (0.0, 1.5), q0, np.zeros(n_links), h, solver="enum")
    assert traj.completed
    log = traj.impacts
    big = np.abs(log.U_before) > 0.1
    assert big.sum() >= 3  # at least three real bounces
    for k, Ub, Ua, lost in zip(log.step, log.U_before, log.U_after, log.energy_lost):
        assert Ub < 0 and Ua == pytest.approx(-e * Ub, rel=1e-9)
        q, v = traj.q[k], traj.v[k]  # state at the start of the impact step (record_every = 1)
        qm = q + 0.5 * h * v
        M = chain.mass_matrix(qm)
        G = wall.jacobian(qm)[0]
        v_free = v + h * np.linalg.solve(M, scene.force(traj.t[k] + 0.5 * h, qm, v))
        W = float(G @ np.linalg.solve(M, G))
        U_free = float(G @ v_free)
        P = (Ua - U_free) / W
        assert lost == pytest.approx(-0.5 * P * (Ub + Ua), rel=1e-9)
        assert lost >= 0.0
        newton = 0.5 * (1 - e**2) * Ub**2 / W
        if abs(Ub) > 0.1:
            # lost/newton = (−e U_before − U_free)/((1 + e)|U_before|), with
            # U_free − U_before = h·(G M⁻¹ f): relative O(h |G M⁻¹ f| / |U_before|)
            assert lost == pytest.approx(newton, rel=1e-2)
            # The run's mechanical energy drops by the logged amount over the step, up to
            # O(h): the positions move with v⁺, not v_free, so the potential and M(q) see
            # the impulse half a step early (N = 1: exactly h/2 f·(v⁺ − v_free) to 1e-4).
            # Measured ≤ 3.3e-3 relative at h = 1e-4.
            assert traj.energy[k] - traj.energy[k + 1] == pytest.approx(lost, rel=100 * h)


def test_joint_stops_in_a_run():
    """A double pendulum whose elbow is limited to |φ1 − φ0| <= 0.5 and whose first link
    to φ0 <= 0.6: the stops are hit, bounce with U_after = −e U_before, and hold to h|U|."""
    chain = PendulumChain([Link.rod(1.0, 0.5), Link.rod(0.5, 0.4)])
    elbow = JointStop(chain, 1, lower=-0.5, upper=0.5, relative_to=0)
    shoulder = JointStop(chain, 0, upper=0.6)
    scene = mo.Scene(chain, [ChainGravity(chain)],
                     [mo.Contact(elbow, 0.5, "elbow"), mo.Contact(shoulder, 0.7, "shoulder")])
    assert scene.constant_jacobian and scene.row_names == ["elbow[lower]", "elbow[upper]", "shoulder"]
    h = 1e-3
    traj = mo.simulate(scene, (0.0, 3.0), [-0.4, 0.0], [5.0, 0.0], h, solver="enum")
    assert traj.completed
    log = traj.impacts
    assert {0, 1, 2} <= set(log.row.tolist())
    e = scene.restitution[log.row]
    np.testing.assert_allclose(log.U_after, -e * log.U_before, rtol=1e-9, atol=1e-12)
    assert traj.gaps.min() >= -h * np.abs(log.U_before).max()
    rel = traj.q[:, 1] - traj.q[:, 0]
    np.testing.assert_allclose(traj.gaps[:, :2], np.column_stack([rel + 0.5, 0.5 - rel]), atol=1e-14)


# ----------------------------------------------------------------------------------------
# the README example: a triple pendulum with three walls
# ----------------------------------------------------------------------------------------
def triple_pendulum_with_walls():
    """A hanging triple pendulum swinging between three arbitrarily placed walls (the
    README example): returns (scene, q0, v0)."""
    # three links hanging from the origin; angles are absolute, from the downward vertical
    chain = PendulumChain([
        Link.rod(m=1.0, l=0.5),                                  # uniform rod: J = m l²/12, com = l/2
        Link.rod(m=0.8, l=0.45),
        Link(m=0.5, J=0.01, l=0.4, com=0.25, com_lateral=0.02),  # central J (kg m²), com offsets (m)
    ])
    tip, elbow = (0.4, 0.0), (0.5, 0.0)  # points in link frames: (along, across) from the proximal joint
    walls = PointLineBarrier(chain, [     # one row per point/line pair, evaluated together
        PointLineRow(2, tip, line_point=(0.55, 0.0), normal=(-1.0, 0.1), name="right"),
        PointLineRow(0, elbow, line_point=(-0.3, 0.0), normal=(1.0, 0.3), name="left"),
        PointLineRow(2, tip, line_point=(0.0, -1.2), normal=(0.2, 1.0), name="floor"),
    ])
    scene = mo.Scene(
        chain,
        effects=[ChainGravity(chain, g=9.81), JointDamping(chain, [0.01, 0.005, 0.005])],
        contacts=[mo.Contact(walls, law=[0.8, 0.5, 0.9], name="walls")],  # restitution per row
        name="triple pendulum with walls",
    )
    return scene, np.array([1.2, 0.3, -0.5]), np.zeros(3)


def test_triple_pendulum_with_walls():
    scene, q0, v0 = triple_pendulum_with_walls()
    h = 1e-3
    traj = mo.simulate(scene, (0.0, 10.0), q0, v0, h, solver="enum")
    assert traj.completed and np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.v))
    log = traj.impacts
    assert set(log.row.tolist()) == {0, 1, 2}  # every wall is hit
    chain = scene.system
    walls = scene.contacts[0].barrier
    vmax = np.abs(traj.v).max(axis=1)
    for r, row in enumerate(walls.rows):
        U = np.abs(log.U_before[log.row == r]).max()
        active = traj.active[:, r].astype(int)
        edges = np.flatnonzero(np.diff(np.r_[0, active, 0]))
        # Contact is detected at a midpoint, so a row may close up to h|U| inside the wall
        # before its impact. While it stays active the velocity condition uses the
        # midpoint Jacobian, and each step drifts by the curvature term ½ Δφᵀ∇²g Δφ with
        # Δφ = h φ̇. For g = n·p: ∂²p/∂φ_i² = −ρ_i e(φ_i + α_i) (ρ_i the lever of link i:
        # l_i before the point's link, |local| on it) and mixed derivatives vanish, so
        # |½ Δφᵀ∇²g Δφ| ≤ ½ Σρ_i (h |φ̇|∞)² per active step; allow the worst run of
        # consecutive active steps.
        levers = chain.lengths[:row.link].sum() + np.hypot(*row.local)
        drift = 0.5 * levers * (h * vmax) ** 2
        allowance = max(drift[a:b + 1].sum() for a, b in zip(edges[::2], edges[1::2]))
        assert traj.gaps[:, r].min() >= -(h * U + allowance), scene.row_names[r]
        assert traj.gaps[:, r].min() < 0.0  # the bound is not vacuous: rows do penetrate
