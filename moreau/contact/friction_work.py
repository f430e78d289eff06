"""The work arrays of the friction solve (:func:`moreau.contact.friction.solve_friction_step`),
allocated once per run, by name."""

from __future__ import annotations

from collections import namedtuple

import numpy as np

__all__ = ["FrictionWorkspace", "friction_workspace"]

#: friction's work arrays (:func:`friction_workspace`; r = m + mf rows, p = m + 3 mf LCP
#: variables): M⁻¹ Gᵀ by rows, M⁻¹ b, W and w; Lemke's matrix, q, z, tableau, basis and
#: basic values; M⁻¹ Gᵀ by columns; the KKT check's (Gv, GtP, rv, d, x, X, rd); the best
#: answer kept (cand (6,), its residuals rb (6,), Pb, vb); the relaxation's U, Q, states,
#: signs, rows, active block AA and its factor Lr, rr, xr, tangent rows tf and impulses Pp
FrictionWorkspace = namedtuple("FrictionWorkspace", "MinvGt vfree W w A qv z T basis xb Xt Gv GtP rv d x cand rb Pb "
                                                    "vb X rd U Q states signs rows AA Lr rr xr tf Pp")


def friction_workspace(n: int, m: int, mf: int) -> FrictionWorkspace:
    """Work arrays for up to m normal and mf tangential rows on n coordinates (numpy:
    allocating compiles nothing)."""
    r = max(m + mf, 1)
    p = max(m + 3 * mf, 1)
    return FrictionWorkspace(
        np.empty((r, n)), np.empty(n), np.empty((r, r)), np.empty(r), np.zeros((p, p)), np.empty(p),
        np.empty(p), np.empty((p, 2 * p + 2)), np.empty(p, dtype=np.int64), np.empty(p), np.empty((n, r)),
        np.empty(r), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(6),
        np.empty(6), np.empty(r), np.empty(n), np.empty((n, n)), np.zeros(n + 1),
        np.empty(r), np.empty(r), np.zeros(max(m, 1), dtype=np.int64), np.zeros(r), np.empty(r, dtype=np.int64),
        np.empty((r, r)), np.empty((r, r)), np.empty(r), np.empty(r), np.empty(max(m, 1), dtype=np.int64),
        np.empty(r))
