"""The impact log of a run (one row per contact onset that is an impact) and its solver
statistics. Quantities are in the scene's units (see :mod:`moreau.results.trajectory`)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from moreau.model.units import unit_suffix

if TYPE_CHECKING:
    import pandas

__all__ = ["ImpactLog", "ImpactRow", "SolverStats"]

#: one onset as the loops log it: (t, step, row, U_before, U_after, impulse, energy_lost, flight, fast, t_cross)
ImpactRow = tuple[float, int, int, float, float, float, float, bool, bool, float]


@dataclass
class ImpactLog:
    """Contact onsets: a row whose impulse became positive in a step after a step in
    which it carried none, logged when it is an impact by either test:

    - ``flight``: since the row last carried an impulse, its gap at the end of some step
      exceeded the *flight gap* (the ``flight_gap`` argument of :func:`moreau.simulate`;
      for the piston 2 % of the clearance). Bounces that never lift the contact by more
      than that are the same contact.
    - ``fast`` (the velocity test): the row approached faster than the smooth forces
      alone change its normal velocity in one step (``−U_before > h |a_n|``); slower
      onsets are a sliding contact closing again, or a grazing touch.

    **An impact is an onset that passes both** (``Trajectory.impacts``; the CLI
    summaries, the notebooks and the README count these): a fast approach after a
    flight. The count converges as h → 0 even where the scheme resolves more and more of
    a Zeno cascade (the e = 0.9 piston). ``Trajectory.velocity_impacts`` keeps the raw
    count of fast onsets, which grows as h → 0 there.

    All arrays have shape (n_onsets,); units are those of the trajectory (``units``).

    Attributes
    ----------
    t : ndarray
        Time at the start of the impact step (time unit ``units["t"]``; with step-size
        control, of the half step it happened in).
    step : ndarray of int
        Index of the step (0 = the step from t0; with step-size control, of the accepted
        step).
    row : ndarray of int
        Contact row (see ``Trajectory.row_names``).
    U_before, U_after : ndarray
        Normal velocity G v before and after the step (the row's gap unit per time unit).
    impulse : ndarray
        Contact impulse P >= 0 of the step (``units["impulses"]`` of the row: N s for a
        scene in SI).
    energy_lost : ndarray
        Kinetic energy dissipated by the contact impulse in the step (``units["energy"]``:
        J in SI).
    flight, fast : ndarray of bool
        Which test the onset passed (see above).
    t_cross : ndarray
        The time the row's gap crossed zero inside the impact step, estimated from the gap
        at the step's start and the approach velocity ``U_before`` (for a landing the
        drift projection caught: linear between the gaps at the step's start and end),
        within [t − h, t + h] (before t where the step started below the barrier): second
        order in h for an approach at a smooth speed, where ``t`` is first order (a ball's
        first impact at h = 1e-3: within 3.4e-7 s where ``t`` is up to 1e-3 s off,
        ``tests/test_ball.py``).
        NaN in a trajectory file written before it was logged.
    row_names : list of str
        Names of the trajectory's contact rows (``row`` indexes them).
    units : dict
        The trajectory's units (``moreau.model.units``).
    """

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    step: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    row: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    U_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    U_after: np.ndarray = field(default_factory=lambda: np.zeros(0))
    impulse: np.ndarray = field(default_factory=lambda: np.zeros(0))
    energy_lost: np.ndarray = field(default_factory=lambda: np.zeros(0))
    flight: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    fast: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    t_cross: np.ndarray = field(default_factory=lambda: np.zeros(0))
    row_names: list[str] = field(default_factory=list, repr=False, compare=False, metadata={"array": False})
    units: dict[str, Any] = field(default_factory=dict, repr=False, compare=False, metadata={"array": False})

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __repr__(self) -> str:
        if not len(self):
            return "ImpactLog(0 impacts)"
        t_unit = unit_suffix(self.units, "t")
        return (f"ImpactLog({len(self)} impacts, t = {self.t[0]:.6g} to {self.t[-1]:.6g}{t_unit}, "
                f"largest impulse {self.impulse.max():.4g}{unit_suffix(self.units, 'impulses')})")

    def times(self) -> np.ndarray:
        """When each impact happened, shape (n_onsets,): the wall crossing ``t_cross``
        where it is known (every run since it was logged), else the step's start ``t``
        (files written before)."""
        return np.where(np.isfinite(self.t_cross), self.t_cross, self.t)

    def to_dataframe(self) -> pandas.DataFrame:
        """The log as a pandas DataFrame, one row per impact, with a ``row_name`` column and
        each column's unit in ``df.attrs["units"]``; see
        ``moreau.results.export.impacts_to_dataframe``. ``ImportError`` naming the ``export``
        extra when pandas is missing."""
        from moreau.results.export import impacts_to_dataframe

        return impacts_to_dataframe(self)

    @classmethod
    def from_rows(cls, rows: list[ImpactRow]) -> ImpactLog:
        """The log of the rows the loops collect (see ``ImpactRow``)."""
        if not rows:
            return cls()
        cols = list(zip(*rows))
        return cls(
            t=np.array(cols[0], dtype=float),
            step=np.array(cols[1], dtype=int),
            row=np.array(cols[2], dtype=int),
            U_before=np.array(cols[3], dtype=float),
            U_after=np.array(cols[4], dtype=float),
            impulse=np.array(cols[5], dtype=float),
            energy_lost=np.array(cols[6], dtype=float),
            flight=np.array(cols[7], dtype=bool),
            fast=np.array(cols[8], dtype=bool),
            t_cross=np.array(cols[9], dtype=float),
        )

    def select(self, mask: np.ndarray) -> ImpactLog:
        """The entries where ``mask`` is True."""
        return ImpactLog(**{name: getattr(self, name)[mask] for name in _impact_arrays()},
                         row_names=self.row_names, units=self.units)


def _impact_arrays() -> tuple[str, ...]:
    """The names of ImpactLog's array fields (what save/load/select handle)."""
    return tuple(f.name for f in fields(ImpactLog) if f.metadata.get("array", True))


@dataclass
class SolverStats:
    """Counters of a run.

    Attributes
    ----------
    solver, fallback : str
        Names of the main and fallback backends.
    steps : int
        Steps taken.
    contact_steps : int
        Steps with at least one closed row (one contact solve each).
    solves : int
        Contact problems solved: one per contact step, and one per further pass of the
        velocity update in such a step (the predictor–corrector's second, the
        energy-consistent step's iterates).
    fallbacks : int
        Solves the main backend failed (wrong answer or error) and the fallback did.
    projections : int
        Steps whose end position drift control corrected.
    worst_residual : float
        Largest accepted scaled KKT residual.
    wall_time : float
        Seconds spent stepping.
    backend : str
        ``"compiled"`` (the whole loop in machine code) or ``"python"``.
    velocity_updates : int
        Velocity updates computed: one per step with the midpoint step, two with the
        predictor–corrector (velocity-dependent forces), and with the energy-consistent step
        one plus its iterates (``velocity_updates / steps`` is its cost factor).
    rejected : int
        Steps step-size control took again with a smaller step (three velocity updates an
        attempt: one step of H, two of H/2; see :class:`moreau.StepControl`).
    forced : int
        Steps step-size control accepted at its smallest step with the local error above
        its tolerance (a warning says so).
    """

    solver: str = ""
    fallback: str = ""
    steps: int = 0
    contact_steps: int = 0
    solves: int = 0
    fallbacks: int = 0
    projections: int = 0
    worst_residual: float = 0.0
    wall_time: float = 0.0
    backend: str = "python"
    velocity_updates: int = 0
    rejected: int = 0
    forced: int = 0

    @property
    def us_per_step(self) -> float:
        """Mean wall time per step (µs)."""
        return 1e6 * self.wall_time / max(1, self.steps)
