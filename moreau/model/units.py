"""Units of a scene and of its results.

moreau computes in whatever consistent units a scene is written in; it converts nothing.
A scene may *declare* its units (``Scene(..., units={...})``); every trajectory of it then
carries them as ``traj.units`` (kept by ``save``/``load``, exported as the ``units``
attributes of :meth:`moreau.Trajectory.to_xarray`).

The units dict
--------------
``"t"`` : str
    Time (``"s"``; ``"1"`` for a non-dimensional time).
``"q"``, ``"v"`` : list of str, one per coordinate
    Coordinates and velocities (``"m"``, ``"rad"``; ``"m/s"``, ``"rad/s"``). Declared as
    one string, it applies to every coordinate; ``v`` defaults to ``q/t``.
``"gaps"``, ``"impulses"`` : list of str, one per contact row
    Gaps g(q) and contact impulses P (``"m"``, ``"N s"``). One string applies to every row.
``"energy"`` : str
    Energies and work (``"J"``).
``"description"`` : str
    Free text: what the units are, e.g. the scales of a non-dimensional model.
``"scales"`` : dict of str to float, and ``"si"`` : dict of str to str
    For non-dimensional quantities: ``value_SI = value * scales[name]`` in the unit
    ``si[name]`` (e.g. ``scales["t"] = 1/ω``, ``si["t"] = "s"``).

An empty string means *not declared*; :func:`moreau.simulate` then assumes nothing, but
the quantities it derives (kinetic energy ½ vᵀMv, impulses) are in the units the scene's
mass matrix and forces make them (J and N s for a scene written in SI).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["UNIT_KEYS", "complete_units", "uniform", "unit_suffix"]

#: the keys of a units dict
UNIT_KEYS = ("t", "q", "v", "gaps", "impulses", "energy", "description", "scales", "si")
_PER_DOF = ("q", "v")
_PER_ROW = ("gaps", "impulses")


def complete_units(units: Mapping[str, Any] | None, ndof: int, nrows: int) -> dict[str, Any]:
    """A units dict with every key: lists per coordinate and per row, ``v`` derived from
    ``q`` and ``t`` when not given, ``""`` where nothing is declared.

    Raises
    ------
    ValueError
        For an unknown key, a unit that is not a string, or a list of the wrong length
        (naming the key and the lengths).
    """
    given = dict(units or {})
    unknown = sorted(set(given) - set(UNIT_KEYS))
    if unknown:
        raise ValueError(f"units: unknown key(s) {unknown}; the keys are {list(UNIT_KEYS)}")
    out: dict[str, Any] = {}
    for key in ("t", "energy", "description"):
        out[key] = _text(given.get(key, ""), key)
    for key, n in [(k, ndof) for k in _PER_DOF] + [(k, nrows) for k in _PER_ROW]:
        out[key] = _per_entry(given.get(key, ""), key, n)
    if "v" not in given:
        out["v"] = [f"{q}/{out['t']}" if q and out["t"] and out["t"] != "1" else "" for q in out["q"]]
    for key in ("scales", "si"):
        value = given.get(key, {})
        if not isinstance(value, Mapping):
            raise ValueError(f"units[{key!r}] must be a dict, got {value!r}")
        out[key] = dict(value)
    for name, factor in out["scales"].items():
        if isinstance(factor, bool) or not isinstance(factor, (int, float)):
            raise ValueError(f"units['scales'][{name!r}] must be a number, got {factor!r}")
    return out


def _text(value: object, key: str) -> str:
    if not isinstance(value, str):
        raise ValueError(f"units[{key!r}] must be a string, got {value!r}")
    return value


def _per_entry(value: object, key: str, n: int) -> list[str]:
    what = "coordinate" if key in _PER_DOF else "contact row"
    if isinstance(value, str):
        return [value] * n
    if not isinstance(value, (list, tuple)) or not all(isinstance(x, str) for x in value):
        raise ValueError(f"units[{key!r}] must be a string or a list of strings (one per {what}), got {value!r}")
    if len(value) != n:
        raise ValueError(f"units[{key!r}] has {len(value)} entries for {n} {what}s")
    return list(value)


def uniform(units: list[str]) -> str:
    """The one unit of a list when all entries agree, else the entries joined by ``", "``."""
    return units[0] if units and all(u == units[0] for u in units) else ", ".join(units)


def unit_suffix(units: Mapping[str, Any], key: str) -> str:
    """``" s"`` for a repr: the unit of ``key`` when declared and the same for every entry,
    ``" (non-dimensional)"`` for ``"1"``, else nothing."""
    u = units.get(key, "")
    u = uniform(u) if isinstance(u, list) else u
    if not u or "," in u:
        return ""
    return " (non-dimensional)" if u == "1" else f" {u}"
