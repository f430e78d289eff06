"""Case 8 — degenerate contact: all four piston corners closed at once.

``PistonParameters`` refuses D <= d, and with D > d at most one top and one bottom corner
can touch (h1 + h3 = h2 + h4 >= Δ − δ > 0). So the zero-clearance fit is built from the
public API: the piston's own chain with four point–line rows whose walls stand 1e-14
(non-dimensional, 4e-16 m) inside the piston's faces — all four gaps are −1e-14, within
the accepted initial penetration (1e-12), and all four rows are closed in the first step.
The Jacobian of the four rows has rank 2 (opposite corners have opposite rows), W is
singular and the impulses are not unique; v⁺ is, and so is Gᵀ P.

(On whole piston runs DAQP and the enumeration differ by ~1e-9 in q: DAQP is exact only
to its own tolerances — see the note in test_fault_injection.py.)
"""


import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.model.chain import PointLineBarrier, PointLineRow
from moreau.problems.piston import PistonParameters, piston_model
from moreau.problems.piston.analysis import max_penetration_ratio
from moreau.problems.piston.model import CORNERS

from .conftest import assert_finite, audit_impacts

SOLVERS = ["enum", "osqp", "daqp", "quadprog"]


def zero_clearance(inset=1e-14, e=0.0):
    model = piston_model(PistonParameters(e=e))
    p, L = model.params, model.params.l1
    top, bottom, half_d = p.h / L, -(p.s - p.h) / L, 0.5 * p.d / L
    wall = half_d - inset
    rows = [PointLineRow(2, (top, half_d), (wall, 0.0), (-1.0, 0.0), name=CORNERS[0]),
            PointLineRow(2, (bottom, half_d), (wall, 0.0), (-1.0, 0.0), name=CORNERS[1]),
            PointLineRow(2, (top, -half_d), (-wall, 0.0), (1.0, 0.0), name=CORNERS[2]),
            PointLineRow(2, (bottom, -half_d), (-wall, 0.0), (1.0, 0.0), name=CORNERS[3])]
    contact = mo.Contact(PointLineBarrier(model.chain, rows), e, name="cylinder")
    return model, mo.Scene(model.chain, model.scene.effects, [contact], name="zero-clearance piston")


def first_step(scene, q0, solver):
    integ = oracle.MoreauJeanMidpoint(scene, 1e-3, solver=solver)
    integ.init(0.0, q0, np.zeros(3))
    integ.step()
    return integ


def test_all_four_corners_closed_unique_velocity():
    model, scene = zero_clearance()
    q0, _ = model.initial_state(phi1=0.3)  # just after firing TDC: the gas force is large
    G = scene.jacobian(q0)
    assert np.linalg.matrix_rank(G) == 2
    np.testing.assert_allclose(scene.gaps(q0), -1e-14, rtol=0.01)
    steps = {s: first_step(scene, q0, s) for s in SOLVERS}
    ref = steps["enum"]
    for s, integ in steps.items():
        assert integ.active.all(), s  # all four rows closed in the step
        assert integ.worst_residual <= 1e-6
        # v⁺ is unique: the same on every backend (1e-8: OSQP is exact to eps = 1e-9 and
        # a KKT-rejected OSQP answer is replaced by the exact fallback)
        np.testing.assert_allclose(integ.v, ref.v, atol=1e-8, rtol=0, err_msg=s)
        # and so is the generalized impulse Gᵀ P (P itself need not be)
        GtP = G.T @ integ.P
        np.testing.assert_allclose(GtP, G.T @ ref.P, atol=1e-8 * np.abs(G.T @ ref.P).max(), rtol=0, err_msg=s)
        assert np.all(integ.P >= 0)
    # the piston is held: no lateral pin velocity, no tilt rate (the rows of a side are
    # ±a, ±b: G v⁺ >= 0 on all four means a·v⁺ = b·v⁺ = 0); the crank still starts turning
    np.testing.assert_allclose(G @ ref.v, 0.0, atol=1e-15)
    assert ref.v[0] > 0 and np.abs(G.T @ ref.P).max() > 0


def test_zero_clearance_run_agrees_across_solvers():
    model, scene = zero_clearance()
    q0, _ = model.initial_state(phi1=0.3)
    runs = {s: mo.simulate(scene, (0.0, 0.5), q0, np.zeros(3), 1e-3, solver=s) for s in SOLVERS}
    for s, traj in runs.items():
        assert traj.completed
        assert not traj.warnings, (s, traj.warnings)  # the start's 1e-14 overlap is no unenforced contact
        assert_finite(traj)
        audit_impacts(traj)
        # over 500 steps the runs agree to 1e-8 in v (OSQP: measured 2e-10)
        np.testing.assert_allclose(traj.v, runs["enum"].v, atol=1e-8, rtol=0, err_msg=s)
        # the midpoint drift lets the piston sink sideways into a wall, bounded by the
        # drift law h·l1 (= 1e-3 non-dimensional; see test_coarse_step.py)
        assert -traj.gaps.min() <= 1.5 * 1e-3


def test_nearly_zero_clearance_parameters():
    """D = d + 1 nm through PistonParameters: the step warning fires (h = 1e-3 is 40 000
    times the limit), the run stays finite, the drift stays at h·l1 — 40 000 clearances."""
    model = piston_model(PistonParameters(e=0.0, D=0.08 + 1e-9))
    with pytest.warns(RuntimeWarning, match="too coarse for the clearance D - d = 0.001 um"):
        traj = model.simulate(0.1, 1e-3, solver="enum")
    assert traj.completed
    assert_finite(traj)
    audit_impacts(traj)
    pen = max_penetration_ratio(traj, model.params) * model.params.clearance  # m
    assert pen <= 1.5 * 1e-3 * model.params.l1
    assert np.abs(traj.v[:, 0] - 1).max() < 0.01
