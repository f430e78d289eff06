"""A ball dropped on a floor: the classic test of an impact integrator.

The ball (mass m, height y) falls under gravity g onto the floor y >= 0 with Newton
restitution e. Its analytic solution is known exactly, which makes it the reference for
impact times, apex heights and the Zeno time at which infinitely many bounces end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import moreau as mo

__all__ = ["bouncing_ball", "BallSolution"]


def bouncing_ball(e: float = 0.5, mass: float = 1.0, g: float = 9.81, floors: int = 1) -> mo.Scene:
    """The scene: q = (y,) in m, M = (m,), gravity, floor(s) at y = 0.

    Parameters
    ----------
    e : float
        Restitution coefficient in [0, 1].
    mass : float
        Mass (kg), > 0.
    g : float
        Gravitational acceleration (m/s²), >= 0.
    floors : int
        Number of identical floors (> 1 makes redundant contacts, for tests).
    """
    mass = float(mass)
    if not np.isfinite(mass) or mass <= 0:
        raise ValueError(f"ball mass must be positive, got {mass!r}")
    system = mo.FunctionSystem(np.array([[mass]]), name="ball")
    effects = [mo.ConstantForce([-mass * g], name="gravity")] if g else []
    contacts = [
        mo.Contact(mo.LinearBarrier([[1.0]], [0.0]), mo.NewtonImpact(e), name="floor" if floors == 1 else f"floor{i}")
        for i in range(floors)
    ]
    units = {"t": "s", "q": "m", "gaps": "m", "impulses": "N s", "energy": "J"}
    return mo.Scene(system, effects, contacts, name="bouncing_ball", units=units)


@dataclass(frozen=True)
class BallSolution:
    """Analytic solution of a ball dropped from rest at height h0 (m).

    Impact k (k = 1, 2, ...) happens at ``impact_time(k)`` with speed ``e^(k-1) v1``,
    ``v1 = sqrt(2 g h0)``; apex k (after impact k) is at ``e^(2k) h0``; the bounces
    accumulate at the Zeno time ``t1 (1 + e)/(1 − e)``, ``t1 = sqrt(2 h0 / g)``.
    """

    h0: float
    e: float
    g: float = 9.81

    @property
    def t1(self) -> float:
        """First impact time (s)."""
        return float(np.sqrt(2 * self.h0 / self.g))

    @property
    def v1(self) -> float:
        """First impact speed (m/s)."""
        return float(np.sqrt(2 * self.g * self.h0))

    @property
    def zeno_time(self) -> float:
        """Time at which the ball comes to rest (s); inf for e = 1."""
        return np.inf if self.e >= 1 else self.t1 * (1 + self.e) / (1 - self.e)

    def impact_time(self, k: int) -> float:
        """Time of impact k >= 1 (s)."""
        e = self.e
        # t_k = t1 + 2 t1 (e + e² + ... + e^(k-1))
        return self.t1 * (1 + 2 * sum(e**j for j in range(1, k)))

    def apex_height(self, k: int) -> float:
        """Height of the apex after impact k (m)."""
        return self.e ** (2 * k) * self.h0

    def position(self, t) -> np.ndarray:
        """Height y(t) (m), vectorized; zero after the Zeno time."""
        t = np.asarray(t, dtype=float)
        y = np.zeros_like(t)
        g, e = self.g, self.e
        free = t < self.t1
        y[free] = self.h0 - 0.5 * g * t[free] ** 2
        tk, vk, k = self.t1, self.v1 * e, 1
        while vk > 1e-12 * self.v1 and tk < t.max() and k < 10_000:
            dur = 2 * vk / g
            sel = (t >= tk) & (t < tk + dur)
            s = t[sel] - tk
            y[sel] = vk * s - 0.5 * g * s**2
            tk, vk, k = tk + dur, vk * e, k + 1
        return y
