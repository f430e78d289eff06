"""moreau: non-smooth multibody mechanics with a Moreau–Jean midpoint time-stepper.

The pieces, in the field's vocabulary, and where they live:

* a *system* (:class:`FunctionSystem`, or a subclass of :class:`MechanicalSystem`): q, M(q);
  *effects*, smooth forces f(t, q, v); *contacts*, a *barrier* g(q) >= 0 with a Newton
  impact law; a *scene* (:class:`Scene`) of exactly the effects and contacts asked for —
  :mod:`moreau.model`;
* the one-step non-smooth problem and its *solvers* — :mod:`moreau.contact`;
* the one-step *integrators* (:class:`MoreauJeanMidpoint`) and drift control —
  :mod:`moreau.step`, run by the compiled time loop in :mod:`moreau.compiled`;
* the front door :func:`simulate` (:mod:`moreau.run`), which returns a
  :class:`Trajectory` (:mod:`moreau.results`);
* physics kernels and errors, the ground floor — :mod:`moreau.core`.
"""

import sys

from .core.jitcache import lock_cache_saves as _lock_cache_saves
from .core.jitcache import use_process_cache_when_none_is_writable as _use_process_cache

_use_process_cache()  # before any of moreau's cached functions is defined
_lock_cache_saves()
from .core.compat import MOVED as _MOVED  # noqa: E402
from .core.compat import install as _install_moved
from .core.compat import moved as _moved
from .core.version import DISTRIBUTION, __version__  # noqa: F401 - DISTRIBUTION is read by the packaging tests

_install_moved(sys.modules[__name__])

from .contact.problem import OneStepProblem, Residuals
from .contact.solvers import (
    ContactSolver,
    EnumerationSolver,
    ExactSolver,
    OSQPSolver,
    QpsolversSolver,
    make_solver,
)
from .core.errors import SimulationError, SolverError
from .model.barriers import Barrier, FunctionBarrier, LinearBarrier, check_jacobian
from .model.constraints import Bilateral
from .model.forces import (
    ConstantForce,
    Effect,
    FourierLoad,
    FunctionForce,
    HarmonicForce,
    LinearDamping,
    LinearSpring,
)
from .model.laws import NewtonImpact, NewtonImpactFriction
from .model.scene import Contact, Scene
from .model.system import FunctionSystem, MechanicalSystem, check_bias
from .results import diagnostics
from .results.trajectory import ImpactLog, SolverStats, Trajectory, load
from .run.simulation import ensure_compiled, simulate
from .step.control import StepControl
from .step.drift import CombinedProjection, PositionProjection
from .step.integrator import (
    MoreauJeanEnergyConsistent,
    MoreauJeanMidpoint,
    MoreauJeanPredictorCorrector,
    OneStepIntegrator,
)
from .step.integrator import MoreauJeanTheta as MoreauJeanTheta  # the former name, not in __all__

__all__ = [
    "__version__",
    "Barrier", "FunctionBarrier", "LinearBarrier", "check_jacobian",
    "SimulationError", "SolverError",
    "ConstantForce", "Effect", "FourierLoad", "FunctionForce", "HarmonicForce", "LinearDamping", "LinearSpring",
    "MoreauJeanMidpoint", "MoreauJeanPredictorCorrector", "MoreauJeanEnergyConsistent", "OneStepIntegrator",
    "PositionProjection", "CombinedProjection", "StepControl",
    "NewtonImpact",
    "NewtonImpactFriction",
    "OneStepProblem", "Residuals",
    "ImpactLog", "SolverStats", "Trajectory", "load",
    "Contact", "Scene", "Bilateral",
    "simulate", "ensure_compiled",
    "ContactSolver", "EnumerationSolver", "ExactSolver", "OSQPSolver", "QpsolversSolver", "make_solver",
    "FunctionSystem", "check_bias", "MechanicalSystem",
    "diagnostics",
]


def __getattr__(name: str) -> object:
    """``moreau.<former module>`` (e.g. ``moreau.chain``): the moved module, with a warning."""
    if f"moreau.{name}" in _MOVED:
        return _moved(f"moreau.{name}")
    raise AttributeError(f"module 'moreau' has no attribute {name!r}")
