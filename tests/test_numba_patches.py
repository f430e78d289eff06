"""Two of numba's compile steps replaced by cheaper ones with the same results
(moreau.core.numba_patches): active on the numba the project installs; inlining without
copies of a fresh IR computes as written, and every other deep copy is numba's own;
liveness on bit sets gives numba's own sets on every function a compile meets."""

import copy
import threading

import numpy as np
from numba import njit
from numba.core import analysis, ir, postproc
from numba.core import inline_closurecall as icc

from moreau.core import numba_patches


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


def test_both_steps_are_replaced_on_this_numba():
    assert numba_patches.install()  # idempotent: moreau installed them on import
    assert numba_patches.installed()


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
    numba_patches._state.fresh = True  # this thread inlining a fresh IR: no copy here ...
    try:
        assert shim.deepcopy(block) is block
        t = threading.Thread(target=lambda: seen.append(shim.deepcopy(block)))
        t.start()
        t.join()
    finally:
        numba_patches._state.fresh = False
    assert seen[0] is not block  # ... but in every other thread
    assert shim.copy is copy.copy  # the rest of the module is copy's own


def _branchy(x, n):
    s = 0.0
    for i in range(n):  # loops, branches and locals defined on some paths only
        if x[i] > 0.0:
            t = x[i] * 2.0
            s += t
        elif x[i] < -1.0:
            while s > 1.0:
                s *= 0.5
        else:
            u = _twice(x[i])
            s -= u
    return s


def test_liveness_on_bit_sets_is_numbas_own_on_every_call_of_a_compile(monkeypatch):
    assert analysis.compute_live_map is numba_patches.live_map
    numbas = numba_patches.originals["compute_live_map"]
    calls = []

    def both(cfg, blocks, uses, defs):
        ours = numba_patches.live_map(cfg, blocks, uses, defs)
        calls.append(ours == {k: set(v) for k, v in numbas(cfg, blocks, uses, defs).items()})
        return ours

    monkeypatch.setattr(analysis, "compute_live_map", both)
    x = np.array([1.0, -2.0, 0.5, -0.5, 3.0])
    assert njit(_branchy)(x, 5) == _branchy(x, 5)
    assert len(calls) > 10 and all(calls)
    assert postproc.analysis is analysis  # PostProcessor reaches it through the module
