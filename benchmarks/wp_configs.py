"""Work–precision study, part 1: the configurations and how a run is timed.

A configuration is an integrator, a contact solver (:data:`SOLVERS`) and a drift control
(:class:`Config`); :class:`Run` holds one run's cost and errors. Used by
``benchmarks/work_precision.py``, which documents the study.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import moreau as mo


@dataclass(frozen=True)
class SolverSpec:
    """A contact solver as the study runs it.

    ``checked``: moreau's default acceptance test (scaled KKT residual <= 1e-6) with the
    exact ``enum`` fallback; unchecked runs take the backend's answer as it is.
    """

    label: str
    make: Callable[[], mo.ContactSolver | str]
    checked: bool = True

    def simulate_kwargs(self) -> dict:
        if self.checked:
            return {"solver": self.make(), "fallback": "auto"}  # enum, or exact when the main is enum
        return {"solver": self.make(), "fallback": None, "tol": 1e30}


SOLVERS: dict[str, SolverSpec] = {
    "osqp": SolverSpec("osqp", lambda: mo.OSQPSolver()),  # eps 1e-9, polish: the default
    "osqp1e-5": SolverSpec("osqp1e-5", lambda: mo.OSQPSolver(eps=1e-5, polish=False), checked=False),
    "osqp1e-3": SolverSpec("osqp1e-3", lambda: mo.OSQPSolver(eps=1e-3, polish=False), checked=False),
    "enum": SolverSpec("enum", lambda: "enum"),
    "exact": SolverSpec("exact", lambda: "exact"),  # the compiled default: runs the compiled loop
    "daqp": SolverSpec("daqp", lambda: "daqp"),
    # checked variants of the loose tolerances (rejected answers fall back to enum)
    "osqp1e-5+check": SolverSpec("osqp1e-5+check", lambda: mo.OSQPSolver(eps=1e-5, polish=False)),
    "osqp1e-3+check": SolverSpec("osqp1e-3+check", lambda: mo.OSQPSolver(eps=1e-3, polish=False)),
}

_INTEGRATORS = {"mid": mo.MoreauJeanMidpoint, "theta": mo.MoreauJeanPredictorCorrector,
                "ec": mo.MoreauJeanEnergyConsistent}
#: drift control variants: none, PositionProjection (plastic rows; "projv": with velocity=True),
#: CombinedProjection (every e)
_DRIFTS = {"none": None, "proj": mo.PositionProjection, "projv": lambda: mo.PositionProjection(velocity=True),
           "comb": mo.CombinedProjection}


@dataclass(frozen=True)
class Config:
    """One configuration: integrator (``"mid"``, ``"theta"`` or ``"ec"``: energy-consistent), solver, drift control
    (``"none"``, ``"proj"``: :class:`~moreau.PositionProjection`, ``"projv"``: the same with ``velocity=True``,
    ``"comb"``: :class:`~moreau.CombinedProjection`; ``False``/``True`` mean none/proj)."""

    integrator: str
    solver: str
    drift: str = "none"
    #: step-size control: the ladder's values are the tolerance of ``mo.StepControl`` and the
    #: step is at most ``h_max`` (a problem's own, see :meth:`run_args`, unless given here)
    adaptive: bool = False
    h_max: float | None = None
    #: the velocities' tolerance as a multiple of the coordinates' (``StepControl``'s tol per
    #: component; 1: one tolerance for both)
    v_tol: float = 1.0

    def __post_init__(self) -> None:
        d = {False: "none", True: "proj"}[self.drift] if isinstance(self.drift, bool) else self.drift
        if d not in _DRIFTS:
            raise ValueError(f"drift must be one of {sorted(_DRIFTS)} (or a bool), got {self.drift!r}")
        object.__setattr__(self, "drift", d)

    @property
    def label(self) -> str:
        tol = ("/tol" if self.h_max is None else f"/tol/H={self.h_max:g}") if self.adaptive else ""
        vtol = f"/v{self.v_tol:g}x" if self.v_tol != 1.0 else ""
        return f"{self.integrator}/{self.solver}/{self.drift}" + tol + vtol

    def run_args(self, x: float, h_max: float = 1e-2, ndof: int | None = None) -> tuple[float, dict]:
        """``(h, simulate's keyword arguments)`` of the ladder value ``x``: the step ``x``, or
        with ``adaptive`` the largest step (this configuration's ``h_max``, else the problem's
        ``h_max``) and ``StepControl(x)`` (with ``v_tol``: x for each of the ``ndof``
        coordinates, ``v_tol`` x for each velocity)."""
        kw = self.simulate_kwargs()
        if not self.adaptive:
            return x, kw
        if self.v_tol == 1.0:
            tol: float | tuple[float, ...] = x
        elif ndof is None:
            raise ValueError(f"a configuration with v_tol = {self.v_tol!r} needs the scene's ndof")
        else:
            tol = (x,) * ndof + (self.v_tol * x,) * ndof
        return self.h_max or h_max, {**kw, "step_control": mo.StepControl(tol)}

    def simulate_kwargs(self) -> dict:
        kw = SOLVERS[self.solver].simulate_kwargs()
        kw["integrator"] = _INTEGRATORS[self.integrator]
        make = _DRIFTS[self.drift]
        kw["drift_control"] = make() if make is not None else None
        return kw


def configs(integrators=("mid", "theta"), solvers=("osqp", "osqp1e-5", "osqp1e-3", "enum", "daqp"),
            drifts=(False, True)) -> list[Config]:
    """The cross product of the given choices."""
    return [Config(i, s, d) for i in integrators for s in solvers for d in drifts]


@dataclass
class Run:
    """One run: its configuration, h, cost and errors.

    ``metrics`` holds the problem's errors (and a few raw figures) by name; ``error`` is
    the primary one (NaN when the run failed).
    """

    problem: str
    config: Config
    h: float
    wall: float
    steps: int
    fallbacks: int
    status: str
    error: float
    metrics: dict = field(default_factory=dict)


def settle() -> None:
    """Collect, then put every object alive now out of the garbage collector's reach
    (``gc.freeze``): a compile leaves some 670 000 (both loop variants), and a full
    collection over them (0.24–0.56 s, measured) landing in a timed run would stand in
    its table. For a benchmark's process, after its compiles and warm-ups."""
    gc.collect()
    gc.freeze()


def _timed(fn, repeat_below: float = 0.0, repeats: int = 10):
    """(trajectory, wall time, status) of ``fn()``. A run faster than ``repeat_below``
    seconds is repeated, up to ``repeats`` runs in all and until the runs together took
    ``repeat_below``, and the shortest time kept: the runs are deterministic, and on a
    shared machine the minimum is the cost (a run of 10 ms is taken 10 times, one of
    0.2 s three times)."""
    best, traj, status, spent = float("inf"), None, "completed", 0.0
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        status = "completed"
        try:
            traj = fn()
        except (mo.SolverError, mo.SimulationError) as exc:
            traj, status = exc.trajectory, "failed"
        wall = time.perf_counter() - t0
        best, spent = min(best, wall), spent + wall
        if wall >= repeat_below or spent >= repeat_below:
            break
    return traj, best, status
