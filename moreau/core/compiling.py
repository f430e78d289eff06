"""How a long compile runs: on a thread of its own, with fewer garbage collections.

- **A fresh frame stack.** CPython 3.11 keeps a thread's Python frames in 16 KiB chunks,
  mapped when a call runs past the last one and unmapped when it returns. A compile started
  from a deep stack (a test runner's fixture, a notebook cell) whose recursion keeps
  crossing a chunk's end maps and unmaps one on nearly every call there; a new thread
  starts with an empty stack, as a script does.
- **Fewer collections.** numba's compile makes millions of short-lived objects; at the
  default threshold each of the collector's frequent full collections runs over every
  object of the process (a process that has imported matplotlib and scipy holds many).

What each costs and saves is measured in ``docs/performance.md`` ("What the compile costs").
"""

from __future__ import annotations

import contextlib
import gc
import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

__all__ = ["compile_call", "fewer_collections", "on_fresh_stack"]

T = TypeVar("T")

#: the collector's first threshold during a compile (CPython's default: 700)
COMPILE_GC_THRESHOLD = 5_000

_threshold_lock = threading.Lock()
_raised: list = []  # [thresholds before the first open block, blocks open]


def on_fresh_stack(fn: Callable[..., T], *args: object) -> T:
    """``fn(*args)`` run on a new thread and waited for; its result returned, its exception
    raised here. A signal (Ctrl-C, SIGTERM turned into an exception) interrupts the wait at
    once: the call goes on in the background (a daemon thread, ended with the process)."""
    outcome: list[tuple[bool, object]] = []

    def run() -> None:
        try:
            outcome.append((True, fn(*args)))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller below
            outcome.append((False, exc))

    worker = threading.Thread(target=run, name=f"moreau-{getattr(fn, '__name__', 'call')}", daemon=True)
    worker.start()
    worker.join()
    ok, value = outcome[0]
    if not ok:
        raise value  # type: ignore[misc]
    return value  # type: ignore[return-value]


@contextlib.contextmanager
def fewer_collections(threshold: int = COMPILE_GC_THRESHOLD) -> Iterator[None]:
    """Within the block, the collector's first threshold is at least ``threshold``; the
    process's thresholds are restored when the last such block (of any thread) ends."""
    with _threshold_lock:
        if not _raised:
            _raised[:] = [gc.get_threshold(), 0]
        old = _raised[0]
        _raised[1] += 1
        gc.set_threshold(max(old[0], threshold), *old[1:])
    try:
        yield
    finally:
        with _threshold_lock:
            _raised[1] -= 1
            if not _raised[1]:
                gc.set_threshold(*old)
                _raised.clear()


def compile_call(fn: Callable[..., T], *args: object) -> T:
    """``fn(*args)``, a call that compiles: on a fresh stack, with fewer collections."""
    with fewer_collections():
        return on_fresh_stack(fn, *args)
