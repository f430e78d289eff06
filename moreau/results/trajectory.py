"""Results: the trajectory of a run, its impact log and solver statistics; save/load.

Every quantity is in the units of the scene (``traj.units``, declared by
``Scene(units=...)``; see ``moreau.model.units``): times in the scene's time unit,
impulses in its momentum unit, energies in its energy unit.
"""

from __future__ import annotations

import contextlib
import json
import os
import uuid
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from moreau.model.units import complete_units, unit_suffix
from moreau.results.file_checks import check_loaded
from moreau.results.impacts import ImpactLog, SolverStats, _impact_arrays

if TYPE_CHECKING:
    import xarray

__all__ = ["Trajectory", "ImpactLog", "SolverStats", "load"]

_FORMAT = 1


@dataclass
class Trajectory:
    """The recorded result of :func:`moreau.simulate`. Arrays are time-major; every quantity
    is in the scene's units, named in ``units``.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Recorded times (``units["t"]``).
    q, v : ndarray, shape (N, n)
        Coordinates and velocities (``units["q"]``, ``units["v"]``: one per coordinate).
    gaps : ndarray, shape (N, m)
        Gaps g(q) at the recorded states (``units["gaps"]``, one per row).
    impulses : ndarray, shape (N, m)
        Contact impulses summed over the steps since the previous record
        (``units["impulses"]``, one per row).
    active : ndarray of bool, shape (N, m)
        True where the row was closed (at a midpoint) in any step since the previous record.
    onsets : ImpactLog
        Every contact onset that is an impact by the flight or the velocity test, logged
        at the step it happened whatever ``record_every``; ``impacts`` and
        ``velocity_impacts`` are its two selections.
    stats : SolverStats
        Solver counters and timing.
    energy, kinetic_energy, potential_energy : ndarray, shape (N,) or None
        Mechanical energy at the records, when computed (``units["energy"]``: J in SI).
    h : float
        Step size (``units["t"]``).
    record_every : int
        Steps between records.
    row_names : list of str
        Names of the m contact rows.
    scene : dict
        The scene's parameters (``Scene.describe()``).
    status : str
        ``"completed"``, ``"interrupted"`` (KeyboardInterrupt) or ``"failed"``.
    message : str
        Why the run stopped early, if it did.
    version : str
        moreau version that computed it.
    max_penetration : ndarray, shape (m,) or None
        Largest penetration max(0, −g) of each row over *every* step's end position (not
        only the records), in the gap's unit.
    max_penetration_t : ndarray, shape (m,) or None
        Time (s) at the end of the step where each row's ``max_penetration`` was reached;
        NaN for a row that never penetrated.
    work : dict
        Energy-ledger terms summed over every step: ``"forces"``, the work of the smooth
        forces h fᵀ(v_k + v⁺)/2, and ``"contacts"``, the work of the contact impulses
        ½ Pᵀ(U⁻ + U⁺) (≤ 0 for e ≤ 1), in the scene's energy unit; with friction also
        ``"friction"``, the work of the tangential impulses ½ P_Tᵀ(U_T⁻ + U_T⁺) (≤ 0 in every
        step where the slip keeps its direction; Coulomb's law holds at U_T⁺, so a step in
        which the slip reverses can add a little, and so can their sum); with bilateral
        constraints ``"constraints"``, the work of their impulses (0 up to round-off), and
        ``"constraint_projection"``, the kinetic energy the velocity projection onto them
        at the end of each step removed (<= 0, O(h⁴) per step). They close the discrete
        balance ΔT = forces + contacts (+ friction, + both constraint terms) exactly for a
        constant mass matrix.
    warnings : list of str
        What the run-level checks found (a penetration beyond its limit, see
        :mod:`moreau.run.trust`); empty for a clean run. Kept by ``save``/``load``.
    units : dict
        The units of every field (``moreau.model.units``: ``t``, ``q`` and ``v`` per
        coordinate, ``gaps`` and ``impulses`` per row, ``energy``, a ``description`` and,
        for non-dimensional models, the ``scales`` to SI). Taken from the scene
        (``Scene(units=...)``); ``""`` where it declared none. Kept by ``save``/``load``
        (files written before units existed load with the undeclared defaults).
    extra : dict
        Whatever the caller attaches (JSON-serializable); kept by ``save``/``load``.
    tangential_impulses : ndarray, shape (N, m) or None
        With friction: the tangential (friction) impulses summed since the previous
        record, per row (zero where mu = 0), in the impulse unit; None without friction.
    slip_velocity : ndarray, shape (N, m) or None
        With friction: the tangential velocity ``T(q) v`` of every row at the records
        (zero rows where mu = 0). None without friction.
    sticking : ndarray of bool, shape (N, m) or None
        With friction: True where the row carried a normal impulse since the previous
        record and its friction impulse stayed strictly inside the cone,
        ``|P_T| < mu P_N`` (Coulomb's law then holds the slip at zero); a sliding row
        is on the cone's edge. None without friction.
    constraint_impulses : ndarray, shape (N, k_E) or None
        With bilateral constraints (``Scene(constraints=...)``): the impulses of their
        rows summed since the previous record (either sign; zero on a redundant row), in
        the impulse unit; None without constraints.
    constraint_residuals : ndarray, shape (N, k_E) or None
        With bilateral constraints: ``g_E(q)`` at the records (held at 0 to about 1e-12
        of the rows' scale by the projection after every step).
    constraint_names : list of str
        Names of the k_E bilateral rows (empty without).
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    gaps: np.ndarray
    impulses: np.ndarray
    active: np.ndarray
    onsets: ImpactLog
    stats: SolverStats
    h: float
    record_every: int = 1
    row_names: list[str] = field(default_factory=list)
    scene: dict[str, Any] = field(default_factory=dict)
    energy: np.ndarray | None = None
    kinetic_energy: np.ndarray | None = None
    potential_energy: np.ndarray | None = None
    status: str = "completed"
    message: str = ""
    version: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    max_penetration: np.ndarray | None = None
    max_penetration_t: np.ndarray | None = None
    work: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    units: dict[str, Any] = field(default_factory=dict)
    tangential_impulses: np.ndarray | None = None
    slip_velocity: np.ndarray | None = None
    sticking: np.ndarray | None = None
    constraint_impulses: np.ndarray | None = None
    constraint_residuals: np.ndarray | None = None
    constraint_names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        ndof = self.q.shape[1] if self.q.ndim == 2 else 0
        nrows = self.gaps.shape[1] if self.gaps.ndim == 2 else len(self.row_names)
        self.units = complete_units(self.units or self.scene.get("units"), ndof, nrows)
        if not self.onsets.row_names:
            self.onsets.row_names = list(self.row_names)
        self.onsets.units = self.units

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __repr__(self) -> str:
        name = self.scene.get("name", "")
        head = f"Trajectory({name!r}: " if name else "Trajectory("
        span = f"t = {self.t[0]:.6g} to {self.t[-1]:.6g}{unit_suffix(self.units, 't')}, " if len(self) else ""
        text = (f"{head}{len(self)} records, {span}{self.q.shape[1] if self.q.ndim == 2 else 0} dof, "
                f"{len(self.row_names)} row{'' if len(self.row_names) == 1 else 's'}, {self.status}, "
                f"{len(self.impacts)} impacts)")
        if self.message:
            text += f"\n  {self.message}"
        return text

    def to_xarray(self) -> xarray.Dataset:
        """The trajectory as an xarray Dataset (dims ``time``, ``dof``, ``row``; a ``units``
        attribute on each variable; scene, solver, version and units in ``attrs``); see
        ``moreau.results.export.trajectory_to_xarray``. ``ImportError`` naming the ``export``
        extra when xarray is missing."""
        from moreau.results.export import trajectory_to_xarray

        return trajectory_to_xarray(self)

    @property
    def impacts(self) -> ImpactLog:
        """The impacts: fast contact onsets after a flight (see :class:`ImpactLog`)."""
        return self.onsets.select(self.onsets.flight & self.onsets.fast)

    @property
    def velocity_impacts(self) -> ImpactLog:
        """The onsets that pass the velocity test (the raw count, see :class:`ImpactLog`)."""
        return self.onsets.select(self.onsets.fast)

    @property
    def completed(self) -> bool:
        return self.status == "completed"

    def row_index(self, name: str) -> int:
        """Index of a contact row by name (``ValueError`` listing the names otherwise)."""
        try:
            return self.row_names.index(name)
        except ValueError:
            raise ValueError(f"no contact row {name!r}; rows are {self.row_names}") from None

    # -- persistence ----------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> str:
        """Write the trajectory to a ``.npz`` file (numpy only, no pickle); returns the path.

        The file is written under a temporary name unique to this call, in the same
        directory, then renamed: concurrent saves of one path do not collide, and a save
        that fails (disk full, interrupt) removes its temporary file and leaves an
        existing file at ``path`` untouched.
        """
        path = os.fspath(path)
        if not path.endswith(".npz"):
            path += ".npz"
        meta = {
            "format": _FORMAT,
            "h": self.h,
            "record_every": self.record_every,
            "row_names": self.row_names,
            "scene": self.scene,
            "status": self.status,
            "message": self.message,
            "version": self.version,
            "stats": {f.name: getattr(self.stats, f.name) for f in fields(self.stats)},
            "extra": self.extra,
            "work": self.work,
            "warnings": self.warnings,
            "units": self.units,
            "constraint_names": self.constraint_names,
        }
        arrays: dict[str, Any] = {
            "t": self.t, "q": self.q, "v": self.v, "gaps": self.gaps,
            "impulses": self.impulses, "active": self.active,
        }
        for name in ("energy", "kinetic_energy", "potential_energy", "max_penetration", "max_penetration_t",
                     "tangential_impulses", "slip_velocity", "sticking", "constraint_impulses", "constraint_residuals"):
            if getattr(self, name) is not None:
                arrays[name] = getattr(self, name)
        for name in _impact_arrays():
            arrays["impacts_" + name] = getattr(self.onsets, name)
        # a temporary file of this call only, in the target directory, renamed over the
        # target: two processes saving one path never collide, a reader never sees half a
        # file, and a failed save leaves nothing behind
        tmp = f"{path}.{os.getpid()}-{uuid.uuid4().hex[:12]}.tmp"
        try:
            with open(tmp, "xb") as fh:
                np.savez_compressed(fh, meta=np.array(json.dumps(meta, default=_json_default)), **arrays)
            os.replace(tmp, path)
        except BaseException as exc:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            if isinstance(exc, OSError) and not exc.filename:  # "[Errno 28] ...": name the file
                raise OSError(exc.errno, exc.strerror or str(exc), path) from exc
            raise
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Trajectory:
        """Read a trajectory written by :meth:`save`.

        Raises
        ------
        ValueError
            When the file is missing, unreadable, not a moreau trajectory, of a newer file
            format than this version reads, or incomplete or inconsistent (the message
            names the field).

        Warns
        -----
        UserWarning
            When the file was written by a newer version of moreau (in the same format):
            it loads, and the warning names both versions.
        """
        path = os.fspath(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise ValueError(f"no trajectory file at {path!r}") from None
        except Exception as exc:  # zipfile, numpy format errors
            raise ValueError(f"cannot read trajectory file {path!r}: {exc}") from None
        if "meta" not in data:
            raise ValueError(f"{path!r} is not a moreau trajectory: it has no 'meta' field "
                             f"(fields: {sorted(data)})")
        try:
            meta = json.loads(str(data.pop("meta")))
        except ValueError as exc:
            raise ValueError(f"trajectory file {path!r}: its 'meta' field is not valid JSON ({exc})") from None
        fmt = meta.get("format") if isinstance(meta, dict) else None
        if isinstance(fmt, int) and fmt > _FORMAT:
            raise ValueError(f"{path!r} is a moreau trajectory of file format {fmt}, written by moreau "
                             f"{meta.get('version', '?')}; this moreau reads format {_FORMAT}: upgrade moreau")
        if fmt != _FORMAT:
            raise ValueError(f"{path!r} is not a moreau trajectory (format {fmt!r})")
        _warn_if_newer(path, meta.get("version"))
        try:
            n_on = data["impacts_t"].shape[0]
            for flag in ("flight", "fast"):  # files from before the flight test: every entry counts
                data.setdefault("impacts_" + flag, np.ones(n_on, dtype=bool))
            data.setdefault("impacts_t_cross", np.full(n_on, np.nan))  # (files from before it was logged)
            onsets = ImpactLog(**{name: data.pop("impacts_" + name) for name in _impact_arrays()})
            traj = cls(
                t=data["t"], q=data["q"], v=data["v"], gaps=data["gaps"],
                impulses=data["impulses"], active=data["active"], onsets=onsets,
                stats=SolverStats(**meta["stats"]), h=meta["h"], record_every=meta["record_every"],
                row_names=meta["row_names"], scene=meta["scene"],
                energy=data.get("energy"), kinetic_energy=data.get("kinetic_energy"),
                potential_energy=data.get("potential_energy"), status=meta["status"],
                message=meta["message"], version=meta["version"], extra=meta.get("extra", {}),
                max_penetration=data.get("max_penetration"),
                max_penetration_t=data.get("max_penetration_t"), work=meta.get("work", {}),
                warnings=list(meta.get("warnings", [])), units=meta.get("units", {}),
                tangential_impulses=data.get("tangential_impulses"), slip_velocity=data.get("slip_velocity"),
                sticking=data.get("sticking"), constraint_impulses=data.get("constraint_impulses"),
                constraint_residuals=data.get("constraint_residuals"),
                constraint_names=list(meta.get("constraint_names", [])),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"trajectory file {path!r} is incomplete: missing {exc}") from None
        except ValueError as exc:  # malformed units
            raise ValueError(f"trajectory file {path!r}: {exc}") from None
        check_loaded(path, traj, n_on)
        return traj


def _version_key(v: str) -> tuple[int, ...]:
    return tuple(int(x) for x in v.split("+")[0].split(".") if x.isdigit())


def _warn_if_newer(path: str, version: object) -> None:
    import warnings

    from moreau.core.version import __version__

    if isinstance(version, str) and _version_key(version) > _version_key(__version__):
        warnings.warn(f"{path!r} was written by moreau {version}, newer than this moreau {__version__}: "
                      "fields it added are ignored", UserWarning, stacklevel=3)


def load(path: str | os.PathLike[str]) -> Trajectory:
    """Read a trajectory saved with :meth:`Trajectory.save`."""
    return Trajectory.load(path)


def _json_default(x: object) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON serializable: {type(x).__name__}")
