"""The numpy reference of the Moreau–Jean step: an independent oracle for the tests.

The product runs every scene in the compiled loop (:mod:`moreau.compiled`). This package
keeps the step written a second time in plain numpy, readable line by line, so that tests
can compare the loop against it: :func:`simulate` with ``backend="python"`` runs the
reference (``traj.stats.backend == "python"``), any other backend runs
:func:`moreau.simulate`. It is not part of the installed package.
"""

from __future__ import annotations

from typing import Any

import numpy as np

import moreau as mo
from moreau.core.validation import as_positive, checked_start
from moreau.model.stability import DEFAULT_ENERGY_GROWTH, as_energy_growth
from moreau.run.flights import flight_gaps, initial_flight
from moreau.run.simulation import _iteration, _steps_and_records
from moreau.run.trust import check_jacobians, penetration_warnings, redundancy_warnings
from oracle import integrator as _ref
from oracle.base import ContactDetails, OneStepIntegrator
from oracle.drift import CombinedProjection, PositionProjection, reference_projection
from oracle.integrator import MoreauJeanEnergyConsistent, MoreauJeanMidpoint, MoreauJeanPredictorCorrector
from oracle.python_loop import run_python

__all__ = ["simulate", "run_piston", "reference_integrator", "OneStepIntegrator", "MoreauJeanMidpoint",
           "MoreauJeanPredictorCorrector", "MoreauJeanEnergyConsistent", "PositionProjection",
           "CombinedProjection", "ContactDetails"]


def reference_integrator(integrator: type) -> type[OneStepIntegrator]:
    """The reference class of a scheme given to :func:`moreau.simulate` (its settings kept)."""
    if issubclass(integrator, OneStepIntegrator):
        return integrator
    if issubclass(integrator, mo.MoreauJeanEnergyConsistent):
        return type(integrator.__name__, (_ref.MoreauJeanEnergyConsistent,),
                    {"max_iterations": integrator.max_iterations, "iteration_tol": integrator.iteration_tol})
    if issubclass(integrator, mo.MoreauJeanPredictorCorrector):
        return _ref.MoreauJeanPredictorCorrector
    if issubclass(integrator, mo.MoreauJeanMidpoint):
        return _ref.MoreauJeanMidpoint
    raise ValueError(f"integrator must be a OneStepIntegrator subclass, got {integrator!r}")


def run_piston(model, cycles: float, h: float, backend: str = "python", **kw: Any) -> mo.Trajectory:
    """``PistonModel.simulate`` (its defaults: penetration limit the clearance, flight gap 2 %
    of it) on ``backend``."""
    from moreau.problems.piston.model import FLIGHT_FRACTION

    p = model.params
    kw.setdefault("penetration_limit", p.clearance / p.l1)
    kw.setdefault("flight_gap", FLIGHT_FRACTION * p.clearance / p.l1)
    q0, v0 = model.initial_state()
    return simulate(model.scene, (0.0, 4 * np.pi * cycles), q0, v0, h, backend=backend, **kw)


def simulate(scene: mo.Scene, t_span, q0, v0, h: float, *, backend: str = "python",
             integrator: type = mo.MoreauJeanMidpoint, solver: Any = None, fallback: Any = "auto",
             record_every: int = 1, progress: Any = False, energy: bool = True, tol: float = 1e-6,
             drift_control: Any = None, check_jacobian: bool = True, penetration_limit: float | None = None,
             flight_gap: Any = 0.0, initial_penetration: float = 1e-12,
             energy_growth: Any = DEFAULT_ENERGY_GROWTH) -> mo.Trajectory:
    """:func:`moreau.simulate` on the reference step (``backend="python"``; default solver
    ``"osqp"``) or on the compiled loop (any other backend)."""
    if backend != "python":
        if isinstance(integrator, type) and issubclass(integrator, OneStepIntegrator):
            integrator = getattr(mo, integrator.__name__)
        return mo.simulate(scene, t_span, q0, v0, h, backend=backend, integrator=integrator, solver=solver,
                           fallback=fallback,
                           record_every=record_every, progress=progress, energy=energy, tol=tol,
                           drift_control=drift_control, check_jacobian=check_jacobian,
                           penetration_limit=penetration_limit, flight_gap=flight_gap,
                           initial_penetration=initial_penetration, energy_growth=energy_growth)
    t0, _, n_steps, stride, n_rec = _steps_and_records(scene, t_span, h, record_every)
    initial_penetration = as_positive(initial_penetration, "initial_penetration", allow_zero=True)
    if isinstance(integrator, type) and issubclass(integrator, mo.OneStepIntegrator):
        _iteration(integrator)  # the product's checks of an iterating step's settings
    integ = reference_integrator(integrator)(scene, h, solver=solver or "osqp", fallback=fallback, tol=tol,
                                             drift_control=reference_projection(drift_control),
                                             penetration_tol=initial_penetration)
    checked_start(lambda: integ.init(t0, q0, v0), scene, t0, q0, v0)
    if check_jacobian and scene.nrows:
        check_jacobians(scene, integ.q)
    traj = run_python(scene, integ, h, n_steps, stride, n_rec, progress, energy, flight_gaps(flight_gap, scene.nrows),
                      initial_flight(scene, integ.q, integ.v), as_energy_growth(energy_growth))
    traj.warnings = (redundancy_warnings(scene, q0) + traj.warnings
                     + penetration_warnings(scene, traj, h, penetration_limit))
    return traj
