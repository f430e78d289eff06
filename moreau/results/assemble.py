"""The one assembler of a :class:`~moreau.results.trajectory.Trajectory`: both paths of
:func:`moreau.simulate` hand their records here."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from moreau.core.version import __version__
from moreau.results.impacts import ImpactLog, SolverStats
from moreau.results.trajectory import Trajectory

__all__ = ["assemble"]

log = logging.getLogger(__name__)


def assemble(scene: Any, *, t: np.ndarray, q: np.ndarray, v: np.ndarray, impulses: np.ndarray,
             active: np.ndarray, onsets: ImpactLog, stats: SolverStats, h: float, stride: int, status: str,
             message: str, work: dict[str, float], max_penetration: np.ndarray,
             max_penetration_t: np.ndarray | None, energy: bool,
             gaps: np.ndarray | None = None, kinetic: np.ndarray | None = None,
             potential: np.ndarray | None = None, tangential_impulses: np.ndarray | None = None,
             slip: np.ndarray | None = None, constraint_impulses: np.ndarray | None = None,
             constraint_residuals: np.ndarray | None = None) -> Trajectory:
    """The Trajectory of a run from its records (arrays of N records, time-major).

    ``gaps``, ``kinetic`` and ``potential`` are what the loop computed at the records (the
    compiled loop does); the ones not given (the Python loop) are evaluated here on the
    recorded states. With friction (``tangential_impulses`` given) the slip velocities
    ``T(q) v`` at the records likewise, and with bilateral constraints their residuals
    ``g_E(q)``. A model function failing in that evaluation leaves NaN and a warning:
    the trajectory is kept (the failure may be why the run stopped).
    """
    m = scene.nrows
    N = t.shape[0]
    if gaps is None:
        gaps = _per_record(lambda i: scene.gaps(q[i]), N if m else 0, (N, m), "gaps")
    if energy and kinetic is None:
        kinetic = _per_record(lambda i: scene.kinetic_energy(q[i], v[i]), N, (N,), "kinetic energy")
    if energy and potential is None:
        potential = _per_record(lambda i: scene.potential_energy(q[i]), N, (N,), "potential energy")
    if tangential_impulses is not None and slip is None:  # the slip velocities T(q) v at the records
        slip = _per_record(lambda i: scene.tangent_jacobian(q[i]) @ v[i], N, (N, m), "slip velocities")
    me = getattr(scene, "nconstraints", 0)
    if me and constraint_residuals is None:
        constraint_residuals = _per_record(lambda i: scene.constraint_gaps(q[i]), N, (N, me),
                                           "constraint residuals")
    sticking = None
    if tangential_impulses is not None:  # strictly inside the cone: Coulomb's law holds the slip at 0
        bound = (1.0 - 1e-9) * np.asarray(scene.friction) * impulses
        sticking = active & (impulses > 0.0) & (np.abs(tangential_impulses) < bound)
    total = kinetic + potential if energy and kinetic is not None and potential is not None else None
    return Trajectory(
        t=t, q=q, v=v, gaps=gaps, impulses=impulses, active=active, onsets=onsets, stats=stats, h=h,
        record_every=stride, row_names=list(scene.row_names), scene=scene.describe(), energy=total,
        kinetic_energy=kinetic if energy else None, potential_energy=potential if energy else None,
        status=status, message=message, version=__version__, max_penetration=max_penetration, work=work,
        max_penetration_t=max_penetration_t,
        tangential_impulses=tangential_impulses, slip_velocity=slip, sticking=sticking,
        constraint_impulses=constraint_impulses if me else None,
        constraint_residuals=constraint_residuals if me else None,
        constraint_names=list(getattr(scene, "constraint_names", [])),
    )


def _per_record(value: Any, N: int, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value(i)`` for the first N records into an array of ``shape`` (NaN where not evaluated)."""
    out = np.full(shape, np.nan)
    try:
        for i in range(N):
            out[i] = value(i)
    except Exception as exc:  # noqa: BLE001 - reported, and the data kept
        log.warning("could not evaluate the %s on the recorded states: %s", what, exc)
    return out
