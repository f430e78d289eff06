"""Lyapunov spectrum from the tangent dynamics with saltation matrices
(moreau.dynamics.tangent, Müller 1995).

References
----------
* Sum of all exponents = mean phase-space contraction: -trace(M⁻¹C) for constant M and
  linear damping C; each frictionless Newton impact multiplies phase-space volume by e²
  (det S = e², Müller 1995; Leine & Nijmeijer 2004).
* Ball on a vibrating table: closed-form multipliers of the period-1 orbit
  (moreau/dynamics/benchmarks.py); exponents ln|μ| / T.
"""

from __future__ import annotations

import numpy as np
import pytest

import moreau as mo
from moreau.dynamics import largest_lyapunov, lyapunov_spectrum_tangent, paired_difference
from moreau.dynamics.benchmarks import forced_triple_pendulum, table_period1, vibrating_table
from moreau.dynamics.tangent import _Flow

E, A = 0.5, 1.49


def test_sum_is_the_contraction_without_impacts():
    """2-DOF, non-diagonal constant M, non-proportional damping, a cubic spring and a
    harmonic force: the sum of the four exponents is -trace(M⁻¹C) (measured to 1e-9
    relative: the exponential step has det exp(h trace A) exactly)."""
    M = np.array([[2.0, 0.3], [0.3, 1.0]])
    C = np.array([[0.3, -0.1], [-0.1, 0.2]])
    K = np.array([[5.0, -1.0], [-1.0, 3.0]])
    scene = mo.Scene(mo.FunctionSystem(M), [
        mo.LinearSpring(K), mo.LinearDamping(C), mo.HarmonicForce([1.0, 0.0], 1.3),
        mo.FunctionForce(lambda t, q, v: -np.array([q[0] ** 3, 0.0]), velocity_dependent=False,
                         time_dependent=False, name="cubic")])
    ref = -np.trace(np.linalg.solve(M, C))
    r = lyapunov_spectrum_tangent(scene, [1.0, 0.0], [0.0, 0.5], 0.02, interval=1.0, n_intervals=50)
    print("exponents", r.exponents, "sum", r.sum, "ref", ref)
    assert r.method == "saltation" and r.n_impacts == 0
    assert abs(r.sum / ref - 1) < 0.01
    assert np.all(np.diff(r.exponents) <= 0)


def test_saltation_determinant_is_e_squared():
    """det S = e² for one frictionless row, with a configuration-dependent M (the triple
    pendulum's two wall rows) and on the table."""
    scene = forced_triple_pendulum(6.0, 3.0)
    flow = _Flow(scene, 1e-7)
    q = np.array([0.3, 0.2, 0.1])
    v = np.array([2.0, 1.5, 3.0])
    for row in (0, 1):
        assert scene.jacobian(q)[row] @ v < 0  # approaching the wall
        S, xp = flow.saltation(0.4, np.concatenate([q, v]), row)
        G = scene.jacobian(q)[row]
        assert np.isclose(G @ xp[3:], -0.8 * (G @ v))
        assert np.isclose(np.linalg.det(S), 0.8 ** 2, rtol=1e-6)
    flow = _Flow(vibrating_table(E, A, c=0.05), 1e-7)
    S, _ = flow.saltation(1.0, np.array([0.0, -2.0]), 0)
    assert np.isclose(np.linalg.det(S), E ** 2, rtol=1e-9)


def test_saltation_matrix_matches_an_event_driven_flow():
    """The whole matrix, not only its determinant: for the triple pendulum (M(q), a curved
    barrier: the tip's x on a wall) S = Φ_post⁻¹ Φ Φ_pre⁻¹, with Φ the central-difference
    Jacobian of an event-located flow through the impact (DOP853, rtol 1e-12) and Φ_pre,
    Φ_post those of the smooth flow to and from the impact instant. Measured: equal to
    1e-7 relative (the finite differences of both sides)."""
    from scipy.integrate import solve_ivp

    scene = forced_triple_pendulum(6.0, 3.0)
    flow = _Flow(scene, 1e-7)
    x0 = np.array([0.1, 0.05, 0.05, 1.0, 0.5, 2.0])  # tip 0.028 from the wall, approaching
    t1, row, opts = 0.2, 0, dict(rtol=1e-12, atol=1e-13, method="DOP853")

    def hit(t, x):
        return scene.gaps(x[:3])[row]
    hit.terminal, hit.direction = True, -1  # type: ignore[attr-defined]

    def smooth(x, ta, tb):
        return solve_ivp(flow.field, (ta, tb), x, **opts).y[:, -1]

    def through(x):
        a = solve_ivp(flow.field, (0.0, t1), x, events=hit, **opts)
        assert a.status == 1
        te, xe = a.t_events[0][0], a.y_events[0][0].copy()
        xe[3:] = flow.newton(xe[:3], xe[3:], row)
        return smooth(xe, te, t1), te, a.y_events[0][0]

    def fd(f, x, d=1e-6):
        return np.column_stack([(f(x + d * e) - f(x - d * e)) / (2 * d) for e in np.eye(6)])

    _, te, xm = through(x0)
    xp = np.concatenate([xm[:3], flow.newton(xm[:3], xm[3:], row)])
    S_flow = np.linalg.solve(fd(lambda x: smooth(x, te, t1), xp), fd(lambda x: through(x)[0], x0)) @ \
        np.linalg.inv(fd(lambda x: smooth(x, 0.0, te), x0))
    S, _ = flow.saltation(te, xm, row)
    print("max relative difference", np.abs(S - S_flow).max() / np.abs(S_flow).max())
    assert np.abs(S - S_flow).max() < 1e-5 * np.abs(S_flow).max()


def _table(n: int, c: float = 0.0, n_intervals: int = 4):
    orb = table_period1(E, A)
    return orb, lyapunov_spectrum_tangent(vibrating_table(E, A, c=c), orb.x_mid[:1], orb.x_mid[1:], orb.T / n,
                                          interval=orb.T, n_intervals=n_intervals, n_align=12, n_transient=40,
                                          t0=orb.t_mid)


@pytest.mark.slow  # a convergence study (10 s): in the slow suite, which CI runs too
def test_table_exponents_converge_at_first_order_in_h():
    """Period-1 orbit of the ball on the table (e = 0.5, no damping; 40 periods of
    transient for the scheme's orbit to settle, 12 of alignment, 4 averaged): both
    exponents tend to ln|μ| / T of the closed-form multipliers (-0.028560, -0.192075) at
    first order in h (the reference trajectory's impact instants and states are O(h)),
    and are within 1 % at T/h = 8000; the sum is 2 ln(e) / T at every h. Measured
    relative errors at T/h = 500, 2000, 8000: largest 19.3 %, 3.46 %, 0.79 % (ratios 5.6,
    4.4), second -2.86 %, -0.52 %, -0.12 %. About 1 s with the compiled smooth steps."""
    err = {}
    for n in (500, 2000, 8000):
        orb, r = _table(n)
        ref = np.log(np.abs(orb.multipliers)) / orb.T
        err[n] = r.exponents / ref - 1
        assert r.n_impacts == 4 and r.meta["persistent_steps"] == 0
        assert abs(r.sum / (2 * np.log(E) / orb.T) - 1) < 1e-9
        print(n, r.exponents, "relative errors", err[n])
    for j in (0, 1):
        e = np.array([abs(err[n][j]) for n in (500, 2000, 8000)])
        assert np.all(3.5 < e[:-1] / e[1:]) and np.all(e[:-1] / e[1:] < 7.0)
    assert np.all(np.abs(err[8000]) < 0.01)


def test_table_sum_with_damping_includes_2_ln_e_per_impact():
    """Damped table (c = 0.05): the sum is -c + 2 ln(e) × impacts per unit time to 1e-6."""
    orb, r = _table(2000, c=0.05)
    ref = -0.05 + 2 * np.log(E) * r.n_impacts / (4 * orb.T)
    print("sum", r.sum, "ref", ref, r.meta)
    assert abs(r.sum / ref - 1) < 1e-6
    assert np.isclose(r.meta["mean_trace"], -0.05, rtol=1e-6)
    assert np.isclose(r.meta["mean_trace"] + r.meta["ln_det_impacts"], r.sum, rtol=1e-9)


def test_persistent_contact_raises_or_is_reported():
    """A ball dropped on a fixed floor with e = 0.5 under gravity ends resting on it after
    a Zeno cascade: a persistent contact, outside the saltation theory. Default: raise;
    ``persistent="scheme"``: a result with the count and a warning."""
    scene = mo.Scene(mo.FunctionSystem(np.eye(1)), [mo.ConstantForce([-1.0]), mo.LinearDamping([[0.1]])],
                     [mo.Contact(mo.LinearBarrier([[1.0]], [0.0]), mo.NewtonImpact(0.5), name="floor")])
    kw = dict(interval=1.0, n_intervals=20)
    with pytest.raises(RuntimeError, match="persistent contact"):
        lyapunov_spectrum_tangent(scene, [0.5], [0.0], 0.01, **kw)
    r = lyapunov_spectrum_tangent(scene, [0.5], [0.0], 0.01, persistent="scheme", **kw)
    assert r.meta["persistent_steps"] > 0 and r.meta["warnings"]
    with pytest.raises(ValueError, match="persistent"):
        lyapunov_spectrum_tangent(scene, [0.5], [0.0], 0.01, persistent="ignore", **kw)


@pytest.fixture(scope="module")
def chaotic_pendulum_exponents(chaotic_pendulum):
    """Triple pendulum with a wall, torque 3 sin(6 t) N m, T/h = 1600, 200 half periods
    after 100 periods of transient: the tangent spectrum (frame re-orthonormalized every
    step) and the flow's mean contraction -<trace(M(q)⁻¹C)> + 2 ln(e) × impacts per unit
    time along the same segment, from a separate recorded run."""
    scene, q0, v0, t0, T = chaotic_pendulum
    h, n_int = T / 1600, 200
    tan = lyapunov_spectrum_tangent(scene, q0, v0, h, interval=T / 2, n_intervals=n_int, n_align=5, t0=t0)
    t1 = t0 + 5 * T / 2
    ref = mo.simulate(scene, (t0, t0 + (5 + n_int) * T / 2), q0, v0, h, solver="enum", progress=False,
                      energy=False)
    sel = ref.t >= t1
    C = scene.effects[1].C
    tr_c = np.mean([np.trace(np.linalg.solve(scene.system.mass_matrix(q), C)) for q in ref.q[sel][::4]])
    rate = np.count_nonzero(ref.impacts.t >= t1) / (n_int * T / 2)
    contraction = -tr_c + 2 * np.log(0.8) * rate
    print(f"saltation spectrum {tan.exponents.round(3)} ± {tan.stderr.round(3)}, sum {tan.sum:.4f}, "
          f"contraction {contraction:.4f}, meta {tan.meta}")
    return tan, contraction


def test_tangent_spectrum_of_the_chaotic_triple_pendulum_sums_to_the_contraction(chaotic_pendulum_exponents):
    """The six exponents sum to the flow's contraction to 1 % (measured 2026-11-26: sum
    -2.833 1/s against -2.826, spectrum (2.57, 0.84, 0.00, -0.73, -1.48, -4.04) 1/s, the
    same to four decimals with the Python smooth steps; the FD-QR spectrum on the same
    segment sums to +2.56 1/s), with a clearly positive largest exponent and no persistent
    contact. About 5 s with the compiled smooth steps (80 s on the Python path)."""
    tan, contraction = chaotic_pendulum_exponents
    assert tan.exponents[0] > 3 * tan.stderr[0]
    assert tan.meta["persistent_steps"] == 0
    assert abs(tan.sum / contraction - 1) < 0.01


@pytest.mark.slow  # 2 x 896 000 steps: ~13 s with the compiled smooth steps (7 min without)
def test_tangent_and_two_trajectory_largest_exponents_agree(chaotic_pendulum):
    """The largest exponent of the chaotic triple pendulum by the tangent method and by two
    trajectories, on the same reference trajectory (the tangent method restarting every
    interval, as the two-trajectory method does: bit-identical), in the window
    h·|v| << d0 << 1 where the two-trajectory method measures the flow's exponent:
    T/h = 25 600 (h·|v|_rms = 5.2e-4), d0 = 1e-2 (a stretch of ≈ 1.5 per interval T/8),
    30 periods after 5 of alignment. The two estimates agree within two combined standard
    errors, and so does the mean of their per-interval differences within two of its own
    (paired) standard errors, an error bar free of the scatter between realizations of
    the chaotic trajectory. Measured (50 periods; ``benchmarks/lyapunov_window.py``):
    paired differences -0.028 ± 0.045 and -0.021 ± 0.074 1/s on two segments (estimates
    3.07 and 2.63 1/s); this test's 30 periods: +0.004 ± 0.115. Outside the window they
    differ: at T/h = 25 600 with d0 = 1e-4 (below h·|v|: the discrete map's exponent) by
    -0.50 ± 0.14, at T/h = 1600 (h·|v| = 7.4e-3) by +0.21 ± 0.09 (d0 = 3e-2) to
    -0.46 ± 0.11 1/s (d0 = 1e-4)."""
    scene, q0, v0, t0, T = chaotic_pendulum
    nh, k = 25600, 8
    kw = dict(interval=T / k, n_intervals=30 * k, n_align=5 * k, t0=t0)
    tan = lyapunov_spectrum_tangent(scene, q0, v0, T / nh, k=1, chunk=nh // k, **kw)
    two = largest_lyapunov(scene, q0, v0, T / nh, d0=1e-2, **kw)
    assert np.array_equal(two.x_final, tan.x_final)  # the same reference trajectory
    d, se_diff = paired_difference(two, tan)
    a, sa, b, sb = two.exponents[0], two.stderr[0], tan.exponents[0], tan.stderr[0]
    print(f"two-trajectory {a:.3f} ± {sa:.3f}, tangent {b:.3f} ± {sb:.3f}, paired difference "
          f"{d:+.3f} ± {se_diff:.3f} 1/s, impacts {tan.n_impacts}")
    assert a > 3 * sa and b > 3 * sb
    assert np.isclose(d, a - b, rtol=1e-9, atol=1e-12)
    assert abs(a - b) < 2 * np.hypot(sa, sb)
    assert abs(d) < 2 * se_diff


def test_paired_difference_of_two_methods_on_one_reference_trajectory():
    """``paired_difference`` of the two-trajectory and the tangent estimate (``chunk`` =
    one interval: the same reference trajectory) is the difference of the estimates, with
    a block standard error; runs on different trajectories are refused."""
    orb = table_period1(E, A)
    scene, n = vibrating_table(E, A), 500
    kw = dict(interval=orb.T, n_intervals=20, n_align=2, t0=orb.t_mid)
    tan = lyapunov_spectrum_tangent(scene, orb.x_mid[:1], orb.x_mid[1:], orb.T / n, k=1, chunk=n, **kw)
    two = largest_lyapunov(scene, orb.x_mid[:1], orb.x_mid[1:], orb.T / n, d0=1e-6, **kw)
    d, se = paired_difference(two, tan)
    assert np.isclose(d, two.exponents[0] - tan.exponents[0], rtol=1e-9, atol=1e-12)
    assert np.isfinite(se) and se >= 0
    # a run from another state does not share the reference trajectory
    other = largest_lyapunov(scene, orb.x_mid[:1] + 1e-3, orb.x_mid[1:], orb.T / n, d0=1e-6, **kw)
    with pytest.raises(ValueError, match="same reference trajectory"):
        paired_difference(other, tan)
    with pytest.raises(ValueError, match="interval"):
        paired_difference(largest_lyapunov(scene, orb.x_mid[:1], orb.x_mid[1:], orb.T / n, d0=1e-6,
                                           **{**kw, "n_intervals": 10}), tan)


def _numpy_smooth_steps(scene, eps):
    """The reference of moreau.compiled.tangent.smooth_steps in numpy: per step exp(h A) at
    the midpoint state, then QR; ``(ln|diag R| (steps, k), h trace A (steps,))``, Q in place."""
    import moreau.dynamics.tangent as tangent
    from moreau.dynamics.saltation import _expm

    flow = tangent._Flow(scene, eps)

    def run(t, h, X, first, last, Q):
        ld, tr = np.empty((last - first, Q.shape[1])), np.empty(last - first)
        for j, s in enumerate(range(first, last)):
            ts = t + s * h
            A = flow.jacobian(ts + 0.5 * h, 0.5 * (X[s] + X[s + 1]))
            Qn, d = tangent._reorthonormalized(_expm(h * A) @ Q, ts)
            Q[:] = Qn
            ld[j], tr[j] = np.log(np.abs(d)), h * np.trace(A)
        return ld, tr

    return run


@pytest.mark.parametrize("k", [6, 2])
def test_compiled_smooth_steps_match_the_python_reference(chaotic_pendulum, monkeypatch, k):
    """The smooth steps run compiled (moreau.compiled.tangent) when the scene compiles; on the
    chaotic triple pendulum (configuration-dependent M, damping, torque, impacts on the
    wall) over 4 half periods at T/h = 800 they give the Python reference's logs and
    contraction to round-off (the two differ in summation order and in M⁻¹ by Cholesky
    against an inverse)."""
    import moreau.compiled.tangent as compiled_tangent
    import moreau.dynamics.tangent as tangent

    scene, q0, v0, t0, T = chaotic_pendulum
    kw = dict(interval=T / 2, n_intervals=4, t0=t0, k=k)
    runs = []
    smooth_steps = compiled_tangent.smooth_steps
    monkeypatch.setattr(compiled_tangent, "smooth_steps", lambda *a: runs.append(a[9] - a[8]) or smooth_steps(*a))
    compiled = lyapunov_spectrum_tangent(scene, q0, v0, T / 800, **kw)
    assert sum(runs) > 0.95 * 4 * 400  # nearly every step is smooth, and ran compiled
    monkeypatch.setattr(tangent, "_compiled_smooth_steps", _numpy_smooth_steps)
    python = lyapunov_spectrum_tangent(scene, q0, v0, T / 800, **kw)
    assert compiled.n_impacts == python.n_impacts > 0
    assert np.array_equal(compiled.times, python.times)
    np.testing.assert_allclose(compiled.logs, python.logs, rtol=1e-7, atol=1e-9)
    assert compiled.meta["mean_trace"] == pytest.approx(python.meta["mean_trace"], rel=1e-9)
