"""The K-harmonic Fourier series of the gas pressure and its least-squares fit.

The paper represents the measured pressure by a Fourier series with K = 25 harmonics of
phi1/2 (period 4 pi, one 720 deg engine cycle); :func:`fit_fourier` fits that series to
the samples of the synthetic curve (:mod:`moreau.problems.piston.pressure_curve`) and
:func:`fourier_fit_error` measures how far the series departs from them. The model and
its conventions are described in :mod:`moreau.problems.piston.pressure`.

Angles in rad, pressures in Pa (gauge).
"""

from __future__ import annotations

import cmath
import functools
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from .geometry import FOUR_PI
from .pressure_curve import K_HARMONICS

__all__ = ["FourierPressure", "fit_fourier", "fourier_fit_error"]


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

    def __call__(self, phi1: ArrayLike) -> np.ndarray | float:
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

    def derivative(self, phi1: ArrayLike) -> np.ndarray | float:
        """dp/dphi1 [Pa/rad]; same calling conventions as :meth:`__call__`."""
        if isinstance(phi1, (float, int)):
            return self._horner(self._dc, phi1)
        x = np.asarray(phi1, dtype=float)
        if x.ndim == 0:
            return self._horner(self._dc, float(x))
        t = np.multiply.outer(x, self._hk)
        return np.cos(t) @ (self._hk * self.b) - np.sin(t) @ (self._hk * self.a)

    def maximum(self, n_grid: int = 7200) -> tuple[float, float]:
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


def fit_fourier(phi: ArrayLike, p: ArrayLike, K: int = K_HARMONICS) -> FourierPressure:
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


def fourier_fit_error(pressure: FourierPressure, phi: ArrayLike, p: ArrayLike,
                      reference: float | None = None) -> dict:
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
