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

Modules
-------
This module holds the model's description and gathers its parts, which live in
modules named by their job (every name is importable from here too):

* :mod:`moreau.problems.piston.geometry` -- slider-crank kinematics and volume
  (:class:`EngineGeometry`);
* :mod:`moreau.problems.piston.pressure_curve` -- the synthetic curve
  (:func:`synthetic_pressure_curve`);
* :mod:`moreau.problems.piston.fourier_fit` -- the K-harmonic series and its fit
  (:class:`FourierPressure`, :func:`fit_fourier`, :func:`fourier_fit_error`);
* :mod:`moreau.problems.piston.calibration` -- the cycle work balance and the
  calibration of the start of combustion (:func:`cycle_work_balance`,
  :func:`calibrate`, :func:`calibrated_pressure`).
"""

from __future__ import annotations

# ``x as x``: names defined in this module before its split, still importable from here
from .calibration import (
    C1_CRANK,
    M0_BRAKE,
    OMEGA_2000RPM,
    CalibrationResult,
    WorkBalance,
    calibrate,
    calibrated_pressure,
    cycle_work_balance,
    damping_work,
    indicated_work,
)
from .calibration import _work_weights as _work_weights
from .fourier_fit import FourierPressure, fit_fourier, fourier_fit_error
from .fourier_fit import _design as _design
from .fourier_fit import _uniform_matrices as _uniform_matrices
from .fourier_fit import _uniform_period as _uniform_period
from .geometry import DEFAULT_GEOMETRY, EngineGeometry
from .geometry import FOUR_PI as FOUR_PI
from .geometry import TWO_PI as TWO_PI
from .pressure_curve import CALIBRATED_SOC_DEG, K_HARMONICS, P_ATM, P_MAX, synthetic_pressure_curve
from .pressure_curve import N_POINTS_DEFAULT as N_POINTS_DEFAULT
from .pressure_curve import _cumtrapz as _cumtrapz
from .pressure_curve import _smootherstep as _smootherstep

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
