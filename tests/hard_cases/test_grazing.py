"""Case 7 — grazing contacts, closed with zero normal velocity: a ball resting on the
floor, a point sliding along it, a projectile whose apex touches a ceiling exactly, a
pendulum that just reaches a wall. No spurious impulse beyond O(h), no NaN, no impact.
"""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.pendulum_wall import pendulum_wall

from .conftest import assert_finite, audit_impacts

G = 9.81


def point_scene(contact_row, offset, e=0.5, mass=1.0):
    """A point mass (x, y) under gravity with one straight barrier A q + b >= 0."""
    system = mo.FunctionSystem(mass * np.eye(2), name="point")
    gravity = mo.ConstantForce([0.0, -G * mass])
    wall = mo.Contact(mo.LinearBarrier([contact_row], [offset]), e, name="wall")
    return mo.Scene(system, [gravity], [wall])


@pytest.mark.parametrize("vx", [0.0, 1.0], ids=["resting", "sliding"])
def test_point_resting_or_sliding_on_the_floor(vx):
    h, T, m = 1e-3, 1.0, 2.0
    traj = mo.simulate(point_scene([0.0, 1.0], 0.0, mass=m), (0.0, T), [0.0, 0.0], [vx, 0.0], h, solver="enum")
    assert traj.completed
    assert_finite(traj)
    # it stays on the floor with zero normal velocity, exactly: the contact impulse of every
    # step is the gravity impulse m g h and nothing more (the enumeration is exact)
    assert np.all(traj.q[:, 1] == 0.0) and np.all(traj.v[:, 1] == 0.0)
    np.testing.assert_allclose(traj.impulses[1:, 0], m * G * h, rtol=1e-14)
    np.testing.assert_allclose(traj.q[:, 0], vx * traj.t, rtol=0, atol=1e-12)
    assert len(traj.impacts) == 0  # a resting contact is not an impact


@pytest.mark.parametrize("where", ["at a step", "at a midpoint"])
def test_projectile_apex_touches_the_ceiling(where):
    """Apex exactly at the ceiling y = H, reached at a step or half-way between steps.

    Störmer–Verlet is exact for a constant force at the steps, and the midpoint
    q_k + h/2 v_k lies g h²/8 above the parabola. Apex half-way between steps: the
    ceiling is closed at that midpoint with an approach speed g h/2 that gravity reverses
    within the step — no impulse is needed and none is applied. Apex at a step: the
    midpoint before it lies exactly on the ceiling (g = 0, closed) while the point still
    rises at g h, and Newton's law sends it back at e g h: a spurious impulse, but O(h),
    at most e m g h (the approach speed of a closed grazing contact is at most g h).
    """
    h, k, m, e = 1e-3, 400, 1.0, 0.5
    t_apex = (k if where == "at a step" else k + 0.5) * h
    vy = G * t_apex
    H = vy**2 / (2 * G)
    scene = point_scene([0.0, -1.0], H, e=e, mass=m)  # gap H − y
    free = mo.Scene(scene.system, scene.effects)
    span, q0, v0 = (0.0, 2 * t_apex), [0.0, 0.0], [1.0, vy]
    traj = mo.simulate(scene, span, q0, v0, h, solver="enum")
    ref = mo.simulate(free, span, q0, v0, h, solver="enum")
    assert traj.completed
    assert_finite(traj)
    assert traj.stats.contact_steps >= 1  # the ceiling was touched (closed at a midpoint)
    # at a step the onset is borderline for the impact log (approach speed g h = what
    # gravity changes in a step): logged or not by round-off; at a midpoint it is not
    assert len(traj.impacts) <= (1 if where == "at a step" else 0)
    audit_impacts(traj)
    P = traj.impulses.sum()
    roundoff = m * 2 * k * np.finfo(float).eps * vy  # k steps of subtracting g h from v_y
    assert P <= e * m * G * h + roundoff
    if where == "at a midpoint":
        assert P == 0.0
        np.testing.assert_array_equal(traj.q, ref.q)  # the ceiling changed nothing
    # the spurious impulse changes v_y by at most P/m: y deviates by at most that times
    # the time since the apex; x is not affected
    after = np.maximum(traj.t - t_apex + h, 0.0)
    assert np.all(np.abs(traj.q[:, 1] - ref.q[:, 1]) <= P / m * after + 1e-12)
    np.testing.assert_array_equal(traj.q[:, 0], ref.q[:, 0])
    # the recorded positions stay below the ceiling (within round-off of H)
    assert traj.gaps.min() >= -1e-12 * H


@pytest.mark.parametrize("h", [1e-2, 5e-3, 1.25e-3, 5e-4])
def test_pendulum_just_reaching_the_wall(h):
    """The wall stands exactly at the discrete amplitude of the free pendulum.

    In a grazing step the approach speed is at most what the smooth force removes in one
    step, U_k ∈ [−h a_n, 0] (a_n = g sin θ cos θ pushes the bob off the wall), so Newton's
    law asks for at most P = m_eff (−(1+e) U_k − h a_n) <= e m_eff h a_n = e m g h tan θ.
    """
    e, theta0, T, m = 0.8, 0.6, 6.0, 1.0
    free = mo.simulate(pendulum_wall(wall_x=None), (0.0, T), [-theta0], [0.0], h, solver="enum")
    amp = free.q[:, 0].max()
    traj = mo.simulate(pendulum_wall(e=e, wall_x=np.sin(amp)), (0.0, T), [-theta0], [0.0], h, solver="enum")
    assert traj.completed and traj.stats.fallbacks == 0
    assert_finite(traj)
    audit_impacts(traj)
    assert len(traj.impacts) == 0  # grazing is not an impact
    # split the impulses into grazing events (runs of records with an impulse)
    on = traj.impulses[:, 0] > 0
    starts = np.flatnonzero(on & ~np.r_[False, on[:-1]])
    ends = np.flatnonzero(on & ~np.r_[on[1:], False])
    per_event = [traj.impulses[a:b + 1, 0].sum() for a, b in zip(starts, ends)]
    bound = e * m * G * h * np.tan(amp)
    # 10 %: a_n varies across the step (and so does U_k's bound), O(h) relative
    assert all(p <= 1.1 * bound for p in per_event), (per_event, bound)
    # at most one event per visit to the wall (period ≈ 1.6 s: four visits in 6 s)
    assert len(per_event) <= 4
    # the gap never opens negative beyond the midpoint overshoot h/2 |v| <= h²/2 |θ''| l
    assert traj.gaps.min() >= -0.5 * h**2 * G * np.sin(amp)
