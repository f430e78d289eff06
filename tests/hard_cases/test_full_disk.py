"""Output that never claims what it did not save: a full disk and a read-only --out.

The filesystems are real: small tmpfs mounts (root only; skipped elsewhere)."""

import contextlib
import csv
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.usefixtures("compiled_loop_in_cache")


@contextlib.contextmanager
def tmpfs(path, options):
    path.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], check=False)


def moreau(*args, cwd):
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "moreau", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


def test_piston_into_a_3_mib_filesystem_keeps_the_numbers_and_says_what_was_not_saved(tmp_path):
    with tmpfs(tmp_path / "small", "size=3m") as small:
        r = moreau("piston", "--no-progress", "--out", str(small / "out"), cwd=tmp_path)
        out = small / "out"
        assert r.returncode == 1, r.stderr[-2000:]
        assert "Traceback" not in r.stderr
        rows = list(csv.DictReader(open(out / "summary.csv")))
        files = {p.name for p in out.iterdir()}
    assert len(rows) == 3
    for row in rows:  # every number computed in memory is kept
        assert row["cycles"] == "3" and row["side_changes_per_cycle"] and row["impacts_per_cycle"] != "nan"
    missing = [f for f in ("piston_e0_D80.04mm.npz", "piston_e0.9_D80.04mm.npz", "piston_e0.9_D80.20mm.npz")
               if f not in files]
    assert missing  # 3 MiB holds at most one trajectory: the disk did fill up
    for name in missing:  # each one named, with the reason, in its row and on stderr
        said = f"{name} not saved: No space left on device"
        assert [x for x in r.stderr.splitlines() if x.startswith("case e=") and said in x], r.stderr[-2000:]
    assert "saved in" not in r.stderr  # no message claims a file that is not there


def test_sweep_into_a_read_only_out_is_one_line_exit_2(tmp_path):
    with tmpfs(tmp_path / "ro", "size=1m,ro") as ro:
        r = moreau("sweep", "piston", "--param", "e=0,0.5", "--cycles", "1", "--transient", "0", "--no-progress",
                   "--out", str(ro / "s.csv"), cwd=tmp_path)
        assert r.returncode == 2, r.stderr[-2000:]
        assert r.stderr.strip().splitlines()[-1].startswith("moreau sweep: error: --out")
        assert "Read-only file system" in r.stderr and "Traceback" not in r.stderr
        r = moreau("piston", "--no-progress", "--out", str(ro / "p"), cwd=tmp_path)
        assert r.returncode == 2 and "Read-only file system" in r.stderr
