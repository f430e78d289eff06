"""Benchmark systems with known answers, for the tests and the notebooks.

The bouncing ball on a sinusoidally vibrating table
---------------------------------------------------
A ball (mass 1) under gravity g above a table at height ``A sin(ω t)``, Newton impacts
with restitution e on the relative velocity. In the table's frame the relative height z
obeys ``z'' = -g + A ω² sin(ω t)`` with the fixed barrier z >= 0 — a scene with a
:class:`~moreau.HarmonicForce` and a :class:`~moreau.LinearBarrier`.

Period-1 orbit (one impact per period T = 2π/ω, Holmes 1982; Luck & Mehta 1993): the
ball leaves the table with absolute velocity g T / 2 and returns after T; the Newton law
fixes the table velocity at impact ``u* = A ω cos φ* = g T (1 - e) / (2 (1 + e))``. The
exact impact map ``(t_k, V_k) -> (t_{k+1}, V_{k+1})`` (V absolute post-impact velocity) is
defined implicitly by ``s(t_k) + V_k τ - g τ²/2 = s(t_{k+1})``, ``τ = t_{k+1} - t_k``, and
``V_{k+1} = (1 + e) s'(t_{k+1}) - e (V_k - g τ)``; linearized at the orbit,

    J = [[1, T / D], [(1 + e) a*, ((1 + e) a* T + e g T) / D - e]],
    D = g T / 2 + u*,   a* = s''(t*) = -A ω² sin φ*,

with det J = e² (the area contraction of one Newton impact). Its eigenvalues are the
Floquet multipliers of the orbit (every section gives a conjugate map). Of the two
solutions ±φ*, only the one with sin φ* > 0 (the table decelerating at impact) can be
stable; it is, when both eigenvalues of J lie inside the unit circle (check
``TablePeriod1.multipliers``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import moreau as mo

__all__ = ["vibrating_table", "TablePeriod1", "table_period1", "forced_triple_pendulum", "chaotic_pendulum"]


def vibrating_table(e: float, A: float, omega: float = 1.0, g: float = 1.0, c: float = 0.0) -> mo.Scene:
    """The ball on the vibrating table in the table's frame; q = (z,), z >= 0.

    Parameters
    ----------
    e : float
        Restitution.
    A : float
        Table amplitude (length units).
    omega : float
        Table angular frequency (rad per time unit).
    g : float
        Gravity (length / time²).
    c : float
        Linear damping on the relative velocity (1 / time units; mass 1), 0 for none.
    """
    effects = [mo.ConstantForce([-g], name="gravity"), mo.HarmonicForce([A * omega ** 2], omega, name="table")]
    if c:
        effects.append(mo.LinearDamping([[c]]))
    return mo.Scene(mo.FunctionSystem(np.eye(1)), effects,
                    [mo.Contact(mo.LinearBarrier([[1.0]], [0.0]), mo.NewtonImpact(e), name="table")],
                    name="ball on a vibrating table")


@dataclass
class TablePeriod1:
    """The stable period-1 orbit of the ball on the table, in closed form.

    Attributes
    ----------
    phi : float
        Impact phase φ* (rad): impacts at ``t = (φ* + 2πk) / ω``.
    T : float
        Period 2π/ω.
    jacobian : ndarray, shape (2, 2)
        Linearized impact map.
    multipliers : ndarray, shape (2,)
        Its eigenvalues, largest modulus first.
    t_mid : float
        Time half a period after an impact (a section in mid-flight).
    x_mid : ndarray, shape (2,)
        Relative state (z, z') at ``t_mid``.
    """

    phi: float
    T: float
    jacobian: np.ndarray
    multipliers: np.ndarray
    t_mid: float
    x_mid: np.ndarray


def table_period1(e: float, A: float, omega: float = 1.0, g: float = 1.0) -> TablePeriod1:
    """Closed-form period-1 orbit (the branch with sin φ* > 0) and its multipliers."""
    T = 2 * np.pi / omega
    u = g * T * (1 - e) / (2 * (1 + e))
    if A * omega < u:
        raise ValueError(f"no period-1 orbit: A ω = {A * omega} < u* = {u}")
    phi = float(np.arccos(u / (A * omega)))
    a = -A * omega ** 2 * np.sin(phi)
    D = g * T / 2 + u
    J = np.array([[1.0, T / D], [(1 + e) * a, ((1 + e) * a * T + e * g * T) / D - e]])
    mu = np.linalg.eigvals(J)
    mu = mu[np.argsort(-np.abs(mu))]
    # mid-flight: τ = T/2 after the impact at t* = φ*/ω; absolute velocity g T/2 - g τ = 0
    tau = T / 2
    t_mid = phi / omega + tau
    z = g * T / 2 * tau - g * tau ** 2 / 2 - A * (np.sin(omega * t_mid) - np.sin(phi))
    zdot = 0.0 - A * omega * np.cos(omega * t_mid)
    return TablePeriod1(phi, T, J, mu, float(t_mid), np.array([z, zdot]))


def forced_triple_pendulum(omega: float, amplitude: float = 1.5, e: float = 0.8,
                           wall: float = 0.12, damping: float = 0.02) -> mo.Scene:
    """A triple physical pendulum with a wall, driven by a harmonic torque on link 1.

    Three uniform rods hanging from a fixed pivot (absolute angles from the downward
    vertical, :mod:`moreau.model.chain`): m = 1.0, 0.8, 0.5 kg, l = 0.5, 0.45, 0.4 m (the
    README's chain); viscous joint damping ``damping`` N m s/rad at every joint; gravity
    9.81 m/s²; a torque ``amplitude · sin(omega t)`` N m on link 1 (the paper's external
    moment on the first link, harmonic instead of a brake); a vertical wall at
    x = ``wall`` m that the tip of link 3 and the joint between links 2 and 3 may not
    cross, Newton restitution e. The parameters are our choice (the seed paper gives
    none for the pendulum itself): link sizes of a table-top rig like Awrejcewicz and
    Kudra's, a wall close enough to be hit at moderate amplitude.

    Returns
    -------
    Scene
        q = (φ1, φ2, φ3) rad; at rest hanging straight down, all gaps are ``wall``.
    """
    from moreau.model.chain import ChainGravity, JointDamping, Link, PendulumChain, PointLineBarrier, PointLineRow

    chain = PendulumChain([Link.rod(m=1.0, l=0.5), Link.rod(m=0.8, l=0.45), Link.rod(m=0.5, l=0.4)])
    walls = PointLineBarrier(chain, [
        PointLineRow(2, (0.4, 0.0), line_point=(wall, 0.0), normal=(-1.0, 0.0), name="tip"),
        PointLineRow(1, (0.45, 0.0), line_point=(wall, 0.0), normal=(-1.0, 0.0), name="joint 3"),
    ])
    return mo.Scene(chain, [ChainGravity(chain, g=9.81), JointDamping(chain, [damping] * 3),
                            mo.HarmonicForce([amplitude, 0.0, 0.0], omega, name="drive")],
                    [mo.Contact(walls, mo.NewtonImpact(e), name="wall")],
                    name="forced triple pendulum with a wall")


def chaotic_pendulum(omega: float = 6.0, amplitude: float = 3.0, periods: int = 100,
                     steps_per_period: int = 400) -> tuple[mo.Scene, np.ndarray, np.ndarray, float, float]:
    """The forced triple pendulum in its chaotic regime, settled on its attractor.

    ``forced_triple_pendulum(omega, amplitude)`` (defaults: torque 3 sin(6 t) N m, the
    regime of ``notebooks/triple_pendulum.py``) started at rest hanging down and run for
    ``periods`` forcing periods of transient at ``steps_per_period`` steps per period
    (exact contact solver).

    Returns
    -------
    scene : Scene
    q0, v0 : ndarray, shape (3,)
        State at the end of the transient (rad, rad/s).
    t0 : float
        Its time (s).
    T : float
        The forcing period 2π/omega (s).
    """
    T = 2 * np.pi / omega
    scene = forced_triple_pendulum(omega, amplitude)
    tr = mo.simulate(scene, (0.0, periods * T), [0.0] * 3, [0.0] * 3, T / steps_per_period, solver="enum",
                     record_every=steps_per_period, progress=False)
    return scene, tr.q[-1], tr.v[-1], float(tr.t[-1]), T
