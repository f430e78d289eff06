"""numba's inlining of the loop's parts without its copies of a fresh IR
(moreau.core.inlining): active on the numba the project installs, the inlined code as
before, and every other deep copy numba's own."""

import copy
import threading

import numpy as np
from numba import njit
from numba.core import inline_closurecall as icc
from numba.core import ir

from moreau.core import inlining


@njit(inline="always")
def _scaled(x, k):
    y = x * k  # a local of the callee: renamed at each site it is inlined at
    for i in range(3):
        y += i
    return y


@njit(inline="always")
def _twice(x):
    return _scaled(x, 2.0) + _scaled(x, 3.0)  # inlined into a function that is itself inlined


def _caller(x):
    a = _twice(x)
    b = _scaled(a, -1.0)
    return a, b


def test_the_copies_are_skipped_on_this_numba():
    assert inlining.install()  # idempotent: moreau installed it on import
    assert inlining.installed()


def test_inlined_functions_compute_as_written_and_their_ir_is_not_copied(monkeypatch):
    blocks = []
    real = copy.deepcopy

    def counting(x, memo=None):
        if isinstance(x, ir.Block):
            blocks.append(x)
        return real(x, memo)

    monkeypatch.setattr(copy, "deepcopy", counting)
    a, b = njit(_caller)(1.5)  # a new dispatcher: compiled here, not loaded
    expect = (1.5 * 2.0 + 3) + (1.5 * 3.0 + 3)
    assert (a, b) == (expect, -expect + 3)
    assert blocks == []  # four sites inlined, no block of their fresh IR copied


def test_other_threads_and_other_callers_copy_as_numba_does():
    block = ir.Block(ir.Scope(None, ir.Loc("f", 1)), ir.Loc("f", 1))
    shim = icc.copy
    assert shim.deepcopy(block) is not block  # outside an inlining: a real copy
    seen = []
    inlining._state.fresh = True  # this thread inlining a fresh IR: no copy here ...
    try:
        assert shim.deepcopy(block) is block
        t = threading.Thread(target=lambda: seen.append(shim.deepcopy(block)))
        t.start()
        t.join()
    finally:
        inlining._state.fresh = False
    assert seen[0] is not block  # ... but in every other thread
    assert shim.copy(np.ones(2)) is not None  # the rest of the module is copy's own
