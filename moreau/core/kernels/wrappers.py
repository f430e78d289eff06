"""Allocating wrappers of the kernels for Python callers (the model objects' methods)."""

from __future__ import annotations

import numpy as np

from moreau.core.kernels.forces import trig

__all__ = ["force_of", "flat", "cos_sin"]


# -- allocating wrappers for Python callers -------------------------------------------------
def force_of(kernel, n: int, *args) -> np.ndarray:
    """Call an accumulating force kernel on a fresh zero vector of size n."""
    out = np.zeros(n)
    kernel(*args, out)
    return out


def flat(*params) -> np.ndarray:
    """The parameters of one kernel as one flat float array (the kernel's layout)."""
    return np.ascontiguousarray(np.concatenate([np.ravel(np.asarray(x, dtype=float)) for x in params]))


def cos_sin(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cos q, sin q) through :func:`trig`, for Python callers."""
    c = np.empty(q.shape[0])
    s = np.empty(q.shape[0])
    trig(q, c, s)
    return c, s
