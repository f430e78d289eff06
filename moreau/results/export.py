"""Results as labelled arrays and tables: :meth:`Trajectory.to_xarray` and
:meth:`ImpactLog.to_dataframe`.

xarray and pandas are optional (the ``export`` extra: ``pip install "moreau-jean[export]"``);
without them these functions raise an ``ImportError`` that names the extra.
"""

from __future__ import annotations

import importlib
import json
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from moreau.model.units import uniform

if TYPE_CHECKING:
    import pandas
    import xarray

    from moreau.results.trajectory import ImpactLog, Trajectory

__all__ = ["trajectory_to_xarray", "impacts_to_dataframe"]


def _require(module: str, what: str) -> ModuleType:
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"{what} needs {module}, which is not installed: "
                          f'pip install "moreau-jean[export]" (or pip install {module})') from None


def trajectory_to_xarray(traj: Trajectory) -> xarray.Dataset:
    """The trajectory as an :class:`xarray.Dataset`.

    Dimensions ``time`` (the records), ``dof`` (coordinates 0..n-1) and ``row`` (the
    contact rows, labelled by their names). Variables: ``q``, ``v`` (time, dof);
    ``gaps``, ``impulses``, ``active`` (time, row); ``energy``, ``kinetic_energy``,
    ``potential_energy`` (time) when computed; with friction ``tangential_impulses``,
    ``slip_velocity`` and ``sticking`` (time, row); ``max_penetration`` (row) when known; the
    coordinates ``q_unit``, ``v_unit`` (dof) and ``row_unit`` (row) name the unit of each
    entry. Each variable's ``attrs["units"]`` is its unit (entries joined by ``", "`` when
    they differ). ``Dataset.attrs``: ``scene`` (name), ``scene_json`` (the scene's
    parameters), ``solver``, ``fallback``, ``backend``, ``version``, ``status``,
    ``message``, ``h``, ``record_every``, ``n_impacts``, ``work_json`` (the energy ledger,
    friction included), ``description`` and ``units`` (the whole units dict as JSON:
    netCDF attributes hold no dicts).

    Raises
    ------
    ImportError
        When xarray is not installed; the message names the ``export`` extra.
    """
    xr = _require("xarray", "Trajectory.to_xarray()")
    u = traj.units
    n = traj.q.shape[1] if traj.q.ndim == 2 else 0
    coords: dict[str, Any] = {
        "time": ("time", traj.t, {"units": u["t"], "long_name": "time"}),
        "dof": ("dof", np.arange(n)),
        "row": ("row", np.array(traj.row_names, dtype=object) if traj.row_names else np.zeros(0, dtype=object)),
        "q_unit": ("dof", np.array(u["q"], dtype=object)),
        "v_unit": ("dof", np.array(u["v"], dtype=object)),
        "row_unit": ("row", np.array(u["gaps"], dtype=object)),
    }
    data: dict[str, Any] = {
        "q": (("time", "dof"), traj.q, {"units": uniform(u["q"]), "long_name": "coordinates"}),
        "v": (("time", "dof"), traj.v, {"units": uniform(u["v"]), "long_name": "velocities"}),
        "gaps": (("time", "row"), traj.gaps, {"units": uniform(u["gaps"]), "long_name": "gaps g(q)"}),
        "impulses": (("time", "row"), traj.impulses,
                     {"units": uniform(u["impulses"]),
                      "long_name": "contact impulses summed since the previous record"}),
        "active": (("time", "row"), traj.active,
                   {"long_name": "row closed in a step since the previous record"}),
    }
    if traj.tangential_impulses is not None:  # friction
        data["tangential_impulses"] = (("time", "row"), traj.tangential_impulses, {
            "units": uniform(u["impulses"]), "long_name": "friction impulses summed since the previous record"})
    if traj.slip_velocity is not None:
        data["slip_velocity"] = (("time", "row"), traj.slip_velocity,
                                 {"long_name": "tangential velocity T(q) v at the record"})
    if traj.sticking is not None:
        data["sticking"] = (("time", "row"), traj.sticking,
                            {"long_name": "closed with |P_T| < mu P_N since the previous record"})
    for name in ("energy", "kinetic_energy", "potential_energy"):
        value = getattr(traj, name)
        if value is not None:
            data[name] = ("time", value, {"units": u["energy"], "long_name": name.replace("_", " ")})
    if traj.max_penetration is not None:
        data["max_penetration"] = ("row", traj.max_penetration,
                                   {"units": uniform(u["gaps"]), "long_name": "largest penetration over every step"})
    if traj.max_penetration_t is not None:
        data["max_penetration_t"] = ("row", traj.max_penetration_t,
                                     {"units": "s", "long_name": "end of the step with the largest penetration"})
    attrs = {
        "scene": str(traj.scene.get("name", "")),
        "scene_json": json.dumps(traj.scene, default=_plain),
        "solver": traj.stats.solver, "fallback": traj.stats.fallback, "backend": traj.stats.backend,
        "version": traj.version, "status": traj.status, "message": traj.message,
        "h": float(traj.h), "record_every": int(traj.record_every), "n_impacts": len(traj.impacts),
        "work_json": json.dumps(traj.work),
        "description": u["description"], "units": json.dumps(u),
    }
    dataset: xarray.Dataset = xr.Dataset(data, coords=coords, attrs=attrs)
    return dataset


def impacts_to_dataframe(log: ImpactLog) -> pandas.DataFrame:
    """The impact log as a :class:`pandas.DataFrame`, one row per impact.

    Columns ``t``, ``t_cross``, ``step``, ``row``, ``row_name``, ``U_before``, ``U_after``,
    ``impulse``, ``energy_lost``; ``df.attrs["units"]`` maps each column to its unit
    (``impulse`` and the velocities per row joined by ``", "`` when the rows differ).

    Raises
    ------
    ImportError
        When pandas is not installed; the message names the ``export`` extra.
    """
    pd = _require("pandas", "ImpactLog.to_dataframe()")
    names = log.row_names
    df = pd.DataFrame({
        "t": log.t, "t_cross": log.t_cross, "step": log.step, "row": log.row,
        "row_name": [names[r] if 0 <= r < len(names) else "" for r in log.row],
        "U_before": log.U_before, "U_after": log.U_after,
        "impulse": log.impulse, "energy_lost": log.energy_lost,
    })
    u = log.units
    t_unit = u.get("t", "")
    gaps = uniform(u.get("gaps", []))
    if gaps == "1" and t_unit == "1":
        velocity = "1"
    else:
        velocity = f"{gaps}/{t_unit}" if gaps and t_unit and t_unit != "1" and "," not in gaps else ""
    df.attrs["units"] = {
        "t": t_unit, "t_cross": t_unit, "step": "", "row": "", "row_name": "",
        "U_before": velocity, "U_after": velocity,
        "impulse": uniform(u.get("impulses", [])), "energy_lost": u.get("energy", ""),
    }
    return df


def _plain(x: object) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return str(x)
