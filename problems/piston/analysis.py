"""Analysis of piston trajectories: crank angle, pin position, tilt, contacts, slaps.

All functions take a :class:`moreau.Trajectory` of the non-dimensional piston scene
(q = (φ1, φ2, φ3), time τ = ω t, lengths in units of l1) and the
:class:`~moreau.problems.piston.params.PistonParameters` it was built from.

Sides and side changes
----------------------
Rows 0–1 are the right wall's corners (top, bottom), rows 2–3 the left wall's. A record
is on the *right* side when only right-wall rows carried an impulse since the previous
record, on the *left* when only left-wall rows did, *both* for a diagonal contact, *none*
in flight. A **side change** is a record on one side after the last one-sided record was
on the other: the transits through flight or a diagonal contact in between do not count
on their own. Repeated impacts on the same wall (e = 0.9) are not side changes; a quick
transit to the other wall and back counts twice, as the paper describes it. Its time is
that of the landing on the new side, at its crossing inside the step (:func:`change_times`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

import moreau as mo

from .model import PistonModel, piston_model
from .params import PistonParameters, groups

__all__ = [
    "RIGHT_ROWS", "LEFT_ROWS", "crank_angle", "pin_position", "lateral_position", "tilt", "contact_side",
    "side_changes", "change_times", "cycle_index", "CycleFigures", "cycle_figures", "friction_loss_per_record",
    "mean_speed_rpm", "settled_speed_rpm", "steady_speed_rpm", "max_penetration_ratio", "SlidingPhase",
    "sliding_phases",
]

RIGHT_ROWS = (0, 1)
LEFT_ROWS = (2, 3)
FOUR_PI = 4.0 * np.pi


def crank_angle(traj: mo.Trajectory) -> np.ndarray:
    """Crank angle φ1 (rad), unwrapped as integrated; firing TDC at multiples of 4π."""
    return traj.q[:, 0]


def pin_position(traj: mo.Trajectory, params: PistonParameters) -> tuple[np.ndarray, np.ndarray]:
    """Piston pin O3: (x_O3, y_O3) in units of l1 (the paper's non-dimensional position)."""
    lam = groups(params).lambda2
    q = traj.q
    return np.sin(q[:, 0]) + lam * np.sin(q[:, 1]), np.cos(q[:, 0]) + lam * np.cos(q[:, 1])


def lateral_position(traj: mo.Trajectory, params: PistonParameters) -> np.ndarray:
    """x_O3 divided by the half-clearance (D − d)/2: ±1 when the pin is as far right/left
    as an untilted piston allows."""
    x, _ = pin_position(traj, params)
    return x / (0.5 * params.clearance / params.l1)


def tilt(traj: mo.Trajectory) -> np.ndarray:
    """Piston tilt φ3 (rad)."""
    return traj.q[:, 2]


def contact_side(traj: mo.Trajectory) -> np.ndarray:
    """Per record: +1 right wall, −1 left wall, 2 both (diagonal), 0 none."""
    P = traj.impulses
    right = (P[:, list(RIGHT_ROWS)] > 0).any(axis=1)
    left = (P[:, list(LEFT_ROWS)] > 0).any(axis=1)
    side = np.zeros(P.shape[0], dtype=int)
    side[right & ~left] = 1
    side[left & ~right] = -1
    side[right & left] = 2
    return side


def side_changes(traj: mo.Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Side changes: record indices and the new side (+1 right, −1 left)."""
    side = contact_side(traj)
    onesided = np.flatnonzero(np.abs(side) == 1)
    if onesided.size < 2:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    s = side[onesided]
    change = np.flatnonzero(s[1:] != s[:-1]) + 1
    return onesided[change], s[change]


def change_times(traj: mo.Trajectory, idx: np.ndarray, new_side: np.ndarray) -> np.ndarray:
    """The time of each side change (τ): when the piston's corner crosses the new side's
    wall, inside the step in which it lands there (the onset's ``t_cross``, second order
    in h for a smooth approach), when a contact onset on that side is logged between the
    change's record and the one before it (``traj.onsets``: after a flight, or fast);
    otherwise (the old side released after a diagonal contact) the change's record time.
    ``idx``, ``new_side``: from :func:`side_changes`.

    A record holds the impulses summed since the one before, so a side change read from the
    records alone is known to the record spacing (``record_every`` steps); the onset log
    places the landing in its step (the step's start ``t`` where ``t_cross`` is unknown:
    files saved before it was logged)."""
    times = traj.t[idx].astype(float)
    if not idx.size:
        return times
    imp = traj.onsets
    right = np.isin(imp.row, RIGHT_ROWS)
    t = traj.t
    # the landing step starts at or after the record before (less 1e-6 of the interval: the
    # round-off of a time summed step by step)
    lo = np.where(idx > 0, t[idx - 1] - 1e-6 * (t[idx] - t[idx - 1]), -np.inf)
    at = imp.times()  # the crossing, else the step's start
    for side, on in ((1, right), (-1, ~right)):
        order = np.argsort(imp.t[on], kind="stable")
        ts, cross = imp.t[on][order], at[on][order]
        sel = np.flatnonzero(new_side == side)
        k = np.searchsorted(ts, lo[sel])  # the first onset on that side from lo on (by its step)
        found = k < ts.size
        j = np.minimum(k, max(ts.size - 1, 0))
        first = ts[j] if ts.size else np.zeros(sel.size)
        hit = found & (first <= t[idx[sel]])
        times[sel[hit]] = cross[j[hit]]
    return times


def cycle_index(traj: mo.Trajectory) -> np.ndarray:
    """Engine cycle (720° of crank angle, from firing TDC) of each record."""
    return np.floor(crank_angle(traj) / FOUR_PI).astype(int)


@dataclass
class CycleFigures:
    """Structural figures of one 720° engine cycle.

    Attributes
    ----------
    cycle : int
        Cycle number k (crank angle in [4πk, 4π(k+1))).
    side_changes : int
        Number of side changes in the cycle.
    change_angles_deg : list of float
        Crank angles of the side changes, 0–720° from firing TDC, at the landing's
        crossing of the wall when the onset log has it (:func:`change_times`).
    impacts : int
        Impacts (logged) in the cycle, all four corners.
    energy_lost : float
        Kinetic energy dissipated at the impacts (J).
    friction_loss : float
        Energy dissipated by skirt friction (J): ``−Σ P_T ½ (U_T + U_T')`` over the
        records of the cycle (impulses summed since the previous record, slip velocities
        at the two records); 0 without friction.
    max_impulse : float
        Largest impulse of a single impact (N s).
    mean_rpm : float
        Mean crank speed over the cycle (rev/min).
    max_penetration : float
        Largest penetration over the cycle divided by the clearance D − d.
    """

    cycle: int
    side_changes: int
    change_angles_deg: list
    impacts: int
    energy_lost: float
    max_impulse: float
    friction_loss: float
    mean_rpm: float
    max_penetration: float


def cycle_figures(traj: mo.Trajectory, params: PistonParameters) -> list[CycleFigures]:
    """Figures of every complete 720° cycle in the trajectory."""
    phi1 = crank_angle(traj)
    cyc = cycle_index(traj)
    idx_change, new_side = side_changes(traj)
    phi_change = np.interp(change_times(traj, idx_change, new_side), traj.t, phi1)
    omega, M11, l1 = params.omega, params.M11, params.l1
    energy_unit = M11 * omega**2  # mass unit M̄_11/l1², length l1, time 1/ω → J
    impulse_unit = M11 * omega / l1  # → N s
    imp = traj.impacts
    imp_phi = np.interp(imp.times(), traj.t, phi1) if len(imp) else np.zeros(0)  # at the crossing
    loss = friction_loss_per_record(traj)
    out = []
    for k in range(int(cyc.min()) if cyc.size else 0, int(cyc.max()) if cyc.size else 0):
        # complete cycles only: the records must cover [4πk, 4π(k+1)]
        if phi1[0] > FOUR_PI * k or phi1[-1] < FOUR_PI * (k + 1):
            continue
        sel = cyc == k
        ch = cyc[idx_change] == k
        in_cycle = (imp_phi >= FOUR_PI * k) & (imp_phi < FOUR_PI * (k + 1))
        t_sel = traj.t[sel]
        mean_speed = (phi1[sel][-1] - phi1[sel][0]) / (t_sel[-1] - t_sel[0])
        g = traj.gaps[sel]
        out.append(CycleFigures(
            cycle=k,
            side_changes=int(ch.sum()),
            change_angles_deg=[float(np.degrees(a - FOUR_PI * k)) for a in phi_change[ch]],
            impacts=int(in_cycle.sum()),
            energy_lost=float(imp.energy_lost[in_cycle].sum() * energy_unit),
            max_impulse=float(imp.impulse[in_cycle].max() * impulse_unit) if in_cycle.any() else 0.0,
            friction_loss=float(loss[sel].sum() * energy_unit),
            mean_rpm=float(mean_speed * params.rpm),
            max_penetration=float(max(0.0, -g.min()) / (params.clearance / l1)) if g.size else 0.0,
        ))
    return out


def friction_loss_per_record(traj: mo.Trajectory) -> np.ndarray:
    """The energy friction dissipated between each record and the one before it (the
    trajectory's units; zeros without friction): ``−Σ_r P_T,r ½ (U_T,r(before) + U_T,r(now))``,
    the tangential impulses summed since the previous record times the mean of the slip
    velocities at the two records (exact for a constant slip between records; the sum
    over a run is checked against the exact ledger ``traj.work["friction"]`` in the tests)."""
    if traj.tangential_impulses is None or traj.slip_velocity is None:
        return np.zeros(len(traj))
    u = traj.slip_velocity
    mean = np.vstack([u[:1], 0.5 * (u[1:] + u[:-1])])
    return -(traj.tangential_impulses * mean).sum(axis=1)


def _analysed_window(traj: mo.Trajectory, skip_cycles: int) -> tuple[int, int, float, float]:
    """Cycles k0 ≤ k < k1 analysed after skipping ``skip_cycles`` from the first complete
    one, and the times (τ) at which the crank passes 4π k0 and 4π k1."""
    phi1 = crank_angle(traj)
    k0 = int(np.ceil(phi1[0] / FOUR_PI)) + skip_cycles
    k1 = int(np.floor(phi1[-1] / FOUR_PI))
    if k1 <= k0:
        raise ValueError("the trajectory holds no complete cycle after the skipped ones")
    t0, t1 = np.interp(FOUR_PI * np.array([k0, k1]), phi1, traj.t)
    return k0, k1, float(t0), float(t1)


def mean_speed_rpm(traj: mo.Trajectory, params: PistonParameters, skip_cycles: int = 0) -> float:
    """Mean crank speed (rev/min) from the start of cycle ``first + skip_cycles`` to the end
    of the last complete cycle: 720° times the number of cycles over the time they took.

    This is the speed the run *had* over those cycles, not the speed the engine settles
    at: a run started at 2000 rpm keeps about that speed for thousands of cycles (the
    relaxation time is ≈ 3 000 cycles); see :func:`settled_speed_rpm` for the settled speed.
    """
    k0, k1, t0, t1 = _analysed_window(traj, skip_cycles)
    return float(FOUR_PI * (k1 - k0) / (t1 - t0) * params.rpm)


def steady_speed_rpm(traj: mo.Trajectory, params: PistonParameters, skip_cycles: int = 0) -> float:
    """Deprecated name of :func:`mean_speed_rpm` (it is a mean over the analysed cycles,
    not a steady speed); warns with ``DeprecationWarning``."""
    warnings.warn("steady_speed_rpm is deprecated: it is the mean crank speed over the analysed cycles; "
                  "use mean_speed_rpm (or settled_speed_rpm for the speed the engine settles at)",
                  DeprecationWarning, stacklevel=2)
    return mean_speed_rpm(traj, params, skip_cycles)


def _state_at(traj: mo.Trajectory, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) at time ``t``, linearly interpolated between the two records around it."""
    i = int(np.clip(np.searchsorted(traj.t, t, side="right") - 1, 0, len(traj.t) - 2))
    w = (t - traj.t[i]) / (traj.t[i + 1] - traj.t[i])
    return (1.0 - w) * traj.q[i] + w * traj.q[i + 1], (1.0 - w) * traj.v[i] + w * traj.v[i + 1]


def settled_speed_rpm(traj: mo.Trajectory, params: PistonParameters, skip_cycles: int = 0,
                      model: PistonModel | None = None) -> float:
    r"""Energy-balance estimate of the speed the engine settles at (rev/min), from the
    analysed cycles of a run (those of :func:`mean_speed_rpm`).

    The engine is self-excited: it settles where the indicated (gas) work per 720° cycle
    balances the brake work 4π M̄0, the joint-damping work W_d and the energy dissipated
    by the piston's contacts — the balance the pressure curve is calibrated to close at
    2000 rpm (:mod:`moreau.problems.piston.pressure`, section Calibration). Of these only
    W_d depends on the speed: at a fixed crank path it is proportional to it
    (W_d = ω ∫ φ'ᵀ C φ' dφ1, φ' = dφ/dφ1), while the gas, brake and contact work per
    cycle are functions of the path alone. So the surplus of the cycles,
    S(ω) = W_gas − 4π M̄0 − E_contacts − W_d(ω), vanishes at

    .. math:: \omega^* = \bar\omega\,\left(1 + \frac{S}{W_d}\right),

    where, over the n analysed cycles, :math:`\bar\omega` is the mean crank speed
    (:func:`mean_speed_rpm`), S = T(end) − T(start) the change of kinetic energy
    T = ½ φ̇ᵀ M(φ) φ̇ between the crank's passes through firing TDC (4π k0 and 4π k1,
    where the configuration, hence gravity's potential, repeats) and
    W_d = ∫ φ̇ᵀ C φ̇ dτ the damping work (C of the scene's ``"damping"`` effect). S and
    W_d are in the scene's energy unit (M̄_11 ω², see
    :mod:`moreau.problems.piston.params`), which cancels; ω is returned in rev/min.
    It is the one-cycle formula of ``benchmarks/steady_speed.py`` (``energy_balance``,
    the README's steady-speed section), applied to the records of the run: the states
    at the two passes are interpolated linearly between records, and W_d is the
    trapezoid rule on the records (at about 0.1° of crank angle per record, the default
    of the job and the study, the estimate is within 0.01 rpm of the one from every
    step).

    A first-order extrapolation: measured at h = 1e-3 (e = 0, D = 80.04 mm), a run
    whose mean speed is 2005.79 rpm gives 1988.37 rpm, while runs of 13 000–18 000
    cycles settle at 1988.57–1988.64 rpm (fitted, README); a run restarted at 1988.46
    rpm gives 1988.65 rpm. With slaps the error grows with the correction: e = 0.9 gives
    1988.71 against 1989.05–1989.13 rpm at D = 80.04 mm, and 1956.03 against
    1957.39–1957.58 rpm at D = 80.2 mm (a 50 rpm correction). It is the settled speed of the discretised engine at the
    run's step h (O(h): 1988.6 rpm at h = 1e-3, 1996.0 at 1e-4).

    Parameters
    ----------
    traj : moreau.Trajectory
        A run of the engine scene (non-dimensional, time τ = ω t).
    params : PistonParameters
        Its parameters (``params.rpm`` converts the non-dimensional speed).
    skip_cycles : int
        Complete cycles skipped at the start (the transient).
    model : PistonModel, optional
        The model that produced ``traj`` (its scene gives M(φ) and C); default
        ``piston_model(params)``, the engine with every effect and the calibrated curve.

    Returns
    -------
    float
        The estimated settled crank speed (rev/min).

    Raises
    ------
    ValueError
        If the trajectory holds no complete cycle after the skipped ones, or the scene
        has no joint damping (then no loss grows with the speed).
    """
    model = piston_model(params) if model is None else model
    damping = [f for f in model.scene.effects if f.name == "damping"]
    if not damping:
        raise ValueError("the settled-speed estimate needs the joint damping in the scene (effect 'damping')")
    C = np.asarray(damping[0].C)
    k0, k1, t0, t1 = _analysed_window(traj, skip_cycles)
    (q0, v0), (q1, v1) = _state_at(traj, t0), _state_at(traj, t1)
    surplus = model.scene.kinetic_energy(q1, v1) - model.scene.kinetic_energy(q0, v0)
    inside = (traj.t > t0) & (traj.t < t1)
    t = np.concatenate([[t0], traj.t[inside], [t1]])
    v = np.vstack([v0, traj.v[inside], v1])
    power = np.einsum("ki,ij,kj->k", v, C, v)
    w_damping = float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))
    if not w_damping > 0.0:
        raise ValueError(f"no damping work over the analysed cycles ({w_damping!r})")
    omega = FOUR_PI * (k1 - k0) / (t1 - t0)
    return float(omega * (1.0 + surplus / w_damping) * params.rpm)


def max_penetration_ratio(traj: mo.Trajectory, params: PistonParameters) -> float:
    """Largest penetration over every step divided by the clearance D − d."""
    return mo.diagnostics.max_penetration(traj) / (params.clearance / params.l1)


@dataclass
class SlidingPhase:
    """A run of records in which one wall alone carries the piston for at least a few
    degrees of crank angle, with the impacts on that wall that led into it.

    Attributes
    ----------
    start, end : int
        First and last record of the phase.
    side : int
        +1 right wall, −1 left wall.
    start_deg, end_deg : float
        Crank angles (0–720° from firing TDC) of its ends.
    impacts_before : int
        Impacts on that wall since the end of the previous sliding phase.
    """

    start: int
    end: int
    side: int
    start_deg: float
    end_deg: float
    impacts_before: int


def sliding_phases(traj: mo.Trajectory, min_deg: float = 1.0) -> list[SlidingPhase]:
    """Sliding phases of at least ``min_deg`` degrees of crank angle, in order."""
    side = contact_side(traj)
    phi = crank_angle(traj)
    imp = traj.impacts
    imp_phi = np.interp(imp.times(), traj.t, phi) if len(imp) else np.zeros(0)
    imp_side = np.where(np.isin(imp.row, RIGHT_ROWS), 1, -1)
    out: list[SlidingPhase] = []
    i, n, prev_end_phi = 0, side.shape[0], phi[0] if side.size else 0.0
    while i < n:
        if abs(side[i]) != 1:
            i += 1
            continue
        j = i
        while j + 1 < n and side[j + 1] == side[i]:
            j += 1
        if np.degrees(phi[j] - phi[i]) >= min_deg:
            before = (imp_phi > prev_end_phi) & (imp_phi <= phi[i]) & (imp_side == side[i])
            out.append(SlidingPhase(i, j, int(side[i]), float(np.degrees(phi[i] % FOUR_PI)),
                                    float(np.degrees(phi[j] % FOUR_PI)), int(before.sum())))
            prev_end_phi = phi[j]
        i = j + 1
    return out
