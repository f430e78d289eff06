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
from moreau.compiled.variants import VARIANTS, named
from moreau.core.compiling import compile_call
from moreau.core.jitcache import cache_dir, call_recovering, clear, compile_lock

__all__ = ["COMPILE_SECONDS", "compiling_ahead", "ensure_compiled"]

log = logging.getLogger(__name__)


#: what the first compile of each variant of the loop takes on a 2-core machine, s, as the
#: message says it (benchmarks/compile_cost.py; docs/performance.md has the figures)
COMPILE_SECONDS = {"plain": 30, "friction": 20, "full": 45}
_NAMES = {"plain": "the plain midpoint step", "friction": "friction",
          "full": "friction, bilateral rows and later passes"}
_ready = {v: threading.Event() for v in VARIANTS}
_ready_lock = threading.Lock()
#: second processes started ahead of their variant's compile (:func:`compiling_ahead`)
_ahead: dict[str, side_compile.Helper] = {}
_ahead_lock = threading.Lock()


def ensure_compiled(variant: str | None = None) -> float:
    """Load a variant of the compiled time loop from numba's cache, or compile it (once per
    machine and version, saying so in one logged line) when it is not there; returns the
    seconds it took (0 when this process has it already).

    ``variant``: one of :data:`moreau.compiled.variants.VARIANTS` (the plain midpoint step,
    with friction, or with friction, bilateral rows and the step's later passes;
    :func:`moreau.compiled.variants.variant` says which a scene runs); None: all. Processes
    started together on an empty cache compile once: the first holds a lock in the cache
    directory (:func:`moreau.core.jitcache.compile_lock`), the others wait and then load
    what it saved. Call it before starting worker
    processes, or to warm a cache (``moreau compile`` does). Each variant runs fixed steps and
    step-size control (:mod:`moreau.compiled.adaptive`) alike.
    """
    if variant is None:
        return sum(ensure_compiled(v) for v in VARIANTS)
    if variant not in VARIANTS:
        raise ValueError(f"variant={variant!r}: expected one of {VARIANTS} or None")
    if _ready[variant].is_set():
        return 0.0
    with _ready_lock:
        if _ready[variant].is_set():
            return 0.0
        t = time.perf_counter()
        with compile_lock("." + variant):  # the variants may compile side by side
            d = cache_dir()
            cold = d is None or variant not in cached_variants()
            if cold:
                log.warning("moreau: compiling the time loop for %s once for this machine (about %d s; later runs "
                            "load it from %s)", _NAMES[variant], COMPILE_SECONDS[variant],
                            d or "nowhere: the cache is not writable")
            # the contact solves compiled beside the loop, in a second process (started ahead, or now)
            helper = _take_ahead(variant)
            if helper is None and cold and d is not None:
                helper = side_compile.start(variant)
            try:
                _load_or_compile(variant, cold, d)
            finally:
                side_compile.stop(helper)
            _ready[variant].set()
        return time.perf_counter() - t


@contextlib.contextmanager
def compiling_ahead(variant: str) -> Iterator[None]:
    """Within the block, the second process of a cold compile of ``variant`` already runs
    (:mod:`moreau.compiled.side_compile`): a run's checks of its initial state, which
    compile the scene's kernels, overlap it, and :func:`ensure_compiled` inside the block
    takes it over. Nothing starts when the variant is loaded or in this process already;
    a process not taken over is ended with the block."""
    helper = None
    with _ahead_lock:  # (not _ready_lock: a compile in another thread holds it throughout)
        if (variant in VARIANTS and not _ready[variant].is_set() and variant not in _ahead
                and cache_dir() is not None and variant not in cached_variants()):
            helper = side_compile.start(variant)
            if helper is not None:
                _ahead[variant] = helper
    try:
        yield
    finally:
        if helper is not None and _take_ahead(variant, helper) is not None:
            side_compile.stop(helper)


def _take_ahead(variant: str, helper: side_compile.Helper | None = None) -> side_compile.Helper | None:
    """The second process started ahead for ``variant`` (that one, when given), taken out
    of the table; None when there is none."""
    with _ahead_lock:
        if variant in _ahead and (helper is None or _ahead[variant] is helper):
            return _ahead.pop(variant)
    return None


def _load_or_compile(variant: str, cold: bool, d: str | None) -> None:
    """The variant loaded from numba's cache, or compiled (``cold``) into ``d``."""
    try:
        # loading machine code runs through LLVM callbacks: a Ctrl-C or SIGTERM raised
        # inside one aborted the process (seen: exit -6), so during a load (0.3 s) they
        # wait and are acted on right after it
        with (contextlib.nullcontext() if cold else _signals_deferred()):
            # (moreau.core.compiling: a fresh stack, fewer collections); a damaged file: compiled again
            call_recovering(lambda: compile_call(_warm_up, variant))
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError,
            ImportError, OSError) as exc:  # an unreadable cache file not found in the traceback
        removed = clear()
        log.warning("moreau: numba's cache in %s could not be read (%s: %s); removed %d files of it "
                    "and compiling the time loop again (about %d s)", d, type(exc).__name__, exc,
                    removed, COMPILE_SECONDS[variant])
        compile_call(_warm_up, variant)


def cached_variants() -> set[str]:
    """The variants of the loop (:data:`moreau.compiled.variants.VARIANTS`) in numba's cache for
    this source (read from numba's index of ``moreau.compiled.loop._run_chunk``: which of
    friction's, the bilateral rows' and the later passes' arrays are None)."""
    from numba.core import types

    from moreau.compiled.loop import _run_chunk

    try:
        index = _run_chunk._cache._cache_file._load_index()  # numba's own (stamp-checked) index
    except Exception:  # noqa: BLE001 - unreadable or another numba: treated as absent, compiled
        return set()
    return {named(*(isinstance(t, types.NoneType) for t in key[0][-5:-2])) for key in index}  # (then ctl, sn)


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


def _compile_loop(variant: str) -> None:
    """The loop of a variant (:data:`moreau.compiled.variants.VARIANTS`), loaded or compiled (for a run's types)."""
    from moreau.compiled.layout import chunk_arguments
    from moreau.compiled.loop import _run_chunk, control_arguments
    from moreau.compiled.runner import chunk_example

    args = (*chunk_arguments(*chunk_example(variant)), *control_arguments(None, None))
    _run_chunk.compile(tuple(_run_chunk.typeof_pyval(a) for a in args))


def ensure_judged(variant: str) -> float:
    """Load (or compile) step-size control's judge of an attempt for a variant of the loop
    (:func:`moreau.compiled.adaptive.judge_attempt`, compiled apart from the loop; else at
    the first run with step-size control), and the variant itself; returns the seconds."""
    t = time.perf_counter()
    ensure_compiled(variant)
    compile_call(_warm_up, variant, True)
    return time.perf_counter() - t


def _warm_up(variant: str, controlled: bool = False) -> None:
    """Two steps of a one-row scene on a variant of the loop: loads (or
    compiles) every compiled function a run of that variant calls; ``controlled``: with
    step-size control (its judge)."""
    scene = one_row_scene()
    _compile_loop(variant)  # before the run's own calls: the drift projection is the second process's meanwhile
    run_compiled(scene, None, 0.0, np.array([1e-3]), np.array([-1.0]), 1e-3, 2, step=STEP_MIDPOINT, solver="exact",
                 fallback=None, stride=1, bar=None, energy=True, tol=1e-8, drift_control=None,
                 flight_gap=np.zeros(1), gmax0=np.full(1, np.inf), variant=variant,
                 control=(2e-3, np.full(2, 1e-3), 0.0, 1e-12) if controlled else None)
