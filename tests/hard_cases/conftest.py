"""Shared checks of the hard cases.

:func:`audit_impacts` is the energy audit every case runs on every run it makes: with
Newton restitution e <= 1 an impact never adds kinetic energy.
"""

from __future__ import annotations

import numpy as np

import moreau as mo

# Round-off allowance of the audit, relative to the energy scale of the run. The logged
# loss is −½ P (U⁺ + U_free), computed from normal velocities that are themselves
# differences of terms of the size of |G||v|: its round-off is a few ulps of the energy
# scale, far below 1e-12 of it.
AUDIT_RTOL = 1e-12


def energy_scale(traj: mo.Trajectory) -> float:
    """The energy scale against which round-off is measured: the largest kinetic energy
    of the run, or of a single impact (P |U|) if larger (energy units of the scene)."""
    scale = 0.0
    if traj.kinetic_energy is not None and len(traj.kinetic_energy):
        scale = float(np.nanmax(np.abs(traj.kinetic_energy)))
    imp = traj.velocity_impacts
    if len(imp):
        scale = max(scale, float(np.max(imp.impulse * np.maximum(np.abs(imp.U_before), np.abs(imp.U_after)))))
    return max(scale, np.finfo(float).tiny)


def newton_dissipation(traj: mo.Trajectory) -> np.ndarray:
    """Kinetic energy the impulse of each logged impact dissipates in the scheme's own
    energy balance: ``−½ P (U⁺ + U⁻)`` per impact (energy units of the scene).

    For a constant mass matrix one step satisfies exactly
    ``ΔT = f(q_m)·(q⁺ − q_k) + ½ Pᵀ G (v_k + v⁺)``, so this is the impulse's share of ΔT;
    with Newton's law (P > 0 ⇒ U⁺ = −e U⁻) it equals ½ P (1 − e) |U⁻| >= 0 for e <= 1.
    """
    imp = traj.velocity_impacts
    return -0.5 * imp.impulse * (imp.U_after + imp.U_before)


def audit_impacts(traj: mo.Trajectory, scale: float | None = None) -> float:
    """Assert that no logged impact of the run gained kinetic energy (e <= 1).

    The audit covers the onsets that pass the velocity test (``traj.velocity_impacts``:
    the row approaches, U⁻ < −h|a_n| < 0), where Newton's law dissipates. An onset after
    a flight may close with U⁻ > 0 (a row pulled back while still moving away): there the
    impulse's work ½ P (U⁻ + U⁺) is positive and is not an impact loss.

    Checks, for every impact: finite values, impulse P >= 0, the logged
    ``impacts.energy_lost >= −AUDIT_RTOL × scale``, and that it is the Newton dissipation
    of the scheme's energy balance (:func:`newton_dissipation`).

    Returns the smallest logged ``energy_lost / scale`` (for reporting).
    """
    imp = traj.velocity_impacts
    if len(imp) == 0:
        return 0.0
    scale = energy_scale(traj) if scale is None else float(scale)
    for name in ("U_before", "U_after", "impulse", "energy_lost"):
        assert np.all(np.isfinite(getattr(imp, name))), f"non-finite impacts.{name}"
    assert np.all(imp.impulse >= 0.0), f"negative impact impulse {imp.impulse.min()!r}"
    worst = int(np.argmin(imp.energy_lost))
    assert imp.energy_lost[worst] >= -AUDIT_RTOL * scale, (
        f"impact {worst} (t = {imp.t[worst]:.9g}, row {imp.row[worst]}) logs a kinetic energy "
        f"gain {-imp.energy_lost[worst]:.3g} > {AUDIT_RTOL:g} x scale {scale:.3g}"
    )
    np.testing.assert_allclose(imp.energy_lost, newton_dissipation(traj), rtol=1e-12, atol=AUDIT_RTOL * scale)
    return float(imp.energy_lost.min() / scale)


def assert_finite(traj: mo.Trajectory) -> None:
    """No NaN or inf in the recorded states, gaps and impulses."""
    for name in ("t", "q", "v", "gaps", "impulses"):
        a = getattr(traj, name)
        assert np.all(np.isfinite(a)), f"non-finite entries in traj.{name}"


def rest_time(t: np.ndarray, v: np.ndarray, tol: float) -> float:
    """First recorded time from which every later |v| stays below ``tol`` (inf if never)."""
    speed = np.abs(np.asarray(v, dtype=float)).reshape(len(t), -1).max(axis=1)
    moving = np.flatnonzero(speed >= tol)
    if moving.size == 0:
        return float(t[0])
    if moving[-1] + 1 >= t.shape[0]:
        return float("inf")
    return float(t[moving[-1] + 1])
