"""What :func:`moreau.load` checks of a trajectory file before it hands the trajectory back:
every array of the records has one entry per record and one column per row, times are
finite and in order, the step and the status are ones a run writes, and the friction and
constraint fields come together or not at all. A file that fails is refused with a
``ValueError`` naming the field."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from moreau.results.impacts import _impact_arrays

__all__ = ["STATUSES", "check_loaded"]

#: the statuses a run ends with
STATUSES = ("completed", "failed", "interrupted")
_FRICTION = ("tangential_impulses", "slip_velocity", "sticking")


def check_loaded(path: str, traj: Any, n_onsets: int) -> None:
    """Raise ``ValueError`` naming the first field of the loaded ``traj`` (from ``path``)
    that no run could have written."""
    where = f"trajectory file {path!r}"
    t = np.asarray(traj.t)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0.0):
        raise ValueError(f"{where} is inconsistent: t must be a non-empty, finite, non-decreasing 1-D array, "
                         f"got shape {t.shape} with {int(np.sum(~np.isfinite(t)))} non-finite values")
    if not isinstance(traj.h, (int, float)) or isinstance(traj.h, bool) or not math.isfinite(traj.h) or traj.h <= 0:
        raise ValueError(f"{where} is inconsistent: h must be a positive number, got {traj.h!r}")
    every = traj.record_every
    if not isinstance(every, int) or isinstance(every, bool) or every < 1:
        raise ValueError(f"{where} is inconsistent: record_every must be a positive integer, got {every!r}")
    if traj.status not in STATUSES:
        raise ValueError(f"{where} is inconsistent: status {traj.status!r} is not one of {list(STATUSES)}")
    N, m, me = t.shape[0], len(traj.row_names), len(traj.constraint_names)
    n = np.asarray(traj.q).shape[1] if np.ndim(traj.q) == 2 else -1
    shapes = {"q": (N, n), "v": (N, n), "gaps": (N, m), "impulses": (N, m), "active": (N, m),
              "energy": (N,), "kinetic_energy": (N,), "potential_energy": (N,), "max_penetration": (m,),
              "max_penetration_t": (m,),
              "tangential_impulses": (N, m), "slip_velocity": (N, m), "sticking": (N, m),
              "constraint_impulses": (N, me), "constraint_residuals": (N, me)}
    for name, shape in shapes.items():
        a = getattr(traj, name)
        if a is not None and not name.startswith("max_penetration") and np.ndim(a) >= 1 and np.shape(a)[0] != N:
            raise ValueError(f"{where} is inconsistent: {name} has {np.shape(a)[0]} records, t has {N}")
        if a is not None and (n < 0 or np.shape(a) != shape):
            raise ValueError(f"{where} is inconsistent: {name} has shape {np.shape(a)}, expected {shape} "
                             f"({N} records, {m} rows named {traj.row_names}, {me} constraint rows)")
    for name in ("active", "sticking"):
        a = getattr(traj, name)
        if a is not None and np.asarray(a).dtype != np.bool_:
            raise ValueError(f"{where} is inconsistent: {name} must be boolean, got {np.asarray(a).dtype}")
    given = [name for name in _FRICTION if getattr(traj, name) is not None]
    if given and len(given) != len(_FRICTION):
        missing = [name for name in _FRICTION if name not in given]
        raise ValueError(f"{where} is inconsistent: friction fields {given} without {missing}")
    if "friction" in (traj.work or {}) and not given:
        raise ValueError(f"{where} is inconsistent: work['friction'] without the friction fields {list(_FRICTION)}")
    for name in ("constraint_impulses", "constraint_residuals"):
        if me and getattr(traj, name) is None:
            raise ValueError(f"{where} is inconsistent: {me} constraint rows named but no {name}")
    for name in _impact_arrays():
        a = getattr(traj.onsets, name)
        if np.shape(a)[0] != n_onsets:
            raise ValueError(f"{where} is inconsistent: impacts_{name} has {np.shape(a)[0]} entries, "
                             f"impacts_t has {n_onsets}")
    rows = np.asarray(traj.onsets.row)
    if rows.size and (rows.min() < 0 or rows.max() >= m):
        raise ValueError(f"{where} is inconsistent: impacts_row holds rows outside 0 ... {m - 1}")
