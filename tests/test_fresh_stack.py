"""Long compiles run on a thread of their own (moreau.core.fresh_stack): the caller's
deep frame stack is not theirs, their result and their exception come back."""

import sys
import threading

import pytest

from moreau.core.fresh_stack import on_fresh_stack


def depth():
    frame, n = sys._getframe(), 0
    while frame is not None:
        frame, n = frame.f_back, n + 1
    return n, threading.get_ident()


def nested(k):
    return on_fresh_stack(depth) if k == 0 else nested(k - 1)


def test_the_call_runs_on_a_fresh_stack_and_returns_its_result():
    here = depth()
    n, ident = nested(300)  # called from 300 frames deeper than this test
    assert ident != here[1]
    assert n < 20  # the thread's own frames and the call's, not the caller's 300


def test_the_calls_exception_is_raised_in_the_caller():
    err = ValueError("bad value 3 for argument x")

    def fails():
        raise err

    with pytest.raises(ValueError) as info:
        on_fresh_stack(fails)
    assert info.value is err
