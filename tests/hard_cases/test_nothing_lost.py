"""Nothing lost: a run interrupted (Ctrl-C) keeps what it computed, and the ``moreau``
command saves it as ``*.partial.npz`` before exiting.

The command is run as a real subprocess in its own process group and sent SIGINT, as a
terminal's Ctrl-C does, once its progress bar shows that it is stepping.
"""

import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import bouncing_ball

pytestmark = pytest.mark.usefixtures("compiled_loop_in_cache")

class InterruptingSolver(mo.EnumerationSolver):
    """The exact solver, with a Ctrl-C arriving during contact solve number ``at``."""

    name = "interrupting"

    def __init__(self, at):
        super().__init__()
        self.at, self.calls = at, 0

    def solve(self, *args):
        self.calls += 1
        if self.calls == self.at:
            raise KeyboardInterrupt
        return super().solve(*args)


def test_interrupt_inside_a_contact_solve_keeps_the_run(tmp_path):
    exact = oracle.simulate(bouncing_ball(0.5), (0.0, 1.5), [1.0], [0.0], 1e-3, solver="enum", backend="python")
    with pytest.raises(KeyboardInterrupt) as info:  # propagates: a script looping over runs stops
        mo.simulate(bouncing_ball(0.5), (0.0, 1.5), [1.0], [0.0], 1e-3, solver=InterruptingSolver(at=30))
    traj = info.value.trajectory  # with everything computed before it
    assert traj.status == "interrupted" and "interrupted by the user at step" in traj.message
    n = len(traj)
    assert 0 < n < len(exact)
    np.testing.assert_array_equal(traj.q, exact.q[:n])  # every record kept is exact
    back = mo.load(traj.save(tmp_path / "run.partial.npz"))
    assert back.status == "interrupted" and back.message == traj.message
    np.testing.assert_array_equal(back.q, traj.q)


#: a progress bar's rate after steps were made ("3.41Mstep/s]"; before, tqdm shows "?step/s]")
STEPPING = re.compile(rb"[0-9][kMG]?step/s\]")


#: ``python -m moreau *args`` with SIGINT handled as in a terminal's foreground job. A child
#: inherits an *ignored* SIGINT (POSIX), and Python then leaves it ignored: in 2 of 3 cold
#: runs of the suite under two workers the command ran its 3e8 steps to the end, exit 0,
#: although SIGINT reached it (the test process ignored SIGINT at the OS level at that moment;
#: what set it was not found). Reproduced by starting the command from a process that ignores
#: SIGINT; the command itself keeps the inherited disposition, as ``nohup`` expects.
FOREGROUND = ("import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
              "sys.argv = ['moreau', *sys.argv[1:]]; runpy.run_module('moreau', run_name='__main__', alter_sys=True)")


def interrupt_command(args, cwd, after_progress=1.0, timeout=180, exit_within=30, when=STEPPING, env=None):
    """Run ``python -m moreau *args`` and send SIGINT to its process group ``after_progress``
    seconds after its stderr first matches ``when`` (by default: its progress bar shows
    steps); return (returncode, stderr, seconds from the interrupt to the exit). A command
    still running ``exit_within`` seconds after the interrupt is killed (returncode -9).
    ``env``: variables added to this process's environment."""
    env = dict(os.environ, MPLBACKEND="Agg", **(env or {}))
    proc = subprocess.Popen([sys.executable, "-c", FOREGROUND, *args], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    err = []
    reader = threading.Thread(target=lambda: err.extend(iter(lambda: proc.stderr.read(1), b"")), daemon=True)
    reader.start()
    t0 = time.monotonic()
    try:
        while not when.search(b"".join(err)):  # (tqdm prints a rate once steps were made)
            if proc.poll() is not None or time.monotonic() - t0 > timeout:
                raise AssertionError(f"no progress seen: {b''.join(err).decode(errors='replace')[-500:]}")
            time.sleep(0.05)
        time.sleep(after_progress)
        os.killpg(proc.pid, signal.SIGINT)
        t_int = time.monotonic()
        try:
            proc.wait(timeout=exit_within)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        t_exit = time.monotonic() - t_int
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    reader.join(5)
    return proc.returncode, b"".join(err).decode(errors="replace"), t_exit


def test_ctrl_c_during_the_first_compile_ends_the_command_at_once(tmp_path):
    # an empty cache of its own: the command compiles the loop (about a minute), on a thread of
    # its own (moreau.core.compiling); a Ctrl-C ends the wait for it, not the compile's end
    rc, err, waited = interrupt_command(["ball", "--out", "out"], tmp_path, after_progress=0.5,
                                        when=re.compile(rb"compiling the time loop"),
                                        env={"NUMBA_CACHE_DIR": str(tmp_path / "cache")})
    assert rc == 130 and waited < 20, (rc, waited, err[-800:])
    assert "interrupted by the user at step 0" in last_line(err)
    assert mo.load(tmp_path / "out" / "ball.partial.npz").status == "interrupted"


def last_line(stderr):
    return stderr.replace("\r", "\n").strip().splitlines()[-1]


def test_ball_command_interrupted_saves_a_partial_trajectory(tmp_path):
    # interrupted as soon as its progress bar shows steps: an event, not a wall time (a fast
    # machine with a warm cache steps far further in a second than a slow, loaded one)
    rc, err, _ = interrupt_command(["ball", "--t-end", "3000", "--h", "1e-5", "--record-every", "1000", "--out", "out",
                                    "--progress"], tmp_path, after_progress=0.0)
    assert rc == 130 and "Traceback" not in err, err[-3000:]  # 128 + SIGINT, the same for every command
    line = last_line(err)
    assert line.startswith("moreau ball: interrupted: interrupted by the user at step")
    assert line.endswith("are saved in out/ball.partial.npz")
    traj = mo.load(tmp_path / "out" / "ball.partial.npz")
    assert traj.status == "interrupted" and 10 < len(traj) < 300_001  # one record per 1000 steps
    assert np.all(np.isfinite(traj.q)) and 0 < traj.t[-1] < 3000  # stopped on the way
    assert not (tmp_path / "out" / "ball.npz").exists()


@pytest.mark.slow
def test_piston_command_interrupted_saves_a_partial_trajectory(tmp_path):
    rc, err, _ = interrupt_command(["piston", "--e", "0", "--D", "80.04", "--cycles", "2000", "--transient", "0",
                                    "--record-every", "100", "--h", "1e-3", "--out", "out", "--progress"], tmp_path)
    assert rc == 130 and "Traceback" not in err
    assert "partial trajectory saved" in err
    traj = mo.load(tmp_path / "out" / "piston_e0_D80.04mm.partial.npz")
    assert traj.status == "interrupted" and len(traj) > 10
    assert traj.extra["case"]["e"] == 0.0
    assert "interrupted" in (tmp_path / "out" / "summary.csv").read_text()


@pytest.mark.slow
def test_piston_command_with_workers_stops_promptly_on_interrupt(tmp_path):
    # three cases on two workers: the third is queued when Ctrl-C arrives
    rc, err, t_exit = interrupt_command(["piston", "--cycles", "1000", "--transient", "0", "--h", "1e-3",
                                         "--record-every", "100", "--workers", "2", "--out", "out", "--progress"],
                                        tmp_path)
    out = tmp_path / "out"
    partial = sorted(p.name for p in out.glob("*.partial.npz"))
    assert len(partial) >= 2  # the running cases saved what they computed
    for name in partial:
        assert mo.load(out / name).status == "interrupted"
    # nothing starts after the interrupt: no case runs on to completion, and the command
    # exits within seconds (a 20-cycle case takes 15–30 s)
    assert not list(out.glob("piston_*mm.npz"))
    assert t_exit < 10.0
    assert rc == 130 and "Traceback" not in err


@pytest.mark.parametrize("control", [None, mo.StepControl(1e-5)], ids=["fixed", "adaptive"])
def test_an_interrupt_after_the_buffers_grew_keeps_what_they_hold(monkeypatch, control):
    """Ctrl-C a chunk after the impact log (4 entries here) grew: the partial trajectory
    holds the impacts logged in the grown buffer, those of the uninterrupted run (before,
    it read the old buffer: rows out of range)."""
    from moreau.compiled import runner

    run = lambda: mo.simulate(bouncing_ball(0.8), (0.0, 4.5), [1.0], [0.0], 1e-3, step_control=control)  # noqa: E731
    whole = run()
    real_records, real_grown = runner._records, runner._grown
    calls = []  # chunks called since the log grew
    small = lambda *a: real_records(*a)._replace(IMP=np.empty((4, runner.lay.N_IMPACT)))  # noqa: E731
    monkeypatch.setattr(runner, "_records", small)
    monkeypatch.setattr(runner, "_grown", lambda recs, impacts: calls.append(0) or real_grown(recs, impacts))
    monkeypatch.setattr(runner, "FIRST_CHUNK", 200)

    def interrupted_after_growth(chunk):
        def run_chunk(*args, **kwargs):
            if len(calls) >= 2:
                raise KeyboardInterrupt
            if calls:
                calls.append(0)
            return chunk(*args, **kwargs)
        return run_chunk

    monkeypatch.setattr(runner.lp, "run_chunk", interrupted_after_growth(runner.lp.run_chunk))
    with pytest.raises(KeyboardInterrupt) as info:
        run()
    got = info.value.trajectory.impacts
    # the log grows when it lacks room for a step's impacts (1 row), or an attempt's three
    assert (4 if control is None else 2) < len(got) < len(whole.impacts)
    np.testing.assert_array_equal(got.row, 0)
    np.testing.assert_array_equal(got.t, whole.impacts.t[:len(got)])
