"""Painlevé's rod (Glocker's thesis; Leine, Brogliato & Nijmeijer 2002): a uniform rod of
half-length 1 sliding on its lower end on a rough floor, g = 10, mu = 5/3, released at 31°
with the end sliding at 30 m/s towards the side it leans from. As the rod rises to 45°
the normal row's effective inverse mass under sliding friction, 1 + 3 cos²φ − 3 mu sinφ
cosφ, goes to zero (Painlevé's point): the contact force diverges and the classical
answer is a tangential impact (an impact without collision) that stops the slip and
throws the rod off the floor, near t ≈ 0.83 s in Glocker's computation."""

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.contact.painleve import painleve_rows

L, MU, GRAV = 1.0, 5.0 / 3.0, 10.0


def rod():
    J = (2 * L) ** 2 / 12

    def gap(q):
        return np.array([q[1] - L * np.sin(q[2])])

    def jac(q):
        return np.array([[0.0, 1.0, -L * np.cos(q[2])]])

    def tangent(q):
        return np.array([[1.0, 0.0, L * np.sin(q[2])]])

    end = mo.FunctionBarrier(gap, jac, nrows=1, ndof=3, tangent_jacobian=tangent)
    return mo.Scene(mo.FunctionSystem(np.diag([1.0, 1.0, J])), [mo.ConstantForce([0.0, -GRAV, 0.0])],
                    [mo.Contact(end, mo.NewtonImpactFriction(0.0, MU), name="end")], name="painleve rod")


def release(phi_deg=31.0, speed=30.0):
    phi = np.radians(phi_deg)
    return [L * np.cos(phi), L * np.sin(phi), phi], [-speed, 0.0, 0.0]


@pytest.mark.parametrize("h", [1e-3, pytest.param(3e-5, marks=pytest.mark.slow)])  # 3e-5: 17 s, slow suite
def test_painleve_rod_tangential_impact(h):
    """The rod slides with |P_T| = mu P_N until 45°; there one step carries a finite
    impulse (3.5–3.8 N s, against 1e-2 per step before) strictly inside the cone: the
    slip stops (sticking) and the rod leaves the floor — the tangential impact, at
    t = 0.815 s, on both step sizes (h = 1e-4 instead lifts off 0.9 ms earlier still
    slipping, at 44.9°, where 1/W_eff = 200: see docs/guide/friction.md). Every solve
    passes the law check (no fallback, residual below the tolerance)."""
    q0, v0 = release()
    traj = oracle.simulate(rod(), (0.0, 0.9), q0, v0, h, backend="python", solver="exact")
    assert traj.completed and traj.stats.fallbacks == 0
    pn = traj.impulses[:, 0]
    i = int(np.argmax(pn))
    assert 0.80 < traj.t[i] < 0.85
    assert 3.0 < pn[i] < 4.5
    assert traj.sticking[i, 0]
    before = (traj.t > 0.1) & (traj.t < traj.t[i] - 0.01) & traj.active[:, 0] & (pn > 0)
    np.testing.assert_allclose(traj.tangential_impulses[before, 0], MU * pn[before], rtol=1e-9)  # sliding
    assert np.degrees(traj.q[i, 2]) == pytest.approx(45.0, abs=0.7)
    after = traj.t > traj.t[i] + 0.01
    assert not traj.active[after, 0].any()  # thrown off the floor
    assert abs(traj.slip_velocity[i + 1, 0]) < 0.1 < abs(traj.slip_velocity[i - 1, 0])


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_rod_that_leaves_the_floor_still_slipping_near_painleves_point_says_so(backend):
    """At h = 1e-4 the rod lifts off at 44.9°, still slipping, where the effective normal
    inverse mass is 0.005 (0.2 % of its frictionless 2.5): no tangential impact, unlike
    h = 1e-3 and 3e-4. Its sliding came within 1 % of Painlevé's point (at 44.5°,
    t = 0.8126 s), where the answer depends on the step size, and the run says so: one
    RuntimeWarning naming the contact, the time and the cause, kept in traj.warnings."""
    q0, v0 = release()
    with pytest.warns(RuntimeWarning, match="Painlevé's paradox") as caught:
        traj = oracle.simulate(rod(), (0.0, 0.83), q0, v0, 1e-4, backend=backend, solver="exact")
    assert traj.completed and traj.stats.backend == backend
    said = [str(x.message) for x in caught if "Painlevé" in str(x.message)]
    assert len(said) == 1 and said[0] in traj.warnings
    t_said = float(said[0].split("at t = ")[1].split(" ")[0])
    assert 0.80 < t_said < 0.815 and "'end'" in said[0] and "vanishing" in said[0]
    assert traj.impulses.max() < 1.0  # no tangential impact: it left the floor still slipping
    assert abs(traj.slip_velocity[-1, 0]) > 5.0 and not traj.active[-1, 0]


def test_painleve_region_is_flagged():
    """painleve_rows flags a sliding contact whose effective normal inverse mass
    1 + 3 cos²φ − 3 mu sinφ cosφ (the rod above, sliding to the left) is not positive:
    at 50° (−0.31), not at 31° (+1.00) nor when sliding the other way."""
    scene = rod()
    bar = scene.contacts[0].barrier
    M = np.diag([1.0, 1.0, 1.0 / 3.0])
    Lc = np.linalg.cholesky(M)
    for phi_deg, slip, expected in [(50.0, -1.0, [0]), (31.0, -1.0, []), (50.0, 1.0, [])]:
        q = np.array([0.0, 0.0, np.radians(phi_deg)])
        PN = np.array([0.1])
        PT = -np.sign(slip) * MU * PN
        got = painleve_rows(Lc, bar.jacobian(q), bar.tangent_jacobian(q), np.array([MU]), PN, PT, np.array([slip]))
        assert got.tolist() == expected, (phi_deg, slip)


def frozen_rod():
    """``(scene, q0, v0)``: the rod frozen at 50° (its rows linearized there, so that the
    scene compiles), its end on the floor sliding left at 10 m/s and approaching at 1 mm/s,
    under a lift of twice its weight."""
    phi = np.radians(50.0)
    c, s = np.cos(phi), np.sin(phi)
    end = mo.LinearBarrier([[0.0, 1.0, -L * c]], [-L * s + L * c * phi], tangent=[[1.0, 0.0, L * s]])
    scene = mo.Scene(mo.FunctionSystem(np.diag([1.0, 1.0, (2 * L) ** 2 / 12])), [mo.ConstantForce([0.0, GRAV, 0.0])],
                     [mo.Contact(end, mo.NewtonImpactFriction(0.0, MU), name="end")])
    return scene, [L * c, L * s, phi], [-10.0, -1e-3, 0.0]


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_run_in_painleves_region_says_so(backend):
    """The rod frozen at 50° (its rows linearized there, so that the scene compiles: the
    effective inverse mass under sliding to the left is 1 + 3 cos²φ − 3 mu sinφ cosφ =
    −0.31), its end sliding left at 10 m/s and approaching the floor at 1 mm/s while a
    lift of twice its weight makes the free step leave the floor. The step's problem has
    the lift-off solution and a sliding one with a large impulse; whichever Lemke returns
    passes the law check, and the run says where it met Painlevé's region: one
    RuntimeWarning naming the contact, kept in traj.warnings, on both paths."""
    scene, q0, v0 = frozen_rod()
    with pytest.warns(RuntimeWarning, match="Painlevé's paradox: at t = 0 ") as caught:
        traj = oracle.simulate(scene, (0.0, 0.005), q0, v0, 1e-3, backend=backend, solver="exact")
    assert traj.completed and traj.stats.backend == backend
    said = [str(x.message) for x in caught if "Painlevé" in str(x.message)]
    assert len(said) == 1 and said[0] in traj.warnings and "'end'" in said[0]


def test_painleves_warning_quotes_the_loops_time_and_a_step_only_on_fixed_steps():
    """The warning's time comes from the loop, not from t0 + k h (with step-size control
    the loop's attempts and half steps count no clock): a tally that met the region at
    t = 0.3125 after 40 loop steps of h = 1e-3 says 0.3125, and the step number only when
    no step was accepted by step control (fixed steps)."""
    from types import SimpleNamespace

    from moreau.compiled import layout as lay
    from moreau.compiled.run_errors import run_warnings

    cnt, acc = np.zeros(lay.N_COUNTERS, dtype=np.int64), np.zeros(lay.N_ACCUMULATORS)
    cnt[lay.C_PAINLEVE_STEP], cnt[lay.C_ACCEPTED], acc[lay.A_T_PAINLEVE] = 41, 9, 0.3125
    fake = SimpleNamespace(row_names=["end"], friction=np.array([MU]))
    out = SimpleNamespace(warnings=[])
    with pytest.warns(RuntimeWarning, match=r"Painlevé's paradox: at t = 0.3125 the sliding contact\(s\) \['end'\]"):
        run_warnings(fake, out, cnt, acc, 1e-3, None)
    cnt[lay.C_ACCEPTED] = 0
    with pytest.warns(RuntimeWarning, match=r"at t = 0.3125 \(step 40\)"):
        run_warnings(fake, out, cnt, acc, 1e-3, None)
    assert len(out.warnings) == 2


@pytest.mark.slow
def test_a_run_with_step_control_says_when_it_met_painleves_region():
    """The frozen rod from t = 0.3 with step-size control: one warning, at t = 0.3, with
    no step number, kept in traj.warnings."""
    scene, q0, v0 = frozen_rod()
    with pytest.warns(RuntimeWarning, match="Painlevé's paradox: at t = 0.3 the sliding") as caught:
        traj = mo.simulate(scene, (0.3, 0.305), q0, v0, 1e-3, solver="exact", step_control=mo.StepControl(1e-6))
    said = [str(x.message) for x in caught if "Painlevé" in str(x.message)]
    assert len(said) == 1 and said[0] in traj.warnings
