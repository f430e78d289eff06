"""moreau.dynamics: is this motion periodic, how stable is it, is it chaotic, where does it
bifurcate? Tools for the non-smooth dynamics of any :class:`moreau.Scene`.

The state is ``x = (q, v)``, shape (2n,). Every long run goes through
:func:`moreau.simulate` (extra keyword arguments are passed through to it), so the tools
speed up with the simulation backend.

* :mod:`~moreau.dynamics.sections`: stroboscopic samples and Poincaré sections s(q, v) = 0,
  from a trajectory or on the fly;
* :mod:`~moreau.dynamics.maps`: the time-T map of a scene, finite-difference Jacobians;
* :mod:`~moreau.dynamics.floquet`: period detection, fixed points and Floquet multipliers
  from the monodromy of the section map;
* :mod:`~moreau.dynamics.lyapunov`: the largest exponent from two nearby trajectories, the
  spectrum from finite-difference Jacobians of the interval map with QR;
* :mod:`~moreau.dynamics.tangent`: the spectrum from the tangent dynamics with saltation
  matrices at the impacts (Müller 1995), built on ``moreau.dynamics.saltation``;
* :mod:`~moreau.dynamics.bifurcation`: bifurcation diagrams on :func:`moreau.sweeps.sweep`.
"""

from .bifurcation import bifurcation_diagram, bifurcation_point, plot_bifurcation
from .floquet import FloquetResult, detect_period, find_fixed_point, floquet_multipliers
from .lyapunov import LyapunovResult, largest_lyapunov, lyapunov_spectrum, paired_difference
from .maps import PoincareMap, TimeMap, jacobian_fd, join_state, split_state
from .sections import Section, poincare, poincare_on_the_fly, stroboscopic
from .tangent import lyapunov_spectrum_tangent

__all__ = [
    "Section", "stroboscopic", "poincare", "poincare_on_the_fly",
    "TimeMap", "PoincareMap", "jacobian_fd", "join_state", "split_state",
    "FloquetResult", "detect_period", "find_fixed_point", "floquet_multipliers",
    "LyapunovResult", "largest_lyapunov", "lyapunov_spectrum", "lyapunov_spectrum_tangent", "paired_difference",
    "bifurcation_diagram", "bifurcation_point", "plot_bifurcation",
]
