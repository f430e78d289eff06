r"""The synthetic four-stroke spark-ignition pressure curve of the piston engine.

A zero-dimensional, single-zone model: polytropic compression and expansion with an
apparent heat release by a Wiebe function between intake valve closing and exhaust
valve opening, smooth blends to near-atmospheric exhaust and intake pressures, and the
heat release chosen so that the peak gauge pressure is ``p_max``. The equations, the
angle conventions (firing TDC at phi1 = 0 mod 4 pi) and the default parameters are in
:mod:`moreau.problems.piston.pressure`; the slider-crank kinematics in
:mod:`moreau.problems.piston.geometry`.

Angles in rad, pressures in Pa (gauge unless stated), volumes in m^3, heat in J.
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import DEFAULT_GEOMETRY, FOUR_PI, TWO_PI, EngineGeometry

__all__ = [
    "P_ATM",
    "P_MAX",
    "K_HARMONICS",
    "N_POINTS_DEFAULT",
    "CALIBRATED_SOC_DEG",
    "synthetic_pressure_curve",
]

#: Atmospheric pressure [Pa].
P_ATM = 101325.0
#: Maximum gauge pressure of the cycle [Pa].
P_MAX = 3.0e6
#: Number of harmonics of phi1/2 in the Fourier representation [-].
K_HARMONICS = 25
#: Default grid size of the synthetic curve (0.05 deg resolution) [-].
N_POINTS_DEFAULT = 14400
#: Start of combustion found by :func:`calibrate` with all defaults [deg]
#: (re-derived in the tests; firing TDC = 0, negative = before TDC).
CALIBRATED_SOC_DEG = -21.6133


def _smootherstep(x):
    """C2 step 0 -> 1 on [0, 1]: 6x^5 - 15x^4 + 10x^3 (clipped)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def _cumtrapz(f, h):
    """Cumulative trapezoid on a uniform grid of step h, starting at 0."""
    out = np.empty_like(f)
    out[0] = 0.0
    np.cumsum(0.5 * h * (f[1:] + f[:-1]), out=out[1:])
    return out


def synthetic_pressure_curve(
    *,
    start_of_combustion: float = math.radians(CALIBRATED_SOC_DEG),
    burn_duration: float = math.radians(45.0),
    wiebe_a: float = 5.0,
    wiebe_m: float = 2.0,
    compression_ratio: float = 10.0,
    polytropic_n: float = 1.3,
    p_max: float = P_MAX,
    p_atm: float = P_ATM,
    p_intake: float = -5.0e3,
    p_exhaust: float = 1.0e4,
    intake_valve_closing: float = math.radians(-150.0),
    exhaust_valve_opening: float = math.radians(140.0),
    blowdown_duration: float = math.radians(60.0),
    overlap_duration: float = math.radians(40.0),
    geometry: EngineGeometry = DEFAULT_GEOMETRY,
    n_points: int = N_POINTS_DEFAULT,
    full_output: bool = False,
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, dict]:
    """Synthetic four-stroke spark-ignition gauge-pressure curve p(phi1).

    See :mod:`moreau.problems.piston.pressure` for the model.  All angles are
    crank angles relative to the firing TDC (negative = before TDC).

    Parameters
    ----------
    start_of_combustion : float
        Start of combustion (Wiebe origin) phi_s [rad]; default is the
        calibrated value (:data:`CALIBRATED_SOC_DEG`).
    burn_duration : float
        Wiebe burn duration [rad] (default 45 deg).
    wiebe_a, wiebe_m : float
        Wiebe efficiency and shape parameters [-] (default 5 and 2).
    compression_ratio : float
        Geometric compression ratio [-] (default 10).
    polytropic_n : float
        Polytropic exponent of compression and expansion [-] (default 1.3).
    p_max : float
        Maximum gauge pressure of the returned curve [Pa] (default 3 MPa).
    p_atm : float
        Atmospheric pressure [Pa].
    p_intake, p_exhaust : float
        Gauge pressures during intake and exhaust strokes [Pa]
        (default -5 kPa and +10 kPa).
    intake_valve_closing : float
        IVC angle [rad], in [-2 pi + overlap/2, start_of_combustion)
        (default -150 deg = 30 deg after BDC).
    exhaust_valve_opening : float
        EVO angle [rad] (default 140 deg = 40 deg before BDC).
    blowdown_duration : float
        Duration of the blow-down blend after EVO [rad] (default 60 deg).
    overlap_duration : float
        Duration of the exhaust -> intake blend centred on the gas-exchange
        TDC at 2 pi [rad] (default 40 deg).
    geometry : EngineGeometry
        Engine geometry.
    n_points : int
        Number of uniformly spaced samples on [0, 4 pi) (default 14400,
        i.e. 0.05 deg).
    full_output : bool
        If True also return a dict with ``heat_release`` (apparent heat
        released per cycle Q_in [J]), ``scale`` (final multiplicative
        correction, 1 to round-off) and ``peak_angle`` [rad].

    Returns
    -------
    phi : ndarray, shape (n_points,)
        Crank angles [rad], uniform on [0, 4 pi), phi[0] = 0 (firing TDC).
    p : ndarray, shape (n_points,)
        Gauge pressure [Pa] with ``p.max() == p_max``.
    info : dict, optional
        Only if ``full_output``.

    Raises
    ------
    ValueError
        For inconsistent valve/combustion timing or if ``p_max`` is below the
        motored (no combustion) peak pressure.
    """
    n_points = int(n_points)
    if n_points < 8 * K_HARMONICS:
        raise ValueError("n_points too small")
    ivc = float(intake_valve_closing)
    evo = float(exhaust_valve_opening)
    soc = float(start_of_combustion)
    _check_timing(ivc, soc, evo, burn_duration, blowdown_duration, overlap_duration)

    h = FOUR_PI / n_points
    phi = np.arange(n_points) * h
    order, ps = _cycle_order(phi, ivc)
    closed0, closed1 = _closed_cycle(
        ps, h, ivc, soc, burn_duration, wiebe_a, wiebe_m, compression_ratio, polytropic_n, p_atm, p_intake,
        geometry,
    )
    P0, P1 = _with_gas_exchange(
        ps, closed0, closed1, evo, blowdown_duration, overlap_duration, p_intake, p_exhaust
    )
    q_in = _heat_release_for_peak(P0, P1, p_max)
    p_sorted = P0 + q_in * P1
    scale = p_max / float(p_sorted.max())
    p_sorted = p_sorted * scale

    p = np.empty_like(p_sorted)
    p[order] = p_sorted
    if full_output:
        info = {
            "heat_release": q_in,
            "scale": scale,
            "peak_angle": float(phi[int(np.argmax(p))]),
        }
        return phi, p, info
    return phi, p


def _check_timing(
    ivc: float, soc: float, evo: float, burn_duration: float, blowdown_duration: float, overlap_duration: float
) -> None:
    """Raise ValueError for inconsistent valve and combustion timing (angles in rad)."""
    half_ov = 0.5 * float(overlap_duration)
    if not (-TWO_PI + half_ov <= ivc < soc < evo):
        raise ValueError("need -2pi + overlap/2 <= IVC < start_of_combustion < EVO")
    if not (evo + blowdown_duration <= TWO_PI - half_ov):
        raise ValueError("blow-down must end before the valve overlap starts")
    if burn_duration <= 0 or blowdown_duration <= 0 or overlap_duration <= 0:
        raise ValueError("durations must be positive")


def _cycle_order(phi: np.ndarray, ivc: float) -> tuple[np.ndarray, np.ndarray]:
    """Sort the grid by the cycle angle psi in [ivc, ivc + 4 pi), increasing from IVC.

    Returns the permutation ``order`` and ``psi[order]`` [rad].
    """
    psi = np.where(phi >= ivc + FOUR_PI, phi - FOUR_PI, phi)
    psi = np.where(psi < ivc, psi + FOUR_PI, psi)
    order = np.argsort(psi, kind="stable")
    return order, psi[order]


def _closed_cycle(
    ps: np.ndarray,
    h: float,
    ivc: float,
    soc: float,
    burn_duration: float,
    wiebe_a: float,
    wiebe_m: float,
    compression_ratio: float,
    polytropic_n: float,
    p_atm: float,
    p_intake: float,
    geometry: EngineGeometry,
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-cycle gauge pressure, affine in the heat release: ``P0 + Q_in P1``.

    The integrating-factor solution of the single-zone first law from IVC (module
    docstring of :mod:`moreau.problems.piston.pressure`) on the sorted cycle angles
    ``ps`` [rad] of step ``h``; ``P0`` [Pa] is the motored pressure, ``P1`` [Pa/J] the
    pressure per joule of apparent heat release.
    """
    vol = geometry.volume(ps, compression_ratio)
    v_ivc = float(geometry.volume(ivc, compression_ratio))
    n = float(polytropic_n)

    # Wiebe burn rate dx_b/dpsi [1/rad]
    u = np.clip((ps - soc) / burn_duration, 0.0, None)
    dxb = wiebe_a * (wiebe_m + 1.0) / burn_duration * u**wiebe_m * np.exp(-wiebe_a * u ** (wiebe_m + 1.0))

    # closed cycle (absolute pressure) = P0 + Q P1
    p_ivc_abs = p_atm + p_intake
    vn = vol**n
    integral = _cumtrapz(vol ** (n - 1.0) * dxb, h)
    # the first grid point lies at most one step after IVC; the Wiebe rate is
    # zero there (IVC < SOC), so the integral from IVC equals the one from ps[0]
    # whenever ps[0] <= soc.
    closed0 = p_ivc_abs * v_ivc**n / vn - p_atm
    closed1 = (n - 1.0) * integral / vn
    return closed0, closed1


def _with_gas_exchange(
    ps: np.ndarray,
    closed0: np.ndarray,
    closed1: np.ndarray,
    evo: float,
    blowdown_duration: float,
    overlap_duration: float,
    p_intake: float,
    p_exhaust: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Blend the closed cycle into the open one (blow-down after EVO, then the
    exhaust -> intake overlap around 2 pi); returns ``(P0, P1)`` as for
    :func:`_closed_cycle`, over the whole cycle."""
    half_ov = 0.5 * float(overlap_duration)
    # open cycle: exhaust -> (overlap at 2 pi) -> intake, as a function of psi
    s_ov = _smootherstep((ps - (TWO_PI - half_ov)) / overlap_duration)
    p_open = p_exhaust + (p_intake - p_exhaust) * s_ov
    s_bd = _smootherstep((ps - evo) / blowdown_duration)
    P0 = (1.0 - s_bd) * closed0 + s_bd * p_open
    P1 = (1.0 - s_bd) * closed1
    return P0, P1


def _heat_release_for_peak(P0: np.ndarray, P1: np.ndarray, p_max: float) -> float:
    """Heat release Q_in [J] whose curve ``P0 + Q_in P1`` peaks at ``p_max`` [Pa]:
    ``min over P1 > 0 of (p_max - P0) / P1``."""
    pos = P1 > 0.0
    if not np.any(pos):
        raise ValueError("no heat release on the grid")
    if np.any(P0[~pos] > p_max):
        raise ValueError("p_max is below the pressure without combustion")
    q_in = float(np.min((p_max - P0[pos]) / P1[pos]))
    if q_in < 0.0:
        raise ValueError("p_max is below the motored peak pressure")
    return q_in
