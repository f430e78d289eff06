"""A four-bar linkage under gravity: a closed loop written as a three-link chain whose
last link is pinned to the ground (:func:`moreau.model.chain.pin_point`), optionally
with a stop that the rocker hits (an impact through the closed loop).

The crank (link 0) turns about the origin O, the coupler (link 1) joins the crank to the
rocker (link 2), and the rocker's far end is held at the ground pivot D = (d, 0): two
bilateral rows. Coordinates: the absolute angles of the three links from the downward
vertical (rad), as the chain of the founding paper; one degree of freedom remains.
Uniform rods, SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import moreau as mo
from moreau.model.chain import ChainGravity, JointStop, Link, PendulumChain, pin_point

__all__ = ["FourBarParameters", "FourBar", "four_bar"]


@dataclass(frozen=True)
class FourBarParameters:
    """Lengths (m) and masses (kg) of the crank, coupler and rocker, the ground link d
    (m), and an optional stop on the rocker's absolute angle (rad) with its restitution.
    The defaults are a Grashof crank-rocker: the crank turns fully round."""

    crank: float = 0.2
    coupler: float = 0.5
    rocker: float = 0.4
    ground: float = 0.45
    masses: tuple = (1.0, 2.0, 1.5)
    stop: float | None = None
    e: float = 0.5


@dataclass
class FourBar:
    """The linkage's scene and its geometry."""

    params: FourBarParameters
    chain: PendulumChain
    scene: mo.Scene

    def configuration(self, crank_angle: float) -> np.ndarray:
        """The closed configuration (rad, shape (3,)) with the crank at ``crank_angle``
        (the branch with the coupler's joint above the line from the crank pin to D)."""
        p = self.params
        A = p.crank * np.array([np.sin(crank_angle), -np.cos(crank_angle)])
        r = np.array([p.ground, 0.0]) - A
        dist = float(np.hypot(*r))
        cos_a = (p.coupler ** 2 + dist ** 2 - p.rocker ** 2) / (2.0 * p.coupler * dist)
        if not -1.0 <= cos_a <= 1.0:
            raise ValueError(f"FourBar.configuration: the loop does not close at crank_angle = {crank_angle!r}")
        th = np.arctan2(r[1], r[0]) + np.arccos(cos_a)
        B = A + p.coupler * np.array([np.cos(th), np.sin(th)])
        e1, e2 = (B - A) / p.coupler, (np.array([p.ground, 0.0]) - B) / p.rocker
        return np.array([crank_angle, np.arctan2(e1[0], -e1[1]), np.arctan2(e2[0], -e2[1])])

    def initial_state(self, crank_angle: float = 0.3, crank_speed: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
        """(q0, v0): the closed configuration and the velocity that turns the crank at
        ``crank_speed`` (rad/s) with the loop kept closed (the M-projection of (ω, 0, 0)
        scaled so that the crank's speed is exactly ω)."""
        q0 = self.configuration(crank_angle)
        v = self.scene.constrained_velocity(q0, np.array([1.0, 0.0, 0.0]))
        return q0, v * (crank_speed / v[0])


def four_bar(params: FourBarParameters | None = None, **kw) -> FourBar:
    """The four-bar linkage (see the module docstring); ``kw`` overrides fields of
    :class:`FourBarParameters`."""
    p = params if params is not None else FourBarParameters(**kw)
    if params is not None and kw:
        raise ValueError("four_bar: give params or keyword overrides, not both")
    chain = PendulumChain([Link.rod(m, l) for m, l in zip(p.masses, (p.crank, p.coupler, p.rocker))])
    closure = pin_point(chain, 2, (p.rocker, 0.0), (p.ground, 0.0), name="ground pivot")
    contacts = []
    if p.stop is not None:
        contacts.append(mo.Contact(JointStop(chain, 2, upper=p.stop), p.e, name="rocker stop"))
    scene = mo.Scene(chain, [ChainGravity(chain)], contacts, constraints=[closure], name="four-bar")
    return FourBar(p, chain, scene)
