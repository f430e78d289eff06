"""Case 9 — an elastic ball (e = 1) for 10 000 impacts: no energy gained at any impact,
and the energy drift stays at round-off.

For a constant force the midpoint scheme is exact in flight, and an elastic impact step
returns the ball to the position it started the step from with the velocity reversed
exactly (q_m = q_k + h/2 v_k, v⁺ = −v_k, q⁺ = q_m + h/2 v⁺ = q_k): the energy is
conserved to round-off at every step. The bounce takes one step longer than the
analytic flight (the impact step has no gravity), so the discrete period is 51 steps
for an analytic 50.

Cost: h0 = 5 cm, 50 steps per analytic period: 510 k steps, ~10–30 s.
"""

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

from .conftest import assert_finite, audit_impacts, newton_dissipation

pytestmark = pytest.mark.slow


def test_elastic_ball_10000_impacts():
    h0, g, n_impacts, steps_per_period = 0.05, 9.81, 10_000, 50
    sol = BallSolution(h0, 1.0, g)
    h = 2 * sol.t1 / steps_per_period
    n_steps = (n_impacts + 2) * (steps_per_period + 1)
    traj = mo.simulate(bouncing_ball(1.0, g=g), (0.0, n_steps * h), [h0], [0.0], h,
                       solver="enum", record_every=10)
    assert traj.completed and traj.stats.fallbacks == 0
    assert_finite(traj)
    imp = traj.impacts
    assert len(imp) >= n_impacts
    # no energy gain at any impact: the logged loss (the Newton dissipation) is 0 for
    # e = 1 to round-off
    audit_impacts(traj)
    scale = 0.5 * sol.v1**2  # kinetic energy at impact, J/kg (m = 1)
    assert np.abs(newton_dissipation(traj)).max() <= 1e-12 * scale
    # every bounce is elastic: the rebound speed equals the impact speed to round-off
    np.testing.assert_allclose(imp.U_after, -imp.U_before, rtol=1e-12)
    # and the impact speed does not drift: v1 at the first bounce and at the last
    assert np.ptp(np.abs(imp.U_before)) <= 1e-10 * sol.v1
    # bounded total drift: one ulp of the energy per step at most (round-off, measured
    # 3e-13 relative after 1000 bounces)
    E = traj.energy
    drift = np.abs(E - E[0]).max() / E[0]
    assert drift <= n_steps * np.finfo(float).eps
    # no secular gain: the last tenth is no higher than the first
    tenth = E.shape[0] // 10
    assert E[-tenth:].max() <= E[:tenth].max() * (1 + n_steps * np.finfo(float).eps)
