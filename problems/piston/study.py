"""Study functions of the piston engine for parameter sweeps and notebooks.

Module-level, picklable, pure functions of their arguments (same arguments, same
numbers, except the measured ``wall_time_s``): :func:`piston_point` (per-cycle figures
of one engine, for ``moreau.sweeps.sweep``) and :func:`bifurcation_samples` (the pin's
lateral position and the piston tilt sampled once per cycle at fixed crank angles — a
Poincaré section φ1 = const mod 720° of the self-excited engine). The figures of such
sweeps (:func:`plot_sweep`, :func:`plot_section`, :func:`plot_side_change_angles`) live in
:mod:`moreau.problems.piston.figures` and are importable from here too.

Like the main job (:func:`moreau.problems.piston.job.run_case`), the runs use drift control
(``drift_control=True``: the engine's :class:`moreau.CombinedProjection`, which projects
every corner back onto the cylinder after each step and applies restitution only at
impacts, accepting 1e-4 of the clearance, ``PROJECTION_FRACTION``): without it the
midpoint drift of a sliding contact leaves the corners O(h) inside the wall (≈ 30 % of
the 40 µm clearance at h = 3e-4 for e = 0, 90 % at h = 1e-3 for e = 0.05).

Units: ``D_mm`` in millimetres, ``h`` in non-dimensional time τ = ω t (one engine cycle
is 4π), energies in J, impulses in N s, angles of the crank in degrees from firing TDC,
x_O3 in half-clearances (D − d)/2 (±1: an untilted piston touching the right/left wall),
the tilt φ3 in mrad.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

import moreau as mo

from .analysis import (
    FOUR_PI,
    contact_side,
    crank_angle,
    cycle_figures,
    cycle_index,
    lateral_position,
    max_penetration_ratio,
    mean_speed_rpm,
    settled_speed_rpm,
    sliding_phases,
    tilt,
)
from .figures import plot_section, plot_side_change_angles, plot_sweep
from .model import piston_model
from .params import PistonParameters

__all__ = [
    "piston_point", "bifurcation_samples", "DEFAULT_ANGLES_DEG", "SLAP_FRACTION", "record_every_for",
    "step_for_clearance", "section_long", "piston_cache_key",
    "plot_sweep", "plot_section", "plot_side_change_angles",
]

DEFAULT_ANGLES_DEG = (60.0, 420.0)


def piston_cache_key() -> str:
    """The ``cache_key`` of piston sweeps (``moreau sweep``, the notebooks): a digest of
    the source of ``moreau.problems.piston`` and of ``moreau``, so that recorded points are
    recomputed after any change to the model, its parameters or the engine."""
    from moreau.sweeps import source_digest

    return source_digest("moreau.problems.piston", "moreau")

SLAP_FRACTION = 0.01
"""An impact is a *slap* when its impulse is at least this fraction of the largest one
of its cycle. The count of all logged impacts can include a swarm of micro-impacts whose
number depends on the numerics (projecting bouncing rows after each step multiplied it
by 5 at e = 0.5, h = 3e-4: 447 against 94 impacts per cycle); the count of slaps does
not (85 against 81)."""


def record_every_for(h: float) -> int:
    """Steps between records for a step ``h``: about 0.1° of crank angle per record."""
    return max(1, int(round(2e-3 / h)))


def step_for_clearance(D_mm: float, h: float = 3e-4, margin: float = 0.5, d_mm: float = 80.0,
                       l1_mm: float = 40.0) -> float:
    """A step size resolving the clearance: ``min(h, margin · (D − d) / l1)``.

    In one step the crank pin moves h·l1 (non-dimensional speed 1), the velocity scale of
    the piston's lateral motion; the piston model warns when that exceeds the clearance
    D − d (:meth:`moreau.problems.piston.model.PistonModel.simulate`). This keeps it to
    ``margin`` of the clearance: with the defaults h = 1.25e-4 at 10 µm, 2.5e-4 at 20 µm
    and 3e-4 from 24 µm up. Rounded to 3 significant digits.

    Parameters
    ----------
    D_mm, d_mm : float
        Cylinder and piston diameters (mm).
    h : float
        Step size for large clearances (non-dimensional time τ = ω t).
    margin : float
        Largest fraction of the clearance the pin may travel in one step.
    l1_mm : float
        Crank radius (mm), the length unit.
    """
    clearance = float(D_mm) - float(d_mm)
    if clearance <= 0:
        raise ValueError(f"D_mm = {D_mm!r} must exceed the piston diameter {d_mm!r} mm")
    return float(f"{min(float(h), margin * clearance / l1_mm):.3g}")


def _run(e: float, D_mm: float, total_cycles: float, h: float, solver: str,
         drift_control: bool, backend: str = "auto", mu: float = 0.0) -> tuple[mo.Trajectory, PistonParameters]:
    """Simulate the engine; a Ctrl-C re-raises KeyboardInterrupt (so a sweep records
    nothing for the point), a failed run raises its SolverError / SimulationError."""
    params = PistonParameters(e=float(e), D=float(D_mm) / 1e3, mu=float(mu))
    model = piston_model(params)
    traj = model.simulate(total_cycles, h, solver=solver, backend=backend, record_every=record_every_for(h),
                          progress=False, energy=False,
                          drift_control=model.drift_control() if drift_control else None)
    if traj.status == "interrupted":
        raise KeyboardInterrupt(traj.message)
    return traj, params


def _section(traj: mo.Trajectory, params: PistonParameters, transient: int, cycles: int,
             angles: np.ndarray) -> dict:
    """x_O3 and φ3 at crank angle 720° k + angle for the analyzed cycles k (long format)."""
    phi = crank_angle(traj)
    ks = np.arange(transient, transient + cycles)
    where = (FOUR_PI * ks[:, None] + np.radians(angles)[None, :]).ravel()
    if where[-1] > phi[-1]:
        raise RuntimeError(f"the run ends at crank angle {np.degrees(phi[-1]):.1f}°, before the last sample")
    return {
        "cycle": np.repeat(ks, angles.size).tolist(),
        "angle_deg": np.tile(angles, cycles).tolist(),
        "x_O3": np.interp(where, phi, lateral_position(traj, params)).tolist(),
        "phi3_mrad": (1e3 * np.interp(where, phi, tilt(traj))).tolist(),
    }


def _angles(angle_deg) -> np.ndarray:
    angles = np.atleast_1d(np.asarray(angle_deg, dtype=float))
    if angles.ndim != 1 or angles.size == 0 or not np.all((angles >= 0) & (angles < 720)):
        raise ValueError(f"angle_deg must be in [0, 720), got {angle_deg!r}")
    return angles


def piston_point(e: float, D_mm: float = 80.04, cycles: int = 5, transient: int = 1, h: float = 3e-4,
                 solver: str = "exact", drift_control: bool = True, backend: str = "auto",
                 section_deg: float | Sequence[float] | None = None, mu: float = 0.0) -> dict:
    """Run the engine for ``transient + cycles`` cycles and return per-cycle figures of
    the ``cycles`` analyzed ones.

    Parameters
    ----------
    e : float
        Restitution at the piston corners, in [0, 1].
    D_mm : float
        Cylinder diameter (mm), > 80 (the piston's diameter).
    cycles : int
        Engine cycles analyzed (720° of crank angle each).
    transient : int
        Cycles simulated first and discarded.
    h : float
        Step size in non-dimensional time τ = ω t (1e-4: reference; 3e-4: sweeps;
        1e-3: quick looks; with drift control the penetration stays below 0.1 % of the
        clearance at D = 80.04 mm).
    solver : str
        Contact solver of :func:`moreau.simulate` (``"exact"`` runs compiled).
    drift_control : bool
        Use the engine's drift control, :meth:`~moreau.problems.piston.model.PistonModel.drift_control` (every corner
        projected back onto the cylinder after each step, restitution only at impacts).
    section_deg : float or sequence of float, optional
        Also sample the state once per analyzed cycle at these crank angles (degrees in
        [0, 720)), as :func:`bifurcation_samples` does, from the same run.
    backend : str
        ``"auto"`` (compiled when possible), ``"compiled"`` or ``"python"``.
    mu : float
        Skirt friction at the cylinder wall (0: the paper's frictionless model).

    Returns
    -------
    dict
        ``clearance_um`` (D − d, µm); per analyzed cycle (lists) and their means:
        ``side_changes``, ``impacts`` (all four corners), ``energy_lost_J`` (kinetic
        energy dissipated at the impacts, J), ``slaps`` (impacts carrying at least
        ``SLAP_FRACTION`` = 1 % of the cycle's largest impulse: the robust count),
        ``flight_deg`` (crank angle with no corner
        in contact, degrees), ``sliding_phases`` (one wall alone carrying the piston for
        at least 1° of crank angle); ``side_change_angles_deg`` (last cycle),
        ``mean_speed_rpm`` (mean crank speed over the analyzed cycles, rev/min; the run
        starts at 2000 rpm), ``settled_speed_rpm`` (energy-balance estimate of the speed
        the engine settles at, from the same cycles, rev/min; see
        :func:`~moreau.problems.piston.analysis.settled_speed_rpm`),
        ``max_penetration_ratio`` (largest penetration over every step of the run, the
        transient included, / (D − d): the figure ``moreau piston`` reports, not the
        recorded states'),
        ``max_impulse_Ns`` (largest single impact), ``friction_loss_J`` (per cycle) and
        its mean (energy dissipated by skirt friction, J; 0 without), ``fallbacks`` (contact solves
        the main backend failed) and ``wall_time_s`` (the only non-reproducible value);
        with ``section_deg``, also ``cycle``, ``angle_deg``, ``x_O3``, ``phi3_mrad``
        (see :func:`bifurcation_samples`).

    Raises
    ------
    ValueError
        Bad parameters (e outside [0, 1], D_mm <= 80, cycles < 1, ...).
    moreau.SolverError, moreau.SimulationError
        The run failed.
    """
    cycles, transient = int(cycles), int(transient)
    if cycles < 1 or transient < 0:
        raise ValueError(f"need cycles >= 1 and transient >= 0, got cycles={cycles}, transient={transient}")
    angles = None if section_deg is None else _angles(section_deg)
    wall0 = time.perf_counter()
    traj, params = _run(e, D_mm, transient + cycles, h, solver, drift_control, backend, mu)
    figs = [c for c in cycle_figures(traj, params) if c.cycle >= transient]
    if len(figs) != cycles:
        raise RuntimeError(f"expected {cycles} analyzed cycles, the run holds {len(figs)}")

    phi = crank_angle(traj)
    cyc = cycle_index(traj)
    side = contact_side(traj)
    dphi = np.diff(phi, prepend=phi[0])  # record i covers (phi[i-1], phi[i]]
    imp = traj.impacts
    imp_cycle = np.floor(np.interp(imp.times(), traj.t, phi) / FOUR_PI).astype(int) if len(imp) else np.zeros(0, int)
    slaps = []
    for c in figs:
        P = imp.impulse[imp_cycle == c.cycle]
        slaps.append(int((P >= SLAP_FRACTION * P.max()).sum()) if P.size else 0)
    flight = [float(np.degrees(dphi[(cyc == c.cycle) & (side == 0)].sum())) for c in figs]
    phases = sliding_phases(traj, min_deg=1.0)
    phase_cycle = np.array([cyc[s.start] for s in phases], dtype=int)
    n_phases = [int((phase_cycle == c.cycle).sum()) for c in figs]

    def mean(xs):
        return float(np.mean(xs))

    section = {} if angles is None else _section(traj, params, transient, cycles, angles)
    return {
        "clearance_um": round(1e6 * params.clearance, 6),
        "side_changes_mean": mean([c.side_changes for c in figs]),
        "impacts_mean": mean([c.impacts for c in figs]),
        "slaps_mean": mean(slaps),
        "energy_lost_J_mean": mean([c.energy_lost for c in figs]),
        "flight_deg_mean": mean(flight),
        "sliding_phases_mean": mean(n_phases),
        "mean_speed_rpm": mean_speed_rpm(traj, params, skip_cycles=transient),
        "settled_speed_rpm": settled_speed_rpm(traj, params, transient),  # the scene _run built
        "max_penetration_ratio": max_penetration_ratio(traj, params),  # every step, not the records
        "max_impulse_Ns": max(c.max_impulse for c in figs),
        "friction_loss_J_mean": mean([c.friction_loss for c in figs]),
        "friction_loss_J": [c.friction_loss for c in figs],
        "side_changes": [c.side_changes for c in figs],
        "impacts": [c.impacts for c in figs],
        "slaps": slaps,
        "energy_lost_J": [c.energy_lost for c in figs],
        "flight_deg": flight,
        "sliding_phases": n_phases,
        "side_change_angles_deg": [round(a, 3) for a in figs[-1].change_angles_deg],
        "fallbacks": int(traj.stats.fallbacks),
        **section,
        "wall_time_s": round(time.perf_counter() - wall0, 3),
    }


def bifurcation_samples(e: float, D_mm: float = 80.04, cycles: int = 30, h: float = 3e-4,
                        angle_deg: float | Sequence[float] = DEFAULT_ANGLES_DEG, transient: int = 1,
                        solver: str = "exact", drift_control: bool = True, backend: str = "auto") -> dict:
    """The pin's lateral position x_O3 and the tilt φ3 once per cycle at fixed crank angles.

    Runs ``transient + cycles`` cycles and samples, in each analyzed cycle k, the state
    at crank angle φ1 = 720° k + angle (linear interpolation between records ~0.1° apart)
    — a Poincaré section of the self-excited engine. A periodic motion gives one point per
    angle, whatever the number of cycles; a scatter means the motion does not repeat.

    Parameters
    ----------
    e, D_mm, h, transient, solver, drift_control, backend
        As for :func:`piston_point`.
    cycles : int
        Analyzed cycles: samples per angle.
    angle_deg : float or sequence of float
        Crank angle(s) of the section in [0, 720) degrees from firing TDC.

    Returns
    -------
    dict
        Long-format samples, one entry per (cycle, angle): ``cycle``, ``angle_deg``,
        ``x_O3`` (half-clearances), ``phi3_mrad``; and ``side_changes`` and ``impacts``
        per analyzed cycle (lists of length ``cycles``).
    """
    cycles, transient = int(cycles), int(transient)
    angles = _angles(angle_deg)
    if cycles < 1 or transient < 0:
        raise ValueError(f"need cycles >= 1 and transient >= 0, got cycles={cycles}, transient={transient}")
    traj, params = _run(e, D_mm, transient + cycles, h, solver, drift_control, backend)
    figs = [c for c in cycle_figures(traj, params) if c.cycle >= transient]
    return {
        **_section(traj, params, transient, cycles, angles),
        "side_changes": [c.side_changes for c in figs],
        "impacts": [c.impacts for c in figs],
    }


# -- tables of sweeps (their figures, plot_sweep etc., are in .figures) --------------------
def section_long(df, by: str | Sequence[str] = "e"):
    """Explode a table of :func:`bifurcation_samples` rows into one row per sample.

    Parameters
    ----------
    df : pandas.DataFrame
        Rows of ``sweep(bifurcation_samples, ...)``.
    by : str or sequence of str
        Parameter column(s) to keep with each sample.

    Returns
    -------
    pandas.DataFrame
        Columns ``by`` + ``cycle``, ``angle_deg``, ``x_O3``, ``phi3_mrad``.
    """
    import pandas as pd

    by = [by] if isinstance(by, str) else list(by)
    ok = df[df["error"].isna()] if "error" in df else df
    frames = []
    for _, row in ok.iterrows():
        f = pd.DataFrame({k: list(row[k]) for k in ("cycle", "angle_deg", "x_O3", "phi3_mrad")})
        for b in by:
            f.insert(0, b, row[b])
        frames.append(f)
    cols = by + ["cycle", "angle_deg", "x_O3", "phi3_mrad"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=cols)
