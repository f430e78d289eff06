"""The units of the piston scene: the paper's non-dimensional ones, with their scales to SI."""

from __future__ import annotations

from typing import Any

from moreau.model.chain import Units

from .params import PistonParameters

__all__ = ["scene_units"]


def scene_units(p: PistonParameters, u: Units) -> dict[str, Any]:
    """The units dict of the engine scene (:mod:`moreau.model.units`).

    Time is τ = ω t (ω = 2π n/60 at the reference speed n), lengths are in l1 and masses
    in μ = M̄_11 / l1² (so that M_11 = 1): t, v, gaps, impulses and energy are
    non-dimensional (``"1"``), the angles q are in rad. ``scales`` converts each to SI:
    ``value_SI = value * scales[name]`` in the unit ``si[name]``.
    """
    return {
        "t": "1", "q": "rad", "v": "1", "gaps": "1", "impulses": "1", "energy": "1",
        "description": (
            f"non-dimensional (the paper's units): time tau = omega t with omega = 2 pi {p.rpm:g}/60 = "
            f"{p.omega:.6g} rad/s (the crank angle advances 1 rad per unit of tau at the reference "
            f"speed), lengths in l1 = {u.length:g} m, masses in M11/l1^2 = {u.mass:.6g} kg; angles q in "
            "rad; to SI: value * scales[name] in si[name]"),
        "scales": {"t": u.time, "v": 1.0 / u.time, "gaps": u.length, "impulses": u.impulse,
                   "energy": u.energy},
        "si": {"t": "s", "v": "rad/s", "gaps": "m", "impulses": "N s", "energy": "J"},
    }
