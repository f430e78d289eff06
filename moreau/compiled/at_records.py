"""Quantities a trajectory reports at its records, evaluated over all records in one
compiled call (not record by record in Python): the slip velocities of a run with friction."""

from __future__ import annotations

from numba import njit

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import SC_M, SC_N
from moreau.core import kernels as _k


@njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]  # numba's internal flag
def slip_velocities(ints, bkind, boff, brow, bnrows, pool, user, tangent_row, Q, V, c, s, G, out):
    """The slip velocities ``T(q_i) v_i`` of records ``Q, V`` (N, n) into ``out`` (N, m):
    row r's from the Jacobian row ``tangent_row[r]`` of ``G`` (m + mf + me, n, work), 0 for a
    row without friction; ``c, s`` (n,) work. Returns 0, or a user callable's status."""
    n, m = ints[SC_N], ints[SC_M]
    for i in range(Q.shape[0]):
        q = Q[i]
        _k.trig(q, c, s)
        st = ev.jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, G)
        if st != 0:
            return st
        for r in range(m):
            tr = tangent_row[r]
            acc = 0.0
            if tr >= 0:
                for j in range(n):
                    acc += G[tr, j] * V[i, j]
            out[i, r] = acc
    return 0
