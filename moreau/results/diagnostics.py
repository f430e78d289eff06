"""Measurements on trajectories shared by tests, benchmarks and notebooks."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from moreau.results.trajectory import Trajectory

if TYPE_CHECKING:
    from moreau.model.scene import Scene

__all__ = ["convergence_order", "max_penetration", "impact_energy_audit"]


def convergence_order(h: ArrayLike, errors: ArrayLike) -> float:
    """Observed order p of ``error ≈ C h^p``: least-squares slope of log(error) on log(h).

    Parameters
    ----------
    h, errors : array_like, shape (k,)
        Step sizes and the errors measured with them (k >= 2, all positive).
    """
    h = np.asarray(h, dtype=float)
    err = np.asarray(errors, dtype=float)
    if h.shape != err.shape or h.shape[0] < 2:
        raise ValueError(f"need at least two (h, error) pairs of equal length, got {h.shape} and {err.shape}")
    if np.any(h <= 0) or np.any(err <= 0) or not np.all(np.isfinite(err)):
        raise ValueError(f"steps and errors must be positive and finite, got h={h.tolist()}, errors={err.tolist()}")
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])


def max_penetration(traj: Trajectory) -> float:
    """Largest penetration ``max(0, -min g)`` over every step of the run (gap units):
    ``traj.max_penetration`` (kept per step by both paths), and the records for a
    trajectory saved without it."""
    rec = max(0.0, -float(np.nanmin(traj.gaps))) if traj.gaps.size else 0.0
    if traj.max_penetration is not None and np.size(traj.max_penetration):
        return max(rec, float(np.max(traj.max_penetration)))
    return rec


def impact_energy_audit(traj: Trajectory) -> float:
    """Smallest kinetic energy lost at any logged impact (J); negative means a gain."""
    if len(traj.impacts) == 0:
        return 0.0
    return float(traj.impacts.energy_lost.min())


def energy_ledger(traj: Trajectory, scene: Scene) -> dict[str, Any]:
    """Energy balance of a run: the work of each effect, the impact losses, ΔKE, ΔPE.

    Every effect's work is the integral of its power ``vᵀ f(t, q, v)`` over the recorded
    states (composite trapezoid), the impact losses are the ``energy_lost`` of every
    onset that passes the velocity test (``traj.velocity_impacts``, not only the impacts
    after a flight) summed, and the ledger closes when

    .. math:: \\sum_e W_e = \\Delta T + E_{\\mathrm{impacts}} + \\text{residual},

    with T the kinetic energy ½ vᵀ M(q) v. The velocity-squared terms of a
    configuration-dependent mass matrix do no work (``vᵀ f_bias = −½ vᵀ Ṁ v``, which is
    part of dT/dt), so they have no entry. For an effect with a potential V the work is
    also ``−ΔV`` exactly; both are returned (``work`` integrated, ``potential_change``
    exact) and the difference is a measure of the quadrature error.

    Error of the integrated work: between impacts the power is smooth and the trapezoid
    rule errs by about ``Δt²/12 · ∫|P''|`` with Δt = ``h · record_every``; at an impact
    the velocity jumps and each jump adds up to ``Δt/2 · |jump of P|`` (of either sign).
    ``quadrature_error`` is the change of Σ work when every other record is dropped — an
    indicator of the quadrature error, not a bound: with jumps the error is not O(Δt²)
    and the indicator can be off by a few times either way. Measured on the chattering
    piston (e = 0.9, h = 1e-3, 20 cycles, ~280 impacts per cycle): Σ work changes by
    at most 1.3 % of the residual from record_every = 1 to 20, and by 40 % at 40 (Δτ = 0.04,
    2.3° of crank angle, too coarse for the combustion peak). Halve ``record_every`` to
    check a ledger.

    What the ledger leaves out and the residual therefore contains: the energy exchanged
    by contact impulses in steps that are not logged impacts (a sustained sliding
    contact, the midpoint drift re-closing a row), and the energy error of the scheme
    itself (order 1 with velocity-dependent forces). The logged ``energy_lost`` is
    measured against the free velocity v_free = v_k + h M⁻¹ f, so it also holds the
    change ½ P h a_n of the smooth forces' work caused by the impulse; on the chattering
    piston (e = 0.9, h = 1e-3) that is about half the residual.

    Parameters
    ----------
    traj : Trajectory
        A run of ``scene`` (at least two records).
    scene : Scene
        The scene that produced it (its effects are evaluated on the records).

    Returns
    -------
    dict
        ``work`` : dict name -> float, integrated work of each effect (energy units of
        the scene, e.g. J; positive = energy put into the system);
        ``potential_change`` : dict name -> float, ΔV of the effects with a potential;
        ``impact_loss`` : float, kinetic energy dissipated at the velocity-test onsets;
        ``kinetic_change`` : float, T(end) − T(start);
        ``residual`` : float, Σ work − kinetic_change − impact_loss;
        ``scale`` : float, ``Σ |work| + |kinetic_change| + impact_loss`` (for a relative
        residual);
        ``quadrature_error`` : float, change of Σ work when every other record is
        dropped (an indicator of the trapezoid error, see above);
        ``records`` : int, number of records used.

    Raises
    ------
    ValueError
        For fewer than two records, or a trajectory whose state size differs from the
        scene's.
    """
    t = np.asarray(traj.t, dtype=float)
    q = np.asarray(traj.q, dtype=float)
    v = np.asarray(traj.v, dtype=float)
    N = t.shape[0]
    if N < 2:
        raise ValueError(f"energy_ledger needs at least two records, got {N}")
    if q.shape[1] != scene.ndof:
        raise ValueError(f"trajectory has {q.shape[1]} coordinates, the scene {scene.ndof}")
    work: dict[str, float] = {}
    potential_change: dict[str, float] = {}
    quad = 0.0
    for eff in scene.effects:
        power = np.array([float(v[i] @ eff.force(t[i], q[i], v[i])) for i in range(N)])
        fine = _trapezoid(t, power)
        work[eff.name] = fine
        if N >= 5:
            coarse = _trapezoid(t[::2], power[::2]) if (N - 1) % 2 == 0 else (
                _trapezoid(t[:-1:2], power[:-1:2]) + _trapezoid(t[-2:], power[-2:]))
            quad += abs(fine - coarse)
        if eff.has_potential:
            potential_change[eff.name] = float(eff.potential(q[-1]) - eff.potential(q[0]))
    if traj.kinetic_energy is not None:
        dT = float(traj.kinetic_energy[-1] - traj.kinetic_energy[0])
    else:
        dT = scene.kinetic_energy(q[-1], v[-1]) - scene.kinetic_energy(q[0], v[0])
    vi = traj.velocity_impacts  # every fast onset: the ledger's impact term (not only those after a flight)
    loss = float(np.sum(vi.energy_lost)) if len(vi) else 0.0
    total = float(sum(work.values()))
    return {
        "work": work,
        "potential_change": potential_change,
        "impact_loss": loss,
        "kinetic_change": dT,
        "residual": total - dT - loss,
        "scale": float(sum(abs(w) for w in work.values()) + abs(dT) + abs(loss)),
        "quadrature_error": quad,
        "records": N,
    }


def _trapezoid(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


__all__ += ["energy_ledger"]
