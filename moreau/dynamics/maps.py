"""The time-T map of a scene and finite-difference Jacobians of maps.

A state is ``x = (q, v)``, shape (2n,). :class:`TimeMap` advances a state from ``t0`` to
``t0 + T`` with :func:`moreau.simulate` (keyword arguments passed through), recording only
the end point.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

import moreau as mo
from moreau.core.validation import as_positive, as_vector

__all__ = ["TimeMap", "PoincareMap", "jacobian_fd", "join_state", "split_state", "restart"]

log = logging.getLogger(__name__)


def join_state(q, v) -> np.ndarray:
    """``x = (q, v)``, shape (2n,)."""
    return np.concatenate([np.asarray(q, float).ravel(), np.asarray(v, float).ravel()])


def split_state(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(q, v)`` from ``x``, each shape (n,)."""
    x = np.asarray(x, float)
    n = x.shape[0] // 2
    return x[:n], x[n:]


class TimeMap:
    """``x(t0) -> x(t0 + T)`` for a scene, integrated by :func:`moreau.simulate`.

    Parameters
    ----------
    scene : moreau.Scene
        The system.
    T : float
        Map time (time units of the scene), e.g. the forcing period 2π/ω.
    h : float
        Step size; the map takes ``round(T / h)`` steps of exactly ``T / round(T / h)``
        so that stroboscopic samples fall on the step grid.
    t0 : float
        Start time of the map (the section phase of a forced system).
    **simulate_kwargs
        Passed to :func:`moreau.simulate` (``solver=``, ``drift_control=``, ...).

    Attributes
    ----------
    h : float
        The step actually used.
    n_steps : int
        Steps per map.
    n_calls : int
        Maps evaluated so far.
    """

    def __init__(self, scene: mo.Scene, T: float, h: float, t0: float = 0.0, **simulate_kwargs) -> None:
        self.scene = scene
        self.T = as_positive(T, "TimeMap.T")
        h = as_positive(h, "TimeMap.h")
        self.n_steps = max(1, int(round(self.T / h)))
        self.h = self.T / self.n_steps
        self.t0 = float(as_vector(t0, "TimeMap.t0", 1)[0])
        kw: dict[str, Any] = {"progress": False, "energy": False}
        kw.update(simulate_kwargs)
        kw["record_every"] = max(1, self.n_steps)  # only the end point is kept
        self.simulate_kwargs = kw
        self.n_calls = 0

    def run(self, x: np.ndarray, t0: float | None = None, n_periods: int = 1) -> mo.Trajectory:
        """The trajectory from ``x`` at ``t0`` (default ``self.t0``) over ``n_periods`` maps."""
        t0 = self.t0 if t0 is None else float(t0)
        q, v = split_state(x)
        kw = dict(self.simulate_kwargs)
        kw["record_every"] = self.n_steps if n_periods > 1 else kw["record_every"]
        self.n_calls += n_periods
        return restart(self.scene, (t0, t0 + n_periods * self.T), q, v, self.h, **kw)

    def __call__(self, x: np.ndarray, t0: float | None = None) -> np.ndarray:
        """``x(t0 + T)``, shape (2n,)."""
        traj = self.run(x, t0)
        if traj.status != "completed":
            raise RuntimeError(f"TimeMap: the simulation stopped early ({traj.status}: {traj.message})")
        return join_state(traj.q[-1], traj.v[-1])

    def orbit(self, x: np.ndarray, n: int, t0: float | None = None) -> np.ndarray:
        """``n`` iterates of the map in one run, shape (n + 1, 2n) including ``x``."""
        traj = self.run(x, t0, n_periods=n)
        return np.hstack([traj.q, traj.v])


def restart(scene: mo.Scene, t_span, q, v, h: float, **simulate_kwargs) -> mo.Trajectory:
    """:func:`moreau.simulate` from a state a previous run ended in.

    The midpoint scheme ends an impact step with a penetration of up to ~ (1 - e)|v|h/2,
    which :func:`moreau.simulate` refuses as an initial state by default; a run that
    continues from such a state is what the uninterrupted run would have done, so that
    state's own penetration is accepted (``initial_penetration``), on whichever path the
    scene runs (the compiled loop when it compiles).
    """
    if scene.gaps is not None and scene.nrows:
        gmin = float(np.min(scene.gaps(np.asarray(q, float))))
        if gmin < -1e-12:
            simulate_kwargs = dict(simulate_kwargs)
            simulate_kwargs.setdefault("initial_penetration", 2.0 * -gmin)
    return mo.simulate(scene, t_span, q, v, h, **simulate_kwargs)


def jacobian_fd(fun: Callable[[np.ndarray], np.ndarray], x, eps: float | np.ndarray = 1e-6,
                scheme: str = "central", f0: np.ndarray | None = None) -> np.ndarray:
    """Finite-difference Jacobian ``df/dx`` of a map, shape (len(f), len(x)).

    Parameters
    ----------
    fun : callable ``fun(x) -> (m,)``
        The map.
    x : array_like, shape (k,)
        The point.
    eps : float or array_like (k,)
        Perturbation per coordinate (absolute, in the units of that coordinate). For a
        map computed by a time-stepper through impacts, eps must be much larger than
        ``h·|v|`` (the impact instant is quantized to the step grid; see
        :mod:`moreau.dynamics.floquet`).
    scheme : {"central", "forward"}
        Central differences (2k evaluations, error O(eps²)) or forward (k, O(eps)).
    f0 : array_like, optional
        ``fun(x)`` when already known (forward scheme).
    """
    x = as_vector(x, "jacobian_fd.x")
    eps = np.broadcast_to(np.asarray(eps, float), x.shape)
    if scheme not in ("central", "forward"):
        raise ValueError(f"scheme must be 'central' or 'forward', got {scheme!r}")
    cols = []
    if scheme == "forward" and f0 is None:
        f0 = np.asarray(fun(x), float)
    for j in range(x.shape[0]):
        e = np.zeros_like(x)
        e[j] = eps[j]
        if scheme == "central":
            cols.append((np.asarray(fun(x + e), float) - np.asarray(fun(x - e), float)) / (2 * eps[j]))
        else:
            cols.append((np.asarray(fun(x + e), float) - f0) / eps[j])
    return np.column_stack(cols)


class PoincareMap:
    """The return map to a section ``s(q, v) = 0`` of an autonomous scene (e.g. an engine
    at a crank angle), on the coordinates ``free`` of the state.

    Each call integrates from the section point with :func:`moreau.simulate` over
    ``t_max`` (recording every step) and returns the state at the first crossing after
    ``t_min`` (linear interpolation between steps, as :func:`moreau.dynamics.poincare`).

    Parameters
    ----------
    scene : Scene
        The system (autonomous, or with a period that the section respects).
    surface : callable ``s(q, v) -> float``
        The section.
    h : float
        Step size.
    x_ref : array_like, shape (2n,)
        A full state on the section: the coordinates not in ``free`` are taken from it.
    free : sequence of int
        Indices into ``x = (q, v)`` that the map acts on (all but one coordinate fixed by
        the section).
    t_min, t_max : float
        The return is searched in ``(t_min, t_max]`` after the start (time units).
    direction : {1, -1, 0}
        Crossing direction.
    t0 : float
        Start time of every run.
    **simulate_kwargs
        Passed to :func:`moreau.simulate`.
    """

    def __init__(self, scene: mo.Scene, surface, h: float, x_ref, free, *, t_min: float, t_max: float,
                 direction: int = 1, t0: float = 0.0, **simulate_kwargs) -> None:
        self.scene, self.surface, self.direction = scene, surface, int(direction)
        self.h = as_positive(h, "PoincareMap.h")
        self.x_ref = as_vector(x_ref, "PoincareMap.x_ref", 2 * scene.ndof).copy()
        self.free = np.asarray(free, dtype=int)
        self.t_min, self.t_max, self.t0 = float(t_min), float(t_max), float(t0)
        if not 0 <= self.t_min < self.t_max:
            raise ValueError(f"PoincareMap: need 0 <= t_min < t_max, got {t_min}, {t_max}")
        kw: dict[str, Any] = {"progress": False, "energy": False}
        kw.update(simulate_kwargs)
        kw["record_every"] = 1
        self.simulate_kwargs = kw
        self.last_return_time = np.nan

    def full_state(self, y) -> np.ndarray:
        """The full state (2n,) with the free coordinates ``y``."""
        x = self.x_ref.copy()
        x[self.free] = y
        return x

    def __call__(self, y) -> np.ndarray:
        """The free coordinates at the next crossing, shape (len(free),)."""
        from .sections import poincare

        q, v = split_state(self.full_state(y))
        traj = restart(self.scene, (self.t0, self.t0 + self.t_max), q, v, self.h, **self.simulate_kwargs)
        sec = poincare(traj, self.surface, self.direction, t_start=self.t0 + self.t_min)
        if len(sec) == 0:
            raise RuntimeError(f"PoincareMap: no crossing within t_max = {self.t_max}")
        self.last_return_time = float(sec.t[0] - self.t0)
        return np.concatenate([sec.q[0], sec.v[0]])[self.free]
