"""Bilateral constraints (issue 28): joints and closed loops in the same solve as the
contacts, on both paths, against known answers."""

import numpy as np
import oracle
import pytest
from numba import njit
from scipy.integrate import solve_ivp

import moreau as mo
from moreau.model.chain import Link, PendulumChain, point_on_line
from moreau.problems.four_bar import four_bar
from moreau.run.trust import constraint_rank

G0, L1, L2, M1, M2 = 9.81, 1.0, 0.7, 1.0, 0.5


@njit(cache=True)
def _rods_gap(q):
    x1, y1, x2, y2 = q[0], q[1], q[2], q[3]
    return np.array([(x1 * x1 + y1 * y1 - L1 * L1) / (2 * L1),
                     ((x2 - x1) ** 2 + (y2 - y1) ** 2 - L2 * L2) / (2 * L2)])


@njit(cache=True)
def _rods_jac(q):
    x1, y1, x2, y2 = q[0], q[1], q[2], q[3]
    G = np.zeros((2, 4))
    G[0, 0], G[0, 1] = x1 / L1, y1 / L1
    G[1, 0], G[1, 1] = -(x2 - x1) / L2, -(y2 - y1) / L2
    G[1, 2], G[1, 3] = (x2 - x1) / L2, (y2 - y1) / L2
    return G


def cartesian_double_pendulum():
    """Two point masses in the plane, q = (x1, y1, x2, y2), held by two rods of fixed length."""
    system = mo.FunctionSystem(np.diag([M1, M1, M2, M2]))
    gravity = mo.ConstantForce(np.array([0.0, -M1 * G0, 0.0, -M2 * G0]))
    rods = mo.Bilateral(mo.FunctionBarrier(_rods_gap, _rods_jac, nrows=2, ndof=4), name="rods")
    return mo.Scene(system, [gravity], constraints=[rods], name="cartesian double pendulum")


def minimal_reference(th1, th2, t_end):
    """The angles at t_end from the minimal-coordinate equations (DOP853, 1e-12)."""
    def rhs(t, z):
        a, b, wa, wb = z
        d = a - b
        M = np.array([[(M1 + M2) * L1 * L1, M2 * L1 * L2 * np.cos(d)], [M2 * L1 * L2 * np.cos(d), M2 * L2 * L2]])
        f = np.array([-M2 * L1 * L2 * np.sin(d) * wb * wb - (M1 + M2) * G0 * L1 * np.sin(a),
                      M2 * L1 * L2 * np.sin(d) * wa * wa - M2 * G0 * L2 * np.sin(b)])
        return [wa, wb, *np.linalg.solve(M, f)]
    sol = solve_ivp(rhs, (0.0, t_end), [th1, th2, 0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12)
    return sol.y[0, -1], sol.y[1, -1]


def _angles(q):
    return np.arctan2(q[0], -q[1]), np.arctan2(q[2] - q[0], -(q[3] - q[1]))


@njit(cache=True)
def _rod_gap(q):
    return np.array([(q[0] * q[0] + q[1] * q[1] - L1 * L1) / (2 * L1)])


@njit(cache=True)
def _rod_jac(q):
    G = np.zeros((1, 2))
    G[0, 0], G[0, 1] = q[0] / L1, q[1] / L1
    return G


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_bilateral_cartesian_pendulum_matches_minimal_coordinates(backend):
    """A point mass on a rod in Cartesian coordinates against θ'' = −(g/l) sin θ (DOP853 at
    1e-12): within 1e-5 rad after 2 s at h = 1e-4 (second order: the midpoint rule on a
    constant mass matrix), the rod's length held to 1e-10."""
    scene = mo.Scene(mo.FunctionSystem(np.eye(2) * M1), [mo.ConstantForce([0.0, -M1 * G0])],
                     constraints=[mo.Bilateral(mo.FunctionBarrier(_rod_gap, _rod_jac, ndof=2), name="rod")])
    th0 = 1.0
    traj = oracle.simulate(scene, (0.0, 2.0), [L1 * np.sin(th0), -L1 * np.cos(th0)], [0.0, 0.0], 1e-4, backend=backend,
                       solver="exact", progress=False)
    ref = solve_ivp(lambda t, z: [z[1], -G0 / L1 * np.sin(z[0])], (0.0, 2.0), [th0, 0.0], method="DOP853",
                    rtol=1e-12, atol=1e-12)
    x, y = traj.q[-1]
    assert traj.completed and abs(np.arctan2(x, -y) - ref.y[0, -1]) <= 1e-5
    assert np.abs(traj.constraint_residuals).max() <= 1e-10


@pytest.fixture(scope="module")
def double_pendulum_runs():
    scene = cartesian_double_pendulum()
    th1, th2 = 1.2, -0.5
    q0 = np.array([L1 * np.sin(th1), -L1 * np.cos(th1),
                   L1 * np.sin(th1) + L2 * np.sin(th2), -L1 * np.cos(th1) - L2 * np.cos(th2)])
    runs = {b: oracle.simulate(scene, (0.0, 2.0), q0, np.zeros(4), 1e-4, backend=b, solver="exact", progress=False)
            for b in ("python", "compiled")}
    return runs, minimal_reference(th1, th2, 2.0)


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_bilateral_cartesian_double_pendulum_matches_minimal_coordinates(double_pendulum_runs, backend):
    """Point masses held by distance constraints follow the minimal-coordinate double
    pendulum (DOP853 at 1e-12) within 2e-3 rad after 2 s at h = 1e-4; the rods stay
    within 1e-10 of their length; the constraint impulses do no work."""
    runs, (a_ref, b_ref) = double_pendulum_runs
    traj = runs[backend]
    assert traj.completed and traj.stats.backend == backend
    a, b = _angles(traj.q[-1])
    assert abs(a - a_ref) <= 2e-3 and abs(b - b_ref) <= 2e-3
    assert np.abs(traj.constraint_residuals).max() <= 1e-10
    assert traj.constraint_names == ["rods[0]", "rods[1]"]
    assert abs(traj.work["constraints"]) <= 1e-10
    # the velocity projection at q⁺ removes O(h⁴) per step: at most 1e-9 of the energy scale
    assert -1e-9 * M1 * G0 * L1 <= traj.work["constraint_projection"] <= 0.0
    assert np.abs(traj.constraint_impulses).max() > 1e-4  # the rods pull


def test_bilateral_paths_agree(double_pendulum_runs):
    """The compiled loop and the Python reference agree to 1e-9 in q, v and the
    constraint impulses."""
    runs, _ = double_pendulum_runs
    py, co = runs["python"], runs["compiled"]
    for name in ("q", "v", "constraint_impulses", "constraint_residuals"):
        np.testing.assert_allclose(getattr(co, name), getattr(py, name), rtol=0, atol=1e-9, err_msg=name)


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_four_bar_energy_conserved_and_loop_closed(backend):
    """A four-bar under gravity, no damping, 10 s: with the predictor–corrector (order 2
    with the chain's velocity-dependent terms) the energy is conserved to 1e-4 of its
    value, the loop stays closed to 1e-10 and the joints do no work."""
    fb = four_bar()
    q0, v0 = fb.initial_state(0.3, 5.0)
    traj = oracle.simulate(fb.scene, (0.0, 10.0), q0, v0, 1e-3, backend=backend, solver="exact", energy=True,
                       integrator=mo.MoreauJeanPredictorCorrector, progress=False)
    assert traj.completed
    E = traj.energy
    assert np.abs(E - E[0]).max() <= 1e-4 * abs(E[0])
    assert np.abs(traj.constraint_residuals).max() <= 1e-10
    assert abs(traj.work["constraints"]) <= 1e-9 * abs(E[0])
    assert np.ptp(traj.q[:, 0]) > 1.0  # a large motion of the whole loop


def test_four_bar_with_a_stop_loses_energy_only_at_impacts():
    """The rocker hits a stop (e = 0.5): an impact through the closed loop. At h = 1e-4 the
    energy lost equals the contact work (the impacts' losses, logged) to 1e-3 of it (the
    difference is first order in h: 1.05e-3 at h = 1e-3, 1.05e-4 at 1e-4, from the
    configuration-dependent M across an impact step), and no step between impacts
    changes the energy by more than 1e-6 of its value."""
    fb = four_bar(stop=0.75, e=0.5)
    q0, v0 = fb.initial_state(0.3, 5.0)
    traj = mo.simulate(fb.scene, (0.0, 3.0), q0, v0, 1e-4, backend="compiled", energy=True,
                       integrator=mo.MoreauJeanPredictorCorrector, progress=False)
    assert traj.completed and len(traj.impacts) >= 2
    E = traj.energy
    lost = E[0] - E[-1]
    assert traj.work["contacts"] < -0.05 * E[0]
    assert abs(lost + traj.work["contacts"]) <= 1e-3 * abs(traj.work["contacts"])
    assert abs(traj.onsets.energy_lost.sum() - lost) <= 0.05 * lost
    hits = np.flatnonzero(traj.active[:, 0])
    free = np.setdiff1d(np.arange(1, len(E)), np.concatenate([hits, hits + 1]))
    assert np.abs(np.diff(E)[free - 1]).max() <= 1e-6 * abs(E[0])
    assert np.abs(traj.constraint_residuals).max() <= 1e-10
    # the stop holds: the midpoint scheme's penetration, at most h times the rocker's speed
    assert traj.gaps.min() >= -1e-4 * np.abs(traj.v[:, 2]).max()


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_four_bar_with_a_stop_under_combined_projection_stays_closed_without_chatter(backend):
    """Drift control of the stop's row (CombinedProjection) moves q along the bilateral rows
    and the velocity is projected onto them at q⁺: the loop stays closed to 1e-10, the
    rocker does not chatter on the stop (before: 98 logged impacts instead of 7, the
    constraint velocity flipping sign every step), the contact work is the run's without
    drift control to 2e-3 (it was 0.9 % off before, 8 % without the velocity projection)
    and the velocity projection only removes energy."""
    fb = four_bar(stop=0.75, e=0.5)
    q0, v0 = fb.initial_state(0.3, 5.0)
    kw = dict(backend=backend, solver="exact", energy=True, progress=False)
    plain = oracle.simulate(fb.scene, (0.0, 3.0), q0, v0, 1e-3, **kw)
    traj = oracle.simulate(fb.scene, (0.0, 3.0), q0, v0, 1e-3, drift_control=mo.CombinedProjection(), **kw)
    assert traj.completed and len(plain.impacts) >= 3
    assert np.abs(traj.constraint_residuals).max() <= 1e-10
    assert len(traj.impacts) <= 2 * len(plain.impacts)
    E, w = traj.energy, traj.work
    assert abs(w["contacts"] - plain.work["contacts"]) <= 2e-3 * abs(plain.work["contacts"])
    assert -1e-3 * abs(E[0]) <= w["constraint_projection"] <= 0.0


def test_four_bar_impacts_through_the_loop_are_logged_alike_on_both_paths():
    """The velocity test of the impact log compares with the free velocity *with the joints
    held*: both paths log the same impacts at the stop (time, row, velocities, loss) to
    1e-9."""
    fb = four_bar(stop=0.75, e=0.5)
    q0, v0 = fb.initial_state(0.3, 5.0)
    runs = [oracle.simulate(fb.scene, (0.0, 1.0), q0, v0, 1e-3, backend=b, solver="exact", progress=False)
            for b in ("python", "compiled")]
    py, co = (r.impacts for r in runs)
    assert len(py.t) == len(co.t) >= 3
    for name in ("t", "U_before", "U_after", "impulse", "energy_lost"):
        np.testing.assert_allclose(getattr(co, name), getattr(py, name), rtol=0, atol=1e-9, err_msg=name)
    assert (py.row == co.row).all() and (py.fast == co.fast).all()


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_closed_loop_slider_crank_follows_the_ideal_kinematics(backend):
    """The slider-crank as a closed chain (crank and rod, the rod's end held on the
    cylinder axis by one row) keeps the piston pin where the ideal slider-crank puts it,
    x = r cos φ + √(l² − r² sin² φ) along the axis, to 1e-9 m."""
    r, l = 0.05, 0.15
    chain = PendulumChain([Link.rod(1.0, r), Link.rod(0.5, l)], orientation="inverted")
    axis = point_on_line(chain, 1, (l, 0.0), (0.0, 0.0), (1.0, 0.0), name="cylinder axis")
    scene = mo.Scene(chain, [], constraints=[axis], name="slider-crank")
    phi0 = 0.4
    q0 = np.array([phi0, -np.arcsin(r * np.sin(phi0) / l)])
    v0 = scene.constrained_velocity(q0, np.array([30.0, 0.0]))
    traj = oracle.simulate(scene, (0.0, 0.5), q0, v0, 1e-4, backend=backend, solver="exact", progress=False)
    assert traj.completed and np.ptp(traj.q[:, 0]) > 2 * np.pi
    phi = traj.q[:, 0]
    pin = np.array([chain.point_position(q, 1, (l, 0.0)) for q in traj.q])
    np.testing.assert_allclose(pin[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(pin[:, 1], r * np.cos(phi) + np.sqrt(l * l - (r * np.sin(phi)) ** 2), atol=1e-9)


def test_bilateral_redundant_rows_keep_the_motion_and_are_reported():
    """The four-bar with one row too many (the ground pivot's x row written twice) runs
    as the plain one to 1e-9; the extra row is named redundant and carries no impulse."""
    fb = four_bar()
    p = fb.params
    extra = point_on_line(fb.chain, 2, (p.rocker, 0.0), (p.ground, 0.0), (1.0, 0.0), name="extra")
    scene = mo.Scene(fb.chain, fb.scene.effects, constraints=[*fb.scene.constraints, extra])
    q0, v0 = fb.initial_state()
    rank, redundant = constraint_rank(scene, q0)
    assert rank == 2 and len(redundant) == 1
    for backend in ("python", "compiled"):
        ref = oracle.simulate(fb.scene, (0.0, 0.5), q0, v0, 1e-3, backend=backend, solver="exact", progress=False)
        red = oracle.simulate(scene, (0.0, 0.5), q0, v0, 1e-3, backend=backend, solver="exact", progress=False)
        np.testing.assert_allclose(red.q, ref.q, rtol=0, atol=1e-9)
        total = red.constraint_impulses[:, [0, 2]].sum(axis=1)  # the two x rows share the x reaction
        np.testing.assert_allclose(total, ref.constraint_impulses[:, 0], rtol=0, atol=1e-9)


def test_bilateral_inconsistent_constraints_are_refused_by_name():
    """A constraint off g = 0 at q0 is refused naming the row; so is a velocity that breaks
    the constraints; a geometry that is not a barrier, or friction with constraints."""
    fb = four_bar()
    p = fb.params
    q0, v0 = fb.initial_state()
    wrong = point_on_line(fb.chain, 2, (p.rocker, 0.0), (p.ground + 0.01, 0.0), (1.0, 0.0), name="wrong")
    scene = mo.Scene(fb.chain, fb.scene.effects, constraints=[*fb.scene.constraints, wrong])
    with pytest.raises(ValueError, match="wrong"):
        mo.simulate(scene, (0.0, 0.1), q0, v0, 1e-3, progress=False)
    with pytest.raises(ValueError, match="velocity breaks the constraints"):
        mo.simulate(fb.scene, (0.0, 0.1), q0, np.array([1.0, 0.0, 0.0]), 1e-3, progress=False)
    with pytest.raises(ValueError, match="geometry must be a Barrier"):
        mo.Bilateral("rod", name="rod")
    bad = mo.Bilateral(mo.FunctionBarrier(lambda q: np.zeros(2), lambda q: np.zeros((3, 3)), nrows=2), name="bad")
    with pytest.raises(ValueError, match="Jacobian of constraint 'bad'"):
        oracle.simulate(mo.Scene(fb.chain, constraints=[bad]), (0.0, 0.1), q0, v0, 1e-3, backend="python",
                    progress=False)
