"""numba's inlining of ``inline="always"`` functions without its two copies of a fresh IR.

The loop's parts are inlined at numba's IR level (``moreau.compiled.layout.part``). For
each call site numba builds the callee's IR anew (``InlineWorker.run_untyped_passes``) and
then ``InlineWorker.inline_ir`` deep-copies it twice: once so that the inlining does not
mutate the caller's copy, once to return an unmutated copy. Here the IR is fresh, and the
only caller of ``inline_function`` (the ``InlineInlinables`` pass) discards the copy
returned, so neither copy is needed. They were 60 % of that pass and about a fifth of the
loop function's own compile (``docs/performance.md``, "What the compile costs"); without
them the loop's machine code is the same bytes.

:func:`install` skips the copies for ``inline_function``'s call of ``inline_ir`` on the
calling thread only; every other deep copy, of any thread, is numba's own. It installs
nothing on a numba whose ``inline_function`` is not the one read here (it then logs why).
"""

from __future__ import annotations

import copy
import logging
import threading
from typing import Any

__all__ = ["install", "installed"]

log = logging.getLogger(__name__)

#: the names numba 0.59-0.68's ``InlineWorker.inline_function`` uses, in order
_EXPECTED_NAMES = ("run_untyped_passes", "__code__", "co_freevars", "inline_ir")

_state = threading.local()  # .fresh: this thread is inlining an IR of its own
_lock = threading.Lock()
_done: list[bool] = []


class _Copies:
    """The ``copy`` module as ``inline_closurecall`` sees it: ``deepcopy`` returns its
    argument while this thread inlines a fresh IR, else it is ``copy.deepcopy``."""

    def __getattr__(self, name: str) -> Any:
        return getattr(copy, name)

    @staticmethod
    def deepcopy(x: Any, memo: Any = None) -> Any:
        return x if getattr(_state, "fresh", False) else copy.deepcopy(x, memo)


def _inline_function(self: Any, caller_ir: Any, block: Any, i: int, function: Any, arg_typs: Any = None) -> Any:
    """numba's ``InlineWorker.inline_function``, its fresh IR inlined without copies."""
    callee_ir = self.run_untyped_passes(function)
    _state.fresh = True
    try:
        return self.inline_ir(caller_ir, block, i, callee_ir, function.__code__.co_freevars, arg_typs=arg_typs)
    finally:
        _state.fresh = False


def install() -> bool:
    """Skip the two copies (once per process); returns whether they are skipped."""
    with _lock:
        if _done:
            return _done[0]
        from numba.core import inline_closurecall as icc

        worker = icc.InlineWorker
        names = getattr(getattr(worker, "inline_function", None), "__code__", None)
        ok = (names is not None and names.co_names == _EXPECTED_NAMES and getattr(icc, "copy", None) is copy
              and callable(getattr(worker, "inline_ir", None)))
        if ok:
            icc.copy = _Copies()  # type: ignore[assignment]  # the module's name for copy, shimmed
            worker.inline_function = _inline_function  # type: ignore[method-assign]
        else:
            log.debug("moreau: numba's InlineWorker is not the one read here; its inlining copies as it does")
        _done.append(ok)
        return ok


def installed() -> bool:
    """Whether :func:`install` skips the copies in this process."""
    from numba.core import inline_closurecall as icc

    return icc.InlineWorker.inline_function is _inline_function
