r"""Synthetic in-cylinder gas pressure for the piston - connecting rod - crankshaft problem.

The paper by Awrejcewicz & Kudra models the piston - connecting rod - crankshaft
system of a single-cylinder four-stroke engine as an inverted triple pendulum
driven by the gas pressure :math:`p(\varphi_1)` and represents the measured
pressure by a Fourier series with :math:`K = 25` harmonics of
:math:`\varphi_1/2`.  The measured data are not public, so this module builds a
documented **synthetic** spark-ignition pressure curve, fits the Fourier series
and calibrates the curve so that the engine's self-excited steady speed is
2000 rpm.

Conventions
-----------
* :math:`\varphi_1` [rad] is the absolute crank angle measured from the
  cylinder axis; :math:`\varphi_1 = 0` (mod :math:`4\pi`) is the *firing* top
  dead centre (TDC).  The cycle has period :math:`4\pi` (720 deg):

  ==========================================  =================
  :math:`\varphi_1` interval                  stroke
  ==========================================  =================
  :math:`[-\pi, 0]` (= :math:`[3\pi, 4\pi]`)  compression
  :math:`[0, \pi]`                            expansion (power)
  :math:`[\pi, 2\pi]`                         exhaust
  :math:`[2\pi, 3\pi]`                        intake
  ==========================================  =================

* Pressures are **gauge** pressures [Pa] (absolute minus atmospheric
  :math:`p_{atm} = 101325` Pa) unless stated otherwise.
* Ideal (centred) slider-crank kinematics.  The crank pin is at
  :math:`(l_1\sin\varphi_1, l_1\cos\varphi_1)` relative to the crank centre,
  the rod angle satisfies :math:`l_1\sin\varphi_1 + l_2\sin\varphi_2 = 0`,
  i.e. :math:`\varphi_2 = -\arcsin(\lambda\sin\varphi_1)`,
  :math:`\lambda = l_1/l_2`, and the piston pin height above the crank axis is

  .. math:: y(\varphi_1) = l_1\cos\varphi_1 + \sqrt{l_2^2 - l_1^2\sin^2\varphi_1}.

* Cylinder volume :math:`V = V_c + A\,(y_{TDC} - y)`, :math:`A = \pi d^2/4`,
  :math:`V_c = V_s/(\varepsilon - 1)`, :math:`V_s = 2 l_1 A`.
* Gas force on the piston pin: :math:`F = p\,A`, along the cylinder axis
  towards the crank.  Indicated work per cycle

  .. math:: W_{ind} = \oint p\,dV = -A\int_0^{4\pi} p(\varphi_1)\,
            \frac{dy}{d\varphi_1}\,d\varphi_1 ,

  positive when the gas does net work (expansion: :math:`y` decreases).

Pressure model ("zero-dimensional", single zone)
------------------------------------------------
Closed part of the cycle (intake valve closing IVC -> exhaust valve opening
EVO).  The first law with an apparent (net) heat release :math:`Q_{in}\,
x_b(\varphi)` and a polytropic exponent :math:`n` in place of the ratio of
specific heats (the usual single-zone "apparent heat release" model, where
:math:`n` lumps wall heat losses) reads

.. math:: \frac{dp}{d\varphi} = -\,n\,\frac{p}{V}\frac{dV}{d\varphi}
          + \frac{n-1}{V}\,Q_{in}\,\frac{dx_b}{d\varphi}.

It is linear and is integrated exactly with the integrating factor
:math:`V^n`:

.. math:: p(\varphi)\,V(\varphi)^n = p_{IVC}\,V_{IVC}^n
          + (n-1)\,Q_{in}\int_{\varphi_{IVC}}^{\varphi} V^{\,n-1}
          \frac{dx_b}{d\varphi'}\,d\varphi'

(absolute pressure; the integral is evaluated by cumulative trapezoidal
quadrature on the output grid).  The mass fraction burned is the Wiebe function

.. math:: x_b = 1 - \exp\!\left[-a\left(\frac{\varphi-\varphi_{s}}
          {\Delta\varphi_b}\right)^{m+1}\right],\qquad \varphi\ge\varphi_s,

with :math:`a = 5`, :math:`m = 2`, burn duration :math:`\Delta\varphi_b =
45` deg and start of combustion (SOC) :math:`\varphi_s` before firing TDC.

Gas exchange (near atmospheric).  Intake pressure :math:`p_{in} = -5` kPa
gauge, exhaust :math:`p_{ex} = +10` kPa gauge.  Blow-down after EVO is a
C2-smooth blend (quintic "smootherstep") from the closed-cycle pressure to
:math:`p_{ex}` over 60 deg; the valve-overlap transition :math:`p_{ex}\to
p_{in}` around the gas-exchange TDC (:math:`2\pi`) is a smootherstep over
40 deg.  Defaults: IVC = 30 deg after BDC (:math:`\varphi_1 = -150` deg),
EVO = 40 deg before BDC (:math:`\varphi_1 = 140` deg).

Peak pressure.  The heat release :math:`Q_{in}` (the engine load) is
chosen in closed form so that the maximum gauge pressure of the curve equals
:math:`p_{max} = 3` MPa; afterwards the curve is multiplied by
:math:`p_{max}/\max p` (a factor equal to 1 to round-off) so that the maximum
is exact.  Setting the peak through the heat release rather than multiplying a
fixed curve keeps the motored compression pressure and the gas-exchange
pressures physical (a pure multiplication would scale them too).  Since the
pressure is affine in :math:`Q_{in}`, :math:`p = P_0 + Q_{in} P_1` with
:math:`P_1\ge 0`, the required value is
:math:`Q_{in} = \min_{P_1>0} (p_{max} - P_0)/P_1`.

Calibration
-----------
The engine is self-excited: its steady speed is where the indicated work per
cycle equals the brake work :math:`4\pi\bar M_0` (:math:`\bar M_0 = 9.807`
N m) plus the viscous joint-damping work.  At constant crank speed
:math:`\omega` the damping work per cycle is

.. math:: W_d = \omega\int_0^{4\pi}\left[\bar c_1 + \bar c_2 (g - 1)^2
          + \bar c_3 g^2\right]d\varphi_1,\qquad
          g = \frac{d\varphi_2}{d\varphi_1}
          = -\frac{\lambda\cos\varphi_1}{\sqrt{1-\lambda^2\sin^2\varphi_1}},

(:math:`\varphi_3 \equiv 0`), about 13.8 J at 2000 rpm with
:math:`\bar c_1 = 0.00432` N m s, :math:`\bar c_2 = \bar c_3 = 0.2\bar c_1`.
With :math:`p_{max}` held at 3 MPa, the **start of combustion**
:math:`\varphi_s` (ignition timing, the most physical free parameter) is
found with :func:`scipy.optimize.brentq` such that :math:`W_{ind}` of the
:math:`K = 25` Fourier representation closes the balance at 2000 rpm.  The
result is :math:`\varphi_s \approx -21.6` deg (SOC 21.6 deg before firing TDC,
peak pressure about 9 deg after TDC, :math:`W_{ind} \approx 137.0` J,
IMEP :math:`\approx 0.34` MPa -- a part-load operating point; see
:data:`CALIBRATED_SOC_DEG`).  At fixed :math:`p_{max}` a later start of
combustion needs more heat release and gives more work,
:math:`dW_{ind}/d\varphi_s \approx 5.8` J/deg, so 0.05 J corresponds to
about 0.01 deg of ignition timing.

Fourier fit error of the calibrated curve (K = 25, on the 14400-point grid):
max abs about 0.8 % and RMS about 0.2 % of :math:`p_{max}`; the maximum of the
series is about 0.6 % below 3 MPa (see :func:`fourier_fit_error`).

All angles are in rad, lengths in m, pressures in Pa, work in J, torques in
N m, damping coefficients in N m s and angular velocities in rad/s.
"""

from __future__ import annotations

import cmath
import functools
import logging
import math
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.optimize import brentq

logger = logging.getLogger(__name__)

__all__ = [
    "P_ATM",
    "P_MAX",
    "K_HARMONICS",
    "M0_BRAKE",
    "C1_CRANK",
    "OMEGA_2000RPM",
    "CALIBRATED_SOC_DEG",
    "EngineGeometry",
    "DEFAULT_GEOMETRY",
    "FourierPressure",
    "WorkBalance",
    "CalibrationResult",
    "synthetic_pressure_curve",
    "fit_fourier",
    "fourier_fit_error",
    "indicated_work",
    "damping_work",
    "cycle_work_balance",
    "calibrate",
    "calibrated_pressure",
]

TWO_PI = 2.0 * math.pi
FOUR_PI = 4.0 * math.pi

#: Atmospheric pressure [Pa].
P_ATM = 101325.0
#: Maximum gauge pressure of the cycle [Pa].
P_MAX = 3.0e6
#: Number of harmonics of phi1/2 in the Fourier representation [-].
K_HARMONICS = 25
#: Mean brake (load) torque [N m].
M0_BRAKE = 9.807
#: Viscous damping coefficient of the crank-ground joint [N m s].
C1_CRANK = 0.00432
#: Crank speed 2000 rpm [rad/s].
OMEGA_2000RPM = TWO_PI * 2000.0 / 60.0
#: Default grid size of the synthetic curve (0.05 deg resolution) [-].
N_POINTS_DEFAULT = 14400
#: Start of combustion found by :func:`calibrate` with all defaults [deg]
#: (re-derived in the tests; firing TDC = 0, negative = before TDC).
CALIBRATED_SOC_DEG = -21.6133


# --------------------------------------------------------------------------
# Geometry / kinematics
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class EngineGeometry:
    """Slider-crank geometry.

    Parameters
    ----------
    bore : float
        Cylinder bore d [m].
    crank_radius : float
        Crank radius l1 [m] (stroke = 2 l1).
    rod_length : float
        Connecting-rod length l2 [m] (pin to pin).
    """

    bore: float = 0.08
    crank_radius: float = 0.04
    rod_length: float = 0.15

    @property
    def area(self) -> float:
        """Piston area A = pi d^2 / 4 [m^2]."""
        return math.pi * self.bore**2 / 4.0

    @property
    def stroke(self) -> float:
        """Stroke 2 l1 [m]."""
        return 2.0 * self.crank_radius

    @property
    def swept_volume(self) -> float:
        """Swept (displacement) volume A * stroke [m^3]."""
        return self.area * self.stroke

    @property
    def lam(self) -> float:
        """Crank-to-rod ratio lambda = l1 / l2 [-]."""
        return self.crank_radius / self.rod_length

    def pin_height(self, phi1):
        """Piston-pin height above the crank axis y(phi1) [m].

        Parameters
        ----------
        phi1 : float or array_like
            Crank angle [rad].
        """
        l1, l2 = self.crank_radius, self.rod_length
        s = np.sin(phi1)
        return l1 * np.cos(phi1) + np.sqrt(l2 * l2 - (l1 * s) ** 2)

    def pin_height_derivative(self, phi1):
        """dy/dphi1 [m/rad] of :meth:`pin_height`."""
        l1, l2 = self.crank_radius, self.rod_length
        s = np.sin(phi1)
        c = np.cos(phi1)
        return -l1 * s - l1 * l1 * s * c / np.sqrt(l2 * l2 - (l1 * s) ** 2)

    def rod_angle(self, phi1):
        """Absolute rod angle phi2 = -arcsin(lambda sin phi1) [rad]."""
        return -np.arcsin(self.lam * np.sin(phi1))

    def rod_angle_derivative(self, phi1):
        """dphi2/dphi1 = -lambda cos phi1 / sqrt(1 - lambda^2 sin^2 phi1) [-]."""
        lam = self.lam
        s = np.sin(phi1)
        return -lam * np.cos(phi1) / np.sqrt(1.0 - (lam * s) ** 2)

    def volume(self, phi1, compression_ratio: float = 10.0):
        """Cylinder volume V = Vc + A (y_TDC - y) [m^3].

        Parameters
        ----------
        phi1 : float or array_like
            Crank angle [rad].
        compression_ratio : float
            Geometric compression ratio (Vs + Vc) / Vc [-]; Vc = Vs / (eps - 1).
        """
        vc = self.swept_volume / (compression_ratio - 1.0)
        y_tdc = self.crank_radius + self.rod_length
        return vc + self.area * (y_tdc - self.pin_height(phi1))


#: Geometry of the paper's engine (d = 0.08 m, l1 = 0.04 m, l2 = 0.15 m).
DEFAULT_GEOMETRY = EngineGeometry()


# --------------------------------------------------------------------------
# Synthetic pressure curve
# --------------------------------------------------------------------------
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
):
    """Synthetic four-stroke spark-ignition gauge-pressure curve p(phi1).

    See the module docstring for the model.  All angles are crank angles
    relative to the firing TDC (negative = before TDC).

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
    half_ov = 0.5 * float(overlap_duration)
    if not (-TWO_PI + half_ov <= ivc < soc < evo):
        raise ValueError("need -2pi + overlap/2 <= IVC < start_of_combustion < EVO")
    if not (evo + blowdown_duration <= TWO_PI - half_ov):
        raise ValueError("blow-down must end before the valve overlap starts")
    if burn_duration <= 0 or blowdown_duration <= 0 or overlap_duration <= 0:
        raise ValueError("durations must be positive")

    h = FOUR_PI / n_points
    phi = np.arange(n_points) * h
    # cycle angle psi in [ivc, ivc + 4 pi), increasing from IVC
    psi = np.where(phi >= ivc + FOUR_PI, phi - FOUR_PI, phi)
    psi = np.where(psi < ivc, psi + FOUR_PI, psi)
    order = np.argsort(psi, kind="stable")
    ps = psi[order]

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

    # open cycle: exhaust -> (overlap at 2 pi) -> intake, as a function of psi
    s_ov = _smootherstep((ps - (TWO_PI - half_ov)) / overlap_duration)
    p_open = p_exhaust + (p_intake - p_exhaust) * s_ov
    s_bd = _smootherstep((ps - evo) / blowdown_duration)
    P0 = (1.0 - s_bd) * closed0 + s_bd * p_open
    P1 = (1.0 - s_bd) * closed1

    pos = P1 > 0.0
    if not np.any(pos):
        raise ValueError("no heat release on the grid")
    if np.any(P0[~pos] > p_max):
        raise ValueError("p_max is below the pressure without combustion")
    q_in = float(np.min((p_max - P0[pos]) / P1[pos]))
    if q_in < 0.0:
        raise ValueError("p_max is below the motored peak pressure")
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


# --------------------------------------------------------------------------
# Fourier representation
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class FourierPressure:
    r"""Truncated Fourier series in phi1/2 (period 4 pi).

    .. math:: p(\varphi_1) = a_0 + \sum_{k=1}^{K}\left[a_k\cos\frac{k\varphi_1}{2}
              + b_k\sin\frac{k\varphi_1}{2}\right]

    Parameters
    ----------
    a0 : float
        Mean value [Pa].
    a, b : ndarray, shape (K,)
        Cosine and sine coefficients for k = 1..K [Pa] (stored read-only).
    fit_max_error : float
        Max abs deviation from the fitted samples [Pa] (nan if unknown).
    fit_rms_error : float
        RMS deviation from the fitted samples [Pa] (nan if unknown).

    Notes
    -----
    Scalar evaluation (Python float or numpy scalar) uses a complex Horner
    scheme in z = exp(i phi1/2) with pre-built Python coefficient tuples and
    returns a Python ``float`` (about 1-2 us).  Arrays are evaluated with numpy
    and return an ndarray of the input shape.
    """

    a0: float
    a: np.ndarray
    b: np.ndarray
    fit_max_error: float = float("nan")
    fit_rms_error: float = float("nan")
    _c: tuple = field(init=False, repr=False)
    _dc: tuple = field(init=False, repr=False)
    _hk: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        a = np.array(self.a, dtype=float).ravel()
        b = np.array(self.b, dtype=float).ravel()
        if a.shape != b.shape:
            raise ValueError("a and b must have the same length")
        a.setflags(write=False)
        b.setflags(write=False)
        hk = 0.5 * np.arange(1, a.size + 1, dtype=float)
        hk.setflags(write=False)
        object.__setattr__(self, "a0", float(self.a0))
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "_hk", hk)
        # p - a0 = Re sum_k (a_k - i b_k) z^k ; p' = Re sum_k i k/2 (a_k - i b_k) z^k
        c = [complex(ak, -bk) for ak, bk in zip(a, b)]
        dc = [1j * hkk * ck for hkk, ck in zip(hk, c)]
        object.__setattr__(self, "_c", tuple(reversed(c)))
        object.__setattr__(self, "_dc", tuple(reversed(dc)))

    @property
    def K(self) -> int:
        """Number of harmonics [-]."""
        return int(self.a.size)

    @staticmethod
    def _horner(coeffs, phi):
        z = cmath.rect(1.0, 0.5 * phi)
        s = 0j
        for ck in coeffs:
            s = s * z + ck
        return (s * z).real

    def __call__(self, phi1):
        """Gauge pressure p(phi1) [Pa].

        Parameters
        ----------
        phi1 : float or array_like
            Crank angle [rad].

        Returns
        -------
        float or ndarray
            Python float for scalar input, else an array of the input shape.
        """
        if isinstance(phi1, (float, int)):
            return self.a0 + self._horner(self._c, phi1)
        x = np.asarray(phi1, dtype=float)
        if x.ndim == 0:
            return self.a0 + self._horner(self._c, float(x))
        t = np.multiply.outer(x, self._hk)
        return self.a0 + np.cos(t) @ self.a + np.sin(t) @ self.b

    def derivative(self, phi1):
        """dp/dphi1 [Pa/rad]; same calling conventions as :meth:`__call__`."""
        if isinstance(phi1, (float, int)):
            return self._horner(self._dc, phi1)
        x = np.asarray(phi1, dtype=float)
        if x.ndim == 0:
            return self._horner(self._dc, float(x))
        t = np.multiply.outer(x, self._hk)
        return np.cos(t) @ (self._hk * self.b) - np.sin(t) @ (self._hk * self.a)

    def maximum(self, n_grid: int = 7200):
        """Maximum of the series and its location.

        Parameters
        ----------
        n_grid : int
            Number of uniform samples on [0, 4 pi) before local refinement.

        Returns
        -------
        p_peak : float
            Maximum gauge pressure [Pa].
        phi_peak : float
            Its crank angle in [0, 4 pi) [rad].
        """
        phi = np.arange(n_grid) * (FOUR_PI / n_grid)
        i = int(np.argmax(self(phi)))
        lo, hi = phi[i] - FOUR_PI / n_grid, phi[i] + FOUR_PI / n_grid
        try:
            x = brentq(self.derivative, lo, hi, xtol=1e-13)
        except ValueError:
            x = float(phi[i])
        return float(self(x)), float(x % FOUR_PI)


def _uniform_period(phi: np.ndarray) -> bool:
    n = phi.size
    if n < 2:
        return False
    h = FOUR_PI / n
    d = np.diff(phi)
    return bool(np.allclose(d, h, rtol=0.0, atol=1e-9 * h))


def _design(phi: np.ndarray, K: int) -> np.ndarray:
    t = np.multiply.outer(phi, 0.5 * np.arange(1, K + 1))
    return np.hstack([np.ones((phi.size, 1)), np.cos(t), np.sin(t)])


@functools.lru_cache(maxsize=8)
def _uniform_matrices(n: int, phi0: float, K: int):
    """Design matrix (n, 2K+1) and projection matrix (2K+1, n) of a uniform grid."""
    phi = phi0 + np.arange(n) * (FOUR_PI / n)
    d = _design(phi, K)
    m = d.T * (2.0 / n)
    m[0] *= 0.5
    d.setflags(write=False)
    m.setflags(write=False)
    return d, m


def fit_fourier(phi, p, K: int = K_HARMONICS) -> FourierPressure:
    """Fit the K-harmonic Fourier series in phi1/2 to samples.

    Least squares.  On a uniform grid covering exactly one period 4 pi
    (n > 2K samples, as returned by :func:`synthetic_pressure_curve`) this is
    evaluated as the discrete orthogonal projection (identical result, faster);
    otherwise :func:`numpy.linalg.lstsq` is used.

    Parameters
    ----------
    phi : array_like, shape (n,)
        Crank angles [rad].
    p : array_like, shape (n,)
        Gauge pressures [Pa].
    K : int
        Number of harmonics (default 25).

    Returns
    -------
    FourierPressure
        With ``fit_max_error`` and ``fit_rms_error`` [Pa] at the samples.
    """
    phi = np.asarray(phi, dtype=float).ravel()
    p = np.asarray(p, dtype=float).ravel()
    if phi.shape != p.shape:
        raise ValueError("phi and p must have the same shape")
    if phi.size < 2 * K + 1:
        raise ValueError("need at least 2K+1 samples")
    if phi.size > 2 * K + 1 and _uniform_period(phi):
        d, m = _uniform_matrices(phi.size, float(phi[0]), int(K))
        coef = m @ p
        resid = d @ coef - p
    else:
        m = _design(phi, K)
        coef, *_ = np.linalg.lstsq(m, p, rcond=None)
        resid = m @ coef - p
    return FourierPressure(
        a0=coef[0],
        a=coef[1 : K + 1],
        b=coef[K + 1 :],
        fit_max_error=float(np.max(np.abs(resid))),
        fit_rms_error=float(np.sqrt(np.mean(resid**2))),
    )


def fourier_fit_error(pressure: FourierPressure, phi, p, reference: float | None = None) -> dict:
    """Deviation of a Fourier series from sampled pressures.

    Parameters
    ----------
    pressure : FourierPressure
        Series to check.
    phi, p : array_like
        Sample angles [rad] and gauge pressures [Pa].
    reference : float, optional
        Pressure used for the relative errors [Pa]; default ``max(p)``.

    Returns
    -------
    dict
        ``max_abs`` and ``rms`` [Pa], ``max_rel`` and ``rms_rel`` (divided by
        ``reference``) [-], ``series_max`` [Pa] and ``series_max_angle`` [rad].
    """
    phi = np.asarray(phi, dtype=float)
    p = np.asarray(p, dtype=float)
    ref = float(np.max(p)) if reference is None else float(reference)
    r = pressure(phi) - p
    pk, xk = pressure.maximum()
    max_abs = float(np.max(np.abs(r)))
    rms = float(np.sqrt(np.mean(r * r)))
    return {
        "max_abs": max_abs,
        "rms": rms,
        "max_rel": max_abs / ref,
        "rms_rel": rms / ref,
        "series_max": pk,
        "series_max_angle": xk,
    }


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
