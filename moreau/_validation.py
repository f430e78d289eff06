"""Input checks shared by the public constructors: each names the bad value."""

from __future__ import annotations

import numpy as np


def as_vector(x, name: str, size: int | None = None) -> np.ndarray:
    """A finite float vector of the given size, or ``ValueError`` naming ``name``."""
    try:
        a = np.array(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers, got {x!r}") from None
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {a.shape}")
    if size is not None and a.shape[0] != size:
        raise ValueError(f"{name} must have shape ({size},), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} has non-finite entries: {a.tolist()}")
    return a


def as_matrix(x, name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A finite 2-D float array (a scalar becomes 1 x 1), or ``ValueError``."""
    try:
        a = np.array(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers, got {x!r}") from None
    if a.ndim == 0:
        a = a.reshape(1, 1)
    if a.ndim != 2:
        raise ValueError(f"{name} must be two-dimensional, got shape {a.shape}")
    if shape is not None and a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} has non-finite entries: {a.tolist()}")
    return a


def as_positive(x, name: str, allow_zero: bool = False) -> float:
    """A finite positive float, or ``ValueError`` naming the value."""
    try:
        val = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not np.isfinite(val) or val < 0 or (val == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be finite and {kind}, got {val!r}")
    return val
