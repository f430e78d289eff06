"""Friction benchmarks with known answers (issue 27): a block sliding to rest, a block on
an incline, a disk that slips then rolls, an impact with friction; the solvers' routes
(Lemke, enumeration, the Tresca fixed point over OSQP) agree."""

import numpy as np
import oracle
import pytest

from .scenes import G, block, disk

BACKENDS = ["python", "compiled"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_block_sliding_to_rest(backend):
    """A block at 2 m/s on a floor with mu = 0.3 stops after v0²/(2 mu g) (within 0.5 % at
    h = 1e-3; here to 1e-5), stays at rest (v = 0 and sticking), and the ledger closes:
    the friction work equals −½ m v0²."""
    m, mu, v0 = 2.0, 0.3, 2.0
    traj = oracle.simulate(block(mu, m), (0.0, 1.0), [0.0, 0.0], [v0, 0.0], 1e-3, backend=backend, solver="exact")
    assert traj.completed
    d = v0**2 / (2 * mu * G)
    assert traj.q[-1, 0] == pytest.approx(d, rel=1e-5)
    stop = v0 / (mu * G)
    after = traj.t > stop + 2e-3
    assert np.abs(traj.v[after, 0]).max() < 1e-14
    assert traj.sticking[after].all()
    assert traj.work["friction"] == pytest.approx(-0.5 * m * v0**2, rel=1e-12)
    assert np.abs(traj.gaps).max() < 1e-14
    # the friction impulses: mu m g per unit time while sliding, opposed to the motion
    sliding = (traj.t > 0) & (traj.t < stop - 2e-3)
    np.testing.assert_allclose(traj.tangential_impulses[sliding, 0], -mu * m * G * 1e-3, rtol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("alpha_deg", [10.0, 25.0])
def test_block_on_incline_sticks_or_slides(backend, alpha_deg):
    """On an incline with mu = 0.3 (tan α < mu below 16.7°) the block at rest sticks; above,
    it slides with a = g (sin α − mu cos α) (the midpoint step is exact for a constant
    acceleration)."""
    mu, alpha = 0.3, np.radians(alpha_deg)
    traj = oracle.simulate(block(mu, alpha=alpha), (0.0, 0.5), [0.0, 0.0], [0.0, 0.0], 1e-3, backend=backend,
                       solver="exact")
    assert traj.completed
    t_dir = np.array([np.cos(alpha), np.sin(alpha)])
    s = traj.q @ t_dir
    if np.tan(alpha) < mu:
        assert np.abs(s).max() < 1e-15 and np.abs(traj.v).max() < 1e-15
        assert traj.sticking[1:].all()
    else:
        a = -G * (np.sin(alpha) - mu * np.cos(alpha))  # down the slope: s decreases
        np.testing.assert_allclose(s, 0.5 * a * traj.t**2, rtol=1e-10, atol=1e-15)
        assert not traj.sticking[2:].any()


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("inertia", "ratio"), [(0.5, 2.0 / 3.0), (0.4, 5.0 / 7.0)])
def test_disk_slips_then_rolls(backend, inertia, ratio):
    """A disk (J = m R²/2) or sphere (2/5) launched sliding without spin at v0 on a floor
    with mu = 0.2 slips, then rolls at 2/3 v0 (5/7 v0 for the sphere), from the time
    v0 (1 − ratio)/(mu g) on, with ẋ = −R θ̇ (no slip)."""
    R, v0, mu = 0.1, 3.0, 0.2
    traj = oracle.simulate(disk(mu, R, inertia=inertia), (0.0, 1.5), [0.0, R, 0.0], [v0, 0.0, 0.0], 1e-3,
                       backend=backend, solver="exact")
    assert traj.completed
    t_roll = v0 * (1 - ratio) / (mu * G)
    rolling = traj.t > t_roll + 2e-3
    np.testing.assert_allclose(traj.v[rolling, 0], ratio * v0, rtol=1e-3)
    np.testing.assert_allclose(traj.v[rolling, 0] + R * traj.v[rolling, 2], 0.0, atol=1e-12)
    assert traj.sticking[rolling].all()
    assert not traj.sticking[(traj.t > 0) & (traj.t < t_roll - 2e-3)].any()
    # energy lost to friction: the kinetic energy drops from ½ m v0² to ½ m (1 + inertia) (ratio v0)²
    T_end = 0.5 * (1 + inertia) * (ratio * v0) ** 2
    assert traj.work["friction"] == pytest.approx(T_end - 0.5 * v0**2, rel=1e-3)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("mu", [0.05, 0.5])
def test_impact_with_friction(backend, mu):
    """A disk (no gravity) hits the floor at normal speed V with contact slip u: with e = 0.5
    the normal speed after is e V; the friction impulse changes the slip by
    −mu (1 + e) V (1 + m R²/J) = −3 mu (1 + e) V if it keeps slipping (mu = 0.05), or stops
    it (mu = 0.5: u⁺ = 0 with |P_T| < mu P_N)."""
    R, V, u, e = 0.1, 2.0, 1.5, 0.5
    scene = disk(mu, R, e=e, gravity=0.0)
    h = 1e-3
    y0 = R + 0.5 * h * V  # closes at the first step's midpoint
    traj = oracle.simulate(scene, (0.0, 0.01), [0.0, y0, 0.0], [u, -V, 0.0], h, backend=backend, solver="exact")
    assert traj.completed
    vy, slip = traj.v[-1, 1], traj.v[-1, 0] + R * traj.v[-1, 2]
    assert vy == pytest.approx(e * V, rel=1e-12)
    PN = traj.impulses[:, 0].sum()
    PT = traj.tangential_impulses[:, 0].sum()
    assert PN == pytest.approx((1 + e) * V, rel=1e-12)
    if mu * (1 + e) * V * 3 < u:
        assert slip == pytest.approx(u - 3 * mu * (1 + e) * V, rel=1e-12)
        assert PT == pytest.approx(-mu * PN, rel=1e-12)
    else:
        assert abs(slip) < 1e-12
        assert abs(PT) < mu * PN
    assert traj.work["friction"] < 0.0


@pytest.mark.parametrize("solver", ["osqp", "enum", "daqp"])
def test_friction_routes_agree_with_lemke(solver):
    """The disk slipping then rolling and bouncing (e = 0.5), mu = 0.2: the Tresca fixed
    point over OSQP (and over daqp) and the enumeration of contact states give the
    trajectory of Lemke's method to 1e-8 (the fixed point's tolerance), with no fallback."""
    R = 0.1
    scene = disk(0.2, R, e=0.5)
    args = (scene, (0.0, 0.6), [0.0, R + 0.05, 0.0], [2.0, 0.0, 5.0], 1e-3)
    ref = oracle.simulate(*args, backend="python", solver="exact")
    other = oracle.simulate(*args, backend="python", solver=solver)
    assert ref.completed and other.completed
    assert other.stats.fallbacks == 0
    assert len(ref.impacts) >= 2
    np.testing.assert_allclose(other.v, ref.v, atol=1e-8)
    np.testing.assert_allclose(other.tangential_impulses, ref.tangential_impulses, atol=1e-8)
