"""Which path runs a scene: compiled when everything in it compiles, else the Python
reference (:func:`choose_backend`); and the trajectory of a run stopped before its first step."""

from __future__ import annotations

import logging
from typing import Any, Protocol

import numpy as np

from moreau.contact.solvers import ContactSolver
from moreau.model.scene import Scene
from moreau.results.assemble import assemble
from moreau.results.impacts import ImpactLog, SolverStats
from moreau.results.trajectory import Trajectory
from moreau.step.integrator import (
    MoreauJeanEnergyConsistent,
    MoreauJeanMidpoint,
    MoreauJeanPredictorCorrector,
    OneStepIntegrator,
)

__all__ = ["DriftControl", "choose_backend", "initial_state_only"]

log = logging.getLogger("moreau.run.simulation")


class DriftControl(Protocol):
    """What ``simulate(..., drift_control=...)`` accepts (:class:`moreau.PositionProjection`)."""

    def project(self, integ: Any, q: np.ndarray) -> np.ndarray:
        """The corrected end position q⁺ of the integrator's last step."""
        ...


def initial_state_only(scene: Scene, t0: float, q0: np.ndarray, v0: np.ndarray, h: float, stride: int,
                        solver: str | ContactSolver | None, fallback: str | ContactSolver | None) -> Trajectory:
    """The trajectory of a run interrupted before its first step: the initial state."""
    m = scene.nrows
    return assemble(
        scene, t=np.array([t0]), q=q0[None, :].copy(), v=v0[None, :].copy(), impulses=np.zeros((1, m)),
        active=np.zeros((1, m), dtype=bool), onsets=ImpactLog(),
        stats=SolverStats(solver=str(solver), fallback=str(fallback or ""), backend="compiled"), h=h, stride=stride,
        status="interrupted", message=f"interrupted by the user at step 0 (t = {t0:.9g})", work={},
        max_penetration=np.zeros(m), max_penetration_t=np.full(m, np.nan), energy=False, gaps=np.full((1, m), np.nan),
    )


def choose_backend(backend: str, scene: Scene, integrator: type[OneStepIntegrator],
                    solver: str | ContactSolver | None, fallback: str | ContactSolver | None,
                    drift_control: DriftControl | None,
                    ) -> tuple[str, Any, str | ContactSolver, str | ContactSolver | None]:
    """``(path, compiled scene or None, solver, fallback)`` for :func:`simulate`."""
    from moreau.compiled.lowering import lower
    from moreau.compiled.runner import COMPILED_SOLVERS
    from moreau.contact.solvers import ContactSolver
    from moreau.step.drift import CombinedProjection, PositionProjection

    if backend not in ("auto", "compiled", "python"):
        raise ValueError(f"backend must be 'auto', 'compiled' or 'python', got {backend!r}")
    for what, x in (("solver", solver), ("fallback", fallback)):
        if x is not None and not isinstance(x, (str, ContactSolver)):
            raise ValueError(f"{what} must be a name or a ContactSolver, got {x!r}")
    reason = ""
    if backend != "python":
        if integrator not in (MoreauJeanMidpoint, MoreauJeanPredictorCorrector, MoreauJeanEnergyConsistent):
            reason = f"integrator {integrator.__name__} has no compiled form"
        elif drift_control is not None and type(drift_control) not in (PositionProjection, CombinedProjection):
            reason = f"drift control {type(drift_control).__name__} has no compiled form"
        elif solver is not None and solver not in COMPILED_SOLVERS:
            reason = f"solver {solver!r} does not run in compiled code (compiled: {sorted(COMPILED_SOLVERS)})"
        elif fallback not in ("auto", None) and fallback not in COMPILED_SOLVERS:
            reason = f"fallback {fallback!r} does not run in compiled code (compiled: {sorted(COMPILED_SOLVERS)})"
        else:
            cs = lower(scene)  # every scene lowers (callables numba cannot compile are called back)
    if backend == "compiled" and reason:
        raise ValueError(f"backend='compiled': {reason}")
    path = "python" if (backend == "python" or reason) else "compiled"
    if backend == "auto" and reason:
        log.info("running %r on the Python path: %s", scene.name, reason)
    if solver is None:
        solver = "exact" if path == "compiled" else "osqp"
    if fallback == "auto":
        fallback = "exact" if solver == "enum" else "enum"
    if isinstance(solver, str) and solver == fallback:
        raise ValueError(f"fallback must differ from the main solver, got {solver!r} twice")
    return path, (cs if path == "compiled" else None), solver, fallback


def _no_gaps(q: np.ndarray) -> np.ndarray:
    """The gaps of a scene without contacts (none)."""
    return np.zeros(0)
