r"""Parameters of the piston – connecting rod – crankshaft engine and the paper's
non-dimensional closed form, eq. (2.1)–(2.3) of Awrejcewicz & Kudra.

Conventions (stated once, used by the whole ``moreau.problems.piston`` package)
-------------------------------------------------------------------------------
* Links: 1 crank (pivot O1 fixed at the origin, length l1), 2 connecting rod
  (O2 → O3, length l2), 3 piston (pin O3). The cylinder axis is vertical, the piston
  above the crank: an *inverted* triple pendulum. Angles φ_i are absolute, measured from
  the cylinder axis; link i points along (sin φ_i, cos φ_i).
* Centre-of-mass offsets e_yi are measured along link i from its proximal joint O_i
  (the paper's convention for the triple pendulum: e_y1 = 0 puts the crank's centre of
  mass on its axis, e_y3 = 0.01 m puts the piston's 1 cm above the pin).
* The moments of inertia J_zi are *central* (about the centre of mass): the paper speaks
  of principal central axes, and J_z2 = 0.0075 kg m² < m2 e_y2² = 0.0144 kg m² rules out
  axes through a joint (parallel-axis theorem).
* The piston is a d × s rectangle whose top lies a distance h above the pin; its four
  corners meet the cylinder walls x = ±D/2 (eq. 2.3): rows 0 top-right, 1 bottom-right,
  2 top-left, 3 bottom-left.
* The printed ``C φ`` of eq. (2.1) acts on the angular velocities (joint damping C φ̇).

Non-dimensional form (our scales; the paper's own α₁ factors are absorbed in them):
length l1, time 1/ω with ω = 2π n/60 (n = 2000 rpm), mass such that M_11 = 1, i.e. the
generalized-inertia unit M̄_11 = J1 + m1 e1² + (m2 + m3) l1². Then
``M(φ) φ'' + N(φ) φ'² + C φ' + p_g(φ) = f_e(φ)`` with

* β_i = M̄_ii / M̄_11, ν12 = (m2 e2 + m3 l2) l1 / M̄_11, ν13 = m3 e3 l1 / M̄_11,
  ν23 = m3 e3 l2 / M̄_11;
* C = c1 [[1 + c21, −c21, 0], [−c21, c21 + c31, −c31], [0, −c31, c31]],
  c1 = c̄1 / (M̄_11 ω);
* f_e = [F0 p sin φ1 − M0, λ2 F0 p sin φ2, 0], p = p̄ / p_max, F0 = p_max (π d²/4) l1 /
  (M̄_11 ω²), M0 = M̄0 / (M̄_11 ω²);
* gravity p_g = −[γ1 sin φ1, γ2 sin φ2, γ3 sin φ3], γ1 = g (m1 e1 + (m2 + m3) l1) /
  (M̄_11 ω²), γ2 = g (m2 e2 + m3 l2) / (M̄_11 ω²), γ3 = g m3 e3 / (M̄_11 ω²);
* gaps (in units of l1): eq. (2.3) with λ2 = l2/l1, η = h/l1, σ = s/l1, δ = d/l1,
  Δ = D/l1.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

__all__ = ["PistonParameters", "Groups", "groups", "closed_form"]


@dataclass(frozen=True)
class PistonParameters:
    """Physical parameters (SI) of the engine; defaults are the paper's.

    Attributes
    ----------
    m1, m2, m3 : float
        Masses of crank, rod, piston (kg).
    J1, J2, J3 : float
        Central moments of inertia (kg m²).
    l1, l2 : float
        Crank radius and rod length (m).
    e1, e2, e3 : float
        Centre-of-mass offsets from the proximal joints, the paper's e_yi (m).
    d, s, h : float
        Piston diameter, height, and distance from its top down to the pin (m).
    D : float
        Cylinder diameter (m); the clearance is D − d.
    c1 : float
        Crank bearing damping c̄1 (N m s).
    c21, c31 : float
        Damping ratios c̄2/c̄1, c̄3/c̄1.
    M0 : float
        Brake moment M̄0 (N m).
    p_max : float
        Peak gauge pressure (Pa).
    rpm : float
        Reference speed n (rev/min), fixing the time scale ω = 2π n / 60.
    g : float
        Gravitational acceleration (m/s²).
    e : float
        Restitution at the four corners.
    mu : float
        Coulomb friction coefficient of the skirt at the cylinder wall (0: the paper's
        frictionless wall).
    """

    m1: float = 10.0
    m2: float = 1.0
    m3: float = 0.4
    J1: float = 1.0
    J2: float = 0.0075
    J3: float = 0.001
    l1: float = 0.04
    l2: float = 0.15
    e1: float = 0.0
    e2: float = 0.12
    e3: float = 0.01
    d: float = 0.08
    s: float = 0.08
    h: float = 0.04
    D: float = 0.08004
    c1: float = 0.00432
    c21: float = 0.2
    c31: float = 0.2
    M0: float = 9.807
    p_max: float = 3e6
    rpm: float = 2000.0
    g: float = 9.81
    e: float = 0.0
    mu: float = 0.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"piston parameter {name} must be a finite number, got {value!r}")
        for name in ("m1", "m2", "m3", "J1", "J2", "J3", "l1", "l2", "d", "s", "D", "rpm"):
            if getattr(self, name) <= 0:
                raise ValueError(f"piston parameter {name} must be positive, got {getattr(self, name)!r}")
        for name in ("c1", "c21", "c31", "M0", "p_max", "g", "h", "mu"):
            if getattr(self, name) < 0:
                raise ValueError(f"piston parameter {name} must be non-negative, got {getattr(self, name)!r}")
        if not 0.0 <= self.e <= 1.0:
            raise ValueError(f"restitution e must be in [0, 1], got {self.e!r}")
        if self.D <= self.d:
            raise ValueError(f"cylinder diameter D = {self.D!r} m must exceed the piston diameter d = {self.d!r} m")
        if self.h > self.s:
            raise ValueError(f"pin depth h = {self.h!r} m must not exceed the piston height s = {self.s!r} m")
        if self.l2 <= self.l1:
            raise ValueError(f"rod length l2 = {self.l2!r} m must exceed the crank radius l1 = {self.l1!r} m")

    def with_(self, **changes) -> PistonParameters:
        """A copy with some parameters changed (validated)."""
        return replace(self, **changes)

    @property
    def omega(self) -> float:
        """Reference angular speed ω = 2π n / 60 (rad/s): the time scale is 1/ω."""
        return 2.0 * math.pi * self.rpm / 60.0

    @property
    def clearance(self) -> float:
        """Diametral clearance D − d (m)."""
        return self.D - self.d

    @property
    def area(self) -> float:
        """Piston area π d²/4 (m²)."""
        return math.pi * self.d**2 / 4.0

    @property
    def M11(self) -> float:
        """M̄_11 = J1 + m1 e1² + (m2 + m3) l1² (kg m²): the generalized-inertia unit."""
        return self.J1 + self.m1 * self.e1**2 + (self.m2 + self.m3) * self.l1**2


@dataclass(frozen=True)
class Groups:
    """The paper's non-dimensional groups (see the module docstring)."""

    beta2: float
    beta3: float
    nu12: float
    nu13: float
    nu23: float
    lambda2: float
    eta: float
    sigma: float
    delta: float
    Delta: float
    F0: float
    M0: float
    c1: float
    c21: float
    c31: float
    gamma1: float
    gamma2: float
    gamma3: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def groups(p: PistonParameters) -> Groups:
    """Non-dimensional groups of the paper's eq. (2.1)–(2.3) for parameters ``p``."""
    M11, w2 = p.M11, p.omega**2
    return Groups(
        beta2=(p.J2 + p.m2 * p.e2**2 + p.m3 * p.l2**2) / M11,
        beta3=(p.J3 + p.m3 * p.e3**2) / M11,
        nu12=(p.m2 * p.e2 + p.m3 * p.l2) * p.l1 / M11,
        nu13=p.m3 * p.e3 * p.l1 / M11,
        nu23=p.m3 * p.e3 * p.l2 / M11,
        lambda2=p.l2 / p.l1,
        eta=p.h / p.l1,
        sigma=p.s / p.l1,
        delta=p.d / p.l1,
        Delta=p.D / p.l1,
        F0=p.p_max * p.area * p.l1 / (M11 * w2),
        M0=p.M0 / (M11 * w2),
        c1=p.c1 / (M11 * p.omega),
        c21=p.c21,
        c31=p.c31,
        gamma1=p.g * (p.m1 * p.e1 + (p.m2 + p.m3) * p.l1) / (M11 * w2),
        gamma2=p.g * (p.m2 * p.e2 + p.m3 * p.l2) / (M11 * w2),
        gamma3=p.g * p.m3 * p.e3 / (M11 * w2),
    )


def closed_form(p: PistonParameters, pressure=None, gravity: bool = True, damping: bool = True,
                gas: bool = True, brake: bool = True):
    """The paper's eq. (2.1)–(2.3) written out, in non-dimensional form.

    Returns
    -------
    dict of callables
        ``M(phi)`` (3, 3), ``N(phi)`` (3, 3), ``C`` (3, 3) array, ``p_g(phi)`` (3,),
        ``f_e(phi)`` (3,), ``gaps(phi)`` (4,), and ``acceleration(phi, dphi)`` (3,) =
        M⁻¹ (f_e − N dphi² − C dphi − p_g). ``pressure`` is p̄(φ1) in Pa (required when
        ``gas``).
    """
    G = groups(p)
    if gas and pressure is None:
        raise ValueError("closed_form: a pressure curve is required when gas=True")

    def M(phi):
        c12, c13, c23 = np.cos(phi[0] - phi[1]), np.cos(phi[0] - phi[2]), np.cos(phi[1] - phi[2])
        return np.array([
            [1.0, G.nu12 * c12, G.nu13 * c13],
            [G.nu12 * c12, G.beta2, G.nu23 * c23],
            [G.nu13 * c13, G.nu23 * c23, G.beta3],
        ])

    def N(phi):
        s12, s13, s23 = np.sin(phi[0] - phi[1]), np.sin(phi[0] - phi[2]), np.sin(phi[1] - phi[2])
        return np.array([
            [0.0, G.nu12 * s12, G.nu13 * s13],
            [-G.nu12 * s12, 0.0, G.nu23 * s23],
            [-G.nu13 * s13, -G.nu23 * s23, 0.0],
        ])

    C = G.c1 * np.array([
        [1 + G.c21, -G.c21, 0.0],
        [-G.c21, G.c21 + G.c31, -G.c31],
        [0.0, -G.c31, G.c31],
    ]) if damping else np.zeros((3, 3))

    def p_g(phi):
        if not gravity:
            return np.zeros(3)
        return -np.array([G.gamma1 * np.sin(phi[0]), G.gamma2 * np.sin(phi[1]), G.gamma3 * np.sin(phi[2])])

    def f_e(phi):
        pr = pressure(phi[0]) / p.p_max if gas else 0.0
        return np.array([
            G.F0 * pr * np.sin(phi[0]) - (G.M0 if brake else 0.0),
            G.lambda2 * G.F0 * pr * np.sin(phi[1]),
            0.0,
        ])

    def gaps(phi):
        a = np.sin(phi[0]) + G.lambda2 * np.sin(phi[1])
        s3, c3 = np.sin(phi[2]), np.cos(phi[2])
        return np.array([
            G.Delta / 2 - a - G.eta * s3 - G.delta / 2 * c3,
            G.Delta / 2 - a + (G.sigma - G.eta) * s3 - G.delta / 2 * c3,
            G.Delta / 2 + a + G.eta * s3 - G.delta / 2 * c3,
            G.Delta / 2 + a - (G.sigma - G.eta) * s3 - G.delta / 2 * c3,
        ])

    def acceleration(phi, dphi):
        return np.linalg.solve(M(phi), f_e(phi) - N(phi) @ dphi**2 - C @ dphi - p_g(phi))

    return {"M": M, "N": N, "C": C, "p_g": p_g, "f_e": f_e, "gaps": gaps, "acceleration": acceleration}
