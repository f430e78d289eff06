"""Exceptions raised by moreau."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from moreau.results.trajectory import Trajectory

__all__ = ["SolverError", "SimulationError", "attach_trajectory"]


class SolverError(RuntimeError):
    """Every backend failed on a step's contact problem.

    Attributes
    ----------
    step : int
        Index of the failed step (0 = the step from t0).
    t : float
        Time at the start of the step.
    rows : list of str
        Names of the active contact rows.
    residuals : dict
        Scaled KKT residuals of the best candidate (or the error of each backend).
    trajectory : Trajectory or None
        The run up to the last good step (``status == "failed"``), attached by
        :func:`moreau.simulate`; None when the solver was called outside a run.
    """

    def __init__(self, message: str, step: int, t: float, rows: list[str], residuals: dict[str, Any],
                 trajectory: Trajectory | None = None) -> None:
        super().__init__(message)
        self.step = step
        self.t = t
        self.rows = rows
        self.residuals = residuals
        self.trajectory = trajectory


class SimulationError(RuntimeError):
    """A run stopped on an error; ``trajectory`` holds everything computed before it.

    Attributes
    ----------
    trajectory : Trajectory or None
        The trajectory up to the last good step (``status == "failed"``).
    step : int
        Index of the step that failed.
    """

    def __init__(self, message: str, trajectory: Trajectory | None, step: int) -> None:
        super().__init__(message)
        self.trajectory = trajectory
        self.step = step


def attach_trajectory(exc: BaseException, trajectory: Trajectory | None) -> None:
    """Attach a run's trajectory to the exception that stopped it, as ``exc.trajectory``
    (:class:`SolverError`, :class:`SimulationError`, or the ``KeyboardInterrupt`` of
    Ctrl-C and SIGTERM)."""
    exc.trajectory = trajectory  # type: ignore[attr-defined]  # KeyboardInterrupt has no such attribute
