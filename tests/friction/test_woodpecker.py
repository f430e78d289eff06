"""The woodpecker toy (Glocker 1995; Pfeiffer & Glocker 1996), a classic benchmark of
friction and impacts: started from the state published with the model, a state on its
limit cycle, the toy must come back to that state once per period, on both paths."""

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

PHI_S, YDOT, PHI_S_DOT, PHI_M = -0.2788, -0.3411, -7.4583, -0.1036  # Glocker's state


def returns(traj):
    """The state each time the bird swings down through φ_S = −0.2788 (linear
    interpolation between records): rows (t, φ_M, ẏ, φ̇_M, φ̇_S)."""
    ps, w = traj.q[:, 2], traj.v[:, 2]
    out = []
    for i in np.flatnonzero((ps[:-1] > PHI_S) & (ps[1:] <= PHI_S) & (w[1:] < 0)):
        a = (PHI_S - ps[i]) / (ps[i + 1] - ps[i])
        row = [traj.t[i] + a * (traj.t[i + 1] - traj.t[i])]
        for x in (traj.q[:, 1], traj.v[:, 0], traj.v[:, 1], traj.v[:, 2]):
            row.append(x[i] + a * (x[i + 1] - x[i]))
        out.append(row)
    return np.array(out)


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_woodpecker_returns_to_glockers_state_every_period(backend):
    """Three periods at h = 1e-4: at every return to φ_S = −0.2788 the sleeve is jammed
    (φ_M within 3e-4 rad of the published −0.1036, φ̇_M = 0), ẏ is within 2 % of
    −0.3411 m/s and φ̇_S within 0.5 % of −7.4583 rad/s; the beak hits the pole once a
    period (0.146 s), every solve passing the law check."""
    q0, v0 = GLOCKER_STATE
    traj = oracle.simulate(woodpecker(), (0.0, 0.45), q0, v0, 1e-4, backend=backend, solver="exact")
    assert traj.completed and traj.stats.fallbacks == 0 and traj.stats.worst_residual < 1e-6
    r = returns(traj)
    assert len(r) == 3
    np.testing.assert_allclose(np.diff(r[:, 0]), 0.146, atol=1e-3)
    np.testing.assert_allclose(r[:, 1], PHI_M, atol=3e-4)
    np.testing.assert_allclose(r[:, 3], 0.0, atol=1e-9)
    np.testing.assert_allclose(r[:, 2], YDOT, rtol=0.02)
    np.testing.assert_allclose(r[:, 4], PHI_S_DOT, rtol=0.005)
    beak = traj.impacts.t[traj.impacts.row == traj.row_index("beak")]
    assert len(beak) == 3
    np.testing.assert_allclose(np.diff(beak), 0.146, atol=1e-3)
    assert traj.work["friction"] < 0.0 and traj.q[-1, 0] < -0.05  # it slides down, rubbing


def test_woodpecker_paths_agree():
    """The compiled loop and the Python reference on one period: equal to 1e-9."""
    q0, v0 = GLOCKER_STATE
    a = mo.simulate(woodpecker(), (0.0, 0.15), q0, v0, 1e-4, backend="compiled")
    b = oracle.simulate(woodpecker(), (0.0, 0.15), q0, v0, 1e-4, backend="python", solver="exact")
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.tangential_impulses, b.tangential_impulses, rtol=0, atol=1e-9)
