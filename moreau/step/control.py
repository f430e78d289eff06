"""Step-size control: ask for an accuracy, not for a step (``simulate(..., step_control=)``).

The compiled loop (:mod:`moreau.compiled.adaptive`) takes each step once with H and twice
with H/2 from the same state, estimates the local error from the difference, and accepts
the step or takes it again with a smaller H (Studer, Leine & Glocker, "Step size
adjustment and extrapolation for time-stepping schemes in non-smooth dynamics", IJNME
76(11), 2008). Smooth steps (no row closed, or the closed rows held at rest) are
extrapolated (Richardson) to one order more; steps in which a row closes or opens, a
contact sticks or slips, or an impact happens, shrink until the switching time is
resolved to the tolerance; then the step grows again, to at most the ``h`` given to
:func:`moreau.simulate`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moreau.core.validation import as_positive, as_vector, is_number

__all__ = ["StepControl"]


@dataclass(frozen=True)
class StepControl:
    """The local error a step may make, and the smallest step.

    A step of H is accepted when, for every coordinate and velocity x_i, ::

        |x_i(two steps of H/2) − x_i(one step of H)| / c  <=  tol_i + rtol · |x_i|

    (c = 3 for a smooth step of the second-order midpoint step, or one whose closed rows are
    held at rest, 1 for other steps with contact; a barrier crossed inside the step, or a
    contact force falling through zero in it, counts as the state error its late switch makes;
    the units of ``tol`` are those of q for the coordinates and of v for the velocities:
    give one per component, scale the model so that all matter alike, or use ``rtol``). The
    error of the run falls in proportion to ``tol`` (docs/guide/accuracy.md measures it).

    Parameters
    ----------
    tol : float or sequence of float
        Absolute local error per step (> 0): one for every component, or one per component
        of x = (q, v), shape (2 n,) for n coordinates (as scipy's ``atol``), kept as a tuple.
        A switch the step's midpoints do not see (above) is measured in the velocities'.
    rtol : float
        Relative local error per step (>= 0; default 0).
    h_min : float or None
        The smallest step (> 0); a step that fails the tolerance even there is accepted,
        counted in ``traj.stats.forced`` and warned of. Default ``1e-9 · h``.

    Notes
    -----
    Each attempt costs three steps (one of H, two of H/2); ``traj.stats.steps`` counts
    the accepted steps, ``traj.stats.rejected`` the attempts taken again,
    ``traj.stats.velocity_updates`` all velocity updates. ``record_every`` counts accepted
    steps, so ``traj.t`` is not uniform.
    """

    tol: float | tuple[float, ...]
    rtol: float = 0.0
    h_min: float | None = None

    def __post_init__(self) -> None:
        if is_number(self.tol):
            tol: float | tuple[float, ...] = as_positive(self.tol, "StepControl tol")
        elif isinstance(self.tol, (Sequence, np.ndarray)) and not isinstance(self.tol, (str, bytes)):
            a = as_vector(self.tol, "StepControl tol")
            if a.size == 0 or not np.all(a > 0):
                raise ValueError(f"StepControl tol must be positive in every component, got {a.tolist()}")
            tol = tuple(float(x) for x in a)
        else:
            raise ValueError(f"StepControl tol must be a number or a sequence of numbers, got {self.tol!r}")
        object.__setattr__(self, "tol", tol)
        object.__setattr__(self, "rtol", as_positive(self.rtol, "StepControl rtol", allow_zero=True))
        if self.h_min is not None:
            object.__setattr__(self, "h_min", as_positive(self.h_min, "StepControl h_min"))

    def absolute(self, n: int) -> np.ndarray:
        """The absolute tolerance of each component of x = (q, v), shape (2 n,) for n
        coordinates; ``ValueError`` when a per-component ``tol`` has another length."""
        if isinstance(self.tol, float):
            return np.full(2 * n, self.tol)
        if len(self.tol) != 2 * n:
            raise ValueError(f"StepControl tol has {len(self.tol)} components, the state (q, v) of this scene "
                             f"{2 * n} (n = {n} coordinates): give one number or 2 n")
        return np.array(self.tol)

    def smallest(self, h: float) -> float:
        """The smallest step of a run whose largest is ``h``; ``ValueError`` when h_min > h."""
        h_min = 1e-9 * h if self.h_min is None else self.h_min
        if h_min > h:
            raise ValueError(f"StepControl h_min = {h_min!r} is larger than the step h = {h!r}")
        return h_min
