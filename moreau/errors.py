"""Exceptions raised by moreau."""

from __future__ import annotations

__all__ = ["SolverError", "SimulationError"]


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
    """

    def __init__(self, message: str, step: int, t: float, rows: list[str], residuals: dict) -> None:
        super().__init__(message)
        self.step = step
        self.t = t
        self.rows = rows
        self.residuals = residuals


class SimulationError(RuntimeError):
    """A run stopped on an error; ``trajectory`` holds everything computed before it.

    Attributes
    ----------
    trajectory : Trajectory
        The trajectory up to the last good step (``status == "failed"``).
    step : int
        Index of the step that failed.
    """

    def __init__(self, message: str, trajectory, step: int) -> None:
        super().__init__(message)
        self.trajectory = trajectory
        self.step = step
