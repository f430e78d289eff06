"""Friction on both paths: the compiled loop and the Python reference solve the same
problem by the same Lemke kernel and agree to round-off; a chain lying on a rough floor
solves every step; what a scene without friction computes does not change."""

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow

from .scenes import block, disk


def _both(scene, t_span, q0, v0, h, **kw):
    ref = oracle.simulate(scene, t_span, q0, v0, h, backend="python", solver="exact", **kw)
    com = mo.simulate(scene, t_span, q0, v0, h, backend="compiled", **kw)
    assert ref.completed and com.completed
    assert ref.stats.backend == "python" and com.stats.backend == "compiled"
    return ref, com


def test_paths_agree_on_a_bouncing_rolling_disk():
    """The disk bouncing (e = 0.5) with spin, slipping then rolling, mu = 0.2: the two paths
    agree to 1e-9 in q, v, the normal and tangential impulses and the friction work."""
    R = 0.1
    ref, com = _both(disk(0.2, R, e=0.5), (0.0, 1.0), [0.0, R + 0.05, 0.0], [2.0, 0.0, 5.0], 1e-3)
    assert len(ref.impacts) >= 2
    for a in ("q", "v", "impulses", "tangential_impulses", "slip_velocity"):
        np.testing.assert_allclose(getattr(com, a), getattr(ref, a), rtol=0, atol=1e-9, err_msg=a)
    assert (com.sticking == ref.sticking).all()
    assert com.work["friction"] == pytest.approx(ref.work["friction"], rel=1e-9)


def test_paths_agree_with_different_mu_per_row():
    """A chain of 3 links swinging onto a floor at three points (the middle link's tip, the
    last link's middle and tip) whose rows have mu = 0.1, 0.4 and 0.8 and e = 0.3 (each
    contact's own mu on its own normal impulse, in the compiled LCP too)."""
    chain = PendulumChain([Link.rod(m=0.2, l=0.1) for _ in range(3)])
    rows = [PointLineRow(link, (along, 0.0), line_point=(0.0, -0.18), normal=(0.0, 1.0))
            for link, along in ((1, 0.1), (2, 0.05), (2, 0.1))]
    law = mo.NewtonImpactFriction(0.3, [0.1, 0.4, 0.8])
    scene = mo.Scene(chain, [ChainGravity(chain)], [mo.Contact(PointLineBarrier(chain, rows), law, name="floor")])
    ref, com = _both(scene, (0.0, 2.0), np.full(3, 1.2), np.zeros(3), 1e-3)
    assert (ref.tangential_impulses != 0).any(axis=0).all()  # every row rubbed
    np.testing.assert_allclose(com.q, ref.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(com.tangential_impulses, ref.tangential_impulses, rtol=0, atol=1e-9)


def test_chain_lying_on_a_rough_floor_solves_every_step():
    """A 24-link chain dropped flat onto a rough floor (mu = 0.5, e = 0): every step's
    problem (up to 24 normal and 24 tangential rows) is solved and passes the law check on
    the compiled path, the chain comes to rest on the floor, and friction only removes
    energy."""
    n = 24
    chain = PendulumChain([Link.rod(m=0.05, l=0.025) for _ in range(n)])
    rows = [PointLineRow(i, (0.025, 0.0), line_point=(0.0, -0.01), normal=(0.0, 1.0)) for i in range(n)]
    scene = mo.Scene(chain, [ChainGravity(chain)],
                     [mo.Contact(PointLineBarrier(chain, rows), mo.NewtonImpactFriction(0.0, 0.5), name="floor")])
    q0 = np.full(n, np.pi / 2)  # horizontal at the pivot, 1 cm above the floor
    traj = mo.simulate(scene, (0.0, 1.0), q0, np.zeros(n), 1e-3, backend="compiled", energy=True)
    assert traj.completed and traj.stats.fallbacks == 0
    assert traj.stats.worst_residual < 1e-6
    assert traj.active[-1].sum() >= n // 2  # lying on the floor
    assert traj.work["friction"] < 0.0
    assert np.abs(traj.v[-1]).max() < 0.05
    assert traj.max_penetration.max() < 0.05 * 0.025


def test_frictionless_scenes_build_no_tangent_rows():
    """mu = 0 is the frictionless law: no tangent rows are evaluated or solved, and the
    trajectory equals the NewtonImpact one bit for bit on both paths."""
    from moreau.compiled.lowering import lower

    plain = mo.Scene(mo.FunctionSystem(2.0 * np.eye(2)), [mo.ConstantForce([0.0, -19.62])],
                     [mo.Contact(mo.LinearBarrier([[0.0, 1.0]], 0.0), mo.NewtonImpact(0.5), name="floor")])
    zero_mu = block(0.0, e=0.5)
    assert not zero_mu.has_friction and zero_mu.tangent_jacobian is None
    assert lower(zero_mu).ints[9] == 0
    for backend in ("python", "compiled"):
        a = oracle.simulate(plain, (0.0, 0.5), [0.0, 0.2], [1.0, 0.0], 1e-3, backend=backend, solver="exact")
        b = oracle.simulate(zero_mu, (0.0, 0.5), [0.0, 0.2], [1.0, 0.0], 1e-3, backend=backend, solver="exact")
        assert np.array_equal(a.q, b.q) and np.array_equal(a.impulses, b.impulses)
        assert b.tangential_impulses is None and "friction" not in b.work


def test_friction_is_kept_by_save_load_and_to_xarray(tmp_path):
    """Tangential impulses, slip velocities, sticking and the friction work survive
    save/load and appear in to_xarray()."""
    pytest.importorskip("xarray")
    traj = mo.simulate(disk(0.2, 0.1), (0.0, 0.3), [0.0, 0.1, 0.0], [3.0, 0.0, 0.0], 1e-3)
    back = mo.load(traj.save(tmp_path / "disk"))
    for a in ("tangential_impulses", "slip_velocity", "sticking"):
        assert np.array_equal(getattr(back, a), getattr(traj, a)), a
    assert back.work == traj.work and back.work["friction"] < 0
    ds = traj.to_xarray()
    assert np.array_equal(ds["tangential_impulses"].values, traj.tangential_impulses)
    assert np.array_equal(ds["sticking"].values, traj.sticking)
    assert '"friction"' in ds.attrs["work_json"]


def test_the_impact_log_with_friction_is_the_same_on_every_solver():
    """Issue 41: the piston with skirt friction (mu = 0.01; a slider-crank with clearance) and
    the engine's drift control, half a cycle at h = 1e-4: every solver (the loop's own, and
    OSQP and daqp called back from it) logs the same impacts at the same steps, and the runs
    agree to round-off. The drift projections are the solves that differ (friction steps
    take the loop's friction solve whatever the solver); none falls back."""
    from moreau.problems.piston import PistonParameters, piston_model

    model = piston_model(PistonParameters(e=0.0, mu=0.01))
    runs = {s: model.simulate(0.5, 1e-4, solver=s, drift_control=model.drift_control(), energy=False,
                              record_every=100) for s in ("exact", "enum", "osqp", "daqp")}
    ref = runs["exact"]
    assert ref.completed and len(ref.impacts) >= 3 and ref.stats.projections > 1000
    for s, traj in runs.items():
        assert traj.completed and traj.stats.solver == s and traj.stats.fallbacks == 0, s
        np.testing.assert_array_equal(traj.impacts.step, ref.impacts.step)
        np.testing.assert_array_equal(traj.impacts.row, ref.impacts.row)
        assert np.abs(traj.q - ref.q).max() <= 1e-12 * np.abs(ref.q).max(), s
