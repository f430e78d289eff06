"""Thread safety of the contact solves (issue 11 D): threads running ``simulate`` with the
default OSQP backend leave ``sys.stdout`` and file descriptor 1 alone, and get the serial
results."""

from __future__ import annotations

import os
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import moreau as mo
import moreau.contact.solvers
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.sweeps import sweep

RESTITUTIONS = (0.0, 0.3, 0.5, 0.8)


def ball_point(e: float) -> dict:
    """A ball run with the default solver (OSQP): many contact solves, some separating."""
    traj = mo.simulate(bouncing_ball(e), (0.0, 1.5), [1.0], [0.0], 2e-4, progress=False)
    return {"y_end": float(traj.q[-1, 0]), "impacts": len(traj.impacts), "fallbacks": traj.stats.fallbacks}


def _run(e: float) -> mo.Trajectory:
    return mo.simulate(bouncing_ball(e), (0.0, 1.5), [1.0], [0.0], 2e-4, progress=False)


def _fd1() -> tuple[int, int]:
    st = os.fstat(1)
    return st.st_dev, st.st_ino


def test_solver_module_touches_no_process_state():
    """No ctypes (``CDLL(None)`` fails on Windows), no stdout swapping in the solvers (the
    modules of :mod:`moreau.contact`, where :mod:`moreau.contact.solvers` imports them from)."""
    folder = os.path.dirname(moreau.contact.solvers.__file__)
    for name in sorted(os.listdir(folder)):
        if name.endswith(".py"):
            src = open(os.path.join(folder, name)).read()
            assert "ctypes" not in src, name
            assert "sys.stdout =" not in src and "dup2" not in src, name


def test_threads_keep_stdout_and_equal_serial(capfd):
    serial = [_run(e) for e in RESTITUTIONS]
    stdout, fd1 = sys.stdout, _fd1()
    for _ in range(3):
        with ThreadPoolExecutor(4) as pool:
            threaded = list(pool.map(_run, RESTITUTIONS))
        assert sys.stdout is stdout
        assert _fd1() == fd1
        for a, b in zip(serial, threaded):
            np.testing.assert_array_equal(a.q, b.q)
            np.testing.assert_array_equal(a.v, b.v)
            np.testing.assert_array_equal(a.impacts.t, b.impacts.t)
    print("stdout still prints")
    sys.stdout.flush()
    out = capfd.readouterr().out
    assert "stdout still prints" in out
    assert "Polishing" not in out  # OSQP's polishing message does not leak either


def test_threaded_sweep_equals_serial(capfd):
    grid = {"e": list(RESTITUTIONS)}
    serial = sweep(ball_point, grid, executor="serial", progress=False)
    stdout, fd1 = sys.stdout, _fd1()
    with ThreadPoolExecutor(4) as pool:
        threaded = sweep(ball_point, grid, executor=pool, progress=False)
    assert sys.stdout is stdout and _fd1() == fd1
    assert threaded.equals(serial)
    assert serial["impacts"].min() > 0
    print("stdout still prints")
    sys.stdout.flush()
    assert "stdout still prints" in capfd.readouterr().out
