"""One local process-pool scheduler, used by ``moreau piston`` (:mod:`moreau.problems.piston.job`)
and by :func:`moreau.sweeps.sweep`.

Stopping
--------
* **Ctrl-C and SIGTERM are handled alike.** :func:`sigterm_as_interrupt` makes SIGTERM (what
  schedulers, systemd and containers send) raise :class:`Terminated`, a
  ``KeyboardInterrupt``, in the main thread. :func:`run_jobs` then starts no new job, sends
  SIGTERM to the workers still running one (they stop as on Ctrl-C: a simulation returns
  or raises with what it computed, and the job saves it), collects what they return for up
  to ``grace`` seconds, stops the pool and re-raises.
* **Workers never outlive the parent.** Each worker polls its parent process id; when the
  parent is gone (even after SIGKILL) a running job is interrupted as above, allowed to
  finish saving for a grace period, and the worker exits without sending anything (there is
  no one to send it to). An idle worker exits at once.
* A job is submitted only when a worker is free, so an interrupt leaves nothing queued.

A worker that dies (killed by the out-of-memory killer, a crash in compiled code) fails
its job with :class:`WorkerDied`, a one-line reason; the pool it broke is replaced and the
jobs the other workers were running (stopped with it) start again.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["Terminated", "WorkerDied", "sigterm_as_interrupt", "interrupt_exit_code", "was_terminated", "run_jobs"]

log = logging.getLogger(__name__)

_WATCH_INTERVAL = 0.5  # s between two checks of the parent process id in a worker
_ORPHAN_GRACE = 30.0  # s an orphaned worker's job gets to save what it computed


class Terminated(KeyboardInterrupt):
    """SIGTERM received: raised like Ctrl-C's ``KeyboardInterrupt`` (a subclass of it)."""


class WorkerDied(RuntimeError):
    """The worker process running a job died before returning it (the message says how)."""


_received: dict[str, int | None] = {"signum": None}


def was_terminated() -> bool:
    """True once this process has received SIGTERM under :func:`sigterm_as_interrupt`."""
    return _received["signum"] == signal.SIGTERM


def interrupt_exit_code(exc: BaseException | None = None) -> int:
    """The exit code of a stopped command: 143 (128 + SIGTERM) after SIGTERM, else 130
    (128 + SIGINT, Ctrl-C)."""
    return 143 if isinstance(exc, Terminated) or was_terminated() else 130


def interrupt_for_signal() -> KeyboardInterrupt:
    """A new interrupt of the kind this process received (Terminated after SIGTERM)."""
    return Terminated("terminated (SIGTERM)") if was_terminated() else KeyboardInterrupt()


@contextlib.contextmanager
def sigterm_as_interrupt():
    """Within the block, SIGTERM raises :class:`Terminated` in the main thread (once: later
    SIGTERMs are ignored while the command stops and saves). Elsewhere than in the main
    thread this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        if _received["signum"] == signal.SIGTERM:
            log.warning("SIGTERM again: still stopping and saving")
            return
        _received["signum"] = signal.SIGTERM
        raise Terminated("terminated (SIGTERM)")

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


# -- the worker side ------------------------------------------------------------------------
_worker: dict[str, Any] = {"running": False, "stopping": False, "parent_gone": False, "started": None}


def _worker_init(parent_pid: int, started=None) -> None:
    _worker["started"] = started
    signal.signal(signal.SIGINT, _worker_signal)
    signal.signal(signal.SIGTERM, _worker_signal)
    sys.unraisablehook = _unraisable
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True, name="moreau-parent-watch").start()


def _worker_signal(signum, frame) -> None:
    """Interrupt the running job once (later signals are ignored while it saves); an idle
    worker ignores the signal (the parent stops the pool)."""
    if not _worker["running"] or _worker["stopping"]:
        return
    _worker["stopping"] = True
    _received["signum"] = signum
    raise Terminated("terminated (SIGTERM)") if signum == signal.SIGTERM else KeyboardInterrupt()


def _unraisable(info: Any) -> None:
    """A signal's exception raised inside a finalizer (an llvmlite object's ``__del__``, say)
    cannot stop the job there: Python would only print it. Deliver the signal again, so the
    job is interrupted where it can keep its results, and print nothing."""
    signum = _received.get("signum")
    if isinstance(info.exc_value, KeyboardInterrupt) and signum:
        _worker["stopping"] = False
        os.kill(os.getpid(), signum)
        return
    sys.__unraisablehook__(info)


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(_WATCH_INTERVAL)
    _worker["parent_gone"] = True
    if _worker["running"]:
        # no logging here: this thread must not wait for a lock (a logging handler's, a
        # stream's) that the interrupted main thread may hold, or os._exit is never reached
        # (seen: two sweep workers orphaned for 87 min, both threads in futex_wait)
        try:
            os.write(2, f"worker {os.getpid()}: the parent process is gone; stopping the job\n".encode())
        except OSError:
            pass
        os.kill(os.getpid(), signal.SIGTERM)  # the job stops as on Ctrl-C and saves what it has
        time.sleep(_ORPHAN_GRACE)
    os._exit(143)


def _call_in_worker(fn: Callable, args: tuple, index: int = -1) -> Any:
    if _worker["started"] is not None:  # tell the parent which process runs which job
        _worker["started"].put((index, os.getpid()))
    _worker["running"], _worker["stopping"] = True, False
    try:
        return fn(*args)
    finally:
        _worker["running"] = False
        if _worker["parent_gone"]:
            os._exit(143)  # nobody to send the result to


# -- the parent side ------------------------------------------------------------------------
def run_jobs(fn: Callable, jobs: Sequence[tuple], workers: int,
             on_done: Callable[[int, Any, BaseException | None], None], grace: float = 60.0) -> None:
    """Run ``fn(*jobs[i])`` on a pool of ``workers`` processes.

    Parameters
    ----------
    fn : callable
        A picklable function (module level).
    jobs : sequence of tuple
        The arguments of each call.
    workers : int
        Processes (>= 1).
    on_done : callable ``on_done(i, result, exc)``
        Called in this process as each job ends: its result, or the exception it raised
        (``exc``, then ``result`` is None; a ``KeyboardInterrupt`` when the job was
        interrupted without returning). Jobs that never started are not reported.
    grace : float
        Seconds the running jobs get to return after an interrupt before their workers are
        killed.

    Raises
    ------
    KeyboardInterrupt
        Re-raised (a :class:`Terminated` after SIGTERM) once the running jobs returned or
        the grace period ended; the pool's processes are gone by then.
    """
    import multiprocessing as mp

    started = mp.get_context().SimpleQueue()  # (job, worker pid) as each job starts

    def new_pool() -> cf.ProcessPoolExecutor:
        return cf.ProcessPoolExecutor(max_workers=max(1, int(workers)), initializer=_worker_init,
                                      initargs=(os.getpid(), started))

    pool = new_pool()
    queue = list(enumerate(jobs))
    running: dict[cf.Future, int] = {}
    procs: dict[int, Any] = {}  # pid -> process, of every worker this call started
    try:
        while queue or running:
            while queue and len(running) < workers:
                i, job = queue.pop(0)
                running[pool.submit(_call_in_worker, fn, tuple(job), i)] = i
                procs.update({p.pid: p for p in (getattr(pool, "_processes", None) or {}).values()})
            done, _ = cf.wait(running, return_when=cf.FIRST_COMPLETED)
            if any(not f.cancelled() and isinstance(f.exception(), cf.process.BrokenProcessPool) for f in done):
                again = _worker_died(running, started, procs, on_done)  # (before _stop kills the others)
                if again:  # their workers were stopped with the broken pool, not by the user
                    log.warning("job(s) %s were stopped when another worker died; running them again", again)
                _stop(pool)
                queue[:0] = [(i, jobs[i]) for i in again]
                running.clear()
                pool = new_pool()
                continue
            for fut in done:
                _deliver(fut, running.pop(fut), on_done)
    except KeyboardInterrupt:
        try:
            _collect_after_interrupt(pool, running, on_done, grace)
        finally:
            _stop(pool)
        raise
    except BaseException:
        _stop(pool)
        raise
    pool.shutdown(wait=True)


def _worker_died(running: dict, started, procs: dict, on_done) -> list[int]:
    """A worker died and broke the pool: fail the job(s) whose worker was killed or
    crashed (on_done with :class:`WorkerDied`), and return the jobs that were stopped
    with them (to run again). When no death can be told apart, every running job fails."""
    pids: dict[int, int] = {}
    while not started.empty():
        i, pid = started.get()
        pids[i] = pid
    died: list[tuple[int, int | None, int | None]] = []
    again: list[tuple[int, int | None, int | None]] = []
    for fut, i in running.items():
        if fut.done() and not isinstance(fut.exception(), cf.process.BrokenProcessPool):
            _deliver(fut, i, on_done)  # it returned before the pool broke
            continue
        proc = procs.get(pids.get(i, -1))
        if proc is not None:
            proc.join(timeout=1.0)  # a dead worker's status settles (another thread may reap it)
        code = None if proc is None else proc.exitcode
        settle = time.monotonic() + 1.0  # the executor's thread may be reaping it: its status lands shortly
        while proc is not None and code is None and time.monotonic() < settle:
            time.sleep(0.01)
            code = proc.exitcode
        # killed by a signal other than the SIGTERM with which the broken pool stops the
        # others (those exit in any way once their job saved what it had)
        killed = code is not None and code < 0 and code != -signal.SIGTERM
        (died if killed else again).append((i, code, pids.get(i)))
    if not died:  # nothing tells which: all fail rather than run again for ever
        died, again = again, []
    for i, code, pid in died:
        on_done(i, None, WorkerDied(f"worker process {pid} died ({_how(code)}) while running job {i}"))
    return sorted(i for i, _, _ in again)


def _how(code: int | None) -> str:
    if code is None:
        return "exit status unknown"
    if code < 0:
        name = signal.Signals(-code).name if -code in signal.Signals._value2member_map_ else str(-code)
        why = ": out of memory, or killed by hand" if -code == signal.SIGKILL else ""
        return f"killed by signal {name}{why}"
    return f"exit code {code}"


def _deliver(fut: cf.Future, i: int, on_done) -> None:
    if fut.cancelled():
        return
    try:
        result, exc = fut.result(), None
    except BaseException as e:  # noqa: BLE001 - the job's own exception, handed over
        result, exc = None, e
    on_done(i, result, exc)


def _collect_after_interrupt(pool, running: dict, on_done, grace: float) -> None:
    """Signal the running jobs (again every second: one may have been starting) and hand
    over what they return until ``grace`` seconds have passed."""
    deadline = time.monotonic() + grace
    while running and time.monotonic() < deadline:
        _signal_workers(pool, signal.SIGTERM)
        done, _ = cf.wait(running, timeout=1.0)
        for fut in done:
            try:
                _deliver(fut, running.pop(fut), on_done)
            except KeyboardInterrupt:  # on_done stopping on an interrupted job: we already are
                pass
    if running:
        log.warning("%d job(s) did not stop within %g s; their workers are killed", len(running), grace)


def _processes(pool) -> list:
    return [p for p in list((getattr(pool, "_processes", None) or {}).values()) if p.is_alive()]


def _signal_workers(pool, signum: int) -> None:
    for proc in _processes(pool):
        try:
            os.kill(proc.pid, signum)
        except (ProcessLookupError, OSError):
            pass


def _stop(pool) -> None:
    """Stop the pool now: nothing queued runs, every worker process ends."""
    procs = _processes(pool)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        if proc.is_alive():
            proc.kill()
    for proc in procs:
        proc.join(timeout=5)
