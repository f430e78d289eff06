"""Two of numba's compile steps made cheaper on the loop's large function, same results.

The compiled loop is one function of some 30 000 LLVM instructions once its parts are
inlined (``moreau.compiled.layout.part``). Two steps of numba's own pipeline grow faster
than its size, and each is replaced here by one that computes the same thing:

- **Inlining without two copies of a fresh IR.** For each call of an ``inline="always"``
  function numba builds the callee's IR anew (``InlineWorker.run_untyped_passes``) and
  ``InlineWorker.inline_ir`` then deep-copies it twice: once so that inlining does not
  mutate the caller's copy, once to return an unmutated copy. The IR is fresh, and the only
  caller of ``inline_function`` (the ``InlineInlinables`` pass) discards the copy returned,
  so neither copy is needed. The copies are skipped for that call, on the calling thread;
  every other deep copy, of any thread, is numba's own.
- **Liveness on bit sets.** ``numba.core.analysis.compute_live_map`` (run after most
  passes, through ``PostProcessor``) propagates Python sets of variable names to a fixed
  point; on the loop function they hold thousands of names per block. :func:`live_map`
  runs the same two fixed points (the definitions reaching each block, then the variables
  live at its entry) on integers used as bit sets, and returns the same sets.

Measured on a one-process compile of the plain variant (``docs/performance.md``, "What the
compile costs"): the copies were 6.7-8.8 s of the inlining pass (1.8-2.0 s without), the
liveness 4.1 s of 812 calls (0.32 s on bit sets, every answer equal); the machine code of
every cached function is the same bytes with and without. :func:`install` replaces only
what it finds as read here (the inlining as numba 0.59-0.68 write it; the liveness as 0.68
computes it, over the blocks in topological order, where 0.59 ran over every block) and
logs what it leaves.
"""

from __future__ import annotations

import copy
import logging
import threading
from typing import Any

__all__ = ["install", "installed", "live_map"]

log = logging.getLogger(__name__)

#: the names numba 0.59-0.68's ``InlineWorker.inline_function`` uses, in order
_INLINE_NAMES = ("run_untyped_passes", "__code__", "co_freevars", "inline_ir")
#: the parameters of numba's ``compute_live_map``
_LIVE_PARAMETERS = ("cfg", "blocks", "var_use_map", "var_def_map")

_state = threading.local()  # .fresh: this thread is inlining an IR of its own
_lock = threading.Lock()
_done: list[bool] = []
#: numba's own functions that :func:`install` replaced, by name (the tests compare against them)
originals: dict[str, Any] = {}


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


def live_map(cfg: Any, blocks: Any, var_use_map: Any, var_def_map: Any) -> dict:
    """The variables live at the entry of each block (``{label: set of names}``), as
    numba's ``compute_live_map`` finds them, with a bit of an integer per variable."""
    index: dict[str, int] = {}

    def bits(names: Any) -> int:
        b = 0
        for name in names:
            b |= 1 << index.setdefault(name, len(index))
        return b

    order = cfg.topo_order()
    defs = {k: bits(s) for k, s in var_def_map.items()}
    uses = {k: bits(s) for k, s in var_use_map.items()}
    succ = {k: [o for o, _ in cfg.successors(k)] for k in order}
    pred = {k: [i for i, _ in cfg.predecessors(k)] for k in order}
    reach = dict.fromkeys(order, 0)  # definitions (or uses) that reach a block's entry
    changed = True
    while changed:
        changed = False
        for k in order:
            r = reach[k] | defs.get(k, 0) | uses.get(k, 0)
            if r != reach[k]:
                reach[k], changed = r, True
            for o in succ[k]:
                ro = reach.get(o, 0)
                if ro | r != ro:
                    reach[o], changed = ro | r, True
    live = {k: uses.get(k, 0) for k in blocks}  # used in a block, then pushed back to its predecessors
    changed = True
    while changed:
        changed = False
        for k in reversed(order):
            lk = live.get(k, 0)
            for i in pred[k]:
                li = live.get(i, 0)
                grown = li | (lk & reach.get(i, 0) & ~defs.get(i, 0))
                if grown != li:
                    live[i], changed = grown, True
    names = list(index)
    out = {}
    for k, b in live.items():
        s = set()
        while b:
            low = b & -b
            s.add(names[low.bit_length() - 1])
            b ^= low
        out[k] = s
    return out


def install() -> bool:
    """Replace both steps (once per process); returns whether both are replaced."""
    with _lock:
        if _done:
            return _done[0]
        from numba.core import analysis, ir_utils
        from numba.core import inline_closurecall as icc

        worker = icc.InlineWorker
        code = getattr(getattr(worker, "inline_function", None), "__code__", None)
        inline_ok = (code is not None and code.co_names == _INLINE_NAMES and getattr(icc, "copy", None) is copy
                     and callable(getattr(worker, "inline_ir", None)))
        if inline_ok:
            icc.copy = _Copies()  # type: ignore[assignment]  # the module's name for copy, shimmed
            worker.inline_function = _inline_function  # type: ignore[method-assign]
        original = getattr(analysis, "compute_live_map", None)
        live_ok = (original is not None and "topo_order" in original.__code__.co_names
                   and original.__code__.co_varnames[:original.__code__.co_argcount] == _LIVE_PARAMETERS)
        if live_ok:
            originals["compute_live_map"] = original
            analysis.compute_live_map = live_map
            if getattr(ir_utils, "compute_live_map", None) is original:
                ir_utils.compute_live_map = live_map
        if not (inline_ok and live_ok):
            log.debug("moreau: numba's %s is not the one read here; numba's own runs",
                      " and ".join(n for n, ok in (("inlining", inline_ok), ("liveness", live_ok)) if not ok))
        _done.append(inline_ok and live_ok)
        return _done[0]


def installed() -> bool:
    """Whether :func:`install` replaced both steps in this process."""
    from numba.core import analysis
    from numba.core import inline_closurecall as icc

    return icc.InlineWorker.inline_function is _inline_function and analysis.compute_live_map is live_map
