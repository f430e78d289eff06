"""Friction benchmark scenes with known answers (shared by the friction tests)."""

import numpy as np

import moreau as mo

G = 9.81


def block(mu, m=2.0, alpha=0.0, e=0.0):
    """A point mass q = (x, y) on a line through the origin at angle ``alpha`` (an incline;
    0: a floor) under gravity, Coulomb friction ``mu``: gap ``n·q``, tangent ``t·q`` with
    n = (−sin α, cos α), t = (cos α, sin α)."""
    n = [-np.sin(alpha), np.cos(alpha)]
    t = [np.cos(alpha), np.sin(alpha)]
    system = mo.FunctionSystem(m * np.eye(2), name="block")
    law = mo.NewtonImpactFriction(e, mu)
    return mo.Scene(system, [mo.ConstantForce([0.0, -m * G])],
                    [mo.Contact(mo.LinearBarrier([n], 0.0, tangent=[t]), law, name="floor")], name="block")


def disk(mu, radius=0.1, m=1.0, inertia=0.5, e=0.0, gravity=G):
    """A disk (``inertia`` = J / (m R²): 1/2 a disk, 2/5 a sphere) q = (x, y, θ) on the floor
    y >= R: gap ``y − R``, contact-point slip ``ẋ + R θ̇`` (tangent row (1, 0, R))."""
    J = inertia * m * radius**2
    system = mo.FunctionSystem(np.diag([m, m, J]), name="disk")
    floor = mo.LinearBarrier([[0.0, 1.0, 0.0]], -radius, tangent=[[1.0, 0.0, radius]])
    effects = [mo.ConstantForce([0.0, -m * gravity, 0.0])] if gravity else []
    return mo.Scene(system, effects, [mo.Contact(floor, mo.NewtonImpactFriction(e, mu), name="floor")], name="disk")
