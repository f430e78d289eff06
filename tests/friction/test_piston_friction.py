"""Skirt friction in the piston engine (issue 27): ``piston_model(mu=...)`` and
``moreau piston --mu``; mu = 0 is the paper's frictionless model, unchanged."""

import csv

import numpy as np
import pytest

import moreau as mo
from moreau.cli import main
from moreau.problems.piston.analysis import friction_loss_per_record
from moreau.problems.piston.model import piston_model


def test_mu_zero_is_the_frictionless_model():
    """mu = 0 builds the same scene as before (no tangent rows) and the same numbers."""
    plain, zero = piston_model(), piston_model(mu=0.0)
    assert not zero.scene.has_friction and zero.scene.describe() == plain.scene.describe()
    a = plain.simulate(0.02, 1e-4, drift_control=plain.drift_control(), energy=False)
    b = zero.simulate(0.02, 1e-4, drift_control=zero.drift_control(), energy=False)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.impulses, b.impulses)


def test_piston_command_with_skirt_friction(tmp_path):
    """``moreau piston --mu 0.05``: completes on the compiled path, writes a positive
    friction loss per cycle, and the record-based loss over the run equals the exact
    ledger (the work of the friction impulses summed over every step) to 1e-3."""
    out = tmp_path / "p"
    rc = main(["piston", "--e", "0", "--mu", "0.05", "--cycles", "1", "--transient", "1", "--out", str(out),
               "--no-progress"])
    assert rc == 0
    rows = list(csv.DictReader(open(out / "summary.csv")))
    assert rows[0]["status"] == "completed" and float(rows[0]["mu"]) == 0.05
    assert float(rows[0]["friction_loss_per_cycle_J"]) > 0.0
    traj = mo.load(out / "piston_e0_D80.04mm_mu0.05.npz")
    assert traj.stats.backend == "compiled" and traj.tangential_impulses is not None
    assert friction_loss_per_record(traj).sum() == pytest.approx(-traj.work["friction"], rel=1e-3)
    assert (out / "piston_e0_D80.04mm_mu0.05.png").stat().st_size > 20_000


@pytest.mark.parametrize("bad", ["-0.1", "nan", "x"])
def test_bad_mu_is_one_line_and_nonzero(tmp_path, bad, cli_error):
    assert cli_error("piston", "--mu", bad, "--out", str(tmp_path)).startswith("moreau piston: error: argument --mu")
