"""Case 5 — a coarse step: h = 1e-2 (non-dimensional, 0.57° of crank angle per step, ten
times the limit for the paper's 40 µm clearance) on the piston does not blow up, and
:meth:`PistonModel.simulate` warns that the step does not resolve the clearance.
"""

import warnings

import numpy as np
import pytest

import moreau as mo
from moreau.problems.piston import PistonParameters, cycle_figures, piston_model
from moreau.problems.piston.analysis import max_penetration_ratio

from .conftest import assert_finite, audit_impacts

H = 1e-2
CYCLES = 1 + 0.6 / (4 * np.pi)  # from 29° before firing TDC through one whole cycle
PHI1 = -0.5


def coarse_run(e, drift_control=None):
    model = piston_model(PistonParameters(e=e))
    with pytest.warns(RuntimeWarning, match=r"step h = 0\.01 .* clearance D - d = 40 um") as rec:
        traj = model.simulate(CYCLES, H, phi1=PHI1, solver="enum", drift_control=drift_control)
    coarse = [w for w in rec if "too coarse" in str(w.message)]
    assert len(coarse) == 1  # one warning per run, not one per step
    assert "use h <= 0.001" in str(coarse[0].message)
    # and, once after the run, the penetration beyond the clearance when there is one
    deep = mo.diagnostics.max_penetration(traj) > model.params.clearance / model.params.l1
    # PositionProjection() says once that it projects no row of the bouncing piston
    idle = [w for w in rec if "projects no row" in str(w.message)]
    assert len(idle) == (type(drift_control) is mo.PositionProjection and e > 0)
    assert len(rec) == 1 + deep + len(idle) and bool(traj.warnings) == deep  # one message per deep row
    return model, traj


def no_drift_control():
    return None


def projection():
    return mo.PositionProjection()


def combined():
    return mo.CombinedProjection()


@pytest.mark.parametrize("e", [0.0, 0.9])
@pytest.mark.parametrize("drift", [no_drift_control, projection, combined], ids=["plain", "projection", "combined"])
def test_coarse_step_does_not_blow_up(e, drift):
    model, traj = coarse_run(e, drift())
    assert traj.completed and traj.stats.fallbacks == 0
    assert_finite(traj)
    audit_impacts(traj)
    # the crank still turns at the reference speed: within ±1 % of 1 at every step
    # (at h = 1e-4 it stays within 0.9999–1.0047; the coarse step changes that by < 1e-4)
    assert np.abs(traj.v[:, 0] - 1.0).max() < 0.01
    pen = max_penetration_ratio(traj, model.params)
    # the tilt stays what the geometry allows: two diagonal corners at most `pen` inside
    # their walls give sin φ3 <= (D − d + 2 pen) / s
    p = model.params
    assert np.abs(np.sin(traj.q[:, 2])).max() <= (p.clearance * (1 + 2 * pen)) / p.s
    if drift is projection and e == 0.0:
        # the projection removes the drift; what is left is the second-order remainder of
        # its linearization (measured 3e-13). It leaves bouncing rows (e > 0) alone.
        assert pen < 0.01
    else:
        # the midpoint drift of a pressed contact: penetration ≈ h·l1 (measured 0.96–1.04 h·l1
        # from h = 1e-4 to 1e-2): ten clearances here for e = 0 (sliding), far less when the
        # piston bounces (e = 0.9, measured 0.5 clearance). Bounded, not growing: 1.5 h·l1.
        assert pen * model.params.clearance <= 1.5 * H * model.params.l1
    figs = cycle_figures(traj, model.params)
    assert len(figs) == 1 and figs[0].side_changes >= 6  # still six stages (and transits)


def test_warning_names_h_and_clearance_only_when_too_coarse():
    model = piston_model(PistonParameters(e=0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # at the limit (h = (D − d)/l1 = 1e-3): no warning
        model.simulate(0.002, 1e-3, solver="enum")
    with pytest.warns(RuntimeWarning, match=r"step h = 0\.0011 .*D - d = 40 um.*h\*l1 = 44 um"):
        model.simulate(0.002, 1.1e-3, solver="enum")
    tiny = piston_model(PistonParameters(e=0.0, D=0.080004))
    with pytest.warns(RuntimeWarning, match=r"D - d = 4 um.*use h <= 0\.0001"):
        tiny.simulate(0.002, 2e-4, solver="enum")
    large = piston_model(PistonParameters(e=0.0, D=0.0802))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        large.simulate(0.002, 5e-3, solver="enum")  # 200 µm allow h <= 5e-3
