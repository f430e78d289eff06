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


def test_bad_option_is_one_line_and_nonzero(tmp_path):
    r = subprocess.run([sys.executable, "-m", "moreau", "ball", "--e", "1.5", "--out", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "argument --e: 1.5 is outside [0, 1]" in r.stderr
    r = subprocess.run([sys.executable, "-m", "moreau", "ball", "--h", "-1"], capture_output=True, text=True)
    assert r.returncode == 2 and "argument --h" in r.stderr and "Traceback" not in r.stderr
