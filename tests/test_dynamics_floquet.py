"""Sections, period detection and Floquet multipliers (moreau.dynamics).

References: the exact solution of a forced linear oscillator (its monodromy is exp(A T));
the closed-form period-1 orbit of a ball on a sinusoidally vibrating table (Holmes 1982,
J. Sound Vib. 84:173; Luck & Mehta 1993, Phys. Rev. E 48:3988), derived in
moreau/dynamics/benchmarks.py.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

import moreau as mo
from moreau.dynamics import (
    TimeMap,
    detect_period,
    find_fixed_point,
    floquet_multipliers,
    poincare,
    poincare_on_the_fly,
    stroboscopic,
)
from moreau.dynamics.benchmarks import table_period1, vibrating_table

E, A = 0.5, 1.49  # stable period-1 orbit with two real multipliers, -0.836 and -0.299


def linear_oscillator(m=1.0, c=0.2, k=4.0, F=1.0, w=1.3):
    return mo.Scene(mo.FunctionSystem([[m]]), [mo.LinearSpring([[k]]), mo.LinearDamping([[c]]),
                                             mo.HarmonicForce([F], w)])


def test_floquet_multipliers_of_a_forced_linear_oscillator():
    """Monodromy over the forcing period = exp(A T): multipliers exp((-c/2 ± i ω_d) T)."""
    m, c, k, w = 1.0, 0.2, 4.0, 1.3
    T = 2 * np.pi / w
    F = TimeMap(linear_oscillator(m, c, k, 1.0, w), T, T / 4000)
    x = find_fixed_point(F, [0.0, 0.0], eps=1e-3, tol=1e-10)
    res = floquet_multipliers(F, x, eps=1e-3)
    lam = -c / (2 * m) + 1j * np.sqrt(k / m - (c / (2 * m)) ** 2)
    exact = np.exp(np.array([lam, np.conj(lam)]) * T)
    got = res.multipliers[np.argsort(res.multipliers.imag)]
    exact = exact[np.argsort(exact.imag)]
    assert np.all(np.abs(got - exact) / np.abs(exact) < 1e-3)
    assert res.stable
    # the fixed point is the steady forced response X sin(w t - δ) sampled at t = 0
    X = 1.0 / np.hypot(k - m * w ** 2, c * w)
    delta = np.arctan2(c * w, k - m * w ** 2)
    assert np.allclose(x, [X * np.sin(-delta), X * w * np.cos(-delta)], rtol=0, atol=1e-4)


@pytest.mark.slow  # 17 s on an idle core
@pytest.mark.parametrize("n_steps", [64000])
def test_bouncing_ball_period1_multipliers_within_1_percent(n_steps):
    """Ball on a vibrating table (e = 0.5, A = 1.49, g = ω = 1): multipliers of the period-1
    orbit from the monodromy of the stroboscopic map by central differences (eps = 0.1)
    against the closed form (-0.83573, -0.29914), within 1 %. Measured: -0.83554 and -0.29923
    (0.02 %, 0.03 %) at 64000 steps per period; 0.4 %/0.9 % at 32000 and 1.2 %/2.8 % at 8000
    (the O(h|v|/eps) impact-quantization error, see moreau.dynamics.floquet)."""
    orb = table_period1(E, A)
    F = TimeMap(vibrating_table(E, A), orb.T, orb.T / n_steps, t0=orb.t_mid)
    # the scheme's orbit is within O(h) of the exact one
    assert np.allclose(F(orb.x_mid), orb.x_mid, atol=2e-3)
    res = floquet_multipliers(F, orb.x_mid, eps=0.1)
    assert np.all(np.abs(res.multipliers.imag) < 1e-12)
    got = np.sort(res.multipliers.real)
    exact = np.sort(orb.multipliers.real)
    print("multipliers", got, "exact", exact, "rel err", got / exact - 1)
    assert np.all(np.abs(got / exact - 1) < 0.01)
    assert res.stable and np.all(res.exponents < 0)
    # det = e²: the area contraction of one Newton impact
    assert abs(np.linalg.det(res.monodromy) / E ** 2 - 1) < 0.02


@pytest.mark.slow
def test_bouncing_ball_multipliers_step_and_perturbation_ladder():
    """Error of the multipliers over a ladder of h (fixed eps) and of eps (fixed h): it
    shrinks with h at every eps, and stays within 1 % for eps in [0.05, 0.2] at 64000
    steps per period. Measured largest relative error, eps = 0.05 / 0.1 / 0.2: 9.7 / 3.4 /
    2.6 % at 4000 steps per period, 2.9 / 0.9 / 1.4 % at 16000, 0.77 / 0.03 / 0.84 % at
    64000."""
    orb = table_period1(E, A)
    exact = np.sort(orb.multipliers.real)
    err = {}
    for n in (4000, 16000, 64000):
        F = TimeMap(vibrating_table(E, A), orb.T, orb.T / n, t0=orb.t_mid)
        for eps in (0.05, 0.1, 0.2):
            got = np.sort(floquet_multipliers(F, orb.x_mid, eps=eps).multipliers.real)
            err[n, eps] = np.max(np.abs(got / exact - 1))
    print({k: round(v, 4) for k, v in err.items()})
    for eps in (0.05, 0.1, 0.2):
        assert err[64000, eps] < 0.01
        assert err[64000, eps] < err[4000, eps]


def test_stroboscopic_section_detects_the_period1_orbit():
    """A run from near the orbit settles on it: one stroboscopic point repeats (period 1),
    at the closed-form state within O(h). The scheme's points jitter by a few h|v|
    (h|v| = 0.0066 at the impact speed 4.19: impact instants are quantized to the grid),
    hence the tolerance 5 h|v|."""
    orb = table_period1(E, A)
    scene = vibrating_table(E, A)
    n = 4000
    traj = mo.simulate(scene, (orb.t_mid, orb.t_mid + 50 * orb.T), orb.x_mid[:1] + 0.05, orb.x_mid[1:],
                       orb.T / n, solver="enum", record_every=n // 4, progress=False)
    sec = stroboscopic(traj, orb.T, phase_time=orb.t_mid, t_start=orb.t_mid + 35 * orb.T)
    assert len(sec) == 16
    assert np.allclose(sec.t, orb.t_mid + orb.T * np.arange(35, 51))
    hv = orb.T / n * 4.19
    assert detect_period(sec.x, rtol=0.0, atol=5 * hv) == 1
    assert detect_period(sec.x, rtol=0.0, atol=0.1 * hv) is None  # the O(h) jitter is there
    assert np.allclose(sec.x[-1], orb.x_mid, atol=5 * hv)
    # one impact per period, at the phase φ*
    t_imp = traj.impacts.t[traj.impacts.t > orb.t_mid + 35 * orb.T]
    assert len(t_imp) == 15
    phase = np.mod(t_imp, orb.T)
    assert np.allclose(phase, orb.phi, atol=5 * orb.T / n)


def test_detect_period():
    rng = np.random.default_rng(1)
    p3 = np.tile([[0.1, 1.0], [0.5, -1.0], [0.9, 0.2]], (10, 1))
    assert detect_period(p3) == 3
    assert detect_period(p3[:, 0]) == 3
    assert detect_period(np.ones((5, 2))) == 1
    assert detect_period(rng.random((60, 2)), max_period=8) is None


def test_poincare_sections_from_a_trajectory_and_on_the_fly(caplog):
    """Undamped oscillator x = sin(ω0 t): upward crossings of x = 0 at t = 2πk/ω0, from a
    recorded run and on the fly, to O(h²)."""
    k = 4.0
    scene = mo.Scene(mo.FunctionSystem([[1.0]]), [mo.LinearSpring([[k]])])
    h = 1e-3
    traj = mo.simulate(scene, (0.0, 10.0), [0.0], [2.0], h, progress=False)
    surf = lambda q, v: q[0]  # noqa: E731
    up = poincare(traj, surf, direction=1, t_start=0.1)
    down = poincare(traj, surf, direction=-1)
    both = poincare(traj, surf, direction=0, t_start=0.1)
    w0 = np.sqrt(k)
    assert np.allclose(up.t, 2 * np.pi / w0 * np.arange(1, len(up) + 1), atol=1e-5)
    assert np.allclose(down.t, np.pi / w0 + 2 * np.pi / w0 * np.arange(len(down)), atol=1e-5)
    assert len(both) == len(up) + len(down)
    assert np.allclose(up.v[:, 0], 2.0, atol=1e-4)
    fly = poincare_on_the_fly(scene, [0.0], [2.0], h, surf, n_crossings=3, t_start=0.1)
    assert np.allclose(fly.t, up.t[:3], atol=1e-12) and np.allclose(fly.v, up.v[:3], atol=1e-12)
    # chunks of 1 s up to t_max = 7.0005: the last is half a step long and still takes its step
    with caplog.at_level(logging.WARNING, logger="moreau.dynamics.sections"):
        short = poincare_on_the_fly(scene, [0.0], [2.0], h, surf, n_crossings=3, t_start=0.1, t_max=7.0005,
                                    chunk_steps=1000)
    assert np.allclose(short.t, up.t[:2], atol=1e-12) and "2 of 3 crossings" in caplog.text


def test_poincare_map_multiplier_of_a_damped_oscillator():
    """Autonomous damped oscillator, section x = 0 upward: the return map of the velocity is
    linear, v -> v exp(-c T_d / 2m) with T_d = 2π/ω_d; its multiplier by central differences
    of the PoincareMap within 1e-3, and the return time T_d within h (measured 2.4e-4 at
    h = 1e-3: the scheme is first order with a velocity-dependent force)."""
    from moreau.dynamics import PoincareMap

    m, c, k = 1.0, 0.3, 4.0
    scene = mo.Scene(mo.FunctionSystem([[m]]), [mo.LinearSpring([[k]]), mo.LinearDamping([[c]])])
    wd = np.sqrt(k / m - (c / (2 * m)) ** 2)
    Td = 2 * np.pi / wd
    P = PoincareMap(scene, lambda q, v: q[0], 1e-3, x_ref=[0.0, 1.0], free=[1], t_min=0.5 * Td,
                    t_max=1.5 * Td, direction=1)
    res = floquet_multipliers(P, [1.0], eps=1e-2)
    exact = np.exp(-c / (2 * m) * Td)
    assert abs(res.multipliers[0].real / exact - 1) < 1e-3
    assert abs(P.last_return_time - Td) < 1e-3
