r"""Cycle energy balance of the engine and the calibration of the pressure curve.

The engine is self-excited: it turns steadily where the indicated (gas) work per 720 deg
cycle, :math:`W_{ind} = \oint p\,dV` (:func:`indicated_work`), equals the brake work
:math:`4\pi\bar M_0` plus the viscous joint-damping work :math:`W_d(\omega)`
(:func:`damping_work`, proportional to the crank speed at a fixed crank path; about
13.8 J at 2000 rpm). :func:`cycle_work_balance` evaluates that balance at a given
speed, and :func:`calibrate` sets the start of combustion of the synthetic curve
(:mod:`moreau.problems.piston.pressure_curve`) so that the balance of its K = 25 Fourier
series (:mod:`moreau.problems.piston.fourier_fit`) closes at 2000 rpm. The derivation
and the calibrated values are in :mod:`moreau.problems.piston.pressure`.

All angles are in rad, pressures in Pa, work in J, torques in N m, damping coefficients
in N m s and angular velocities in rad/s.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import brentq

from .fourier_fit import FourierPressure, fit_fourier, fourier_fit_error
from .geometry import DEFAULT_GEOMETRY, FOUR_PI, TWO_PI, EngineGeometry
from .pressure_curve import K_HARMONICS, N_POINTS_DEFAULT, P_MAX, synthetic_pressure_curve

logger = logging.getLogger(__name__)

__all__ = [
    "M0_BRAKE",
    "C1_CRANK",
    "OMEGA_2000RPM",
    "WorkBalance",
    "CalibrationResult",
    "indicated_work",
    "damping_work",
    "cycle_work_balance",
    "calibrate",
    "calibrated_pressure",
]

#: Mean brake (load) torque [N m].
M0_BRAKE = 9.807
#: Viscous damping coefficient of the crank-ground joint [N m s].
C1_CRANK = 0.00432
#: Crank speed 2000 rpm [rad/s].
OMEGA_2000RPM = TWO_PI * 2000.0 / 60.0


# --------------------------------------------------------------------------
# Work balance
# --------------------------------------------------------------------------
def indicated_work(pressure, geometry: EngineGeometry = DEFAULT_GEOMETRY, n_quad: int = 8192) -> float:
    """Indicated work per 720 deg cycle W = -A * int_0^{4pi} p dy/dphi1 dphi1 [J].

    The integrand is smooth and 4 pi-periodic, so the uniform trapezoidal rule
    converges spectrally (exact to round-off for a K = 25 series with the
    default ``n_quad``).

    Parameters
    ----------
    pressure : callable
        Vectorised gauge pressure p(phi1) [Pa].
    geometry : EngineGeometry
        Engine geometry.
    n_quad : int
        Number of quadrature nodes on [0, 4 pi).
    """
    if isinstance(pressure, FourierPressure):
        # same quadrature, applied to the coefficients (linear functional)
        w0, wa, wb = _work_weights(geometry, int(n_quad), pressure.K)
        return float(pressure.a0 * w0 + pressure.a @ wa + pressure.b @ wb)
    phi = np.arange(n_quad) * (FOUR_PI / n_quad)
    dy = geometry.pin_height_derivative(phi)
    p = np.asarray(pressure(phi), dtype=float)
    return float(-geometry.area * np.sum(p * dy) * (FOUR_PI / n_quad))


@functools.lru_cache(maxsize=8)
def _work_weights(geometry: EngineGeometry, n_quad: int, K: int):
    """Work per unit Fourier coefficient: W = a0 w0 + a.wa + b.wb [J/Pa]."""
    phi = np.arange(n_quad) * (FOUR_PI / n_quad)
    wdy = -geometry.area * geometry.pin_height_derivative(phi) * (FOUR_PI / n_quad)
    t = np.multiply.outer(phi, 0.5 * np.arange(1, K + 1))
    wa = wdy @ np.cos(t)
    wb = wdy @ np.sin(t)
    wa.setflags(write=False)
    wb.setflags(write=False)
    return float(np.sum(wdy)), wa, wb


def damping_work(
    omega: float,
    c1: float = C1_CRANK,
    c2: float | None = None,
    c3: float | None = None,
    geometry: EngineGeometry = DEFAULT_GEOMETRY,
    n_quad: int = 4096,
) -> float:
    """Viscous joint-damping work per cycle at constant crank speed [J].

    Power c1 w1^2 + c2 (w2 - w1)^2 + c3 (w3 - w2)^2 with w1 = omega,
    w2 = omega dphi2/dphi1, w3 = 0 (piston does not rotate), integrated over
    one cycle (4 pi / omega seconds).

    Parameters
    ----------
    omega : float
        Crank angular velocity [rad/s].
    c1 : float
        Crank-ground joint coefficient [N m s].
    c2, c3 : float, optional
        Crank-rod and rod-piston coefficients [N m s]; default 0.2 c1.
    geometry : EngineGeometry
        Engine geometry.
    n_quad : int
        Quadrature nodes on [0, 4 pi) (trapezoid, spectrally accurate).
    """
    c2 = 0.2 * c1 if c2 is None else c2
    c3 = 0.2 * c1 if c3 is None else c3
    phi = np.arange(n_quad) * (FOUR_PI / n_quad)
    g = geometry.rod_angle_derivative(phi)
    integrand = c1 + c2 * (g - 1.0) ** 2 + c3 * g * g
    return float(omega * np.sum(integrand) * (FOUR_PI / n_quad))


@dataclass(frozen=True)
class WorkBalance:
    """Energy balance per 720 deg cycle at constant crank speed.

    Attributes
    ----------
    omega : float
        Crank speed [rad/s].
    rpm : float
        Crank speed [rev/min].
    indicated_work : float
        W_ind = closed integral of p dV [J].
    imep : float
        Indicated mean effective pressure W_ind / V_s [Pa].
    brake_work : float
        4 pi M0 [J].
    damping_work : float
        Joint damping work [J].
    surplus : float
        W_ind - brake_work - damping_work [J]; > 0 means the engine would
        accelerate at this speed.
    """

    omega: float
    rpm: float
    indicated_work: float
    imep: float
    brake_work: float
    damping_work: float
    surplus: float

    def as_dict(self) -> dict:
        """Fields as a plain dict."""
        return asdict(self)


def cycle_work_balance(
    pressure,
    omega: float = OMEGA_2000RPM,
    M0: float = M0_BRAKE,
    c1: float = C1_CRANK,
    c2: float | None = None,
    c3: float | None = None,
    geometry: EngineGeometry = DEFAULT_GEOMETRY,
) -> WorkBalance:
    """Cycle energy balance of the engine at constant crank speed.

    Parameters
    ----------
    pressure : callable
        Vectorised gauge pressure p(phi1) [Pa], e.g. a :class:`FourierPressure`.
    omega : float
        Crank speed [rad/s] (default 2000 rpm).
    M0 : float
        Mean brake torque [N m] (default 9.807).
    c1, c2, c3 : float
        Joint damping coefficients [N m s] (c2, c3 default 0.2 c1).
    geometry : EngineGeometry
        Engine geometry.

    Returns
    -------
    WorkBalance
    """
    w_ind = indicated_work(pressure, geometry)
    w_brake = FOUR_PI * M0
    w_damp = damping_work(omega, c1, c2, c3, geometry)
    return WorkBalance(
        omega=float(omega),
        rpm=float(omega * 60.0 / TWO_PI),
        indicated_work=w_ind,
        imep=w_ind / geometry.swept_volume,
        brake_work=w_brake,
        damping_work=w_damp,
        surplus=w_ind - w_brake - w_damp,
    )


# --------------------------------------------------------------------------
# Calibration
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Result of :func:`calibrate`.

    Attributes
    ----------
    start_of_combustion : float
        Calibrated start of combustion [rad] (negative = before firing TDC).
    heat_release : float
        Apparent heat released per cycle Q_in [J].
    pressure : FourierPressure
        K-harmonic series of the calibrated curve [Pa].
    balance : WorkBalance
        Work balance of ``pressure`` at the calibration speed.
    fit_error : dict
        Output of :func:`fourier_fit_error` (relative to p_max).
    """

    start_of_combustion: float
    heat_release: float
    pressure: FourierPressure
    balance: WorkBalance
    fit_error: dict


@functools.lru_cache(maxsize=16)
def calibrate(
    omega: float = OMEGA_2000RPM,
    M0: float = M0_BRAKE,
    c1: float = C1_CRANK,
    c2: float | None = None,
    c3: float | None = None,
    p_max: float = P_MAX,
    K: int = K_HARMONICS,
    n_points: int = N_POINTS_DEFAULT,
    geometry: EngineGeometry = DEFAULT_GEOMETRY,
    soc_bracket_deg: tuple = (-45.0, 0.0),
) -> CalibrationResult:
    """Calibrate the start of combustion so that the cycle work balance closes.

    With all other parameters of :func:`synthetic_pressure_curve` at their
    defaults and the peak gauge pressure held at ``p_max``, find the start of
    combustion phi_s such that the indicated work of the K-harmonic Fourier
    representation equals 4 pi M0 plus the damping work at ``omega``
    (brentq, ``|surplus| << 0.05 J``).  Results are cached.

    Parameters
    ----------
    omega : float
        Target steady crank speed [rad/s] (default 2000 rpm).
    M0 : float
        Mean brake torque [N m].
    c1, c2, c3 : float
        Joint damping coefficients [N m s] (c2, c3 default 0.2 c1).
    p_max : float
        Peak gauge pressure [Pa].
    K : int
        Number of harmonics.
    n_points : int
        Grid size of the synthetic curve.
    geometry : EngineGeometry
        Engine geometry.
    soc_bracket_deg : tuple of float
        Search interval for phi_s [deg].

    Returns
    -------
    CalibrationResult

    Raises
    ------
    ValueError
        If the required work is not reachable within the bracket.
    """
    w_target = FOUR_PI * M0 + damping_work(omega, c1, c2, c3, geometry)

    def fourier(soc):
        phi, p = synthetic_pressure_curve(
            start_of_combustion=soc, p_max=p_max, geometry=geometry, n_points=n_points
        )
        return fit_fourier(phi, p, K)

    def residual(soc):
        return indicated_work(fourier(soc), geometry) - w_target

    lo, hi = (math.radians(v) for v in soc_bracket_deg)
    r_lo, r_hi = residual(lo), residual(hi)
    if r_lo * r_hi > 0.0:
        raise ValueError(
            f"required indicated work {w_target:.3f} J not reachable for start of "
            f"combustion in {soc_bracket_deg} deg (surplus {r_lo:.3f}, {r_hi:.3f} J)"
        )
    soc = brentq(residual, lo, hi, xtol=1e-12, rtol=4 * np.finfo(float).eps)
    phi, p, info = synthetic_pressure_curve(
        start_of_combustion=soc, p_max=p_max, geometry=geometry, n_points=n_points, full_output=True
    )
    fp = fit_fourier(phi, p, K)
    bal = cycle_work_balance(fp, omega, M0, c1, c2, c3, geometry)
    err = fourier_fit_error(fp, phi, p, reference=p_max)
    logger.debug(
        "calibrated start of combustion %.4f deg, W_ind %.4f J, surplus %.2e J",
        math.degrees(soc),
        bal.indicated_work,
        bal.surplus,
    )
    return CalibrationResult(
        start_of_combustion=float(soc),
        heat_release=info["heat_release"],
        pressure=fp,
        balance=bal,
        fit_error=err,
    )


def calibrated_pressure(
    omega: float = OMEGA_2000RPM,
    M0: float = M0_BRAKE,
    c1: float = C1_CRANK,
    p_max: float = P_MAX,
    K: int = K_HARMONICS,
) -> FourierPressure:
    """Fourier pressure p(phi1) [Pa] calibrated for a steady speed ``omega``.

    Shortcut for ``calibrate(omega, M0, c1, p_max=p_max, K=K).pressure``
    (cached); see :func:`calibrate`.

    Parameters
    ----------
    omega : float
        Steady crank speed [rad/s] (default 2000 rpm).
    M0 : float
        Mean brake torque [N m] (default 9.807).
    c1 : float
        Crank-joint damping [N m s]; c2 = c3 = 0.2 c1.
    p_max : float
        Peak gauge pressure of the synthetic curve [Pa] (default 3 MPa).
    K : int
        Number of harmonics (default 25).
    """
    return calibrate(float(omega), float(M0), float(c1), None, None, float(p_max), int(K)).pressure
