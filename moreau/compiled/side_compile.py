"""The functions the loop calls, compiled in a second process while the loop compiles.

A variant's first compile types the loop function and, as it meets them, compiles the
functions it calls: the contact solve (:func:`moreau.contact.lcp.solve_one_step`, about 5 s
here), its KKT check, the energy check, the drift projection (4 s) and, in the friction
and full variants, the friction solve (:func:`moreau.contact.friction.solve_friction_step`, about
13 s) and (full) the bilateral rows' parts; the loop calls its drift projection
(:func:`moreau.compiled.drift.project_rows`) and its friction solve through their
addresses, which a run looks up after the loop's compile. A second
process compiles them with the loop's argument types and saves them into numba's cache,
ahead of the loop's compile where it can be: the solves through their Python entries
(:class:`moreau.ExactSolver`, :func:`moreau.contact.friction.friction_one_step`), then
the calls at the end of a step, the energy check and the KKT check by typing
:func:`_calls_of_the_loop`, which calls them as the loop does, then what a run looks up
after the loop's compile: a chain's warm start
(:func:`~moreau.compiled.step.warm_start_addresses`) and the projection
(:func:`~moreau.compiled.drift.projection_address`); all on the arguments of a run
(:func:`moreau.compiled.runner.chunk_example`). A run starts it as its checks of the
initial state begin (:func:`moreau.compiled.cache.compiling_ahead`), a direct
:func:`~moreau.compiled.cache.ensure_compiled` as its compile does.

It writes a line as it starts each compile and as it saves one. When the loop's compile
meets a function the second process is compiling, it waits for that save and loads it
(:class:`Helper`); anything else it compiles itself, as before. If the second process is
late, or its types ever differ from the loop's, the loop compiles its own copy and only a
wait was lost. It runs only on a machine with two cores or more and a cache shared with it,
ends when its compiles do or when the process that started it ends, and
``MOREAU_SIDE_COMPILE=0`` turns it off.

    python -m moreau.compiled.side_compile {plain,friction,full} PARENT_PID   # as start() runs it
"""

from __future__ import annotations

import importlib
import logging
import os
import subprocess
import sys
import threading
import time
from typing import Any

import numpy as np
from numba import njit

from moreau.compiled import evaluate as ev
from moreau.compiled.energy import _energy_check
from moreau.compiled.layout import C_K, F_H, F_T0, SC_MASS_OFF, chunk_arguments
from moreau.compiled.loop import _end_gaps
from moreau.contact.kkt import kkt_residuals_kernel

__all__ = ["Helper", "start", "stop"]

log = logging.getLogger(__name__)

#: seconds between the second process's looks at whether its parent still runs
_WATCH_INTERVAL = 0.2
#: the longest the loop's compile waits for one function of the second process's, s
_WAIT_LIMIT = 60.0


class Helper:
    """The second process of one compile, and what the loop's compile waits for: each
    moreau function it is compiling has, until saved, a ``compile`` of its own that waits
    for the save (or for the process's end) and then loads it from the cache."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self._lock = threading.Lock()
        self._busy: dict[str, tuple[threading.Event, Any]] = {}  # name -> (saved, its dispatcher)
        self._reader = threading.Thread(target=self._follow, daemon=True)
        self._reader.start()

    def _follow(self) -> None:
        """Read the second process's lines to its end; then nothing waits any more."""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            kind, _, name = line.strip().partition(" ")
            if kind == "start":
                self._started(name)
            elif kind == "saved":
                self._release(name)
        for name in list(self._busy):
            self._release(name)

    def _started(self, name: str) -> None:
        disp = _dispatcher(name)
        if disp is None or "compile" in vars(disp):
            return
        saved = threading.Event()

        def compile(sig: Any) -> Any:  # the dispatcher's own, after the second process saved it
            if (sig if isinstance(sig, tuple) else getattr(sig, "args", None)) not in disp.overloads:
                t = time.perf_counter()  # (not for a copy this process has: a second call site's)
                saved.wait(_WAIT_LIMIT)
                log.debug("moreau: waited %.1f s for the second process's %s", time.perf_counter() - t, name)
            return type(disp).compile(disp, sig)

        with self._lock:
            self._busy[name] = (saved, disp)
            disp.compile = compile

    def _release(self, name: str) -> None:
        with self._lock:
            busy = self._busy.pop(name, None)
            if busy is not None:
                vars(busy[1]).pop("compile", None)
                busy[0].set()


def _dispatcher(name: str) -> Any:
    """moreau's cached compiled function of that ``module:qualname``, or None."""
    module, _, qualname = name.partition(":")
    if not module.startswith("moreau.") or "<" in qualname:
        return None
    try:
        obj: Any = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError):
        return None
    cache = getattr(obj, "_cache", None)
    return obj if cache is not None and type(cache).__name__ != "NullCache" else None


def start(variant: str) -> Helper | None:
    """The second process for a compile of a variant of the loop
    (:data:`moreau.compiled.variants.VARIANTS`), or None
    (one core, or turned off by ``MOREAU_SIDE_COMPILE=0``)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cores < 2 or os.environ.get("MOREAU_SIDE_COMPILE", "1") == "0":
        return None
    try:
        proc = subprocess.Popen([sys.executable, "-m", __name__, variant, str(os.getpid())],
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                text=True)
    except OSError:  # no process to be had: the loop compiles everything itself
        return None
    return Helper(proc)


def stop(helper: Helper | None) -> None:
    """End the second process if it still runs: the compile it served is over (numba
    writes a cache file under a temporary name, so a kill leaves none half written)."""
    if helper is not None:
        helper.proc.kill()
        helper.proc.wait()
        helper._reader.join()


@njit(nogil=True, _nrt=False)  # type: ignore[call-overload]  # numba's internal flag
def _calls_of_the_loop(model, user, iset, fset, Minv, eligible, q, v, k_end, in_contact, P_acc, act_acc,
                       T, Q, V, PS, ACT, GP, KE, PE, IMP, pen, cnt, acc, fail, last_imp, gmax, fgap, rs, work, PTS,
                       fr, eqw, ec):
    """The loop's calls at the end of a step (in the full variant the bilateral rows' hold),
    of its energy check and record and of the contact solve's KKT check (which the loop's
    compile meets first, and mostly compiles itself), on ``_run_chunk``'s arguments:
    typing it compiles them as the loop's compile would (never run)."""
    own, ws, lw = work
    M, L, cm, sm, cq, sq, qm, f, v_new, vbar, q_new, gm, gq, P, active, G, vfree, fb = own
    h, k = fset[F_H], cnt[C_K]
    status = _end_gaps(model, user, iset, fset, q_new, cq, sq, active, gq, M, L, cnt, acc, fail, eligible, ws, lw,
                       rs, in_contact, pen, gmax, eqw, v_new, P_acc, act_acc, last_imp,
                       (fset[F_T0] + k * h, h, f, fgap, IMP))
    status += _energy_check(model, user, iset, fset, k, q, v, cq, sq, M, cnt, acc, lw.q_warn, lw.v_warn)
    pe = ev.potential(model.ints, model.ekind, model.eoff, model.pool, q, cq, sq)  # the record's
    flag = k >= 0  # a bool variable, as the loop passes its flags (a literal would be typed apart)
    kkt_residuals_kernel(M, L, f, lw.GA, lw.cA, v_new, lw.PA, k, ws.res, ws.Gv, ws.GtP, ws.rv, ws.d, ws.x, ws.X,
                         ws.rd, flag, model.pool, model.ints[SC_MASS_OFF], cm, sm, lw.gen, flag)  # the contact check
    return status + np.int64(pe)


class _Typed(Exception):
    """Raised when :func:`_calls_of_the_loop` is typed: its callees are compiled, and
    itself is never run."""


def type_calls_of_the_loop(variant: str) -> None:
    """Type :func:`_calls_of_the_loop` for a run of a variant of the loop:
    the functions it calls are compiled (or loaded), and it is not."""
    from numba.core import event

    from moreau.compiled.runner import chunk_example

    class Typed(event.Listener):
        def on_start(self, ev: Any) -> None:
            pass

        def on_end(self, ev: Any) -> None:
            failed = getattr(ev, "_exc_details", None) is not None  # (numba 0.68's ``is_failed`` is inverted)
            if not failed and ev.data["qualname"] == "_calls_of_the_loop" and ev.data["name"].startswith(
                    "nopython_type_inference"):
                raise _Typed

    args = chunk_arguments(*chunk_example(variant))
    with event.install_listener("numba:run_pass", Typed()):
        try:
            _calls_of_the_loop.compile(tuple(_calls_of_the_loop.typeof_pyval(a) for a in args))
        except _Typed:
            return


def _compile(variant: str) -> None:
    """Call the solves' Python entries on one contact row: they compile (or load) the
    loop's copies."""
    import numpy as np

    from moreau.contact.exact import ExactSolver
    from moreau.contact.friction import friction_one_step

    M, b, G = np.eye(2), np.array([0.0, -1.0]), np.array([[0.0, 1.0]])
    ExactSolver().solve(M, b, G, np.zeros(1), np.array([0]))  # first: the loop's compile meets it
    if variant != "plain":  # only a run looks it up (through its address)
        friction_one_step(M, b, G, np.zeros(1), np.array([[1.0, 0.0]]), np.array([0.5]))


def _report() -> None:
    """Write ``start module:qualname`` as each compile starts and ``saved module:qualname``
    once its machine code is in the cache."""
    from numba.core import caching, event

    def say(kind: str, fn: Any) -> None:
        print(kind, f"{fn.__module__}:{fn.__qualname__}", flush=True)

    class Starts(event.Listener):
        def on_start(self, ev: Any) -> None:
            say("start", ev.data["dispatcher"].py_func)

        def on_end(self, ev: Any) -> None:
            pass

    event.register("numba:compile", Starts())
    plain = caching.Cache.save_overload

    def save_overload(self: Any, sig: Any, data: Any) -> None:
        plain(self, sig, data)
        say("saved", self._py_func)

    caching.Cache.save_overload = save_overload  # type: ignore[method-assign]  # this process only compiles


def _watch_parent(parent: int) -> None:
    """End this process when the one that started it is gone."""
    while os.getppid() == parent:
        time.sleep(_WATCH_INTERVAL)
    os._exit(0)


if __name__ == "__main__":
    threading.Thread(target=_watch_parent, args=(int(sys.argv[2]),), daemon=True).start()
    _report()
    _compile(sys.argv[1])
    type_calls_of_the_loop(sys.argv[1])  # what the loop's compile meets next; the rest only a run looks up
    from moreau.compiled.drift import projection_address
    from moreau.compiled.runner import chunk_example
    from moreau.compiled.step import warm_start_addresses

    example = chunk_example(sys.argv[1])
    warm_start_addresses(example[0], example[6])
    projection_address(*example[:7])
