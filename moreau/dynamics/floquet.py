"""Periodic orbits on a section: period detection, fixed points, Floquet multipliers.

The multipliers are the eigenvalues of the monodromy matrix ``dP^p/dx`` of the section map
P (for a forced system the stroboscopic map :class:`~moreau.dynamics.maps.TimeMap` over
one forcing period), at a point of the period-p orbit, computed by finite differences of
the map. The multipliers do not depend on the section chosen (all sections give conjugate
maps); impacts enter through the map itself.

Step size and perturbation size
-------------------------------
The time-stepper has no event detection: an impact happens at the first step whose
midpoint penetrates, so the post-impact state of the *discrete* map is a sawtooth in the
initial state with teeth of height ~ (1 + e)|v|h and width ~ h|v| (in the coordinate
along the flow). A finite difference over eps therefore carries an error ~ (1 + e)|v|h /
eps besides the truncation error O(eps²) of central differences: eps must be large
compared with h|v| and small compared with the curvature scale of the map. The tests and
the notebook show both dependences (a ladder of h at fixed eps, a ladder of eps at fixed
h).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from moreau.core.validation import as_vector

from .maps import jacobian_fd

__all__ = ["FloquetResult", "detect_period", "find_fixed_point", "floquet_multipliers"]

log = logging.getLogger(__name__)


@dataclass
class FloquetResult:
    """Monodromy of a period-p orbit of a section map.

    Attributes
    ----------
    x : ndarray, shape (k,)
        The point of the orbit on the section.
    period : int
        p, in iterates of the section map.
    monodromy : ndarray, shape (k, k)
        ``d(P^p)/dx`` at x.
    multipliers : ndarray of complex, shape (k,)
        Its eigenvalues, largest modulus first.
    eps : ndarray, shape (k,)
        The perturbations used.
    """

    x: np.ndarray
    period: int
    monodromy: np.ndarray
    multipliers: np.ndarray
    eps: np.ndarray

    @property
    def stable(self) -> bool:
        """All multipliers inside the unit circle."""
        return bool(np.all(np.abs(self.multipliers) < 1.0))

    @property
    def exponents(self) -> np.ndarray:
        """``log|μ|`` per map iterate divided by p (Lyapunov exponents per iterate)."""
        return np.log(np.abs(self.multipliers)) / self.period


def detect_period(points, max_period: int = 16, rtol: float = 1e-3, atol: float = 0.0,
                  n_check: int | None = None) -> int | None:
    """Smallest p with ``|x_{k+p} - x_k| <= atol + rtol·scale`` over the last points.

    Parameters
    ----------
    points : array_like, shape (K, d) or (K,)
        Successive section points (the transient already discarded).
    max_period : int
        Largest period tried.
    rtol, atol : float
        Tolerances; scale is the largest magnitude of the points per component (1 where
        it is 0). With impacts, the scheme's section points of a periodic orbit jitter by
        ``O(h·|v|)`` (the impact instant is quantized to the step grid): the tolerance must
        exceed that.
    n_check : int, optional
        Number of pairs compared (default: all ``K - p``).

    Returns
    -------
    int or None
        The period in section iterates, or None (not periodic within max_period: a
        quasi-periodic or chaotic motion, or a transient not yet over).
    """
    x = np.asarray(points, float)
    if x.ndim == 1:
        x = x[:, None]
    mag = np.abs(x).max(axis=0)
    scale = np.where(mag > 0, mag, 1.0)
    for p in range(1, max_period + 1):
        if x.shape[0] <= p:
            break
        d = np.abs(x[p:] - x[:-p])
        if n_check is not None:
            d = d[-n_check:]
        if np.all(d <= atol + rtol * scale):
            return p
    return None


def find_fixed_point(fun: Callable[[np.ndarray], np.ndarray], x0, period: int = 1, *,
                     eps: float | np.ndarray = 1e-4, tol: float = 1e-10, max_iter: int = 10,
                     scheme: str = "central") -> np.ndarray:
    """A point of a period-p orbit of the map by Newton's method on ``P^p(x) - x = 0``.

    The Jacobian is by finite differences (perturbation ``eps``); converges also to
    unstable orbits. Raises ``RuntimeError`` when it does not converge.
    """
    x = as_vector(x0, "find_fixed_point.x0").copy()

    def Pp(y):
        for _ in range(period):
            y = fun(y)
        return y

    for it in range(max_iter):
        r = Pp(x) - x
        nr = float(np.linalg.norm(r))
        log.debug("find_fixed_point: iteration %d, residual %.3e", it, nr)
        if nr <= tol * max(1.0, float(np.linalg.norm(x))):
            return x
        J = jacobian_fd(Pp, x, eps, scheme=scheme)
        x = x - np.linalg.solve(J - np.eye(x.shape[0]), r)
    r = float(np.linalg.norm(Pp(x) - x))
    if r <= tol * max(1.0, float(np.linalg.norm(x))):
        return x
    raise RuntimeError(f"find_fixed_point: residual {r:.3e} after {max_iter} Newton iterations")


def floquet_multipliers(fun: Callable[[np.ndarray], np.ndarray], x, period: int = 1, *,
                        eps: float | np.ndarray = 1e-4, scheme: str = "central") -> FloquetResult:
    """Floquet multipliers of a period-p orbit through x of the section map ``fun``.

    Parameters
    ----------
    fun : callable ``fun(x) -> (k,)``
        The section map, e.g. a :class:`~moreau.dynamics.maps.TimeMap` of one forcing
        period.
    x : array_like, shape (k,)
        A point of the orbit (see :func:`find_fixed_point`).
    period : int
        p: iterates of ``fun`` per orbit.
    eps : float or array_like (k,)
        Perturbation per coordinate (see the module docstring for its choice).
    scheme : {"central", "forward"}
        Finite-difference scheme.

    Returns
    -------
    FloquetResult
    """
    x = as_vector(x, "floquet_multipliers.x")
    eps_v = np.broadcast_to(np.asarray(eps, float), x.shape).copy()

    def Pp(y):
        for _ in range(period):
            y = fun(y)
        return y

    J = jacobian_fd(Pp, x, eps_v, scheme=scheme)
    mu = np.linalg.eigvals(J)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    return FloquetResult(x=x, period=int(period), monodromy=J, multipliers=mu, eps=eps_v)
