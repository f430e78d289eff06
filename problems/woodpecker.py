"""The woodpecker toy (Pfeiffer & Glocker): a classic benchmark of friction and impacts.

A bird (mass m_S, inertia J_S) hangs by a rotational spring from a sleeve (m_M, J_M)
that slides down a vertical pole with a little clearance. Tilted, the sleeve jams on the
pole at its upper or lower edge (friction holds it); the bird swings, its beak hits the
pole, and the sleeve unjams and slides a little further down: a self-sustained limit
cycle. Coordinates q = (y, φ_M, φ_S): the sleeve's height (m), its tilt and the bird's
(rad). The model is Glocker's linearized one (Ch. Glocker, *Dynamik von
Starrkörpersystemen mit Reibung und Stößen*, PhD thesis, TU München 1995, pp. 162 ff.;
Pfeiffer & Glocker, *Multibody Dynamics with Unilateral Contacts*, Wiley 1996): a
constant mass matrix, gaps linear in q with constant tangent rows, three contacts with
Coulomb friction mu = 0.3 — the beak (e = 0.5) and the sleeve's two edges (e = 0).

:data:`GLOCKER_STATE` is the initial state given with the model, a state on the limit
cycle: the sleeve jammed at its edge and the bird swinging towards the pole.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import moreau as mo

__all__ = ["WoodpeckerParameters", "woodpecker", "GLOCKER_STATE"]

#: (q0, v0) of Glocker's thesis: y = 0, φ_M = −0.1036, φ_S = −0.2788; ẏ = −0.3411 m/s,
#: φ̇_M = 0, φ̇_S = −7.4583 rad/s — with φ_M = −(r_M − r_0)/h_M = −0.10345, the sleeve's edge
#: exactly at the pole (the published −0.1036, rounded, puts it 0.9 µm inside, which
#: moreau refuses as an initial state)
GLOCKER_STATE = (np.array([0.0, -0.6e-3 / 5.8e-3, -0.2788]), np.array([-0.3411, 0.0, -7.4583]))


@dataclass(frozen=True)
class WoodpeckerParameters:
    """The toy's parameters (SI), Glocker's values by default.

    Attributes
    ----------
    m_M, J_M : float
        Sleeve mass (kg) and moment of inertia (kg m²).
    m_S, J_S : float
        Bird mass (kg) and moment of inertia about its centre of mass (kg m²).
    c_phi : float
        Rotational spring between sleeve and bird (N m/rad).
    r_0, r_M : float
        Pole radius and the sleeve's inner radius (m).
    h_M : float
        Half the sleeve's height (m).
    l_M, l_G : float
        Vertical distances sleeve centre – spring, spring – bird's centre of mass (m).
    h_S, l_S : float
        The beak's position in the bird's frame (m).
    g : float
        Gravity (m/s²).
    mu : float
        Friction at the three contacts.
    e_beak : float
        Restitution of the beak (the sleeve's edges: 0).
    """

    m_M: float = 3.0e-4
    J_M: float = 5.0e-9
    m_S: float = 4.5e-3
    J_S: float = 7.0e-7
    c_phi: float = 5.6e-3
    r_0: float = 2.5e-3
    r_M: float = 3.1e-3
    h_M: float = 5.8e-3
    l_M: float = 1.0e-2
    l_G: float = 1.5e-2
    h_S: float = 2.0e-2
    l_S: float = 2.01e-2
    g: float = 9.81
    mu: float = 0.3
    e_beak: float = 0.5


def woodpecker(params: WoodpeckerParameters | None = None) -> mo.Scene:
    """The scene: q = (y, φ_M, φ_S), the constant mass matrix of Glocker's linearized
    model, gravity and the spring, and the contacts ``beak`` (1 row) and ``sleeve``
    (rows ``sleeve[0]``, the edge that jams for φ_M < 0, and ``sleeve[1]``)."""
    p = WoodpeckerParameters() if params is None else params
    mS, lM, lG = p.m_S, p.l_M, p.l_G
    M = np.array([[p.m_M + mS, mS * lM, mS * lG],
                  [mS * lM, p.J_M + mS * lM**2, mS * lM * lG],
                  [mS * lG, mS * lM * lG, p.J_S + mS * lG**2]])
    system = mo.FunctionSystem(M, name="woodpecker")
    gravity = mo.ConstantForce([-(p.m_M + mS) * p.g, -mS * lM * p.g, -mS * lG * p.g], name="gravity")
    c = p.c_phi
    spring = mo.LinearSpring([[0.0, 0.0, 0.0], [0.0, c, -c], [0.0, -c, c]], name="spring")
    beak = mo.LinearBarrier([[0.0, 0.0, -p.h_S]], [lM + lG - p.l_S - p.r_0], tangent=[[1.0, lM, lG - p.l_S]])
    sleeve = mo.LinearBarrier([[0.0, p.h_M, 0.0], [0.0, -p.h_M, 0.0]], [p.r_M - p.r_0] * 2,
                              tangent=[[1.0, p.r_M, 0.0], [1.0, p.r_M, 0.0]])
    contacts = [mo.Contact(beak, mo.NewtonImpactFriction(p.e_beak, p.mu), name="beak"),
                mo.Contact(sleeve, mo.NewtonImpactFriction(0.0, p.mu), name="sleeve")]
    return mo.Scene(system, [gravity, spring], contacts, name="woodpecker",
                    units={"t": "s", "q": ["m", "rad", "rad"], "v": ["m/s", "rad/s", "rad/s"], "gaps": "m",
                           "impulses": "N s", "energy": "J", "description": "the woodpecker toy (Glocker 1995)"})
