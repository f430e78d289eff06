"""InstCombine before LLVM's function passes on moreau's large compiled functions.

numba gives every variable a stack slot and reads a variable holding a tuple whole at each
use. The loop function (``moreau.compiled.loop._run_chunk``) reads its work tuples (up to
21 arrays, some 150 fields) 163 times this way in the plain variant, each read followed by
one field's ``extractvalue``. The function passes numba runs on each function before
linking (``CPUCodeLibrary._optimize_functions``, LLVM's O3 function pipeline) start with
SROA, which splits every such read into all of its fields before anything removes the
unused ones: 1.3 s of the 2.1-2.2 s those passes took on the plain variant's loop function.
InstCombine run first folds each field read of a loaded tuple into a load of that field
alone; the passes then take 0.65-0.69 s with it, the loop's compile 14.4-14.9 s against
15.8-16.3 s, and the optimized module is as large (32 525-32 531 instructions); the step
costs the same within 1.5 % (``docs/performance.md``).

:func:`install` wraps numba's ``_optimize_functions`` so that moreau's own functions of at
least :data:`LARGE` instructions as numba lowers them (their names mangled under the
``moreau`` package: the loop function, the drift projection, the KKT check's rows, the dual
active-set method, the warm start) get the InstCombine first; every other function, a
user's callables among them, is compiled as numba compiles it. Its source is part of the
cache's digest (``moreau.core.jitcache.CODEGEN_FILES``).
"""

from __future__ import annotations

import logging
import threading
from typing import Any

__all__ = ["install", "installed", "is_moreaus"]

log = logging.getLogger(__name__)

_lock = threading.Lock()
_done: list[bool] = []


def is_moreaus(name: str) -> bool:
    """Whether an LLVM function name is one of moreau's compiled functions (or their wrappers):
    numba mangles a function as ``_ZN<len><module path>...``, wrappers prefixed ``cpython``/``cfunc``."""
    for prefix in ("_ZN", "_ZN7cpython", "_ZN5cfunc"):
        if name.startswith(prefix + "6moreau"):
            return True
    return False


#: the instructions a function has (as numba lowers it) from which it gets the InstCombine first
LARGE = 4000


def _size(func: Any) -> int:
    """The instructions of an LLVM function."""
    return sum(1 for block in func.blocks for _ in block.instructions)


def _with_prepass(optimize_functions: Any) -> Any:
    """numba's ``CPUCodeLibrary._optimize_functions``, InstCombine first on moreau's functions."""
    import llvmlite.binding as llvm  # type: ignore[import-untyped]

    def run(self: Any, ll_module: Any) -> None:
        tm, layout = getattr(self._codegen, "_tm", None), getattr(self._codegen, "_data_layout", None)
        if tm is None or layout is None:  # not numba's codegen as read here: its own passes only
            return optimize_functions(self, ll_module)
        ll_module.data_layout = layout  # (numba's sets it first as well: InstCombine needs it)
        for func in ll_module.functions:
            if not func.is_declaration and is_moreaus(func.name) and _size(func) >= LARGE:
                pb = llvm.create_pass_builder(tm, llvm.create_pipeline_tuning_options(0))
                pm = llvm.create_new_function_pass_manager()
                pm.add_instruction_combine_pass()
                pm.run(func, pb)
        optimize_functions(self, ll_module)

    run.__wrapped__ = optimize_functions  # type: ignore[attr-defined]
    return run


def install() -> bool:
    """Put the InstCombine before numba's function passes (once per process); returns
    whether it is in place (False when numba's codegen is not as read here)."""
    with _lock:
        if _done:
            return _done[0]
        from numba.core import codegen

        lib = getattr(codegen, "CPUCodeLibrary", None)
        original = getattr(lib, "_optimize_functions", None)
        ok = callable(original)
        if ok:
            lib._optimize_functions = _with_prepass(original)  # type: ignore[union-attr]
        else:
            log.debug("moreau: numba's CPUCodeLibrary._optimize_functions is not the one read here; numba's own runs")
        _done.append(ok)
        return ok


def installed() -> bool:
    """Whether :func:`install` put the InstCombine in place in this process."""
    from numba.core import codegen

    return hasattr(codegen.CPUCodeLibrary._optimize_functions, "__wrapped__")
