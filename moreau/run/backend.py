"""A run's checked choices (:func:`choose_backend`: the lowered scene, its solvers) and the
trajectory of a run stopped before its first step."""

from __future__ import annotations

import logging
import warnings
from typing import Any

import numpy as np

from moreau.contact.solvers import ContactSolver, make_solver
from moreau.model.scene import Scene
from moreau.results.assemble import assemble
from moreau.results.impacts import ImpactLog, SolverStats
from moreau.results.trajectory import Trajectory
from moreau.step.drift import PositionProjection
from moreau.step.integrator import OneStepIntegrator

__all__ = ["DriftControl", "choose_backend", "initial_state_only"]

log = logging.getLogger("moreau.run.simulation")


#: what ``simulate(..., drift_control=...)`` accepts (CombinedProjection is one)
DriftControl = PositionProjection


def initial_state_only(scene: Scene, t0: float, q0: np.ndarray, v0: np.ndarray, h: float, stride: int,
                        solver: str | ContactSolver | None, fallback: str | ContactSolver | None) -> Trajectory:
    """The trajectory of a run interrupted before its first step: the initial state."""
    m = scene.nrows
    return assemble(
        scene, t=np.array([t0]), q=q0[None, :].copy(), v=v0[None, :].copy(), impulses=np.zeros((1, m)),
        active=np.zeros((1, m), dtype=bool), onsets=ImpactLog(),
        stats=SolverStats(solver=_name(solver), fallback=_name(fallback), backend="compiled"), h=h, stride=stride,
        status="interrupted", message=f"interrupted by the user at step 0 (t = {t0:.9g})", work={},
        max_penetration=np.zeros(m), max_penetration_t=np.full(m, np.nan), energy=False, gaps=np.full((1, m), np.nan),
    )


def choose_backend(backend: str, scene: Scene, integrator: type[OneStepIntegrator],
                   solver: str | ContactSolver | None, fallback: str | ContactSolver | None,
                   drift_control: DriftControl | None) -> tuple[Any, str | ContactSolver, str | ContactSolver | None]:
    """``(compiled scene, solver, fallback)`` for :func:`simulate`: the checked choices of a
    run, every scene lowered to the compiled loop."""
    from moreau.compiled.lowering import lower

    if backend not in ("auto", "compiled", "python"):
        raise ValueError(f"backend must be 'auto' or 'compiled', got {backend!r}")
    if backend == "python":
        warnings.warn("backend='python' is deprecated and chooses nothing: every scene runs in the compiled "
                      "loop", DeprecationWarning, stacklevel=4)
    for what, x in (("solver", solver), ("fallback", fallback)):
        if x is not None and not isinstance(x, (str, ContactSolver)):
            raise ValueError(f"{what} must be a name or a ContactSolver, got {x!r}")
        if isinstance(x, str) and x != "auto":
            make_solver(x)  # an unknown name is refused here, naming the choices
    if drift_control is not None and not isinstance(drift_control, PositionProjection):
        raise ValueError(f"drift_control must be a PositionProjection or a CombinedProjection, got {drift_control!r}")
    if solver is None or solver == "auto":  # the loop's exact solver picks its method by size
        solver = "exact"
    if fallback == "auto":
        fallback = "exact" if solver == "enum" else "enum"
    if fallback is not None and _name(solver) == _name(fallback):
        raise ValueError(f"fallback must be another solver than the main one, got {_name(solver)!r} twice")
    return lower(scene), solver, fallback


def _name(solver: str | ContactSolver | None) -> str:
    """A solver's name in results ("" for none)."""
    return "" if solver is None else solver if isinstance(solver, str) else solver.name
