"""A worker process that dies (SIGKILL: the out-of-memory killer, a crash in compiled
code) is a failed case with a one-line reason, not a traceback: the other cases finish."""

import csv
import os
import signal
import subprocess
import sys
import time

import pytest

from moreau.sweeps.pool import WorkerDied, run_jobs

pytestmark = pytest.mark.usefixtures("compiled_loop_in_cache")


def _job(i, die):
    if die:
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.2)
    return i * 10


def test_a_killed_worker_fails_its_job_and_the_others_complete():
    results = {}
    run_jobs(_job, [(0, False), (1, True), (2, False), (3, False)], 2,
             lambda i, r, exc: results.__setitem__(i, (r, exc)))
    assert sorted(results) == [0, 1, 2, 3]  # every job reported once
    assert isinstance(results[1][1], WorkerDied) and results[1][0] is None
    assert "killed by signal SIGKILL" in str(results[1][1])
    assert [results[i] for i in (0, 2, 3)] == [(0, None), (20, None), (30, None)]


def _children(pid):
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True)
    return [int(x) for x in out.stdout.split()]


def test_piston_command_with_a_killed_worker_fails_that_case_only(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    # the victim is killed while it imports or steps its case
    proc = subprocess.Popen([sys.executable, "-m", "moreau", "piston", "--cycles", "3", "--transient", "0",
                             "--workers", "2", "--no-progress", "--out", "out"], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        t0 = time.monotonic()
        while not _children(proc.pid):  # the pool's workers start with the first cases
            assert proc.poll() is None and time.monotonic() - t0 < 120, "no worker started"
            time.sleep(0.02)
        time.sleep(0.3)  # importing or stepping its case
        victim = min(_children(proc.pid))
        os.kill(victim, signal.SIGKILL)
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, err[-2000:]
    assert "Traceback" not in err
    rows = list(csv.DictReader(open(tmp_path / "out" / "summary.csv")))
    status = sorted(r["status"] for r in rows)
    assert status == ["completed", "completed", "failed"], rows
    failed = [r for r in rows if r["status"] == "failed"][0]
    assert f"worker process {victim} died (killed by signal SIGKILL" in failed["warnings"]
    line = [x for x in err.splitlines() if "failed" in x and f"e={failed['e']}" in x]
    assert len(line) == 1 and "worker process" in line[0], err[-2000:]
    # a case stopped with the broken pool and run again leaves its completed file only
    out_dir = tmp_path / "out"
    for done in out_dir.glob("piston_*mm.npz"):
        assert not done.with_name(done.name[:-len(".npz")] + ".partial.npz").exists(), sorted(os.listdir(out_dir))
    assert "interrupted by the user" not in err
