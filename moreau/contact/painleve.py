"""Painlevé's point: a sliding contact whose normal row loses its inverse mass under
friction (the one-step problem then has several solutions or none), found in a step's
answer and named in one warning by both paths."""

from __future__ import annotations

import numpy as np

__all__ = ["PAINLEVE_MARGIN", "painleve_rows", "painleve_message"]

#: a sliding contact whose effective normal inverse mass is at most this fraction of its
#: frictionless one, W_NN, is at Painlevé's point or past it (1 %: a normal force amplified 100x)
PAINLEVE_MARGIN = 0.01


def painleve_rows(L: np.ndarray, GA: np.ndarray, TA: np.ndarray, muA: np.ndarray, PN: np.ndarray,
                  PT: np.ndarray, U_T: np.ndarray) -> np.ndarray:
    """Indices (into the k active rows) of sliding contacts at or in Painlevé's region:
    the normal velocity the sliding friction impulse makes along with the normal impulse,
    ``W_NN − mu s W_NT`` (s the slip direction), is not positive, or within
    ``PAINLEVE_MARGIN`` of ``W_NN`` from zero. The normal row then has a vanishing or
    negative "effective inverse mass": the force the slip needs grows without bound, and
    the one-step problem can have several solutions (lift-off, a sliding contact with a
    large impulse, a tangential impact) or none, the step size choosing among them. A row
    whose ``W_NN`` is at round-off of its ``W_TT`` is held by bilateral rows (redundant, as
    ``moreau.run.trust.redundancy_warnings`` says), not in Painlevé's case.
    ``L`` = chol(M); ``U_T`` (k,) the post-step slip velocities."""
    from moreau.core.kernels import cho_solve

    out = []
    n = L.shape[0]
    x = np.empty(n)
    for j in np.flatnonzero(muA > 0.0):
        edge = abs(PT[j]) >= (1.0 - 1e-9) * muA[j] * PN[j]
        if not edge or (PN[j] == 0.0 and U_T[j] == 0.0):
            continue
        s = -np.sign(PT[j]) if PN[j] > 0.0 else np.sign(U_T[j])
        cho_solve(L, np.ascontiguousarray(GA[j], dtype=float), x, n)
        wnn, wnt = float(GA[j] @ x), float(TA[j] @ x)
        cho_solve(L, np.ascontiguousarray(TA[j], dtype=float), x, n)
        # W_NN at round-off of W_TT: a row the bilateral rows hold (redundant), not Painlevé's case
        if wnn - muA[j] * s * wnt <= PAINLEVE_MARGIN * wnn and wnn > 1e-9 * float(TA[j] @ x):
            out.append(int(j))
    return np.array(out, dtype=np.int64)


def painleve_message(t: float, step: int | None, rows: list[str], mu: list[float]) -> str:
    """The warning of a run that met Painlevé's region (``step`` None: a run with
    step-size control, whose loop steps are not numbered by time)."""
    at = f"at t = {t:.9g}" + ("" if step is None else f" (step {step})")
    return (f"Painlevé's paradox: {at} the sliding contact(s) {rows} (mu = {mu}) have a "
            "non-positive or vanishing (below 1 % of its frictionless value) effective normal inverse mass: the "
            "normal force the slip needs grows without bound, the one-step problem can have several solutions "
            "(lift-off, sliding, a tangential impact) or none, and the motion from here on depends on the step "
            "size; compare step sizes")
