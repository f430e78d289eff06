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
transit to the other wall and back counts twice, as the paper describes it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import moreau as mo

from .params import PistonParameters, groups

__all__ = [
    "RIGHT_ROWS", "LEFT_ROWS", "crank_angle", "pin_position", "lateral_position", "tilt",
    "contact_side", "side_changes", "cycle_index", "CycleFigures", "cycle_figures",
    "steady_speed_rpm", "max_penetration_ratio", "SlidingPhase", "sliding_phases",
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
        Crank angles of the side changes, 0–720° from firing TDC.
    impacts : int
        Impacts (logged) in the cycle, all four corners.
    energy_lost : float
        Kinetic energy dissipated at the impacts (J).
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
    mean_rpm: float
    max_penetration: float


def cycle_figures(traj: mo.Trajectory, params: PistonParameters) -> list[CycleFigures]:
    """Figures of every complete 720° cycle in the trajectory."""
    phi1 = crank_angle(traj)
    cyc = cycle_index(traj)
    idx_change, _ = side_changes(traj)
    omega, M11, l1 = params.omega, params.M11, params.l1
    energy_unit = M11 * omega**2  # mass unit M̄_11/l1², length l1, time 1/ω → J
    impulse_unit = M11 * omega / l1  # → N s
    imp = traj.impacts
    imp_phi = np.interp(imp.t, traj.t, phi1) if len(imp) else np.zeros(0)
    out = []
    for k in range(int(cyc.min()) if cyc.size else 0, int(cyc.max()) if cyc.size else 0):
        # complete cycles only: the records must cover [4πk, 4π(k+1)]
        if phi1[0] > FOUR_PI * k or phi1[-1] < FOUR_PI * (k + 1):
            continue
        sel = cyc == k
        ch = idx_change[cyc[idx_change] == k]
        in_cycle = (imp_phi >= FOUR_PI * k) & (imp_phi < FOUR_PI * (k + 1))
        t_sel = traj.t[sel]
        mean_speed = (phi1[sel][-1] - phi1[sel][0]) / (t_sel[-1] - t_sel[0])
        g = traj.gaps[sel]
        out.append(CycleFigures(
            cycle=k,
            side_changes=int(ch.size),
            change_angles_deg=[float(np.degrees(a - FOUR_PI * k)) for a in phi1[ch]],
            impacts=int(in_cycle.sum()),
            energy_lost=float(imp.energy_lost[in_cycle].sum() * energy_unit),
            max_impulse=float(imp.impulse[in_cycle].max() * impulse_unit) if in_cycle.any() else 0.0,
            mean_rpm=float(mean_speed * params.rpm),
            max_penetration=float(max(0.0, -g.min()) / (params.clearance / l1)) if g.size else 0.0,
        ))
    return out


def steady_speed_rpm(traj: mo.Trajectory, params: PistonParameters, skip_cycles: int = 0) -> float:
    """Mean crank speed (rev/min) from the start of cycle ``first + skip_cycles`` to the end
    of the last complete cycle."""
    phi1 = crank_angle(traj)
    k0 = int(np.ceil(phi1[0] / FOUR_PI)) + skip_cycles
    k1 = int(np.floor(phi1[-1] / FOUR_PI))
    if k1 <= k0:
        raise ValueError("the trajectory holds no complete cycle after the skipped ones")
    t0 = np.interp(FOUR_PI * k0, phi1, traj.t)
    t1 = np.interp(FOUR_PI * k1, phi1, traj.t)
    return float(FOUR_PI * (k1 - k0) / (t1 - t0) * params.rpm)


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
    imp_phi = np.interp(imp.t, traj.t, phi) if len(imp) else np.zeros(0)
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
