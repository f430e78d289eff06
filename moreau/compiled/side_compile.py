"""The contact solves the loop calls, compiled in a second process while the loop compiles.

A variant's first compile types the loop function and, as it meets them, compiles the
functions it calls: the contact solve (:func:`moreau.contact.lcp.solve_one_step`, about 6 s
here) and, in the full variant, the friction solve
(:func:`moreau.contact.friction.solve_friction_step`, about 13 s). Their Python entries
(:class:`moreau.ExactSolver`, :func:`moreau.contact.friction.friction_one_step`) call them
with the loop's argument types, so a second process that calls those entries on a small
problem saves the very compiled code the loop needs into numba's cache, and the loop's
compile loads it there instead of compiling it (``benchmarks/compile_cost.py``).

Nothing waits for the second process: if it is late, or its types ever differ from the
loop's, the loop compiles its own copy as before and only a second core's time was spent.
It runs only on a machine with two cores or more and a cache shared with it, ends when its
compiles do or when the process that started it ends, and ``MOREAU_SIDE_COMPILE=0`` turns
it off.

    python -m moreau.compiled.side_compile {plain,full} PARENT_PID   # as start() runs it
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

__all__ = ["start", "stop"]

#: seconds between the second process's looks at whether its parent still runs
_WATCH_INTERVAL = 0.2


def start(full: bool) -> subprocess.Popen | None:
    """The second process for a compile of the ``full`` variant or the plain one, or None
    (one core, or turned off by ``MOREAU_SIDE_COMPILE=0``)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cores < 2 or os.environ.get("MOREAU_SIDE_COMPILE", "1") == "0":
        return None
    try:
        return subprocess.Popen([sys.executable, "-m", __name__, "full" if full else "plain", str(os.getpid())],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:  # no process to be had: the loop compiles everything itself
        return None


def stop(proc: subprocess.Popen | None) -> None:
    """End the second process if it still runs: the compile it served is over (numba
    writes a cache file under a temporary name, so a kill leaves none half written)."""
    if proc is not None:
        proc.kill()
        proc.wait()


def _watch_parent(parent: int) -> None:
    """End this process when the one that started it is gone."""
    while os.getppid() == parent:
        time.sleep(_WATCH_INTERVAL)
    os._exit(0)


def _compile(full: bool) -> None:
    """Call the solves' Python entries on one contact row: they compile (or load) the
    loop's copies."""
    import numpy as np

    from moreau.contact.exact import ExactSolver
    from moreau.contact.friction import friction_one_step

    M, b, G = np.eye(2), np.array([0.0, -1.0]), np.array([[0.0, 1.0]])
    if full:  # first: the full variant's loop meets it before the contact solve is ready
        friction_one_step(M, b, G, np.zeros(1), np.array([[1.0, 0.0]]), np.array([0.5]))
    ExactSolver().solve(M, b, G, np.zeros(1), np.array([0]))


if __name__ == "__main__":
    threading.Thread(target=_watch_parent, args=(int(sys.argv[2]),), daemon=True).start()
    _compile(sys.argv[1] == "full")
