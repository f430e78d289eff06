"""Quantities a trajectory reports at its records, evaluated over all records in one
compiled call (not record by record in Python): the slip velocities of a run with friction."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from numba import njit

from moreau.compiled import evaluate as ev
from moreau.compiled.layout import SC_M, SC_ME, SC_MF, SC_N
from moreau.compiled.usercalls import decode
from moreau.core import kernels as _k
from moreau.core.jitcache import call_recovering

log = logging.getLogger("moreau.compiled.runner")


def slips(cs: Any, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
    """The slip velocities T(q) v at the records ``Q, V`` (N, n) of the lowered scene ``cs``
    (N, m), in one compiled pass; NaN and a logged warning when a user callable fails there
    (the trajectory is kept)."""
    n, m, mf, me = (int(cs.ints[i]) for i in (SC_N, SC_M, SC_MF, SC_ME))
    Q, V = np.ascontiguousarray(Q), np.ascontiguousarray(V)
    out = np.zeros((Q.shape[0], m))
    st = call_recovering(slip_velocities, cs.ints, cs.bkind, cs.boff, cs.brow, cs.bnrows, cs.pool, cs.user.addresses,
                         cs.tangent_row, Q, V, np.zeros(n), np.zeros(n), np.zeros((m + mf + me, n)), out)
    if st != 0:
        slot, index, what = decode(int(st))
        log.warning("could not evaluate the slip velocities on the recorded states: %s callable %d %s",
                    slot, index, what)
        out[:] = np.nan
    return out


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
