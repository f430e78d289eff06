"""User callables in the compiled loop: one fixed C signature, called through an address.

The compiled time loop (:mod:`moreau.compiled.loop`) is compiled once per machine and version and
loaded from numba's cache by every scene. A scene's own ``@numba.njit`` callables (the
mass matrix and bias of a :class:`~moreau.FunctionSystem`, :class:`~moreau.FunctionForce`,
:class:`~moreau.FunctionBarrier`) do not specialize that loop: each *slot* (mass, bias,
forces, gaps, Jacobians) becomes one small C function (a numba ``cfunc``) of the
signature ``SIGNATURE``, compiled for the scene alone (well under a second per slot),
and the loop calls it through its address with ``call_user``. An address of 0 means
the slot is empty (a built-in scene has five zeros).

Each wrapper checks what the user's function returns, every call, as the Python path
does: the shape (a wrong length is never written past a buffer), finiteness, and an
exception raised inside the function. It returns 0, or a code that names the callable
and what went wrong (:func:`decode`); the loop stops the run with that code and the
driver turns it into a :class:`~moreau.SimulationError`. In C::

    int64 slot(double t, double *q, double *v, double *out, int64 n, int64 m)

``q``, ``v``: the state (n,); ``out``: M (n x n, written), f (n, added to), g (m,) or
G (m x n, rows of the slot's barriers written).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]
from numba import carray, cfunc, types
from numba.extending import intrinsic

__all__ = ["SIGNATURE", "U_MASS", "U_BIAS", "U_FORCES", "U_GAPS", "U_JACOBIANS", "SLOTS", "UserKernels",
           "call_user", "user_kernels", "decode"]

#: the slots of the ``user`` address array
U_MASS, U_BIAS, U_FORCES, U_GAPS, U_JACOBIANS = range(5)
SLOTS = ("mass", "bias", "forces", "gaps", "jacobians")
#: what a wrapper reports (the low 3 bits of its code; the callable's index above them)
RAISED, WRONG_SHAPE, NONFINITE = 1, 2, 3
_KINDS = {RAISED: "raised an exception", WRONG_SHAPE: "returned an array of the wrong shape",
          NONFINITE: "returned a non-finite value"}

_P = types.CPointer(types.float64)
#: the C signature of every slot
SIGNATURE = types.int64(types.float64, _P, _P, _P, types.int64, types.int64)


def _call_user(typingctx, addr, t, q, v, out, n, m):
    """Call the slot function at address ``addr`` on the data of arrays ``q, v, out``
    (C-contiguous float64); returns its int64 code."""
    sig = types.int64(types.int64, types.float64, q, v, out, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        a, tt, qa, va, oa, nn, mm = args
        dp = ir.DoubleType().as_pointer()
        i64 = ir.IntType(64)
        fn = builder.inttoptr(a, ir.FunctionType(i64, [ir.DoubleType(), dp, dp, dp, i64, i64]).as_pointer())

        def data(ty, val):
            return builder.bitcast(context.make_array(ty)(context, builder, val).data, dp)

        return builder.call(fn, [tt, data(signature.args[2], qa), data(signature.args[3], va),
                                 data(signature.args[4], oa), nn, mm])

    return sig, codegen


#: ``call_user(addr, t, q, v, out, n, m) -> int64`` in compiled code
call_user: Any = intrinsic(_call_user)


# -- the wrappers' source, one template per slot ------------------------------------------
_HEAD = """
def slot(t, qp, vp, outp, n, m):
    q = carray(qp, (n,))
    v = carray(vp, (n,))
"""
_CALL = """
    try:
        r = {fn}({args})
    except Exception:
        return {code} + RAISED
"""
_BODY = {
    "mass": _HEAD + "    out = carray(outp, (n, n))\n" + _CALL.format(fn="f0", args="q", code=8) + """
    if r.shape[0] != n or r.shape[1] != n:
        return 8 + WRONG_SHAPE
    for i in range(n):
        for j in range(n):
            x = r[i, j]
            if not isfinite(x):
                return 8 + NONFINITE
            out[i, j] = x
    return 0
""",
    "bias": _HEAD + "    out = carray(outp, (n,))\n" + _CALL.format(fn="f0", args="q, v", code=8) + """
    if r.shape[0] != n:
        return 8 + WRONG_SHAPE
    for i in range(n):
        x = r[i]
        if not isfinite(x):
            return 8 + NONFINITE
        out[i] += x
    return 0
""",
}
_FORCE = _CALL + """
    if r.shape[0] != n:
        return {code} + WRONG_SHAPE
    for i in range(n):
        x = r[i]
        if not isfinite(x):
            return {code} + NONFINITE
        out[i] += x
"""
_GAP = _CALL + """
    if r.shape[0] != {k}:
        return {code} + WRONG_SHAPE
    for j in range({k}):
        x = r[j]
        if not isfinite(x):
            return {code} + NONFINITE
        out[{r0} + j] = x
"""
_JAC = _CALL + """
    if r.shape[0] != {k} or r.shape[1] != n:
        return {code} + WRONG_SHAPE
    for j in range({k}):
        for i in range(n):
            x = r[j, i]
            if not isfinite(x):
                return {code} + NONFINITE
            out[{r0} + j, i] = x
"""


def _source(slot: str, count: int, rows: tuple[int, ...], nrows: tuple[int, ...]) -> str:
    if slot in _BODY:
        return _BODY[slot]
    if slot == "forces":
        src = _HEAD + "    out = carray(outp, (n,))\n"
        for i in range(count):
            src += _FORCE.format(fn=f"f{i}", args="t, q, v", code=8 * (i + 1))
    else:
        src = _HEAD + ("    out = carray(outp, (m,))\n" if slot == "gaps" else "    out = carray(outp, (m, n))\n")
        for i in range(count):
            src += (_GAP if slot == "gaps" else _JAC).format(fn=f"f{i}", args="q", code=8 * (i + 1),
                                                             k=nrows[i], r0=rows[i])
    return src + "    return 0\n"


def _compile(slot: str, fns: tuple, rows: tuple[int, ...] = (), nrows: tuple[int, ...] = ()) -> Any:
    names = {"carray": carray, "isfinite": math.isfinite, "RAISED": RAISED, "WRONG_SHAPE": WRONG_SHAPE,
             "NONFINITE": NONFINITE}
    names.update({f"f{i}": f for i, f in enumerate(fns)})
    exec(_source(slot, len(fns), rows, nrows), names)  # noqa: S102 - our own template
    return cfunc(SIGNATURE)(names["slot"])


@dataclass(frozen=True)
class UserKernels:
    """A scene's user slots: ``addresses`` (5,) int64 for the loop, and the compiled
    wrappers kept alive with them."""

    addresses: np.ndarray
    wrappers: tuple


_lock = threading.Lock()
_memo: dict[tuple, UserKernels] = {}


def user_kernels(mass: Any, bias: Any, forces: tuple, barriers: tuple, rows: tuple[int, ...],
                 nrows: tuple[int, ...]) -> UserKernels:
    """The slot wrappers of a scene's ``@njit`` callables (compiled once per process for
    each combination: a scene simulated again reuses them).

    Parameters
    ----------
    mass, bias : numba dispatcher or None
        ``M(q) -> (n, n)`` and ``b(q, v) -> (n,)``.
    forces : tuple of dispatchers
        Each ``f(t, q, v) -> (n,)``, added.
    barriers : tuple of (gap, jacobian) pairs
        ``g(q) -> (k,)``, ``G(q) -> (k, n)`` written at rows ``rows[i]`` ... ``+ nrows[i]``.
    """
    key = (mass, bias, forces, barriers, rows, nrows)
    with _lock:
        got = _memo.get(key)
        if got is not None:
            return got
        wrappers: list[Any] = [None] * 5
        if mass is not None:
            wrappers[U_MASS] = _compile("mass", (mass,))
        if bias is not None:
            wrappers[U_BIAS] = _compile("bias", (bias,))
        if forces:
            wrappers[U_FORCES] = _compile("forces", forces)
        if barriers:
            wrappers[U_GAPS] = _compile("gaps", tuple(b[0] for b in barriers), rows, nrows)
            wrappers[U_JACOBIANS] = _compile("jacobians", tuple(b[1] for b in barriers), rows, nrows)
        addresses = np.array([0 if w is None else w.address for w in wrappers], dtype=np.int64)
        got = UserKernels(addresses, tuple(wrappers))
        _memo[key] = got
        return got


def decode(status: int) -> tuple[str, int, str]:
    """``(slot name, index of the callable in its slot, what went wrong)`` of a loop's
    user status (``code * 8 + slot``, see :mod:`moreau.compiled.evaluate`)."""
    slot, code = status % 8, status // 8
    return SLOTS[slot], code // 8 - 1, _KINDS.get(code % 8, f"failed (code {code})")
