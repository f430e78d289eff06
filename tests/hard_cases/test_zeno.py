"""Case 1 — Zeno: a bouncing ball comes to rest at the analytic Zeno time, without
tunnelling through the floor and without jitter afterwards.

(``tests/test_ball.py`` checks the first apexes and impact times for e = 0.5; here the
accumulation point itself, for a slow (e = 0.5) and a fast-chattering (e = 0.9) decay.)
"""

import math

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import BallSolution, bouncing_ball

from .conftest import assert_finite, audit_impacts, rest_time

V_REST = 1e-9  # "at rest": |v| below this (m/s)


@pytest.mark.parametrize("e, h", [(0.5, 1e-4), (0.9, 5e-4)])
def test_ball_comes_to_rest_at_the_zeno_time(e, h):
    g = 9.81
    sol = BallSolution(1.0, e, g)
    t_end = 1.5 * sol.zeno_time  # half the Zeno time again at rest: long enough to see jitter
    traj = mo.simulate(bouncing_ball(e, g=g), (0.0, t_end), [1.0], [0.0], h, solver="enum")
    assert traj.completed
    assert_finite(traj)
    audit_impacts(traj)
    imp = traj.impacts
    assert len(imp) >= 5

    # No tunnelling: an impact is seen at a midpoint at most h/2 |U| inside the floor and
    # the step ends at most h/2 |U| further in, so the gap never falls below −h |U_impact|.
    assert traj.q[:, 0].min() >= -h * np.abs(imp.U_before).max()

    # Once a bounce is shorter than a step (speed below ~2 g h) the ball stays in contact
    # at every midpoint and Newton's law multiplies |v| by e each step (its sign
    # alternates): |v| < V_REST after n_tail = ln(2 g h / V_REST) / ln(1/e) steps.
    n_tail = math.log(2 * g * h / V_REST) / math.log(1 / e)
    t_rest = rest_time(traj.t, traj.v, V_REST)
    assert t_rest <= sol.zeno_time + h * (n_tail + 2)
    # ... and it is not at rest early either: the bounces it cannot resolve (speed below
    # 2 g h, flights 2 v / g, geometric with ratio e) last at most 4 h / (1 − e) together.
    assert t_rest >= sol.zeno_time - 4 * h / (1 - e) - h

    # every logged impact before the Zeno time (one step of resolution), none after rest
    assert imp.t.max() <= sol.zeno_time + h
    # no jitter after rest: the velocity stays below V_REST until the end, the ball on the
    # floor within the penetration bound above
    after = traj.t >= t_rest
    assert after.sum() > 0.3 * traj.t.shape[0]  # a long rest phase is actually observed
    assert np.abs(traj.v[after, 0]).max() < V_REST
    assert np.ptp(traj.q[after, 0]) < V_REST * h * after.sum()  # it does not move


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_ball_at_rest_never_reaches_subnormal_velocities(backend):
    """At rest on the floor, Newton's law multiplies |v| by e every step: after about a
    thousand steps at e = 0.5 that reached subnormal numbers (below 2.2e-308), whose
    arithmetic is some 100 times slower. A velocity below NEGLIGIBLE_VELOCITY is taken as
    0 by the law: every recorded velocity is 0 or a normal number, and the ball (dropped
    from 1 mm, at rest after its Zeno time of 0.043 s) stays at rest."""
    traj = oracle.simulate(bouncing_ball(0.5), (0.0, 3.0), [1e-3], [0.0], 1e-3, backend=backend, progress=False)
    assert traj.completed
    v = np.abs(traj.v)
    assert np.all((v == 0.0) | (v >= np.finfo(float).tiny))
    late = traj.t > 0.5
    assert np.ptp(traj.q[late]) <= 1e-12 and v[late].max() <= 1e-9  # at rest
