"""Stopping cleanly, keeping everything (issue 11 C) and the command's answers to bad
input (issue 11 F, command side).

SIGTERM is handled like Ctrl-C by every command, with exit code 143 (Ctrl-C: 130); worker
processes never outlive ``moreau piston``; a rerun leaves no older file beside the new
ones; ``Trajectory.save`` goes through a unique temporary file; a ``KeyboardInterrupt``
that carries the partial trajectory as ``exc.trajectory`` is saved like a returned
interrupted trajectory.
"""

from __future__ import annotations

import csv
import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import moreau as mo
import moreau.cli
import moreau.problems.piston.job as job
from moreau.cli import main
from moreau.problems.bouncing_ball import bouncing_ball

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc, sends POSIX signals")



pytestmark = pytest.mark.usefixtures("compiled_loop_in_cache")

def children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (Linux /proc)."""
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    stat = fh.read()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(d))
    return out


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def start_command(args, cwd):
    """``python -m moreau *args`` in its own session; returns (proc, stderr chunks)."""
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.Popen([sys.executable, "-m", "moreau", *args], cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, start_new_session=True)
    err: list[bytes] = []
    threading.Thread(target=lambda: err.extend(iter(lambda: proc.stderr.read(1), b"")), daemon=True).start()
    return proc, err


def wait_for(err, text: bytes, proc, timeout=120.0):
    t0 = time.monotonic()
    while text not in b"".join(err):
        if proc.poll() is not None or time.monotonic() - t0 > timeout:
            raise AssertionError(f"{text!r} not seen: {b''.join(err).decode(errors='replace')[-800:]}")
        time.sleep(0.05)


def wait_for_progress(err, labels, steps: int, proc, timeout=240.0):
    """Wait until the progress bar of every case in ``labels`` has passed ``steps`` steps
    (the state the test needs, not a time: a loaded machine starts a worker late)."""
    t0 = time.monotonic()
    while True:
        text = b"".join(err).decode(errors="replace")
        done = [max([int(n) for n in re.findall(re.escape(label) + r":[^|]*\|[^|]*\| (\d+)/", text)] or [0])
                for label in labels]
        if min(done) > steps:
            return
        if proc.poll() is not None or time.monotonic() - t0 > timeout:
            raise AssertionError(f"progress of {labels} past {steps} not seen: {text[-800:]}")
        time.sleep(0.05)


def finish(proc, timeout=60.0) -> int:
    try:
        return proc.wait(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


def summary(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# -- SIGTERM: like Ctrl-C ----------------------------------------------------------------------
@linux
def test_sigterm_to_piston_saves_partials_lists_every_case_and_leaves_no_worker(tmp_path):
    # three cases on two workers: the third has not started when SIGTERM arrives
    proc, err = start_command(["piston", "--cycles", "400", "--transient", "0", "--h", "1e-3", "--workers", "2",
                               "--out", "out", "--progress"], tmp_path)
    wait_for_progress(err, ["e0_D80.04mm", "e0.9_D80.04mm"], 20_000, proc)  # both workers recording
    workers = children(proc.pid)
    assert len(workers) >= 2
    os.kill(proc.pid, signal.SIGTERM)  # the parent only, as a scheduler or systemd does
    t0 = time.monotonic()
    rc = finish(proc)
    stderr = b"".join(err).decode(errors="replace")
    assert rc == 143, stderr[-800:]
    assert time.monotonic() - t0 < 20 and "Traceback" not in stderr
    assert "moreau piston: terminated (SIGTERM): 0 of 3 case(s) completed" in stderr
    out = tmp_path / "out"
    rows = summary(out / "summary.csv")
    assert [r["status"] for r in rows] == ["interrupted", "interrupted", "not started"]
    for r in rows[:2]:
        label = f"e{float(r['e']):g}_D{float(r['D_mm']):.2f}mm"
        traj = mo.load(out / f"piston_{label}.partial.npz")
        assert traj.status == "interrupted" and len(traj) > 10
    assert not list(out.glob("*mm.npz")) and not list(out.glob("*.tmp"))
    time.sleep(0.5)
    assert not [p for p in workers if alive(p)]  # no worker outlives the command


@linux
def test_workers_end_when_the_parent_is_killed(tmp_path):
    proc, err = start_command(["piston", "--cycles", "400", "--transient", "0", "--h", "1e-3", "--workers", "2",
                               "--out", "out", "--progress"], tmp_path)
    wait_for(err, b"step/s]", proc)
    workers = children(proc.pid)
    assert len(workers) >= 2
    os.kill(proc.pid, signal.SIGKILL)  # no chance to clean up: the workers must notice
    proc.wait(timeout=10)
    t0 = time.monotonic()
    while any(alive(p) for p in workers) and time.monotonic() - t0 < 30:
        time.sleep(0.2)
    left = [p for p in workers if alive(p)]
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left, "worker processes outlived their parent"
    assert time.monotonic() - t0 < 15


@linux
def test_sigterm_to_sweep_keeps_the_record_lists_every_point_and_leaves_no_worker(tmp_path):
    from moreau.sweeps import read_table

    proc, err = start_command(["sweep", "piston", "--param", "e=0,0.5,0.9", "--cycles", "4000", "--transient", "0",
                               "--h", "1e-3", "--workers", "2", "--out", "s.csv", "--no-progress"], tmp_path)
    t0 = time.monotonic()
    while len(children(proc.pid)) < 2 and time.monotonic() - t0 < 60:
        time.sleep(0.1)
    time.sleep(3.0)
    workers = children(proc.pid)
    os.kill(proc.pid, signal.SIGTERM)
    rc = finish(proc)
    stderr = b"".join(err).decode(errors="replace")
    assert rc == 143 and "Traceback" not in stderr, stderr[-800:]
    assert "moreau sweep: terminated (SIGTERM): the finished points are kept" in stderr
    table = read_table(tmp_path / "s.csv")
    assert table["e"].tolist() == [0.0, 0.5, 0.9] and (table["error"] == "not computed").all()
    assert not (tmp_path / "s.csv.parts" / "sweep.lock").exists()
    time.sleep(0.5)
    assert not [p for p in workers if alive(p)]


@linux
def test_sigterm_to_ball_saves_the_partial_trajectory(tmp_path):
    proc, err = start_command(["ball", "--t-end", "3000", "--h", "1e-5", "--record-every", "1000", "--out", "out",
                               "--progress"], tmp_path)
    wait_for(err, b"step/s]", proc)
    os.kill(proc.pid, signal.SIGTERM)
    rc = finish(proc)
    stderr = b"".join(err).decode(errors="replace")
    assert rc == 143 and "Traceback" not in stderr
    last = stderr.replace("\r", "\n").strip().splitlines()[-1]
    assert last.startswith("moreau ball: terminated (SIGTERM): ") and last.endswith("saved in out/ball.partial.npz")
    assert mo.load(tmp_path / "out" / "ball.partial.npz").status == "interrupted"


# -- the KeyboardInterrupt contract: exc.trajectory --------------------------------------------
def _partial_ball():
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 0.2), [1.0], [0.0], 1e-3, solver="enum")
    traj.status, traj.message = "interrupted", "interrupted by the user at step 200 (t = 0.2)"
    return traj


@pytest.mark.parametrize("with_trajectory", [True, False])
def test_ball_command_saves_a_trajectory_carried_by_the_interrupt(tmp_path, monkeypatch, capsys, with_trajectory):
    partial = _partial_ball() if with_trajectory else None

    def raising(*args, **kw):
        exc = KeyboardInterrupt()
        exc.trajectory = partial
        raise exc

    monkeypatch.setattr(mo, "simulate", raising)
    rc = main(["ball", "--out", str(tmp_path), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 130 and len(err) == 1
    if with_trajectory:
        assert err[0].endswith("the 201 records computed are saved in " + str(tmp_path / "ball.partial.npz"))
        assert len(mo.load(tmp_path / "ball.partial.npz")) == 201
    else:
        assert err[0] == "moreau ball: interrupted: nothing computed to save"
        assert not list(tmp_path.glob("ball*.npz"))


class _InterruptingModel:
    """Stands in for the piston model: its run is interrupted, the partial run attached."""

    def drift_control(self):
        return None

    def simulate(self, *args, **kw):
        exc = KeyboardInterrupt()
        exc.trajectory = _partial_ball()
        raise exc


def test_piston_job_saves_a_trajectory_carried_by_the_interrupt_and_starts_nothing_more(tmp_path, monkeypatch):
    monkeypatch.setattr(job, "piston_model", lambda params: _InterruptingModel())
    monkeypatch.setattr(job, "_figures_row", lambda case, params, traj, status, wall, model=None: (
        {**job.summary_row(case, status, wall), "cycles": 0}, []))
    cases = [job.Case(e=0.0, D=0.08004, h=1e-3, cycles=1, transient=0), job.Case(e=0.9, D=0.08004, h=1e-3, cycles=1)]
    with pytest.raises(KeyboardInterrupt) as info:
        job.run_cases(cases, str(tmp_path), progress=False, workers=1)
    assert [r["status"] for r in info.value.rows] == ["interrupted", "not started"]
    assert mo.load(tmp_path / "piston_e0_D80.04mm.partial.npz").status == "interrupted"
    assert not (tmp_path / "piston_e0.9_D80.04mm.partial.npz").exists()


# -- reruns ----------------------------------------------------------------------------------
def test_piston_rerun_removes_the_cases_old_files(tmp_path):
    out = tmp_path / "p"
    out.mkdir()
    stale = [out / "piston_e0_D80.04mm.partial.npz", out / "piston_e0_D80.04mm.png", out / "summary.csv"]
    for p in stale:
        p.write_text("from an earlier run")
    other = out / "piston_e0.5_D80.04mm.npz"  # another case: not this run's business
    other.write_text("kept")
    rc = main(["piston", "--e", "0", "--D", "80.04", "--cycles", "1", "--transient", "0", "--h", "1e-3",
               "--out", str(out), "--no-progress"])
    assert rc == 0
    assert not stale[0].exists()
    assert stale[1].read_bytes()[:4] == b"\x89PNG" and summary(stale[2])[0]["status"] == "completed"
    assert mo.load(out / "piston_e0_D80.04mm.npz").completed
    assert other.read_text() == "kept"


# -- Trajectory.save ---------------------------------------------------------------------------
def test_concurrent_saves_of_one_path_do_not_collide(tmp_path):
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 0.3), [1.0], [0.0], 1e-3, solver="enum")
    path = tmp_path / "same.npz"
    errors = []

    def save_many():
        try:
            for _ in range(20):
                traj.save(path)
        except Exception as exc:  # noqa: BLE001 - collected and asserted below
            errors.append(exc)

    threads = [threading.Thread(target=save_many) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    np.testing.assert_array_equal(mo.load(path).q, traj.q)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["same.npz"]  # no temporary file left


def test_failed_save_leaves_no_temporary_file_and_the_old_file_intact(tmp_path, monkeypatch):
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 0.3), [1.0], [0.0], 1e-3, solver="enum")
    path = traj.save(tmp_path / "run.npz")
    before = open(path, "rb").read()

    def disk_full(file, *args, **kw):  # writes part of the file, then fails
        if isinstance(file, (str, os.PathLike)):
            with open(file, "wb") as fh:
                fh.write(b"PK partial")
        else:
            file.write(b"PK partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", disk_full)
    with pytest.raises(OSError, match="No space left on device: .*run.npz") as info:
        traj.save(path)
    assert info.value.errno == 28
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]
    assert open(path, "rb").read() == before


def test_ball_command_on_a_full_disk_names_the_file_in_one_line(tmp_path, monkeypatch, capsys):
    from matplotlib.figure import Figure

    def disk_full(self, fname, *args, **kw):
        with open(fname, "wb") as fh:
            fh.write(b"partial png")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", disk_full)
    rc = main(["ball", "--t-end", "0.2", "--no-progress", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and err[-1].startswith("moreau ball: error: [Errno 28] No space left on device: ")
    assert err[-1].endswith("ball.png'")
    assert not list((tmp_path / "o").glob("*.tmp*"))  # no temporary file left


# -- the command's answers to bad input (F) ------------------------------------------------------
def run_cli(*args, cwd=None, timeout=60):
    return subprocess.run([sys.executable, "-m", "moreau", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=dict(os.environ, MPLBACKEND="Agg"))


def one_error_line(r, code=2) -> str:
    assert r.returncode == code, r.stderr
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    return lines[0]


def test_out_that_is_a_file_or_inside_a_file_is_one_line_exit_2(tmp_path, cli_error):
    f = tmp_path / "file"
    f.write_text("x")
    line = cli_error("ball", "--out", str(f))
    assert line == f"moreau ball: error: --out {str(f)!r} is a file, not a directory"
    line = cli_error("piston", "--out", str(f / "sub"))
    assert line.startswith(f"moreau piston: error: --out {str(f / 'sub')!r}: cannot create the directory")
    line = cli_error("sweep", "piston", "--out", str(f / "t.csv"))
    assert line == f"moreau sweep: error: --out {str(f / 't.csv')!r}: {str(f)!r} is a file, not a directory"
    line = cli_error("sweep", "piston", "--out", str(f / "sub" / "t.csv"))
    assert line.startswith(f"moreau sweep: error: --out {str(f / 'sub' / 't.csv')!r}: cannot create the directory")
    line = cli_error("sweep", "piston", "--out", str(tmp_path))
    assert "is a directory; give the table's file name" in line


def test_version():
    r = run_cli("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"moreau {mo.__version__}"


def test_missing_optional_dependency_is_one_line_exit_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pandas", None)
    assert main(["sweep", "piston", "--out", str(tmp_path / "t.csv"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["moreau sweep: error: moreau sweep needs pandas: pip install 'moreau[sweeps]'"]


def test_unreachable_dask_scheduler_is_one_line_exit_2_within_seconds(tmp_path):
    pytest.importorskip("distributed")
    t0 = time.monotonic()
    r = run_cli("sweep", "piston", "--dask", "tcp://127.0.0.1:9", "--dask-timeout", "1", "--out",
                str(tmp_path / "t.csv"), "--no-progress")
    line = one_error_line(r)
    assert line.startswith("moreau sweep: error: cannot reach the Dask scheduler at 'tcp://127.0.0.1:9' within 1 s")
    assert time.monotonic() - t0 < 25


def test_record_every_is_offered_where_the_memory_guard_asks_for_it(tmp_path, capsys):
    assert main(["ball", "--out", str(tmp_path), "--t-end", "0.5", "--h", "1e-3", "--record-every", "10",
                 "--no-progress"]) == 0
    assert len(mo.load(tmp_path / "ball.npz")) == 51
    with pytest.raises(SystemExit) as info:
        main(["piston", "--record-every", "0", "--out", str(tmp_path)])
    assert info.value.code == 2 and "argument --record-every: must be >= 1, got 0" in capsys.readouterr().err


def test_sweep_files_on_a_full_disk_name_the_file(tmp_path, monkeypatch):
    import pandas as pd

    from moreau.sweeps.record import _Record
    from moreau.sweeps.table import _write_table

    def disk_full(*args, **kw):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pd.DataFrame, "to_csv", disk_full)
    with pytest.raises(OSError, match=r"No space left on device: .*table\.csv'"):
        _write_table(pd.DataFrame({"a": [1]}), str(tmp_path / "table.csv"))
    monkeypatch.setattr("json.dump", disk_full)
    with pytest.raises(OSError, match=r"No space left on device: .*k\.json'"):
        _Record._write(str(tmp_path / "k.json"), {"x": 1})
    assert not list(tmp_path.glob("*.tmp"))
