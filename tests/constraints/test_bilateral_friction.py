"""Friction and bilateral rows in one problem: the tangent rows are reduced into the null
space of the bilateral rows with their slip offsets, and Coulomb's law holds in the
original coordinates."""

import numpy as np
import oracle
import pytest
from numba import njit

import moreau as mo

R, M_DISK, M_P, G0 = 0.1, 1.0, 1.0, 9.81
ECC = 0.06  # the point mass's distance from the disk's centre (m)


@njit(cache=True)
def _rim_gap(q):
    x, y, th, xp, yp = q[0], q[1], q[2], q[3], q[4]
    return np.array([xp - x - ECC * np.sin(th), yp - y + ECC * np.cos(th)])


@njit(cache=True)
def _rim_jac(q):
    th = q[2]
    G = np.zeros((2, 5))
    G[0, 0], G[0, 2], G[0, 3] = -1.0, -ECC * np.cos(th), 1.0
    G[1, 1], G[1, 2], G[1, 4] = -1.0, -ECC * np.sin(th), 1.0
    return G


def disk_with_mass(mu: float, eccentric: bool, e: float = 0.0) -> mo.Scene:
    """A disk (x, y, θ) on a rough floor carrying a point mass (xp, yp) held by two
    bilateral rows: at its centre (linear rows) or at ``ECC`` from it (rows nonlinear in θ)."""
    J = 0.5 * M_DISK * R**2
    system = mo.FunctionSystem(np.diag([M_DISK, M_DISK, J, M_P, M_P]), name="disk + mass")
    floor = mo.LinearBarrier([[0.0, 1.0, 0.0, 0.0, 0.0]], -R, tangent=[[1.0, 0.0, R, 0.0, 0.0]])
    gravity = mo.ConstantForce([0.0, -M_DISK * G0, 0.0, 0.0, -M_P * G0])
    if eccentric:
        geometry: mo.Barrier = mo.FunctionBarrier(_rim_gap, _rim_jac, nrows=2, ndof=5)
    else:
        geometry = mo.LinearBarrier([[-1.0, 0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0, 1.0]], 0.0)
    return mo.Scene(system, [gravity], [mo.Contact(floor, mo.NewtonImpactFriction(e, mu), name="floor")],
                    constraints=[mo.Bilateral(geometry, name="mass")], name="disk + mass")


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_bilateral_friction_rolling_speed_known_answer(backend):
    """A disk carrying a point mass at its centre, launched sliding at v0 without spin:
    friction makes it roll at ``v = m_t v0 / (m_t + J/R²)`` = 0.8 v0 (m_t = m + m_p, J = m R²/2)."""
    scene = disk_with_mass(0.3, eccentric=False)
    v0 = 2.0
    q0 = np.array([0.0, R, 0.0, 0.0, R])
    traj = oracle.simulate(scene, (0.0, 1.0), q0, [v0, 0.0, 0.0, v0, 0.0], 1e-3, backend=backend, solver="exact",
                       progress=False)
    assert traj.completed
    mt = M_DISK + M_P
    assert traj.v[-1, 0] == pytest.approx(mt * v0 / (mt + 0.5 * M_DISK), rel=1e-12)
    assert traj.v[-1, 0] == pytest.approx(-R * traj.v[-1, 2], rel=1e-12)  # rolling
    assert traj.work["friction"] < 0.0 and abs(traj.work["constraints"]) <= 1e-12


@pytest.fixture(scope="module")
def eccentric_runs():
    """The disk with the mass off its centre, dropped spinning onto the rough floor
    (e = 0.5): it bounces, slips, then rolls with the mass going round."""
    scene = disk_with_mass(0.4, eccentric=True, e=0.5)
    q0 = np.array([0.0, R + 0.02, 0.0, 0.0, R + 0.02 - ECC])
    v0 = scene.constrained_velocity(q0, np.array([1.0, 0.0, 20.0, 1.0, 0.0]))
    return {b: oracle.simulate(scene, (0.0, 1.0), q0, v0, 1e-4, backend=b, solver="exact", energy=True,
                           progress=False) for b in ("python", "compiled")}


def test_bilateral_friction_paths_agree(eccentric_runs):
    """Both paths, friction and bilateral rows nonlinear in q: q, v, all impulses to 1e-9."""
    py, co = eccentric_runs["python"], eccentric_runs["compiled"]
    assert py.completed and co.completed and len(py.impacts) >= 2
    for name in ("q", "v", "impulses", "tangential_impulses", "constraint_impulses"):
        np.testing.assert_allclose(getattr(co, name), getattr(py, name), rtol=0, atol=1e-9, err_msg=name)


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_bilateral_friction_ledger_and_rolling(eccentric_runs, backend):
    """The kinetic-energy ledger closes exactly (constant M): ΔT = work of gravity, normal
    and friction impulses and joints (the last 0), and the velocity projection's
    dissipation; once the disk rolls, the contact
    point's slip (in the original coordinates) is 0 and friction does no more work."""
    traj = eccentric_runs[backend]
    w = traj.work
    dT = traj.kinetic_energy[-1] - traj.kinetic_energy[0]
    assert dT == pytest.approx(w["forces"] + w["contacts"] + w["friction"] + w["constraints"]
                               + w["constraint_projection"], abs=1e-9)
    assert abs(w["constraints"]) <= 1e-12 and w["friction"] < 0.0
    late = traj.t > 0.8
    assert traj.sticking[late].all()
    assert np.abs(traj.slip_velocity[late]).max() <= 1e-9
    assert np.ptp(traj.q[late, 2]) > 1.0  # still rolling: the mass goes round
    assert np.abs(traj.constraint_residuals).max() <= 1e-10
