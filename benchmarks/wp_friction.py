"""Work–precision study, part 2b: the problems with Coulomb friction (issue 27).

* :class:`BlockProblem` — a block sliding to rest on a floor (mu = 0.3, v0 = 2 m/s)
  against its analytic motion x(t) = v0 t − ½ mu g t² up to the stop at
  v0²/(2 mu g).
* :class:`WoodpeckerProblem` — the woodpecker toy (:mod:`moreau.problems.woodpecker`)
  from Glocker's published state on its limit cycle, three periods, against the compiled
  midpoint run at h = 1e-6: the instants and velocities at which the bird swings down
  through φ_S = −0.2788.
"""

from __future__ import annotations

import numpy as np
from wp_configs import Config, _timed
from wp_problems import Problem

import moreau as mo

G = 9.81


class BlockProblem(Problem):
    """A block sliding to rest; errors: ``position`` (max |x − x_exact| over the records)
    and ``stop`` (|x(t_end) − v0²/(2 mu g)|)."""

    name = "block"
    primary = "position"
    metrics = ("position", "stop")

    def __init__(self, ladder, config_list, mu=0.3, v0=2.0, t_end=1.0):
        super().__init__(ladder, config_list)
        self.mu, self.v0, self.t_end = mu, v0, t_end
        m = 2.0
        floor = mo.LinearBarrier([[0.0, 1.0]], 0.0, tangent=[[1.0, 0.0]])
        self.scene = mo.Scene(mo.FunctionSystem(m * np.eye(2)), [mo.ConstantForce([0.0, -m * G])],
                              [mo.Contact(floor, mo.NewtonImpactFriction(0.0, mu), name="floor")], name="block")

    def exact(self, t):
        ts = self.v0 / (self.mu * G)
        tt = np.minimum(t, ts)
        return self.v0 * tt - 0.5 * self.mu * G * tt**2

    def run(self, config, h):
        hs, kw = config.run_args(h)
        traj, wall, status = _timed(lambda: mo.simulate(
            self.scene, (0.0, self.t_end), [0.0, 0.0], [self.v0, 0.0], hs, energy=False, **kw), repeat_below=0.5)
        m = {}
        if status == "completed":
            m["position"] = float(np.abs(traj.q[:, 0] - self.exact(traj.t)).max())
            m["stop"] = float(abs(traj.q[-1, 0] - self.v0**2 / (2 * self.mu * G)))
        return self._run(config, h, traj, wall, status, m)


def _returns(traj, phi=-0.2788):
    """(t, ẏ, φ̇_S) each time the bird swings down through φ_S = phi (interpolated)."""
    ps, w = traj.q[:, 2], traj.v[:, 2]
    out = []
    for i in np.flatnonzero((ps[:-1] > phi) & (ps[1:] <= phi) & (w[1:] < 0)):
        a = (phi - ps[i]) / (ps[i + 1] - ps[i])
        out.append([x[i] + a * (x[i + 1] - x[i]) for x in (traj.t, traj.v[:, 0], traj.v[:, 2])])
    return np.array(out)


class WoodpeckerProblem(Problem):
    """The woodpecker toy; errors at the returns to Glocker's state against the h = 1e-6
    reference: ``return_time`` (s), ``ydot`` (m/s), ``phidot`` (rad/s), each the largest
    over the three returns."""

    name = "woodpecker"
    primary = "return_time"
    metrics = ("return_time", "ydot", "phidot")

    def __init__(self, ladder, config_list, t_end=0.45, h_ref=1e-6):
        super().__init__(ladder, config_list)
        from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

        self.scene = woodpecker()
        self.q0, self.v0 = GLOCKER_STATE
        self.t_end, self.h_ref = t_end, h_ref
        self.ref = None

    def _simulate(self, config, h):
        hs, kw = config.run_args(h, h_max=1e-3)
        return _timed(lambda: mo.simulate(self.scene, (0.0, self.t_end), self.q0, self.v0, hs, energy=False, **kw),
                      repeat_below=0.5)

    def prepare(self):
        if self.ref is None:
            traj, _, status = self._simulate(Config("mid", "exact", "none"), self.h_ref)
            if status != "completed":
                raise RuntimeError(f"woodpecker: the reference run failed: {traj.message}")
            self.ref = _returns(traj)

    def run(self, config, h):
        self.prepare()
        traj, wall, status = self._simulate(config, h)
        m = {}
        if status == "completed":
            r = _returns(traj)
            if r.shape == self.ref.shape:
                d = np.abs(r - self.ref).max(axis=0)
                m["return_time"], m["ydot"], m["phidot"] = (float(x) for x in d)
            else:
                m["return_time"] = m["ydot"] = m["phidot"] = float("inf")
        return self._run(config, h, traj, wall, status, m)
