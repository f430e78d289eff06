"""Sections: stroboscopic samples and Poincaré sections on a surface s(q, v) = 0.

From a recorded :class:`moreau.Trajectory` (linear interpolation between records, exact
when the sample falls on a record) or on the fly, chunk by chunk of a run.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

import moreau as mo
from moreau.core.validation import as_positive, as_vector

__all__ = ["Section", "stroboscopic", "poincare", "poincare_on_the_fly"]

log = logging.getLogger(__name__)


@dataclass
class Section:
    """Points of a section.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Times of the points.
    q, v : ndarray, shape (K, n)
        Coordinates and velocities at the points.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def x(self) -> np.ndarray:
        """States ``(q, v)``, shape (K, 2n)."""
        return np.hstack([self.q, self.v])


def _interp(traj: mo.Trajectory, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = traj.t
    tol = 1e-6 * traj.h
    k = np.clip(np.searchsorted(t, ts - tol), 1, len(t) - 1)
    exact = np.abs(t[k] - ts) <= tol
    w = np.where(exact, 1.0, (ts - t[k - 1]) / (t[k] - t[k - 1]))[:, None]
    q = (1 - w) * traj.q[k - 1] + w * traj.q[k]
    v = (1 - w) * traj.v[k - 1] + w * traj.v[k]
    return q, v


def stroboscopic(traj: mo.Trajectory, period: float, phase_time: float = 0.0,
                 t_start: float | None = None) -> Section:
    """States once per period: at ``t = phase_time + k·period`` within the trajectory.

    Parameters
    ----------
    traj : Trajectory
        A recorded run (choose ``h`` dividing ``period`` and ``record_every`` dividing
        ``period / h`` so the samples fall on records; otherwise they are interpolated
        linearly, which smears velocity jumps of impacts inside a record interval).
    period : float
        Forcing period 2π/ω (time units), or the engine cycle (4π in crank angle time for a
        four-stroke engine whose time is the crank angle).
    phase_time : float
        Time of one sample (its phase within the period), e.g. ``φ/ω``.
    t_start : float, optional
        Discard samples before this time (the transient).

    Returns
    -------
    Section
        K samples, K = number of sample times in ``[max(t_start, t[0]), t[-1]]``.
    """
    period = as_positive(period, "stroboscopic.period")
    lo = traj.t[0] if t_start is None else max(traj.t[0], float(t_start))
    tol = 1e-6 * traj.h
    k0 = np.ceil((lo - phase_time - tol) / period)
    k1 = np.floor((traj.t[-1] - phase_time + tol) / period)
    ts = phase_time + period * np.arange(k0, k1 + 1)
    q, v = _interp(traj, ts)
    return Section(ts, q, v)


def _crossings(t, s, direction):
    s0, s1 = s[:-1], s[1:]
    if direction > 0:
        hit = (s0 < 0) & (s1 >= 0)
    elif direction < 0:
        hit = (s0 > 0) & (s1 <= 0)
    else:
        hit = ((s0 < 0) & (s1 >= 0)) | ((s0 > 0) & (s1 <= 0))
    idx = np.nonzero(hit)[0]
    w = s0[idx] / (s0[idx] - s1[idx])
    return idx, w


def poincare(traj: mo.Trajectory, surface: Callable[[np.ndarray, np.ndarray], float],
             direction: int = 1, t_start: float | None = None) -> Section:
    """Crossings of the surface ``s(q, v) = 0`` in the given direction.

    Parameters
    ----------
    traj : Trajectory
        A recorded run (every step recorded for the best accuracy: a crossing is located
        by linear interpolation of s between records, error O(h²) in a smooth flight).
    surface : callable ``s(q, v) -> float``
        The section surface; q, v of shape (n,).
    direction : {1, -1, 0}
        Keep crossings from s < 0 to s >= 0 (1), the reverse (-1), or both (0).
    t_start : float, optional
        Discard crossings before this time.

    Returns
    -------
    Section
        States interpolated linearly at the crossings.
    """
    s = np.array([float(surface(q, v)) for q, v in zip(traj.q, traj.v)])
    idx, w = _crossings(traj.t, s, direction)
    ts = traj.t[idx] + w * (traj.t[idx + 1] - traj.t[idx])
    q = (1 - w)[:, None] * traj.q[idx] + w[:, None] * traj.q[idx + 1]
    v = (1 - w)[:, None] * traj.v[idx] + w[:, None] * traj.v[idx + 1]
    keep = np.ones(len(ts), bool) if t_start is None else ts >= t_start
    return Section(ts[keep], q[keep], v[keep])


def poincare_on_the_fly(scene: mo.Scene, q0, v0, h: float,
                        surface: Callable[[np.ndarray, np.ndarray], float], n_crossings: int, *,
                        t0: float = 0.0, direction: int = 1, t_max: float = np.inf,
                        t_start: float | None = None, integrator: type = mo.MoreauJeanMidpoint,
                        chunk_steps: int = 4096, **simulate_kwargs) -> Section:
    """Run until ``n_crossings`` crossings of ``s(q, v) = 0`` have been found.

    The run goes in chunks of ``chunk_steps`` steps of :func:`moreau.simulate`, each from
    the last state of the one before; only the crossings are kept, so the run length is
    bounded by the number of points wanted rather than by memory. Each chunk starts
    afresh: drift control's memory of persistent contacts restarts with it.

    Parameters
    ----------
    scene : Scene
        The system.
    q0, v0 : array_like, shape (n,)
        Initial state at ``t0``.
    h : float
        Step size.
    surface, direction, t_start
        As in :func:`poincare`.
    n_crossings : int
        Crossings to collect (after ``t_start``).
    t_max : float
        Stop at this time even if fewer crossings were found.
    integrator : OneStepIntegrator subclass
        Default :class:`moreau.MoreauJeanMidpoint`.
    chunk_steps : int
        Steps per chunk (default 4096).
    **simulate_kwargs
        Passed to :func:`moreau.simulate` (``solver=``, ``drift_control=``, ...).
    """
    h = as_positive(h, "poincare_on_the_fly.h")
    t, q, v = float(t0), as_vector(q0, "q0", scene.ndof), as_vector(v0, "v0", scene.ndof)
    kw = {"progress": False, **simulate_kwargs, "record_every": 1, "integrator": integrator}
    T: list[np.ndarray] = []
    Q: list[np.ndarray] = []
    V: list[np.ndarray] = []
    found, pen = 0, float(kw.pop("initial_penetration", 1e-12))
    while found < n_crossings and t < t_max:
        # at least one step: a chunk ends past t_max by less than h, as a run of one span would
        end = max(min(t + chunk_steps * h, t_max), t + h)
        traj = mo.simulate(scene, (t, end), q, v, h, initial_penetration=pen, **kw)
        sec = poincare(traj, surface, direction=direction, t_start=t_start)
        take = min(len(sec), n_crossings - found)
        T.append(sec.t[:take])
        Q.append(sec.q[:take])
        V.append(sec.v[:take])
        found += take
        t, q, v = float(traj.t[-1]), traj.q[-1], traj.v[-1]
        # the next chunk starts where this one ended, inside a barrier by at most its penetration
        depth = traj.max_penetration
        pen = max(1e-12, 1.01 * float(depth.max(initial=0.0))) if depth is not None else 1e-12
    n = scene.ndof
    if found < n_crossings:
        log.warning("poincare_on_the_fly: %d of %d crossings before t_max = %g", found, n_crossings, t_max)
    if not T:
        return Section(np.zeros(0), np.zeros((0, n)), np.zeros((0, n)))
    return Section(np.concatenate(T), np.concatenate(Q).reshape(-1, n), np.concatenate(V).reshape(-1, n))
