"""Long compiles run on a thread of their own, with fewer collections
(moreau.core.compiling): the caller's deep frame stack is not theirs, their result and
their exception come back, and the collector's thresholds are restored."""

import gc
import sys
import threading

import pytest

from moreau.core.compiling import COMPILE_GC_THRESHOLD, compile_call, fewer_collections, on_fresh_stack


def depth():
    frame, n = sys._getframe(), 0
    while frame is not None:
        frame, n = frame.f_back, n + 1
    return n, threading.get_ident(), gc.get_threshold()


def nested(k):
    return on_fresh_stack(depth) if k == 0 else nested(k - 1)


def test_the_call_runs_on_a_fresh_stack_and_returns_its_result():
    here = depth()
    n, ident, _ = nested(300)  # called from 300 frames deeper than this test
    assert ident != here[1]
    assert n < 20  # the thread's own frames and the call's, not the caller's 300


def test_the_calls_exception_is_raised_in_the_caller():
    err = ValueError("bad value 3 for argument x")

    def fails():
        raise err

    with pytest.raises(ValueError) as info:
        compile_call(fails)
    assert info.value is err


def test_collections_are_rarer_during_a_compile_and_restored_after_it():
    before = gc.get_threshold()
    try:
        gc.set_threshold(700, 10, 10)
        assert compile_call(depth)[2] == (COMPILE_GC_THRESHOLD, 10, 10)
        with fewer_collections():  # blocks overlapping in two threads: restored when both ended
            t = threading.Thread(target=lambda: compile_call(depth))
            t.start()
            t.join()
            assert gc.get_threshold() == (COMPILE_GC_THRESHOLD, 10, 10)
        assert gc.get_threshold() == (700, 10, 10)
        gc.set_threshold(10 * COMPILE_GC_THRESHOLD, 5, 5)  # a process's own higher threshold is kept
        assert compile_call(depth)[2] == (10 * COMPILE_GC_THRESHOLD, 5, 5)
        assert gc.get_threshold() == (10 * COMPILE_GC_THRESHOLD, 5, 5)
    finally:
        gc.set_threshold(*before)
