"""Long compiles on a thread of their own, which starts with an empty frame stack.

CPython 3.11 keeps a thread's Python frames in 16 KiB chunks. It maps a chunk when a call
runs past the last one and unmaps it when that call returns. A compile started from a deep
stack (a test runner's fixture, a notebook cell) whose recursion keeps crossing a chunk's
end maps and unmaps one on nearly every call there: the test suite's first two workers,
compiling the loop's two variants, spent 71 s of system time and 130 s of wall time where
the same compiles on a fresh stack take 5 s and 94 s (``python -m pytest tests/test_api.py``
from an empty cache, 2026-11-28; ``strace -c`` showed only ``mmap``/``munmap`` of 16 KiB).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TypeVar

__all__ = ["on_fresh_stack"]

T = TypeVar("T")


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
