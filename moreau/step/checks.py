"""The initial state a run starts from, checked once before the loop."""

from __future__ import annotations

from typing import Any

import numpy as np

from moreau.core.validation import as_vector
from moreau.model.scene import Scene

__all__ = ["START_PENETRATION_TOL", "check_initial_state"]

#: the penetration (gap units) an initial state may have: round-off of a state on a barrier
START_PENETRATION_TOL = 1e-12


def check_initial_state(scene: Scene, t0: Any, q0: Any, v0: Any,
                        penetration_tol: float = START_PENETRATION_TOL) -> tuple[float, np.ndarray, np.ndarray]:
    """Validate an initial state for ``scene``; return ``(t0, q0, v0)`` as floats/arrays.

    Raises ``ValueError`` for non-finite or wrongly shaped q0/v0, a mass matrix that is
    not symmetric positive definite at q0, malformed forces/gaps/Jacobians, and a state
    that penetrates a barrier (gap < ``-penetration_tol``): moreau refuses it rather than
    projecting silently.
    """
    n, m = scene.ndof, scene.nrows
    t0 = float(t0)
    if not np.isfinite(t0):
        raise ValueError(f"t0 must be finite, got {t0!r}")
    q0 = as_vector(q0, "q0", n)
    v0 = as_vector(v0, "v0", n)
    scene.check_state(t0, q0, v0, where=" at the initial state")
    scene.check_constraints(q0, v0, where=" at the initial state")
    if m:
        assert scene.gaps is not None  # a scene with rows has gaps
        g0 = np.asarray(scene.gaps(q0), dtype=float)
        bad = np.flatnonzero(g0 < -penetration_tol)
        if bad.size:
            names = ", ".join(f"{scene.row_names[i]}: g = {g0[i]:.6g}" for i in bad)
            raise ValueError(
                f"initial state penetrates a barrier ({names}); moreau refuses a penetrating "
                "start: move q0 onto the admissible side (g >= 0)"
            )
    return t0, q0, v0
