"""Lyapunov spectrum from the tangent (variational) dynamics with saltation matrices.

The method of Müller (1995, "Calculation of Lyapunov exponents for dynamic systems with
discontinuities", Chaos Solitons Fractals 5(9):1671–1681), on the reference trajectory
of :func:`moreau.simulate` (recorded at every step):

* between impacts the frame Φ (2n × k) follows the variational equation ``Φ' = A Φ`` of
  the smooth flow ``x' = F(t, x) = (v, M(q)⁻¹ f(t, q, v))`` (f: the scene's effects and
  bias force). ``A = ∂F/∂x`` is taken by forward finite differences of F at the step's
  midpoint state (``2n + 1`` evaluations of M and f per step), and a step advances Φ by
  ``exp(h A)`` (exponential midpoint rule, order 2). So ``det`` of a step is
  ``exp(h trace A)`` and the sum of the exponents contains the flow's contraction,
  ``−trace(M⁻¹C)`` for linear damping C (the bias terms of a configuration-dependent M
  add ``−d/dt ln det M``, zero on average).
* at every impact of the log (a row whose impulse becomes positive in a step after a
  step without), the frame is multiplied by the saltation matrix (Müller 1995; Leine &
  Nijmeijer 2004, "Dynamics and Bifurcations of Non-Smooth Mechanical Systems", §2.5)

  .. code-block:: text

      S = J + (F⁺ − J F⁻) nᵀ / (nᵀ F⁻),   n = (∇g, 0),   nᵀ F⁻ = U⁻ = G v⁻,

  with J the Jacobian of the Newton map ``v⁺ = v − (1 + e) M⁻¹Gᵀ (G v) / (G M⁻¹ Gᵀ)``
  (analytic in v, central differences in q) and F∓ the vector field just before and
  after. For one frictionless row ``det S = e²``. The crossing instant inside the step
  is ``t_k + τ``, ``τ = g(q_k) / (−G v_k)`` (linear in the step; the scheme's own impact
  instant is only known to O(h)); the step is split into ``exp((h − τ) A⁺) S exp(τ A⁻)``.
  Rows hit in the same step are taken one after the other in the order of their τ.

Φ is QR re-orthonormalized after every step; the logs of ``|diag R|`` are summed per
``interval``. The runs of smooth steps between impacts are taken in compiled code
(:mod:`moreau.compiled.tangent`, the same rule on the lowered scene; the impact and
persistent steps stay here), with the same exponents to round-off. That code is compiled
on its first use, apart from the time loop, then kept in numba's cache.

The error is O(h) (the impact instants and states of the reference trajectory), not
``O(h·|v| / delta)`` as for finite differences of the scheme: there is no perturbation
size, and a grazing impact (U⁻ → 0) enters with its exact 1 / U⁻ saltation.

Persistent contacts (a row carrying an impulse in consecutive steps: sliding, resting,
the end of a chattering sequence) are outside the impact saltation theory: on a
constrained phase the flow maps an open set of states onto the constraint manifold, the
phase-space volume collapses, and the sum of all exponents of the true flow is −∞. They
are detected; by default they raise, ``persistent="scheme"`` continues with the Jacobian
of the scheme's own contact step (active set frozen, finite differences) and reports the
number of such steps in ``meta["persistent_steps"]`` and ``meta["warnings"]``: the smaller
exponents and the sum then depend on h.

Checks (``tests/test_dynamics_tangent.py``): the sum is ``−trace(M⁻¹C)`` for a damped
system without impacts (to 1e-9); S equals the saltation matrix of an event-located
flow through an impact of the triple pendulum (M(q), a curved barrier) to 1e-7; the ball
on the vibrating table gives ln|μ|/T of the closed-form multipliers of its period-1
orbit at first order in h (largest exponent 19 %, 3.5 %, 0.8 % off at T/h = 500, 2000,
8000). The sum of the exponents is, by construction, the time average of ``trace A``
plus ``Σ ln|det S|`` per unit time: that it matches the flow's contraction checks the
implementation (det S = e², trace A), while the individual exponents are checked by the
table and by the other methods.

On the chaotic triple pendulum (``forced_triple_pendulum(6.0, 3.0)``) the sum of the
spectrum matches the flow's contraction −⟨trace(M(q)⁻¹C)⟩ + 2 ln(e) × impact rate,
computed from a separate run, to about 0.3 % (:doc:`/studies` has the spectra and their
error bars). At T/h = 1600 there are no persistent contacts and no
grazing onsets (every contact step is a single impact, the slowest at 0.14 m/s); at
T/h = 400 a persistent contact of the wall row now occurs (t = 175.4 s) and the default
``persistent="raise"`` stops there. The finite-difference
spectrum (:func:`~moreau.dynamics.lyapunov_spectrum`) misses the sum there for another
reason, see :mod:`moreau.dynamics.lyapunov`. On the same reference trajectory
(``chunk`` = one interval) the largest exponent agrees with the two-trajectory estimate
where that one resolves the impacts (T/h = 25 600, d0 = 1e-2: paired difference
−0.03 ± 0.05 1/s; ``benchmarks/lyapunov_window.py``).
"""

from __future__ import annotations

import logging
import math

import numpy as np

import moreau as mo

from .lyapunov import LyapunovResult, _setup, _stats, _transient
from .maps import restart, split_state
from .saltation import _expm
from .saltation import _Flow as _Flow  # re-exported: the tests reach it here

__all__ = ["lyapunov_spectrum_tangent"]

log = logging.getLogger(__name__)


def lyapunov_spectrum_tangent(scene: mo.Scene, q0, v0, h: float, *, interval: float, n_intervals: int,
                              k: int | None = None, t0: float = 0.0, n_transient: int = 0, n_align: int = 0,
                              n_blocks: int = 10, persistent: str = "raise", eps: float = 1e-7,
                              chunk: int = 200_000, progress: bool = False,
                              **simulate_kwargs) -> LyapunovResult:
    """The k largest Lyapunov exponents from the tangent dynamics with saltation matrices.

    Parameters
    ----------
    scene : Scene
        Any scene with frictionless Newton contacts.
    h : float
        Step size of the reference trajectory (adjusted to divide ``interval``); the
        error of the exponents is O(h).
    interval : float
        Time per log entry (time units); the frame is re-orthonormalized every step.
    n_intervals : int
        Intervals averaged after the transient and the alignment.
    k : int, optional
        Number of exponents (default all, 2n).
    persistent : {"raise", "scheme"}
        What to do at a step where a row carries an impulse after a step in which it
        already did (a persistent contact): raise ``RuntimeError`` (default), or use the
        Jacobian of the scheme's contact step with the active set frozen, counted in
        ``meta["persistent_steps"]`` with a line in ``meta["warnings"]``.
    eps : float
        Relative finite-difference step of ``∂F/∂x`` (forward) and, as ``sqrt(eps)``,
        of the Newton map's ``∂v⁺/∂q`` (central).
    chunk : int
        Steps of the reference trajectory simulated (and held in memory) at once. With
        ``chunk`` equal to the steps of one interval the reference trajectory is, bit for
        bit, the one :func:`~moreau.dynamics.largest_lyapunov` follows from the same
        arguments (both restart every interval), so that the two estimates can be
        compared interval by interval.
    Other parameters
        ``q0``, ``v0``, ``t0``, ``n_transient``, ``n_align``, ``n_blocks``, ``progress``
        and ``**simulate_kwargs`` as in :func:`~moreau.dynamics.largest_lyapunov`.

    Returns
    -------
    LyapunovResult
        ``exponents`` of shape (k,), method ``"saltation"``. ``meta`` holds ``h``,
        ``interval``, ``n_impacts`` (impacts with a saltation matrix, all rows),
        ``grazing`` (of them, those with ``|U⁻| < h |a_n|``, the scheme's "slow" onsets),
        ``multi_row_steps``, ``skipped_rows`` (a row of a multi-row step no longer
        approaching after the first), ``min_impact_speed``, ``persistent_steps``,
        ``warnings``, and the contraction the frame accumulated: ``mean_trace``, the time
        average of ``trace A`` (1 / time unit), and ``ln_det_impacts``, ``Σ ln|det S|`` per
        unit time; with k = 2n, ``exponents.sum()`` equals their sum up to round-off.
    """
    if persistent not in ("raise", "scheme"):
        raise ValueError(f"persistent must be 'raise' or 'scheme', got {persistent!r}")
    x, _, fmap = _setup(scene, q0, v0, h, interval, t0, None, simulate_kwargs)
    dim = x.shape[0]
    k = dim if k is None else int(k)
    if not 1 <= k <= dim:
        raise ValueError(f"k must be in [1, {dim}], got {k}")
    t = float(t0)
    x, t = _transient(fmap, x, t, n_transient)
    flow = _Flow(scene, float(eps))
    hh, ns = fmap.h, fmap.n_steps
    kw = dict(fmap.simulate_kwargs)
    kw["record_every"] = 1
    n_all = n_align + n_intervals
    per_chunk = max(1, chunk // ns)
    Q = np.ascontiguousarray(np.eye(dim)[:, :k])
    logs = np.zeros((n_all, k))
    times = np.empty(n_all)
    P_prev = np.zeros(scene.nrows)
    stats = {"n_impacts": 0, "grazing": 0, "multi_row_steps": 0, "skipped_rows": 0, "persistent_steps": 0}
    min_speed = math.inf
    trace_sum = 0.0
    lndet_sum = 0.0
    from tqdm import tqdm
    bar = tqdm(total=n_all, disable=not progress, desc="Lyapunov spectrum (saltation)")
    smooth_run = _compiled_smooth_steps(scene, float(eps))
    i = 0
    while i < n_all:
        m = min(per_chunk, n_all - i)
        X, P = _reference(scene, fmap, x, t, m, kw)
        closed = np.any(P[1:] > 0.0, axis=1)
        s = 0
        while s < m * ns:
            if not closed[s]:  # a run of smooth steps, compiled
                e, tr_run = _smooth_run(smooth_run, closed, s, i, ns, n_align, t, hh, X, Q, logs, times, bar)
                trace_sum += tr_run
                P_prev = P[e]
                s = e
                continue
            ts = t + s * hh
            xs, xe = X[s], X[s + 1]
            Ps = P[s + 1]
            counted = i + s // ns >= n_align
            hit = np.flatnonzero(Ps > 0.0)
            if np.any(P_prev[hit] > 0.0):
                stats["persistent_steps"] += counted
                Q, tr_step, ld_step = _persistent_step(flow, Q, ts, hh, xs, hit, P_prev, eps, persistent)
            else:
                Q, tr_step, ld_step, speed = _impact_step(flow, Q, ts, hh, xs, xe, hit, counted, stats)
                min_speed = min(min_speed, speed)
            P_prev = Ps
            Q, d = _reorthonormalized(Q, ts)
            ii = i + s // ns
            logs[ii] += np.log(np.abs(d))
            if counted:
                trace_sum += tr_step
                lndet_sum += ld_step
            if (s + 1) % ns == 0:
                times[ii] = ts + hh
                bar.update(1)
            s += 1
        x = X[-1]
        t += m * fmap.T
        i += m
    bar.close()
    return _result(fmap, logs, times, x, n_align, n_intervals, n_blocks, eps, stats, min_speed, trace_sum,
                   lndet_sum)


def _smooth_run(smooth_run, closed: np.ndarray, s: int, i: int, ns: int, n_align: int, t: float, hh: float,
                X: np.ndarray, Q: np.ndarray, logs: np.ndarray, times: np.ndarray, bar) -> tuple[int, float]:
    """The run of smooth steps from step s of the chunk (interval i at its step 0) to the
    next step with an impulse, in compiled code: its logs added to ``logs``, the ends of
    intervals among them into ``times``. Returns the first step after the run and the
    run's ``Σ h trace A`` over the counted intervals."""
    e = s + int(np.argmax(closed[s:])) if closed[s:].any() else closed.size
    ld, tr = smooth_run(t, hh, X, s, e, Q)
    ii = i + np.arange(s, e) // ns
    np.add.at(logs, ii, ld)
    for st in range(s + (ns - 1 - s % ns), e, ns):  # the interval ends among them
        times[i + st // ns] = t + st * hh + hh
        bar.update(1)
    return e, float(tr[ii >= n_align].sum())


def _compiled_smooth_steps(scene: mo.Scene, eps: float):
    """``run(t, h, X, first, last, Q) -> (ln|diag R| (steps, k), h trace A (steps,))``: the
    smooth steps ``first .. last − 1`` in compiled code (:mod:`moreau.compiled.tangent`, Q
    updated in place)."""
    from moreau.compiled.lowering import lower
    from moreau.compiled.tangent import decode_status, smooth_steps

    cs = lower(scene)
    user = cs.user.addresses

    def run(t: float, h: float, X: np.ndarray, first: int, last: int, Q: np.ndarray):
        ld = np.empty((last - first, Q.shape[1]))
        tr = np.empty(last - first)
        status = smooth_steps(cs.ints, cs.ekind, cs.eoff, cs.pool, user, t, h, X, first, last, eps, Q, ld, tr)
        if status:
            step, code = decode_status(status)
            at = f"t = {t + step * h:.9g}"
            if code == -2:
                raise RuntimeError(f"lyapunov_spectrum_tangent: degenerate frame at {at}")
            if code == -1:
                raise RuntimeError(f"lyapunov_spectrum_tangent: M(q) not positive definite near {at}")
            raise RuntimeError(f"lyapunov_spectrum_tangent: a user callable of scene {scene.name!r} failed "
                               f"near {at} (status {code})")
        return ld, tr

    return run


# -- the steps of the tangent dynamics ----------------------------------------------------
def _reference(scene: mo.Scene, fmap, x: np.ndarray, t: float, m: int, kw: dict) -> tuple[np.ndarray, np.ndarray]:
    """The reference trajectory over m intervals from ``(t, x)``, recorded at every step:
    its states X (steps + 1, 2n) and impulses P (steps + 1, rows)."""
    q, v = split_state(x)
    traj = restart(scene, (t, t + m * fmap.T), q, v, fmap.h, **kw)
    if traj.status != "completed":
        raise RuntimeError(f"lyapunov_spectrum_tangent: the simulation stopped early ({traj.message})")
    X = np.hstack([traj.q, traj.v])
    P = traj.impulses if scene.nrows else np.zeros((X.shape[0], 0))
    return X, P


def _persistent_step(flow: _Flow, Q: np.ndarray, ts: float, hh: float, xs: np.ndarray, hit: np.ndarray,
                     P_prev: np.ndarray, eps: float, persistent: str) -> tuple[np.ndarray, float, float]:
    """A step of a persistent contact: raise (``persistent="raise"``), or the Jacobian of the
    scheme's contact step with the rows ``hit`` held closed (central differences). Returns
    ``(Q, 0, ln|det J|)``."""
    scene = flow.scene
    if persistent == "raise":
        rows = [scene.row_names[r] for r in hit[P_prev[hit] > 0.0]]
        raise RuntimeError(
            f"lyapunov_spectrum_tangent: persistent contact of row(s) {rows} at t = {ts:.9g} "
            "(an impulse in consecutive steps: sliding, resting or chattering), outside the "
            "impact saltation theory; persistent='scheme' continues with the scheme's "
            "contact-step Jacobian (the sum then depends on h)")
    dim = xs.shape[0]
    Js = np.empty((dim, dim))
    for j in range(dim):
        d = eps ** 0.5 * max(1.0, abs(xs[j]))
        yp, ym = xs.copy(), xs.copy()
        yp[j] += d
        ym[j] -= d
        Js[:, j] = (flow.scheme_step(ts, yp, hh, hit) - flow.scheme_step(ts, ym, hh, hit)) / (2 * d)
    Q = Js @ Q
    return Q, 0.0, float(np.log(abs(np.linalg.det(Js))))


def _impact_step(flow: _Flow, Q: np.ndarray, ts: float, hh: float, xs: np.ndarray, xe: np.ndarray,
                 hit: np.ndarray, counted: bool, stats: dict) -> tuple[np.ndarray, float, float, float]:
    """A step with impacts of the rows ``hit``: ``exp((h − τ) A⁺) S exp(τ A⁻)``, the rows in
    the order of their crossing instants τ; counts them in ``stats`` when ``counted``.
    Returns ``(Q, Σ dt trace A, Σ ln|det S|, the slowest counted impact's speed or inf)``."""
    min_speed = math.inf
    qs, vs = split_state(xs)
    g = flow.gaps(qs)
    U = flow.jac(qs) @ vs
    tau = {int(r): (float(np.clip(g[r] / -U[r], -0.5 * hh, hh)) if U[r] < 0 else 0.5 * hh)
           for r in hit}
    order = sorted(tau, key=tau.get)  # type: ignore[arg-type]
    stats["multi_row_steps"] += counted and len(order) > 1
    y, tau_done, tr_step, ld_step = xs.copy(), 0.0, 0.0, 0.0
    A = flow.jacobian(ts, y)
    for r in order:
        dt = tau[r] - tau_done
        y = y + dt * flow.field(ts + tau_done, y)
        Q = _expm(dt * A) @ Q
        tr_step += dt * np.trace(A)
        tau_done = tau[r]
        qy, vy = split_state(y)
        Ur = float(flow.jac(qy)[r] @ vy)
        if Ur >= 0.0:
            stats["skipped_rows"] += counted
            continue
        an = float(flow.jac(qy)[r] @ flow.accel(ts + tau_done, qy, vy))
        S, y = flow.saltation(ts + tau_done, y, r)
        Q = S @ Q
        ld_step += float(np.log(abs(np.linalg.det(S))))
        if counted:
            stats["n_impacts"] += 1
            stats["grazing"] += -Ur < hh * abs(an)
            min_speed = min(min_speed, -Ur)
        A = flow.jacobian(ts + tau_done, y)
    dt = hh - tau_done
    A = flow.jacobian(ts + tau_done + 0.5 * dt, 0.5 * (y + xe))
    Q = _expm(dt * A) @ Q
    tr_step += dt * np.trace(A)
    return Q, tr_step, ld_step, min_speed


def _reorthonormalized(Q: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """The frame re-orthonormalized by QR (diag R made positive) and diag R."""
    Q, R = np.linalg.qr(Q)
    d = np.diag(R)
    if np.any(d == 0) or not np.all(np.isfinite(d)):
        raise RuntimeError(f"lyapunov_spectrum_tangent: degenerate frame at t = {ts:.9g}")
    return Q * np.sign(d), d


def _result(fmap, logs: np.ndarray, times: np.ndarray, x: np.ndarray, n_align: int, n_intervals: int,
            n_blocks: int, eps: float, stats: dict, min_speed: float, trace_sum: float,
            lndet_sum: float) -> LyapunovResult:
    """The exponents from the logs after the alignment, with their ``meta``."""
    warnings: list[str] = []
    if stats["persistent_steps"]:
        warnings.append(f"{stats['persistent_steps']} persistent-contact steps taken with the scheme's "
                        "contact-step Jacobian: the smaller exponents and the sum depend on h")
        log.warning("lyapunov_spectrum_tangent: %s", warnings[-1])
    logs, times = logs[n_align:], times[n_align:]
    exps, err, running = _stats(logs, fmap.T, n_blocks)
    duration = n_intervals * fmap.T
    meta = {"h": fmap.h, "interval": fmap.T, "eps": eps, **stats,
            "min_impact_speed": min_speed, "warnings": warnings}
    meta["mean_trace"] = trace_sum / duration
    meta["ln_det_impacts"] = lndet_sum / duration
    return LyapunovResult(exps, err, times, running, logs, stats["n_impacts"], np.asarray(x, float),
                          "saltation", meta)
