"""A triple pendulum chain falling against three walls: impacts on curved constraints.

Three links hang from a fixed pivot (absolute angles, :mod:`moreau.model.chain`): two uniform
rods (m = 1.0, 0.8 kg; l = 0.5, 0.45 m) and a third link with an off-axis centre of mass
(m = 0.5 kg, J = 0.01 kg m², l = 0.4 m, centre of mass 0.25 m along and 0.02 m across the
link), joint damping 0.01, 0.005, 0.005 N m s/rad, gravity 9.81 m/s². Three inclined
walls: the tip of link 3 against a right wall (e = 0.8) and a floor (e = 0.9), the end of
link 1 against a left wall (e = 0.5). Released from rest at q = (1.2, 0.3, −0.5) rad, it
hits the walls 5 times in 1.5 s.

The scene has a configuration-dependent mass matrix, gyroscopic terms and gap functions
that are nonlinear in q: the class of mechanism on which the time-stepping variants differ
most. It serves the compiled-path tests and the work–precision study.
"""

from __future__ import annotations

import numpy as np

import moreau as mo

__all__ = ["chain_walls"]


def chain_walls() -> tuple[mo.Scene, np.ndarray, np.ndarray]:
    """The scene and its initial state.

    Returns
    -------
    scene : Scene
        q = (φ1, φ2, φ3) rad from the downward vertical; rows ``right``, ``left``,
        ``floor`` with restitutions 0.8, 0.5, 0.9.
    q0, v0 : ndarray, shape (3,)
        Released from rest at (1.2, 0.3, −0.5) rad.
    """
    from moreau.model.chain import ChainGravity, JointDamping, Link, PendulumChain, PointLineBarrier, PointLineRow

    chain = PendulumChain([Link.rod(m=1.0, l=0.5), Link.rod(m=0.8, l=0.45),
                           Link(m=0.5, J=0.01, l=0.4, com=0.25, com_lateral=0.02)])
    walls = PointLineBarrier(chain, [
        PointLineRow(2, (0.4, 0.0), line_point=(0.55, 0.0), normal=(-1.0, 0.1), name="right"),
        PointLineRow(0, (0.5, 0.0), line_point=(-0.3, 0.0), normal=(1.0, 0.3), name="left"),
        PointLineRow(2, (0.4, 0.0), line_point=(0.0, -1.2), normal=(0.2, 1.0), name="floor"),
    ])
    scene = mo.Scene(chain, [ChainGravity(chain, g=9.81), JointDamping(chain, [0.01, 0.005, 0.005])],
                     [mo.Contact(walls, law=[0.8, 0.5, 0.9], name="walls")], name="triple chain, 3 walls")
    return scene, np.array([1.2, 0.3, -0.5]), np.zeros(3)
