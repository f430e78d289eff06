"""An independent event-driven reference for systems with isolated impacts.

Between impacts the smooth equations of motion are integrated by scipy's ``solve_ivp``
(DOP853, tight tolerances) with a terminal event on the gap; at an impact the velocity
jumps by Newton's law for a single active contact,

.. math:: v^+ = v^- - (1 + e)\\, M^{-1} G^T \\frac{G v^-}{G M^{-1} G^T},

so that the normal velocity becomes ``G v⁺ = −e G v⁻``, and the integration restarts from
``(t*, q*, v⁺)``. Nothing here uses moreau's time-stepper or its contact solvers: it is an
independent check of moreau's impact times and states (issue 5).

Limits, on purpose:

* **one contact at a time.** Each gap row triggers its own event; an impact resets the
  velocity with that row alone. Simultaneous impacts on several rows are not handled.
* **Zeno guard.** A contact that keeps bouncing with ever smaller rebounds (the bouncing
  ball) has infinitely many impacts before it comes to rest at the Zeno time. The
  integration **stops** (``status == "zeno"``) after an impact whose rebound speed
  ``e |G v⁻|`` is below ``min_rebound`` times the largest impact speed seen so far, or after
  ``max_impacts`` impacts (``status == "max_impacts"``); e = 0 therefore stops at the first
  impact. The last state is then the post-impact state at rest on the barrier (to within the
  threshold); the reference does **not** continue with a persistent contact (that would need
  the constrained, index-reduced dynamics). Compare moreau against it only on
  ``[t_span[0], solution.t_end]``.
* **grazing.** Events are only detected with a decreasing gap (``direction = −1``), at the
  step resolution of the integrator and located by root finding on its dense output
  (about 1e-12 in time with the default tolerances).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["EventDrivenSolution", "event_driven", "pendulum_wall_reference", "moreau_impact_times"]


@dataclass
class EventDrivenSolution:
    """Result of :func:`event_driven`.

    Unpacks as ``t, q, v, impact_times = event_driven(...)``.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Times of the integrator's steps, non-decreasing; an impact time appears twice,
        with the pre- and the post-impact state.
    q, v : ndarray, shape (N, n)
        Coordinates and velocities at ``t``.
    impact_times : ndarray, shape (k,)
        Times of the impacts, increasing.
    impact_rows : ndarray of int, shape (k,)
        Gap row of each impact.
    impact_velocities : ndarray, shape (k, 2)
        Normal velocity ``G v`` before and after each impact.
    status : str
        ``"completed"`` (reached ``t_span[1]``), ``"zeno"`` (stopped by the rebound
        guard), ``"max_impacts"`` or ``"failed"`` (solve_ivp failed; ``message`` says why).
    t_end : float
        Time the reference reaches (``t_span[1]`` when completed).
    message : str
        Why it stopped.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    impact_times: np.ndarray
    impact_rows: np.ndarray
    impact_velocities: np.ndarray
    status: str
    t_end: float
    message: str = ""
    _segments: list = field(default_factory=list, repr=False)

    def __iter__(self):
        return iter((self.t, self.q, self.v, self.impact_times))

    def state(self, times) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at arbitrary ``times`` in ``[t_span[0], t_end]`` from the dense outputs
        (DOP853's 7th-order interpolant); right-continuous at impacts (post-impact
        velocity). Returns arrays of shape (len(times), n)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        n = self.q.shape[1]
        Q = np.full((times.size, n), np.nan)
        V = np.full((times.size, n), np.nan)
        starts = np.array([s[0] for s in self._segments])
        inside = (times >= starts[0] - 1e-14) & (times <= self.t_end + 1e-12)
        seg = np.maximum(0, np.searchsorted(starts, times, side="right") - 1)
        for j in np.unique(seg[inside]):  # each segment's interpolant once, on all its times
            at = np.flatnonzero(inside & (seg == j))
            t0, t1, sol = self._segments[j]
            y = (sol(np.clip(times[at], t0, t1)).T if sol is not None
                 else np.broadcast_to(self._segment_const(j), (at.size, 2 * n)))
            Q[at], V[at] = y[:, :n], y[:, n:]
        return Q, V

    def _segment_const(self, j):
        # a zero-length last segment (stopped right at an impact): the stored state
        t0 = self._segments[j][0]
        k = int(np.flatnonzero(self.t == t0)[-1])
        return np.concatenate([self.q[k], self.v[k]])


def _as_mass(mass) -> Callable[[np.ndarray], np.ndarray]:
    if callable(mass):
        return lambda q: np.atleast_2d(np.asarray(mass(q), dtype=float))
    M = np.atleast_2d(np.asarray(mass, dtype=float))
    return lambda q: M


def event_driven(
    rhs: Callable,
    gap: Callable,
    jacobian: Callable,
    mass,
    e: float,
    t_span: tuple[float, float],
    y0,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    *,
    min_rebound: float = 1e-6,
    max_impacts: int = 10_000,
    max_step: float = np.inf,
) -> EventDrivenSolution:
    """Event-driven integration of a mechanical system with unilateral gaps and Newton
    restitution (single active contact at a time).

    Parameters
    ----------
    rhs : callable ``rhs(t, y) -> dy``
        Smooth first-order right-hand side, y = (q, v) with n = len(y)/2 (e.g.
        :func:`moreau.problems.pendulum_wall.pendulum_rhs`).
    gap : callable ``gap(q) -> g``
        Gaps, scalar or shape (m,); admissible when all g >= 0.
    jacobian : callable ``jacobian(q) -> G``
        ``∂g/∂q``, shape (m, n) (a vector is taken as one row).
    mass : array_like (n, n) or callable ``mass(q)``
        Mass matrix (constant or configuration dependent).
    e : float
        Newton restitution coefficient in [0, 1].
    t_span : (float, float)
        Start and end time.
    y0 : array_like, shape (2n,)
        Initial (q0, v0); must not penetrate (all g(q0) >= 0).
    rtol, atol : float
        Tolerances of DOP853 (default 1e-12).
    min_rebound : float
        Zeno guard: stop after an impact whose rebound normal speed ``e |G v⁻|`` is below
        ``min_rebound`` times the largest impact speed so far (see the module docstring).
    max_impacts : int
        Stop after this many impacts.
    max_step : float
        Largest step of DOP853 (default unbounded).

    Returns
    -------
    EventDrivenSolution
        Unpacks as ``t, q, v, impact_times``.
    """
    if not (0.0 <= e <= 1.0):
        raise ValueError(f"restitution e must be in [0, 1], got {e!r}")
    t0, t1 = (float(x) for x in t_span)
    if not t1 > t0:
        raise ValueError(f"t_span must satisfy t1 > t0, got {t_span!r}")
    y = np.asarray(y0, dtype=float).copy()
    if y.ndim != 1 or y.size % 2:
        raise ValueError(f"y0 must be a vector (q0, v0) of even length, got shape {y.shape}")
    n = y.size // 2

    def gaps(q):
        return np.atleast_1d(np.asarray(gap(q), dtype=float))

    def jac(q):
        return np.atleast_2d(np.asarray(jacobian(q), dtype=float)).reshape(-1, n)

    g0 = gaps(y[:n])
    if np.any(g0 < -1e-12):
        raise ValueError(f"initial state penetrates a barrier: g(q0) = {g0.tolist()}")
    events = [_gap_event(gaps, n, r) for r in range(g0.size)]
    return _integrate(rhs, events, jac, _as_mass(mass), e, t0, t1, y, dict(rtol=rtol, atol=atol, max_step=max_step),
                      min_rebound=min_rebound, max_impacts=max_impacts)


def _gap_event(gaps: Callable, n: int, r: int) -> Callable:
    """Terminal event of ``solve_ivp`` on gap row ``r`` closing (decreasing through 0)."""
    def ev(t, yy):
        return gaps(yy[:n])[r]
    ev.terminal = True
    ev.direction = -1.0
    return ev


def _newton_reset(M: np.ndarray, G: np.ndarray, v: np.ndarray, U: float, e: float) -> np.ndarray:
    """Post-impact velocity of one row: v⁺ = v⁻ − (1 + e) M⁻¹Gᵀ (G v⁻) / (G M⁻¹ Gᵀ)."""
    MinvGt = np.linalg.solve(M, G)
    return v - (1.0 + e) * MinvGt * (U / float(G @ MinvGt))


def _integrate(rhs: Callable, events: list, jac: Callable, M_of: Callable, e: float, t0: float, t1: float,
               y: np.ndarray, ivp: dict, *, min_rebound: float, max_impacts: int) -> EventDrivenSolution:
    """The event loop of :func:`event_driven` from the checked start ``(t0, y)``: DOP853
    (``ivp``: its rtol, atol, max_step) up to the next impact, Newton's reset, repeat."""
    n = y.size // 2
    T, Y = [np.array([t0])], [y[None, :]]
    segments: list = []
    imp_t, imp_r, imp_u = [], [], []
    status, message = "completed", "reached the end of the time span"
    t = t0
    u_max = 0.0
    while t < t1:
        sol = solve_ivp(rhs, (t, t1), y, method="DOP853", events=events, dense_output=True, **ivp)
        segments.append((t, float(sol.t[-1]), sol.sol))
        T.append(sol.t[1:])
        Y.append(sol.y[:, 1:].T)
        t = float(sol.t[-1])
        if sol.status == -1:
            status, message = "failed", f"solve_ivp failed at t = {sol.t[-1]:.12g}: {sol.message}"
            break
        if sol.status == 0:
            break
        # impact: the row whose event fired (the first one if several did)
        r = next(i for i, te in enumerate(sol.t_events) if te.size)
        y_minus = sol.y_events[r][0].copy()
        q, v = y_minus[:n], y_minus[n:]
        G = jac(q)[r]
        U = float(G @ v)
        if U >= 0.0:  # grazing: nothing to reset
            y = y_minus
            continue
        v_plus = _newton_reset(M_of(q), G, v, U, e)
        y = np.concatenate([q, v_plus])
        T.append(np.array([t]))
        Y.append(y[None, :])
        imp_t.append(t)
        imp_r.append(r)
        imp_u.append((U, float(G @ v_plus)))
        u_max = max(u_max, -U)
        if e * (-U) < min_rebound * u_max:
            segments.append((t, t, None))
            status = "zeno"
            message = (f"stopped after impact {len(imp_t)} at t = {t:.12g}: rebound speed "
                       f"{e * -U:.3g} below min_rebound x largest impact speed ({min_rebound:g} x {u_max:.3g})")
            break
        if len(imp_t) >= max_impacts:
            segments.append((t, t, None))
            status, message = "max_impacts", f"stopped after max_impacts = {max_impacts} impacts at t = {t:.12g}"
            break
    Ta = np.concatenate(T)
    Ya = np.concatenate(Y, axis=0)
    return EventDrivenSolution(
        t=Ta, q=Ya[:, :n], v=Ya[:, n:],
        impact_times=np.array(imp_t), impact_rows=np.array(imp_r, dtype=int),
        impact_velocities=np.array(imp_u).reshape(-1, 2),
        status=status, t_end=t, message=message, _segments=segments,
    )


def pendulum_wall_reference(
    e: float = 0.8,
    wall_x: float = 0.5,
    t_end: float = 5.0,
    theta0: float = 0.0,
    omega0: float = 0.0,
    damping: float = 0.0,
    *,
    mass: float = 1.0,
    length: float = 1.0,
    g: float = 9.81,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    **kwargs,
) -> EventDrivenSolution:
    """The event-driven reference of :func:`moreau.problems.pendulum_wall.pendulum_wall` from
    ``(theta0, omega0)`` at t = 0 to ``t_end`` (same parameters and units).

    The bob hits the wall x = ``wall_x`` where ``sin θ = wall_x / length``; gravity pulls
    it away from the wall, so the impacts are isolated (no Zeno) for 0 < e.
    """
    from .pendulum_wall import pendulum_rhs

    l = float(length)
    xw = float(wall_x)
    return event_driven(
        pendulum_rhs(mass=mass, length=length, g=g, damping=damping),
        gap=lambda q: xw - l * np.sin(q[0]),
        jacobian=lambda q: np.array([[-l * np.cos(q[0])]]),
        mass=np.array([[mass * l * l]]),
        e=e,
        t_span=(0.0, t_end),
        y0=[theta0, omega0],
        rtol=rtol,
        atol=atol,
        **kwargs,
    )


def moreau_impact_times(traj) -> np.ndarray:
    """Impact times of a moreau run, comparable with ``impact_times`` of :class:`EventDrivenSolution`.

    The impact log gives the start t_k of the step in which an impact happened; reading
    that alone adds an O(h) quantization noise (the impact lies anywhere in the step)
    that hides the order of convergence. The time is therefore interpolated inside the
    step, ``t_k + g(q_k) / (−U_k)`` with ``U_k = G v_k`` the approach velocity: the
    crossing time of the gap at constant velocity. The scheme closes a contact when its
    gap at the step's midpoint is <= 0, so the crossing may lie in the previous step
    (g(q_k) < 0): the correction is clipped to [−h, h].

    Parameters
    ----------
    traj : moreau.Trajectory
        A run recorded at every step (``record_every == 1``). A run with step-size control
        (steps of different sizes) gives its impact log's times as they are: the steps
        around an impact are as short as its tolerance asks.
    """
    im = traj.impacts
    if len(im) == 0:
        return np.zeros(0)
    steps = np.diff(traj.t)
    if steps.size > 1 and np.ptp(steps[:-1]) > 1e-6 * traj.h:  # step-size control: the steps around an
        return im.t.copy()  # impact are as short as the tolerance asks, and its start is the time
    if traj.record_every != 1:
        raise ValueError("moreau_impact_times needs a trajectory recorded at every step (record_every=1)")
    g = traj.gaps[im.step, im.row]
    dt = np.where(im.U_before < 0, g / np.maximum(-im.U_before, 1e-300), 0.0)
    return im.t + np.clip(dt, -traj.h, traj.h)
