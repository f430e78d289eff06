"""What accuracy costs (issue 5): measured orders of convergence on small problems, drift
control on the piston, and the work–precision benchmark script itself."""

import importlib.util
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import moreau as mo
from moreau.model.chain import ChainGravity, Link, PendulumChain
from moreau.problems.pendulum_wall import pendulum_rhs, pendulum_wall
from moreau.results.diagnostics import convergence_order

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "benchmarks", "work_precision.py")


@pytest.fixture(scope="module")
def wp():
    """benchmarks/work_precision.py as a module (benchmarks/ is not a package)."""
    spec = importlib.util.spec_from_file_location("work_precision", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["work_precision"] = mod
    spec.loader.exec_module(mod)
    return mod


# ----------------------------------------------------------------------------------------
# smooth phases
# ----------------------------------------------------------------------------------------
STEPS = [0.02, 0.01, 0.005, 0.0025, 0.00125]


def damped_pendulum_errors(integrator, damping=0.5, T=2.0, y0=(1.0, 0.5)):
    ref = solve_ivp(pendulum_rhs(damping=damping), (0, T), y0, method="DOP853", rtol=1e-13, atol=1e-13)
    scene = pendulum_wall(wall_x=None, damping=damping)
    assert scene.velocity_dependent
    errs = []
    for h in STEPS:
        traj = mo.simulate(scene, (0.0, T), [y0[0]], [y0[1]], h, integrator=integrator, energy=False)
        assert traj.t[-1] == pytest.approx(T, abs=1e-12)
        errs.append(max(abs(traj.q[-1, 0] - ref.y[0, -1]), abs(traj.v[-1, 0] - ref.y[1, -1])))
    return errs


def test_midpoint_is_first_order_with_damping():
    assert convergence_order(STEPS, damped_pendulum_errors(mo.MoreauJeanMidpoint)) == pytest.approx(1.0, abs=0.15)


def test_theta_variant_is_second_order_with_damping():
    errs = damped_pendulum_errors(mo.MoreauJeanPredictorCorrector)
    assert convergence_order(STEPS, errs) == pytest.approx(2.0, abs=0.2)
    assert errs[-1] < damped_pendulum_errors(mo.MoreauJeanMidpoint)[-1] / 100


@pytest.mark.parametrize("links", [2, 3])
def test_chain_energy_error_second_order_with_theta_first_with_midpoint(links):
    """A conservative chain (gravity only, no damping, no barriers): its centrifugal
    terms depend on v, so the midpoint's energy error is O(h), the θ variant's O(h²)."""
    chain = PendulumChain([Link.rod(1.0, 1.0)] * links)
    scene = mo.Scene(chain, [ChainGravity(chain)], [])
    assert scene.velocity_dependent and scene.nrows == 0
    q0 = np.array([1.0, 0.5, -0.3][:links])
    v0 = np.array([0.0, 1.0, 0.5][:links])
    E0 = scene.energy(q0, v0)
    orders = {}
    for integ in (mo.MoreauJeanMidpoint, mo.MoreauJeanPredictorCorrector):
        errs = [np.abs(mo.simulate(scene, (0.0, 2.0), q0, v0, h, integrator=integ).energy - E0).max()
                for h in STEPS]
        orders[integ] = convergence_order(STEPS, errs)
    assert orders[mo.MoreauJeanMidpoint] == pytest.approx(1.0, abs=0.15)
    assert orders[mo.MoreauJeanPredictorCorrector] == pytest.approx(2.0, abs=0.2)


# ----------------------------------------------------------------------------------------
# across impacts
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("integrator", ["mid", "theta"])
def test_both_integrators_first_order_across_impacts(wp, integrator):
    """θ(t) in L∞ over 15 s with 10 wall impacts, against the event-driven reference
    (through the benchmark's problem class): order 1 for both schemes."""
    ladder = [1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4]
    cfg = wp.Config(integrator, "enum", False)
    prob = wp.PendulumWallProblem(ladder, [cfg], t_end=15.0)
    runs = [prob.run(cfg, h) for h in ladder]
    assert all(r.status == "completed" and r.metrics["impacts"] == 10 for r in runs)
    assert wp.fit_orders(runs, "theta")[(prob.name, cfg.label)] == pytest.approx(1.0, abs=0.2)
    assert wp.fit_orders(runs)[(prob.name, cfg.label)] == pytest.approx(1.0, abs=0.2)  # impact times


# ----------------------------------------------------------------------------------------
# piston with drift control
# ----------------------------------------------------------------------------------------
def test_piston_drift_control_keeps_penetration_below_one_percent_at_h_1e_3():
    """e = 0, h = 1e-3, transient 1 + 3 cycles with PositionProjection: the penetration
    stays below 1 % of the clearance (without it: ~100 %) and every cycle after the
    transient still has the 6 side changes."""
    from moreau.problems.piston.analysis import cycle_figures
    from moreau.problems.piston.model import piston_model
    from moreau.problems.piston.params import PistonParameters

    params = PistonParameters(e=0.0)
    model = piston_model(params)
    traj = model.simulate(4, 1e-3, solver="enum", record_every=1, energy=False,
                          drift_control=mo.PositionProjection())
    assert traj.completed and traj.stats.fallbacks == 0
    figs = [c for c in cycle_figures(traj, params) if c.cycle >= 1]
    assert len(figs) == 3
    assert [c.side_changes for c in figs] == [6, 6, 6]
    assert max(c.max_penetration for c in figs) <= 0.01
    assert traj.stats.projections > 0


# ----------------------------------------------------------------------------------------
# the benchmark
# ----------------------------------------------------------------------------------------
def test_study_api_on_a_tiny_ladder(wp):
    ladder = [1e-2, 5e-3, 2.5e-3]
    cfgs = [wp.Config("mid", "enum", False), wp.Config("mid", "osqp1e-3", True)]
    problems = [wp.BallProblem(ladder, cfgs)]
    runs = wp.run_study(problems)
    assert len(runs) == 6 and all(r.status == "completed" for r in runs)
    assert all(np.isfinite(r.error) and r.error > 0 and r.wall > 0 for r in runs)
    orders = wp.fit_orders(runs)
    assert set(orders) == {("ball", c.label) for c in cfgs}
    table = wp.format_table(runs, problems)
    assert "== ball" in table and "mid/enum/none" in table and "impact_time" in table
    assert "p(impact_time)" in wp.format_orders(runs, problems)
    assert wp.SOLVERS["osqp1e-3"].simulate_kwargs()["fallback"] is None  # loose = unchecked


def test_angle_distance_is_a_circular_hausdorff_distance(wp):
    assert wp._angle_distance([10.0, 200.0], [12.0, 199.0]) == pytest.approx(2.0)
    assert wp._angle_distance([1.0], [719.0]) == pytest.approx(2.0)
    assert wp._angle_distance([10.0, 200.0, 300.0], [10.0, 200.0]) == pytest.approx(100.0)
    assert wp._angle_distance([], []) == 0.0
    assert wp._angle_distance([5.0], []) == np.inf


@pytest.mark.slow
def test_quick_benchmark_runs_and_prints_the_table():
    out = subprocess.run([sys.executable, SCRIPT, "--quick"], capture_output=True, text=True, timeout=600,
                         cwd=ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    text = out.stdout
    for what in ("== ball", "== pendulum", "== pendulum-smooth", "== block", "== woodpecker", "== piston-e0 ",
                 "== piston-e0.9",
                 "observed order", "drift control on the piston", "OSQP tolerances",
                 "step-size control against fixed steps"):
        assert what in text, what
    assert "mid/enum/none" in text and "theta/enum/none" in text and "mid/exact/none/tol" in text


def test_step_control_gain_compares_the_cheapest_runs_reaching_each_target(wp):
    """The gain table: per target, the cheapest fixed-step and step-control runs at or
    below it and the ratio of their times; a target one of them misses gives NaN."""
    fixed, tol = wp.Config("mid", "exact", "none"), wp.Config("mid", "exact", "none", adaptive=True)
    assert tol.label == "mid/exact/none/tol" and tol.run_args(1e-5, h_max=0.1)[0] == 0.1
    assert isinstance(tol.run_args(1e-5)[1]["step_control"], mo.StepControl) and fixed.run_args(1e-3)[0] == 1e-3
    runs = [wp.Run("x", fixed, 1e-2, 1.0, 10, 0, "completed", 1.0), wp.Run("x", fixed, 1e-3, 10.0, 100, 0,
                                                                           "completed", 0.1),
            wp.Run("x", fixed, 1e-4, 100.0, 1000, 0, "completed", 0.01), wp.Run("x", tol, 1e-3, 0.5, 20, 0,
                                                                                 "completed", 0.05)]
    problem = type("P", (), {"name": "x"})()
    rows = wp.step_control_gain(runs, [problem], decades=2)
    assert [r["target"] for r in rows] == pytest.approx([0.1, 0.01])
    assert rows[0]["fixed"].wall == 10.0 and rows[0]["adaptive"].wall == 0.5 and rows[0]["ratio"] == 0.05
    assert rows[1]["adaptive"] is None and np.isnan(rows[1]["ratio"])
    assert "not reached" in wp.format_gain(rows)


def test_a_configuration_with_per_component_tolerances_survives_its_csv(wp, tmp_path):
    """v_tol: the velocities' tolerance a multiple of the coordinates' (StepControl's tol per
    component), in the label and the CSV; without the scene's ndof it is refused."""
    c = wp.Config("mid", "exact", "projv", adaptive=True, h_max=0.1, v_tol=30.0)
    assert c.label == "mid/exact/projv/tol/H=0.1/v30x"
    assert c.run_args(1e-7, ndof=2)[1]["step_control"].tol == (1e-7, 1e-7, 3e-6, 3e-6)
    with pytest.raises(ValueError, match="v_tol = 30.0 needs the scene's ndof"):
        c.run_args(1e-7)
    plain = wp.Config("mid", "exact", "none", adaptive=True)
    runs = [wp.Run("x", cfg, 1e-7, 1.0, 10, 0, "completed", 0.5) for cfg in (c, plain)]
    path = str(tmp_path / "wp.csv")
    wp.write_csv(runs, {("x", c.label): 1.0, ("x", plain.label): 2.0}, path)
    back, orders = wp.read_csv(path)
    assert [r.config for r in back] == [c, plain] and orders[("x", c.label)] == 1.0
    assert os.listdir(tmp_path) == ["wp.csv"]  # (written through a temporary name)
