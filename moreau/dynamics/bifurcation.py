"""Bifurcation diagrams on :func:`moreau.sweeps.sweep` (process pool or Dask, resumable).

For every value of one parameter: build the scene, integrate with :func:`moreau.simulate`,
discard the transient, sample the stroboscopic section once per forcing period and keep
the chosen state components — optionally with the largest Lyapunov exponent.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

import moreau as mo
from moreau.sweeps import sweep

from .floquet import detect_period
from .lyapunov import largest_lyapunov
from .sections import stroboscopic

__all__ = ["bifurcation_diagram", "bifurcation_point", "plot_bifurcation"]

log = logging.getLogger(__name__)


def bifurcation_point(*, make_scene: Callable, param: str, value: float, q0, v0, h: float,
                      period: float | Callable[[float], float], n_transient: int, n_points: int,
                      components: Sequence[int] = (0,), phase_time: float = 0.0,
                      lyapunov: dict | None = None, max_period: int = 16, rtol: float = 1e-4,
                      simulate_kwargs: dict | None = None) -> dict:
    """One column of a bifurcation diagram (the function the sweep runs).

    Parameters
    ----------
    make_scene : callable ``make_scene(value) -> Scene``
        Module-level (picklable) scene factory.
    param : str
        Name of the parameter (for the table).
    value : float
        The parameter's value.
    q0, v0 : array_like, shape (n,)
        Initial state at t = 0.
    h : float
        Step size (adjusted so that it divides the period).
    period : float or callable ``period(value) -> float``
        Forcing period (time units).
    n_transient, n_points : int
        Periods discarded, periods sampled.
    components : sequence of int
        Indices into the state ``x = (q, v)`` that are kept.
    phase_time : float
        Sample times ``phase_time + k·period``.
    lyapunov : dict, optional
        Keyword arguments of :func:`~moreau.dynamics.lyapunov.largest_lyapunov`
        (``n_intervals``, ``d0``, ``n_align``, ``scale``; ``interval`` defaults to the
        period), started from the end of the sampled run; adds ``lyapunov`` and
        ``lyapunov_err``.
    max_period, rtol : int, float
        Period detection on the section (:func:`~moreau.dynamics.floquet.detect_period`).
    simulate_kwargs : dict, optional
        Passed to :func:`moreau.simulate`.

    Returns
    -------
    dict
        ``section`` (list of n_points lists, one value per component), ``t_section``,
        ``period_detected`` (int or None), ``n_impacts`` over the sampled periods and,
        if asked, ``lyapunov`` / ``lyapunov_err`` (1 / time unit).
    """
    scene = make_scene(value)
    T = float(period(value) if callable(period) else period)
    n_steps = max(1, int(round(T / h)))
    hh = T / n_steps
    kw: dict[str, Any] = {"progress": False, "energy": False}
    if scene.nrows:
        kw["solver"] = "enum"
    kw.update(simulate_kwargs or {})
    kw.setdefault("record_every", n_steps)
    traj = mo.simulate(scene, (0.0, (n_transient + n_points) * T), q0, v0, hh, **kw)
    if traj.status != "completed":
        raise RuntimeError(f"{param} = {value}: simulation {traj.status}: {traj.message}")
    sec = stroboscopic(traj, T, phase_time, t_start=n_transient * T + phase_time - 0.5 * T)
    X = sec.x[-n_points:][:, list(components)]
    t_imp = traj.impacts.times() if len(traj.impacts) else np.zeros(0)
    out = {
        "section": X.tolist(),
        "t_section": sec.t[-n_points:].tolist(),
        "period_detected": detect_period(X, max_period=max_period, rtol=rtol),
        "n_impacts": int(np.sum(t_imp >= n_transient * T)),
    }
    if lyapunov:
        lk = dict(lyapunov)
        lk.setdefault("interval", T)
        res = largest_lyapunov(scene, traj.q[-1], traj.v[-1], hh, t0=float(traj.t[-1]),
                               **lk, **{k: v for k, v in (simulate_kwargs or {}).items()})
        out["lyapunov"] = float(res.exponents[0])
        out["lyapunov_err"] = float(res.stderr[0])
    return out


def bifurcation_diagram(make_scene: Callable, param: str, values: Sequence[float], *, q0, v0, h: float,
                        period: float | Callable[[float], float], n_transient: int, n_points: int,
                        components: Sequence[int] = (0,), phase_time: float = 0.0,
                        lyapunov: dict | None = None, simulate_kwargs: dict | None = None,
                        executor="processes", workers: int | None = None, out=None,
                        progress: bool = True, retry_errors: bool = False):
    """A bifurcation diagram: :func:`bifurcation_point` over ``values`` on a sweep.

    Parameters
    ----------
    make_scene : callable ``make_scene(value) -> Scene``
        Module-level function (the sweep pickles it for the workers).
    param : str
        The parameter's name: the table's first column.
    values : sequence of float
        Parameter values (one sweep point each).
    executor, workers, out, progress, retry_errors
        As in :func:`moreau.sweeps.sweep`; with ``out`` the diagram is resumable.
    Other parameters
        As in :func:`bifurcation_point`.

    Returns
    -------
    pandas.DataFrame
        One row per value: ``param``, ``section``, ``t_section``, ``period_detected``,
        ``n_impacts`` [, ``lyapunov``, ``lyapunov_err``], ``error``.
    """
    fun = functools.partial(
        _point, make_scene=make_scene, param=param, q0=np.asarray(q0, float).tolist(),
        v0=np.asarray(v0, float).tolist(), h=h, period=period, n_transient=n_transient,
        n_points=n_points, components=list(components), phase_time=phase_time,
        lyapunov=lyapunov, simulate_kwargs=simulate_kwargs)
    return sweep(fun, {"value": [float(v) for v in values]}, executor=executor, workers=workers, out=out,
                 progress=progress, retry_errors=retry_errors).rename(columns={"value": param})


def _point(value, **kwargs):
    return bifurcation_point(value=value, **kwargs)


def plot_bifurcation(df, param: str, component: int = 0, ax=None, transform=None, **scatter_kwargs):
    """Scatter the section values of a diagram table against the parameter; returns the axes.

    ``transform`` (callable on an array) maps the values first, e.g. wraps an angle.
    """
    import matplotlib.pyplot as plt

    ax = ax or plt.gca()
    xs, ys = [], []
    for p, sec in zip(df[param], df["section"]):
        if sec is None or (isinstance(sec, float) and np.isnan(sec)):
            continue
        s = np.asarray(sec, float)[:, component]
        if transform is not None:
            s = np.asarray(transform(s), float)
        xs.append(np.full(s.shape, p))
        ys.append(s)
    kw = {"s": 1.0, "c": "k", "alpha": 0.6, "linewidths": 0}
    kw.update(scatter_kwargs)
    if xs:
        ax.scatter(np.concatenate(xs), np.concatenate(ys), **kw)
    ax.set_xlabel(param)
    return ax
