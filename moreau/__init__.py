"""moreau: non-smooth multibody mechanics with a Moreau–Jean midpoint time-stepper.

The pieces, in the field's vocabulary:

* a *system* (:class:`FunctionSystem`, or a subclass of :class:`MechanicalSystem`): q, M(q);
* *effects* (:mod:`moreau.forces`): smooth forces f(t, q, v);
* *contacts*: a *barrier* g(q) >= 0 (:mod:`moreau.barriers`) with a Newton impact law;
* a *scene* (:class:`Scene`): exactly the effects and contacts asked for;
* an *integrator* (:class:`MoreauJeanMidpoint`) and a contact *solver*
  (:mod:`moreau.solvers`);
* the front door :func:`simulate`, which returns a :class:`Trajectory`.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

#: the distribution's name on the package index; the import name is ``moreau``
DISTRIBUTION = "moreau-jean"

try:
    __version__ = _version(DISTRIBUTION)
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

from . import diagnostics
from .barriers import Barrier, FunctionBarrier, LinearBarrier, check_jacobian
from .compiled import ensure_compiled
from .drift import CombinedProjection, PositionProjection
from .errors import SimulationError, SolverError
from .forces import ConstantForce, Effect, FourierLoad, FunctionForce, HarmonicForce, LinearDamping, LinearSpring
from .integrator import MoreauJeanMidpoint, MoreauJeanPredictorCorrector, OneStepIntegrator
from .integrator import MoreauJeanTheta as MoreauJeanTheta  # the former name, not in __all__
from .laws import NewtonImpact
from .onestep import OneStepProblem, Residuals
from .result import ImpactLog, SolverStats, Trajectory, load
from .scene import Contact, Scene
from .simulate import simulate
from .solvers import ContactSolver, EnumerationSolver, ExactSolver, OSQPSolver, QpsolversSolver, make_solver
from .system import FunctionSystem, MechanicalSystem

__all__ = [
    "__version__",
    "Barrier", "FunctionBarrier", "LinearBarrier", "check_jacobian",
    "SimulationError", "SolverError",
    "ConstantForce", "Effect", "FourierLoad", "FunctionForce", "HarmonicForce", "LinearDamping", "LinearSpring",
    "MoreauJeanMidpoint", "MoreauJeanPredictorCorrector", "OneStepIntegrator",
    "PositionProjection", "CombinedProjection",
    "NewtonImpact",
    "OneStepProblem", "Residuals",
    "ImpactLog", "SolverStats", "Trajectory", "load",
    "Contact", "Scene",
    "simulate", "ensure_compiled",
    "ContactSolver", "EnumerationSolver", "ExactSolver", "OSQPSolver", "QpsolversSolver", "make_solver",
    "FunctionSystem", "MechanicalSystem",
    "diagnostics",
]
