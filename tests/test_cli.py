"""The moreau command: outputs, errors in one line, partial results saved."""

import subprocess
import sys

import numpy as np

import moreau as mo
from moreau.cli import main


def test_ball_command_writes_figure_summary_trajectory(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["ball", "--out", str(out), "--t-end", "0.5", "--h", "1e-3", "--no-progress"]) == 0
    assert (out / "ball.png").stat().st_size > 10_000
    assert "impacts" in (out / "ball_summary.csv").read_text()
    traj = mo.load(out / "ball.npz")
    assert traj.completed and traj.t[-1] == np.float64(0.5)
    assert "summary written" in capsys.readouterr().out
    # the summary gets the user's default permissions like every other output (not mkstemp's 0600)
    modes = {p.name: p.stat().st_mode & 0o777 for p in out.iterdir()}
    assert modes["ball_summary.csv"] == modes["ball.npz"] == 0o666 & ~_umask(), modes


def _umask():
    import os

    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_bad_option_is_one_line_and_nonzero(tmp_path):
    r = subprocess.run([sys.executable, "-m", "moreau", "ball", "--e", "1.5", "--out", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "argument --e: 1.5 is outside [0, 1]" in r.stderr
    r = subprocess.run([sys.executable, "-m", "moreau", "ball", "--h", "-1"], capture_output=True, text=True)
    assert r.returncode == 2 and "argument --h" in r.stderr and "Traceback" not in r.stderr


def test_piston_command_writes_figure_summary_trajectory(tmp_path):
    out = tmp_path / "p"
    rc = main(["piston", "--e", "0", "--D", "80.04", "--cycles", "1", "--transient", "0", "--h", "1e-3",
               "--out", str(out), "--no-progress"])
    assert rc == 0
    assert (out / "piston_e0_D80.04mm.png").stat().st_size > 20_000
    summary = (out / "summary.csv").read_text().splitlines()
    assert summary[0].startswith("e,D_mm,mu,h,status,cycles,mean_speed_rpm,settled_speed_rpm,"
                                  "side_changes_per_cycle")
    assert summary[1].startswith("0.0,80.04,0.0,0.001,completed,1,")
    traj = mo.load(out / "piston_e0_D80.04mm.npz")
    assert traj.extra["case"]["e"] == 0.0 and traj.completed


def test_piston_bad_diameter_is_rejected(tmp_path, cli_error):
    line = cli_error("piston", "--D", "79", "--out", str(tmp_path))
    assert line == "moreau piston: error: argument --D: 79 is outside (80, 100]"


def test_piston_into_a_log_file_prints_a_line_per_case_not_bar_codes(tmp_path, capsys):
    # pytest's captured stderr is no terminal: no bars (their cursor codes), one line per case
    out = tmp_path / "out"
    assert main(["piston", "--e", "0.9", "--D", "80.2", "--cycles", "1", "--transient", "0", "--h", "1e-3",
                 "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert "\x1b[" not in said.err and "\r" not in said.err and "step/s" not in said.err
    assert said.out.count("case e0.9_D80.20mm: completed (simulated in") == 1
    assert main(["piston", "--e", "0.9", "--D", "80.2", "--cycles", "1", "--transient", "0", "--h", "1e-3",
                 "--out", str(out), "--no-progress"]) == 0
    assert "simulated in" not in capsys.readouterr().out
