"""A compiled function called through its address (moreau.compiled.native), as the loop
calls its drift projection and friction's solver."""

import numba
import numpy as np
import pytest

from moreau.compiled.native import MISMATCH, address_and_key, call_checked


@numba.njit
def _axpy(y, x, k):
    """y += x / k (k an int: 0 raises ZeroDivisionError); returns the length."""
    for i in range(y.shape[0]):
        y[i] += x[i] / (1 // k)
    return np.int64(y.shape[0])


@numba.njit
def _through(addr, key, y, x, k):
    return call_checked(addr, key, (y, x, k))


def test_the_call_through_the_address_equals_the_direct_call():
    y, x = np.ones(3), np.array([1.0, 2.0, 3.0])
    addr, key = address_and_key(_axpy, (y, x, 1))
    assert address_and_key(_axpy, (y, x, 1)) == (addr, key)
    assert _through(addr, key, y, x, 1) == 3
    assert np.array_equal(y, [2.0, 3.0, 4.0])


def test_an_address_made_for_other_types_is_not_called():
    y, x = np.ones(3), np.ones(3)
    addr, key = address_and_key(_axpy, (y, x.astype(np.float32), 1))
    assert _through(addr, key, y, x, 1) == MISMATCH
    assert np.array_equal(y, np.ones(3))  # untouched


def test_an_exception_raised_in_the_callee_is_raised_in_the_caller():
    y, x = np.ones(3), np.ones(3)
    with pytest.raises(ZeroDivisionError):
        _through(*address_and_key(_axpy, (y, x, 0)), y, x, 0)


def test_only_int64_functions_have_an_address():
    @numba.njit
    def half(x):
        return x / 2

    with pytest.raises(TypeError, match="returns float64, not int64"):
        address_and_key(half, (1.0,))
