"""Lyapunov exponents of a non-smooth system from its simulated trajectories.

Two methods, both on :func:`moreau.simulate` (any scene, impacts included):

* :func:`largest_lyapunov`: two nearby trajectories, the second renormalized to the
  distance ``d0`` from the first after every ``interval`` (Benettin et al. 1976).
* :func:`lyapunov_spectrum`: the Jacobian of the discrete interval map (``interval`` of
  time, many steps) by forward finite differences applied to an orthonormal frame, QR
  re-orthonormalization after every interval (Benettin et al. 1980; Shimada & Nagashima
  1979). The tangent dynamics are *not* linearized analytically: the frame columns are
  nearby trajectories of the scheme itself, so an impact enters as the difference of
  two impacting trajectories — which tends to the saltation (transition) matrix of
  Müller (1995) when ``h·|v| << delta << 1``, and the sum of the exponents contains the
  contraction ``2 ln e`` of every impact. Checked on the ball on a vibrating table
  (``tests/test_dynamics_lyapunov.py``: the sum matches -c + 2 ln e per impact to 0.3 %).
  Known limit (our reading of the measurements below): every impact adds to every
  frame column a relative error of order ``h·|v| / delta`` (the perturbed trajectory's
  impact instant is quantized to the step grid), while a delta large enough to make it
  small is outside the linear range of the weaker directions (their columns are the
  small differences left after the largest direction's growth is removed). On the
  chaotic triple pendulum (1.7 impacts per second, largest exponent ≈ 2.5 1/s) no step
  and delta tried gives a window between the two: the sum of the spectrum is −1.42,
  +2.56, +0.25, +0.39 1/s at (T/h, delta) = (400, 1e-4), (1600, 3e-2), (25600, 3e-3),
  (25600, 1e-3) against the flow's contraction −2.8 to −2.9 1/s, the smaller exponents
  being biased upward, while the largest exponent
  is robust. Use :func:`~moreau.dynamics.lyapunov_spectrum_tangent`
  (:mod:`moreau.dynamics.tangent`) there: the variational equation along the simulated
  trajectory with the saltation matrix of Müller (1995) at every logged impact, no
  perturbation size. On the triple pendulum at T/h = 1600 its sum is the flow's
  contraction (−2.83 1/s).

The two-trajectory method has the same window, ``h·|v| << d0 << 1``, for the largest
exponent: below it both trajectories impact in the same step and the separation follows
the scheme's discrete step map (biased low), above it the separation is not linear. On
the chaotic triple pendulum, compared interval by interval with the tangent method on the
same reference trajectory (``benchmarks/lyapunov_window.py``), the window exists at
T/h = 25 600 (``h·|v|`` = 5.2e-4): d0 = 1e-2 differs from the tangent estimate by
−0.03 ± 0.05 and −0.02 ± 0.07 1/s on two segments (estimates 3.07 and 2.63 1/s), while
d0 = 1e-4 gives −0.50 ± 0.14. At T/h = 1600 (``h·|v|`` = 7.4e-3) the difference runs from
+0.21 ± 0.09 (d0 = 3e-2) through −0.11 ± 0.21 (3e-3) to −0.46 ± 0.11 1/s (1e-4): there
the estimate is whatever d0 makes it.

Distances are measured in the scaled state ``x / scale`` (default scale 1: choose
``scale`` so that position and velocity perturbations are comparable). Exponents are per
unit of the scene's time. Error bars are standard errors of the means of ``n_blocks``
consecutive blocks of intervals.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

import moreau as mo
from moreau.core.validation import as_positive, as_vector

from .maps import TimeMap, join_state, split_state

__all__ = ["LyapunovResult", "largest_lyapunov", "lyapunov_spectrum", "paired_difference"]

log = logging.getLogger(__name__)


@dataclass
class LyapunovResult:
    """Lyapunov exponents and how they converged.

    Attributes
    ----------
    exponents : ndarray, shape (k,)
        The exponents (1 / time unit), largest first.
    stderr : ndarray, shape (k,)
        Standard error from block means (NaN with fewer than 2 blocks).
    times : ndarray, shape (N,)
        End time of each interval after the transient.
    running : ndarray, shape (N, k)
        The estimate after each interval (cumulative mean).
    logs : ndarray, shape (N, k)
        log stretch per interval.
    n_impacts : int
        Impacts of the reference trajectory after the transient.
    x_final : ndarray, shape (2n,)
        Final state of the reference trajectory.
    method : str
        ``"two-trajectory"``, ``"fd-qr"`` or ``"saltation"``
        (:func:`~moreau.dynamics.lyapunov_spectrum_tangent`).
    meta : dict
        Parameters of the run (``h``, ``interval``, ...) and method-specific counters.
    """

    exponents: np.ndarray
    stderr: np.ndarray
    times: np.ndarray
    running: np.ndarray
    logs: np.ndarray
    n_impacts: int
    x_final: np.ndarray
    method: str
    meta: dict = field(default_factory=dict)

    @property
    def sum(self) -> float:
        """Sum of the exponents (mean phase-space contraction rate when k = 2n)."""
        return float(np.sum(self.exponents))


def _stats(logs: np.ndarray, interval: float, n_blocks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    N = logs.shape[0]
    running = np.cumsum(logs, axis=0) / (interval * np.arange(1, N + 1))[:, None]
    exps = running[-1]
    nb = min(n_blocks, N)
    if nb >= 2:
        blocks = np.array([b.mean(axis=0) / interval for b in np.array_split(logs, nb)])
        err = blocks.std(axis=0, ddof=1) / np.sqrt(nb)
    else:
        err = np.full(logs.shape[1], np.nan)
    return exps, err, running


def paired_difference(a: LyapunovResult, b: LyapunovResult, n_blocks: int = 10) -> tuple[float, float]:
    """Mean and standard error of ``a``'s largest exponent minus ``b``'s, interval by interval.

    For two estimates on the same reference trajectory (the two-trajectory method and
    the tangent method with ``chunk`` = one interval follow it bit for bit): the mean
    of the per-interval differences of the log stretches equals the difference of the
    estimates, and its block standard error is free of the scatter between realizations
    of a chaotic trajectory, which both estimates share.

    Parameters
    ----------
    a, b : LyapunovResult
        Runs with the same interval and number of intervals, ending in the same state.
    n_blocks : int
        Blocks for the standard error (as in the estimates).

    Returns
    -------
    mean, stderr : float
        1 / time unit.

    Raises
    ------
    ValueError
        If the two runs did not follow the same reference trajectory.
    """
    ia, ib = a.meta.get("interval"), b.meta.get("interval")
    if ia != ib or a.logs.shape[0] != b.logs.shape[0]:
        raise ValueError(f"paired_difference: the runs differ in interval ({ia} vs {ib}) or number of "
                         f"intervals ({a.logs.shape[0]} vs {b.logs.shape[0]})")
    if not np.array_equal(a.x_final, b.x_final):
        raise ValueError("paired_difference: the runs did not follow the same reference trajectory "
                         "(x_final differs); use chunk = one interval for the tangent method")
    exps, err, _ = _stats(a.logs[:, :1] - b.logs[:, :1], float(a.meta["interval"]), n_blocks)
    return float(exps[0]), float(err[0])


def _admissible(scene: mo.Scene, x: np.ndarray, x_ref: np.ndarray) -> bool:
    """True unless the perturbed state penetrates deeper than the reference one."""
    if scene.gaps is None:  # no contacts
        return True
    g = np.asarray(scene.gaps(split_state(x)[0]), float)
    g_ref = np.asarray(scene.gaps(split_state(x_ref)[0]), float)
    return bool(np.all(g >= np.minimum(g_ref, 0.0) - 1e-12))


def _setup(scene, q0, v0, h, interval, t0, scale, simulate_kwargs):
    n = scene.ndof
    x = join_state(as_vector(q0, "q0", n), as_vector(v0, "v0", n))
    W = np.ones(2 * n) if scale is None else np.broadcast_to(np.asarray(scale, float), (2 * n,)).copy()
    if np.any(W <= 0):
        raise ValueError(f"scale must be positive, got {W.tolist()}")
    kw = {"solver": "enum"} if scene.nrows else {}
    kw.update(simulate_kwargs)
    fmap = TimeMap(scene, as_positive(interval, "interval"), h, t0=t0, **kw)
    return x, W, fmap


def _transient(fmap: TimeMap, x: np.ndarray, t: float, n_transient: int) -> tuple[np.ndarray, float]:
    if n_transient > 0:
        traj = fmap.run(x, t, n_periods=n_transient)
        x = join_state(traj.q[-1], traj.v[-1])
        t += n_transient * fmap.T
    return x, t


def largest_lyapunov(scene: mo.Scene, q0, v0, h: float, *, interval: float, n_intervals: int,
                     t0: float = 0.0, n_transient: int = 0, n_align: int = 0, d0: float = 1e-6, scale=None,
                     n_blocks: int = 10, seed: int = 0, progress: bool = False,
                     **simulate_kwargs) -> LyapunovResult:
    """Largest Lyapunov exponent from two nearby trajectories with renormalization.

    Parameters
    ----------
    scene : Scene
        Any scene.
    q0, v0 : array_like, shape (n,)
        Initial state at ``t0``.
    h : float
        Step size (adjusted to divide ``interval``).
    interval : float
        Time between renormalizations (time units): short enough that the separation
        stays small (``d0·exp(λ·interval) << 1``).
    n_intervals : int
        Intervals averaged after the transient.
    t0 : float
        Start time.
    n_transient : int
        Intervals discarded first (the reference trajectory only).
    n_align : int
        Intervals computed but not averaged after the transient, while the perturbation
        turns from its arbitrary start into the most unstable direction (a start across
        a non-normal Jacobian can stretch by far more than the exponent says).
    d0 : float
        Separation in the scaled norm. With impacts it must be large compared with
        ``h·|v| / scale`` (the scheme quantizes the impact instant to the step grid).
    scale : array_like (2n,), optional
        Scale of each state component in the norm.
    n_blocks : int
        Blocks for the error bar.
    seed : int
        Seed of the random initial direction.
    progress : bool
        A tqdm bar over the intervals.
    **simulate_kwargs
        Passed to :func:`moreau.simulate` (``solver="enum"`` is the default for scenes
        with contacts).

    Returns
    -------
    LyapunovResult
        ``exponents`` of shape (1,), method ``"two-trajectory"``.
    """
    x, W, fmap = _setup(scene, q0, v0, h, interval, t0, scale, simulate_kwargs)
    t = float(t0)
    x, t = _transient(fmap, x, t, n_transient)
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(size=(x.shape[0],))
    u /= np.linalg.norm(u)
    n_all = n_align + n_intervals
    logs = np.empty((n_all, 1))
    times = np.empty(n_all)
    n_imp = 0
    from tqdm import tqdm
    for i in tqdm(range(n_all), disable=not progress, desc="largest Lyapunov exponent"):
        y = x + d0 * W * u
        if not _admissible(scene, y, x):
            u = -u
            y = x + d0 * W * u
        traj = fmap.run(x, t)
        x1 = join_state(traj.q[-1], traj.v[-1])
        n_imp += len(traj.impacts) if i >= n_align else 0
        y1 = fmap(y, t)
        d = (y1 - x1) / W
        dn = float(np.linalg.norm(d))
        if not np.isfinite(dn) or dn == 0.0:
            raise RuntimeError(f"largest_lyapunov: separation {dn} after interval {i}")
        logs[i, 0] = np.log(dn / d0)
        u = d / dn
        x, t = x1, t + fmap.T
        times[i] = t
    logs, times = logs[n_align:], times[n_align:]
    exps, err, running = _stats(logs, fmap.T, n_blocks)
    return LyapunovResult(exps, err, times, running, logs, n_imp, x, "two-trajectory",
                          {"h": fmap.h, "interval": fmap.T, "d0": d0})


def lyapunov_spectrum(scene: mo.Scene, q0, v0, h: float, *, interval: float, n_intervals: int,
                      k: int | None = None, t0: float = 0.0, n_transient: int = 0, n_align: int = 0,
                      delta: float = 1e-6, scale=None, scheme: str = "forward", n_blocks: int = 10,
                      progress: bool = False, **simulate_kwargs) -> LyapunovResult:
    """The k largest Lyapunov exponents: finite-difference interval-map Jacobians with QR.

    Every interval costs ``k + 1`` runs of ``interval`` (forward differences): the
    reference trajectory and one per frame column, started at ``x + delta·scale·Q[:, j]``
    (or at ``x - ...`` with the sign of the difference reversed when the + side would
    penetrate a barrier); ``2k + 1`` with central differences (both sides).

    Parameters
    ----------
    k : int, optional
        Number of exponents (default all, 2n).
    delta : float
        Finite-difference perturbation in the scaled norm (see :func:`largest_lyapunov`
        for its choice with impacts). Error O(delta) forward, O(delta²) central, plus
        ``O(h·|v| / delta)`` with impacts.
    scheme : {"forward", "central"}
        Finite differences.
    Other parameters
        As in :func:`largest_lyapunov`.

    Returns
    -------
    LyapunovResult
        ``exponents`` of shape (k,), method ``"fd-qr"``. With k = 2n their sum is the mean
        phase-space contraction rate.
    """
    x, W, fmap = _setup(scene, q0, v0, h, interval, t0, scale, simulate_kwargs)
    dim = x.shape[0]
    k = dim if k is None else int(k)
    if not 1 <= k <= dim:
        raise ValueError(f"k must be in [1, {dim}], got {k}")
    if scheme not in ("forward", "central"):
        raise ValueError(f"scheme must be 'forward' or 'central', got {scheme!r}")
    t = float(t0)
    x, t = _transient(fmap, x, t, n_transient)
    Q = np.eye(dim)[:, :k]
    n_all = n_align + n_intervals
    logs = np.empty((n_all, k))
    times = np.empty(n_all)
    n_imp = 0
    from tqdm import tqdm
    for i in tqdm(range(n_all), disable=not progress, desc="Lyapunov spectrum"):
        traj = fmap.run(x, t)
        x1 = join_state(traj.q[-1], traj.v[-1])
        n_imp += len(traj.impacts) if i >= n_align else 0
        Z = np.empty((dim, k))
        for j in range(k):
            if scheme == "central":
                yp, ym = x + delta * W * Q[:, j], x - delta * W * Q[:, j]
                if _admissible(scene, yp, x) and _admissible(scene, ym, x):
                    Z[:, j] = (fmap(yp, t) - fmap(ym, t)) / (2 * W * delta)
                    continue
            sgn = 1.0
            y = x + delta * W * Q[:, j]
            if not _admissible(scene, y, x):
                sgn = -1.0
                y = x - delta * W * Q[:, j]
            Z[:, j] = sgn * (fmap(y, t) - x1) / (W * delta)
        Q, R = np.linalg.qr(Z)
        d = np.diag(R)
        if np.any(d == 0) or not np.all(np.isfinite(d)):
            raise RuntimeError(f"lyapunov_spectrum: degenerate frame after interval {i}")
        Q = Q * np.sign(d)
        logs[i] = np.log(np.abs(d))
        x, t = x1, t + fmap.T
        times[i] = t
    logs, times = logs[n_align:], times[n_align:]
    exps, err, running = _stats(logs, fmap.T, n_blocks)
    return LyapunovResult(exps, err, times, running, logs, n_imp, x, "fd-qr",
                          {"h": fmap.h, "interval": fmap.T, "delta": delta, "scheme": scheme})
