"""The compiled loop's machine code: loaded from numba's cache, or compiled once per machine
and version under a lock (:func:`ensure_compiled`)."""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import signal
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from moreau.compiled import side_compile
from moreau.compiled.layout import STEP_MIDPOINT
from moreau.compiled.runner import one_row_scene, run_compiled
from moreau.core.compiling import compile_call
from moreau.core.jitcache import cache_dir, call_recovering, clear, compile_lock

__all__ = ["COMPILE_SECONDS", "ensure_compiled"]

log = logging.getLogger(__name__)


#: what the first compile of each variant of the loop takes on a 2-core machine, s, as the
#: message says it (benchmarks/compile_cost.py; docs/performance.md has the figures)
COMPILE_SECONDS = {False: 30, True: 70}
_NAMES = {False: "the plain midpoint step", True: "friction, bilateral rows and later passes"}
_ready = {False: threading.Event(), True: threading.Event()}
_drivers: set[bool] = set()  # the variants whose step-control driver this process has
_ready_lock = threading.Lock()


def ensure_compiled(full: bool | None = None, step_control: bool = False) -> float:
    """Load a variant of the compiled time loop from numba's cache, or compile it (once per
    machine and version, saying so in one logged line) when it is not there; returns the
    seconds it took (0 when this process has it already).

    ``full``: the variant with friction, bilateral rows and the step's later passes (True)
    or the one without them (False; :func:`moreau.compiled.loop.variant` says which a scene
    runs); None: both. Processes started together on an empty cache compile once: the
    first holds a lock in the cache directory (:func:`moreau.core.jitcache.compile_lock`),
    the others wait and then load what it saved. Call it before starting worker
    processes, or to warm a cache (``moreau compile`` does). ``step_control``: also step-size
    control's driver for that variant (:mod:`moreau.compiled.adaptive`; otherwise compiled or loaded
    on first use).
    """
    if full is None:
        return ensure_compiled(False, step_control) + ensure_compiled(True, step_control)
    full = bool(full)
    if step_control:
        spent = ensure_compiled(full)
        with _ready_lock:
            if full in _drivers:
                return spent
            t = time.perf_counter()
            compile_call(_warm_up, full, True)  # (the driver takes its own lock, and loads or compiles)
            _drivers.add(full)
            return spent + time.perf_counter() - t
    if _ready[full].is_set():
        return 0.0
    with _ready_lock:
        if _ready[full].is_set():
            return 0.0
        t = time.perf_counter()
        with compile_lock(".full" if full else ".plain"):  # the two variants may compile side by side
            d = cache_dir()
            cold = d is None or full not in cached_variants()
            if cold:
                log.warning("moreau: compiling the time loop for %s once for this machine (about %d s; later runs "
                            "load it from %s)", _NAMES[full], COMPILE_SECONDS[full],
                            d or "nowhere: the cache is not writable")
            # the contact solves compiled beside the loop, in a second process
            helper = side_compile.start(full) if cold and d is not None else None
            try:
                _load_or_compile(full, cold, d)
            finally:
                side_compile.stop(helper)
            _ready[full].set()
        return time.perf_counter() - t


def _load_or_compile(full: bool, cold: bool, d: str | None) -> None:
    """The variant loaded from numba's cache, or compiled (``cold``) into ``d``."""
    try:
        # loading machine code runs through LLVM callbacks: a Ctrl-C or SIGTERM raised
        # inside one aborted the process (seen: exit -6), so during a load (0.3 s) they
        # wait and are acted on right after it
        with (contextlib.nullcontext() if cold else _signals_deferred()):
            # (moreau.core.compiling: a fresh stack, fewer collections); a damaged file: compiled again
            call_recovering(lambda: compile_call(_warm_up, full))
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError,
            ImportError, OSError) as exc:  # an unreadable cache file not found in the traceback
        removed = clear()
        log.warning("moreau: numba's cache in %s could not be read (%s: %s); removed %d files of it "
                    "and compiling the time loop again (about %d s)", d, type(exc).__name__, exc,
                    removed, COMPILE_SECONDS[full])
        compile_call(_warm_up, full)


def cached_variants() -> set[bool]:
    """The variants of the loop (``full``, see :func:`ensure_compiled`) in numba's cache for
    this source (read from numba's index of ``moreau.compiled.loop._run_chunk``: its
    argument ``fr`` is None in the plain variant)."""
    from numba.core import types

    from moreau.compiled.loop import _run_chunk

    try:
        index = _run_chunk._cache._cache_file._load_index()  # numba's own (stamp-checked) index
    except Exception:  # noqa: BLE001 - unreadable or another numba: treated as absent, compiled
        return set()
    return {not isinstance(key[0][-3], types.NoneType) for key in index}


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM are recorded, and handled as before once it ends
    (main thread only; elsewhere nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    old: dict[int, Any] = {}
    for s in (signal.SIGINT, signal.SIGTERM):
        old[int(s)] = signal.signal(s, lambda signum, frame: got.append(signum))
    try:
        yield
    finally:
        for num, handler in old.items():
            signal.signal(num, handler)
        for num in got:
            handler = old[int(num)]
            if callable(handler):
                handler(num, None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), num)


def _compile_loop(full: bool) -> None:
    """The loop of the ``full`` variant or the plain one, loaded or compiled (for a run's types)."""
    from moreau.compiled.layout import chunk_arguments
    from moreau.compiled.loop import _run_chunk
    from moreau.compiled.runner import chunk_example

    args = chunk_arguments(*chunk_example(full))
    _run_chunk.compile(tuple(_run_chunk.typeof_pyval(a) for a in args))


def _warm_up(full: bool, adaptive: bool = False) -> None:
    """Two steps of a one-row scene on the ``full`` variant or the plain one: loads (or
    compiles) every compiled function a run of that variant calls; ``adaptive``: with
    step-size control (its driver)."""
    scene = one_row_scene()
    _compile_loop(full)  # before the run's own calls: the drift projection is the second process's meanwhile
    run_compiled(scene, None, 0.0, np.array([1e-3]), np.array([-1.0]), 1e-3, 2, step=STEP_MIDPOINT, solver="exact",
                 fallback=None, stride=1, bar=None, energy=True, tol=1e-8, drift_control=None,
                 flight_gap=np.zeros(1), gmax0=np.full(1, np.inf), full=full,
                 control=(2e-3, 1e-3, 0.0, 1e-12) if adaptive else None)
