"""Flight gaps: the test that makes a contact onset an impact (see :class:`moreau.ImpactLog`).

A row is *in flight* once its gap, at the end of some step since it last carried an
impulse, exceeds its flight gap; its next contact onset is then an impact. Shared by
both paths of :func:`moreau.simulate`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["initial_flight", "flight_gaps"]


def initial_flight(scene, q0: np.ndarray, v0: np.ndarray) -> np.ndarray:
    """Each row's largest gap "since its last contact" at the start: its gap, or +inf when
    it approaches at t0 (a row that starts closed and moving in is hit by an impact)."""
    if not scene.nrows:
        return np.zeros(0)
    g0 = np.asarray(scene.gaps(q0), dtype=float).copy()
    g0[np.asarray(scene.jacobian(q0) @ v0) < 0.0] = np.inf
    return g0


def flight_gaps(flight_gap, m: int) -> np.ndarray:
    """``flight_gap`` as an array of shape (m,), validated."""
    if type(flight_gap) in (float, int) and math.isfinite(flight_gap) and flight_gap >= 0:  # the common case
        return np.full(m, float(flight_gap))
    if isinstance(flight_gap, (bool, str)) or flight_gap is None:
        raise ValueError(f"flight_gap must be a number >= 0 or an array of shape ({m},), got {flight_gap!r}")
    try:
        fg = np.asarray(flight_gap, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"flight_gap must be a number >= 0 or an array of shape ({m},), got {flight_gap!r}") from None
    if fg.ndim == 0:
        fg = np.full(m, float(fg))
    if fg.shape != (m,) or not np.all(np.isfinite(fg)) or np.any(fg < 0):
        raise ValueError(f"flight_gap must be a finite number >= 0 or such an array of shape ({m},), "
                         f"got {flight_gap!r}")
    return fg
