"""A pendulum whose bob hits a vertical wall.

A point mass m on a massless rod of length l hangs from the origin; θ is measured from
the downward vertical, positive towards +x. The bob at (l sin θ, −l cos θ) must stay left
of the wall x = x_w: ``g(θ) = x_w − l sin θ >= 0``. Gravity gives the torque
−m g l sin θ; optional viscous damping −c θ̇ in the pivot.

The mass matrix m l² is constant and gravity depends on position only, so without damping
the midpoint scheme is second order in smooth phases; damping makes it first order.
"""

from __future__ import annotations

import numpy as np

import moreau as mo

__all__ = ["pendulum_wall", "pendulum_rhs"]


def pendulum_wall(
    e: float = 0.8,
    mass: float = 1.0,
    length: float = 1.0,
    g: float = 9.81,
    wall_x: float | None = 0.5,
    damping: float = 0.0,
) -> mo.Scene:
    """The scene: q = (θ,) rad.

    Parameters
    ----------
    e : float
        Restitution at the wall.
    mass, length, g : float
        Bob mass (kg), rod length (m), gravity (m/s²).
    wall_x : float or None
        Wall position x_w (m), 0 < x_w < length; None for no wall.
    damping : float
        Pivot damping c (N m s); 0 for none (then no damping effect is in the scene).
    """
    m, l = float(mass), float(length)
    if not (np.isfinite(m) and m > 0):
        raise ValueError(f"pendulum mass must be positive, got {mass!r}")
    if not (np.isfinite(l) and l > 0):
        raise ValueError(f"pendulum length must be positive, got {length!r}")
    system = mo.FunctionSystem(np.array([[m * l * l]]), name="pendulum")
    mgl = m * g * l
    effects: list[mo.Effect] = [
        mo.FunctionForce(
            lambda t, q, v: -mgl * np.sin(q),
            potential=lambda q: -mgl * float(np.cos(q[0])),
            velocity_dependent=False,
            time_dependent=False,
            name="gravity",
        )
    ]
    if damping:
        effects.append(mo.LinearDamping([[damping]], name="damping"))
    contacts = []
    if wall_x is not None:
        if not (0 < wall_x < l):
            raise ValueError(f"wall_x must lie in (0, length={l}), got {wall_x!r}")
        xw = float(wall_x)
        wall = mo.FunctionBarrier(
            gap=lambda q: np.array([xw - l * np.sin(q[0])]),
            jacobian=lambda q: np.array([[-l * np.cos(q[0])]]),
            ndof=1,
        )
        contacts.append(mo.Contact(wall, mo.NewtonImpact(e), name="wall"))
    units = {"t": "s", "q": "rad", "gaps": "m", "impulses": "N s", "energy": "J"}
    return mo.Scene(system, effects, contacts, name="pendulum_wall", units=units)


def pendulum_rhs(mass: float = 1.0, length: float = 1.0, g: float = 9.81, damping: float = 0.0):
    """Smooth right-hand side ``y' = F(t, y)``, y = (θ, θ̇), for scipy references."""
    ml2 = mass * length * length

    def rhs(t, y):
        return [y[1], (-mass * g * length * np.sin(y[0]) - damping * y[1]) / ml2]

    return rhs
