"""User callables in the compiled loop: one fixed C signature, called through an address.

The compiled time loop (:mod:`moreau.compiled.loop`) is compiled once per machine and version and
loaded from numba's cache by every scene. A scene's own callables (the mass matrix and bias
of a :class:`~moreau.FunctionSystem`, :class:`~moreau.FunctionForce`,
:class:`~moreau.FunctionBarrier`, ``@numba.njit`` or plain) do not specialize that loop:
each *slot* (mass, bias, forces, gaps, Jacobians) becomes one small C function (a numba
``cfunc``) of the signature ``SIGNATURE``, compiled for the scene alone (well under a
second per slot), and the loop calls it through its address with ``call_user``. Plain
functions are compiled by numba as they are; a slot with a callable numba cannot compile is
a C callback into Python instead (:mod:`moreau.compiled.callbacks`). An address of 0 means
the slot is empty (a built-in scene has five zeros).

Each wrapper checks what the user's function returns, every call: the shape (a wrong length
is never written past a buffer), finiteness, and an exception raised inside the function. It
returns 0, or a code that names the callable and what went wrong (:func:`decode`); the loop
stops the run with that code and the driver turns it into a
:class:`~moreau.SimulationError`. In C::

    int64 slot(double t, double *q, double *v, double *out, int64 n, int64 m)

``q``, ``v``: the state (n,); ``out``: M (n x n, written), f (n, added to), g (m,) or
G (m x n, rows of the slot's barriers written).
"""

from __future__ import annotations

import logging
import math
import re
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]
from numba import carray, cfunc, njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from moreau.compiled.callbacks import (
    INTERRUPTED,
    NONFINITE,
    RAISED,
    WRONG_SHAPE,
    SlotCallback,
    compile_or_reason,
    fingerprint,
    first_reason,
)

__all__ = ["SIGNATURE", "U_MASS", "U_BIAS", "U_FORCES", "U_GAPS", "U_JACOBIANS", "SLOTS", "UserKernels",
           "call_solver", "call_user", "user_kernels", "decode"]

#: the slots of the ``user`` address array
U_MASS, U_BIAS, U_FORCES, U_GAPS, U_JACOBIANS = range(5)
SLOTS = ("mass", "bias", "forces", "gaps", "jacobians")
#: what a slot's callables are, in messages
SLOT_WORDS = {"mass": "mass matrix", "bias": "bias", "forces": "force", "gaps": "gap function",
              "jacobians": "Jacobian"}
#: what a wrapper reports (the low 3 bits of its code, from moreau.compiled.callbacks; the
#: callable's index above them)
_KINDS = {RAISED: "raised an exception", WRONG_SHAPE: "returned an array of the wrong shape",
          NONFINITE: "is non-finite", INTERRUPTED: "was interrupted"}

log = logging.getLogger("moreau.run.simulation")

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


def _call_solver(typingctx, addr, M, b, G, c, v, P, n, k):
    """Call a one-step solver at address ``addr`` (:class:`moreau.compiled.callbacks.SolverCallback`)
    on the data of ``M`` (n, n), ``b`` (n,), the first k rows of ``G`` (rows of length n), ``c``;
    it writes ``v`` (n,) and ``P`` (k,) and returns 0 when it solved."""
    sig = types.int64(types.int64, M, b, G, c, v, P, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        dp = ir.DoubleType().as_pointer()
        i64 = ir.IntType(64)
        fn = builder.inttoptr(args[0], ir.FunctionType(i64, [dp] * 6 + [i64, i64]).as_pointer())
        ptrs = [builder.bitcast(context.make_array(ty)(context, builder, val).data, dp)
                for ty, val in zip(signature.args[1:7], args[1:7])]
        return builder.call(fn, ptrs + [args[7], args[8]])

    return sig, codegen


#: ``call_solver(addr, M, b, G, c, v, P, n, k) -> int64`` in compiled code
call_solver: Any = intrinsic(_call_solver)


def _guarded(typingctx, fn, args):
    """``(ok, value)`` of the ``@njit`` function ``fn`` called on the tuple ``args``; ``ok``
    is False when it raised (the exception is not propagated: no ``try`` block to compile)."""
    if not isinstance(fn, types.Dispatcher) or not isinstance(args, (types.Tuple, types.UniTuple)):
        return None
    target = typingctx.resolve_function_type(fn, tuple(args.types), {})
    if target is None:
        return None
    cres = fn.dispatcher.overloads.get(tuple(target.args))
    if cres is None or cres.objectmode:  # a slot numba cannot build: the callable is called back
        return None

    def codegen(context, builder, signature, llargs):
        vals = cgutils.unpack_tuple(builder, llargs[1])
        # parameters left to their defaults (numba's Omitted types)
        vals += [context.get_constant_generic(builder, ty, ty.value) for ty in target.args[len(vals):]]
        context.add_linking_libs([cres.library])
        func = context.declare_function(builder.module, cres.fndesc)
        status, value = context.call_conv.call_function(builder, func, cres.fndesc.restype,
                                                        cres.fndesc.argtypes, vals)
        return context.make_tuple(builder, signature.return_type, [status.is_ok, value])

    return types.Tuple((types.boolean, target.return_type))(fn, args), codegen


#: ``guarded(fn, args) -> (ok, value)`` in compiled code
guarded: Any = intrinsic(_guarded)


@njit(cache=True, nogil=True)
def _put_vector(r: Any, dst: np.ndarray) -> int:
    """Write a callable's result ``r`` (k,) to ``dst`` (k,); 0, or the code of a wrong shape
    or a non-finite entry. ``r`` may be a tuple of k numbers, as the checks take it."""
    if len(r) != dst.shape[0]:
        return WRONG_SHAPE
    for j in range(dst.shape[0]):
        if not math.isfinite(r[j]):
            return NONFINITE
        dst[j] = r[j]
    return 0


@njit(cache=True, nogil=True)
def _add_vector(r: Any, dst: np.ndarray) -> int:
    """Add a callable's result ``r`` (n,) to ``dst`` (n,); codes as :func:`_put_vector`."""
    if len(r) != dst.shape[0]:
        return WRONG_SHAPE
    for j in range(dst.shape[0]):
        if not math.isfinite(r[j]):
            return NONFINITE
        dst[j] += r[j]
    return 0


@njit(cache=True, nogil=True)
def _put_matrix(r: np.ndarray, dst: np.ndarray) -> int:
    """Write a callable's result ``r`` (k, n) to ``dst`` (k, n); codes as :func:`_put_vector`."""
    if r.shape[0] != dst.shape[0] or r.shape[1] != dst.shape[1]:
        return WRONG_SHAPE
    for j in range(dst.shape[0]):
        for i in range(dst.shape[1]):
            if not math.isfinite(r[j, i]):
                return NONFINITE
            dst[j, i] = r[j, i]
    return 0


@njit(cache=True, nogil=True)
def _put_rows(r: Any, dst: np.ndarray) -> int:
    """As :func:`_put_matrix`, for a result given row by row (a list or tuple of rows)."""
    if len(r) != dst.shape[0]:
        return WRONG_SHAPE
    for j in range(dst.shape[0]):
        row = r[j]
        if len(row) != dst.shape[1]:
            return WRONG_SHAPE
        for i in range(dst.shape[1]):
            if not math.isfinite(row[i]):
                return NONFINITE
            dst[j, i] = row[i]
    return 0


# -- the wrappers' source: one call of each callable, its result checked and put --------
_HEAD = """
def slot(t, qp, vp, outp, n, m):
    q = carray(qp, (n,))
    v = carray(vp, (n,))
    out = carray(outp, {shape})
"""
_CALL = """
    ok, r = guarded({fn}, ({args},))
    if not ok:
        return {code} + RAISED
    c = {put}
    if c != 0:
        return {code} + c
"""
#: per slot: the shape of ``out``, the arguments, the helper that puts a result and where
#: (a callable's rows as a slice: constants passed to the helpers would compile them again
#: for each value); a matrix given as a list or tuple of rows is put by ``put_rows``
_SLOTS = {"mass": ("(n, n)", "q", "put_matrix", "out"),
          "bias": ("(n,)", "q, v", "add_vector", "out"),
          "forces": ("(n,)", "t, q, v", "add_vector", "out"),
          "gaps": ("(m,)", "q", "put_vector", "out[{r0}:{r1}]"),
          "jacobians": ("(m, n)", "q", "put_matrix", "out[{r0}:{r1}]")}


def _source(slot: str, fns: tuple, rows: tuple[int, ...], nrows: tuple[int, ...]) -> str:
    shape, args, helper, target = _SLOTS[slot]
    src = _HEAD.format(shape=shape)
    for i, f in enumerate(fns):
        if f is None:  # tangent rows: no gaps
            continue
        at = {"r0": rows[i], "r1": rows[i] + nrows[i]} if rows else {}
        rowwise = helper == "put_matrix" and any(isinstance(rt, _SEQUENCE) for rt in _returns(slot, f))
        put = f"{'put_rows' if rowwise else helper}(r, {target.format(**at)})"
        src += _CALL.format(fn=f"f{i}", args=args, code=8 * (i + 1), put=put)
    return src + "    return 0\n"


def _compile(slot: str, fns: tuple, rows: tuple[int, ...] = (), nrows: tuple[int, ...] = ()) -> Any:
    names = {"carray": carray, "guarded": guarded, "put_vector": _put_vector, "add_vector": _add_vector,
             "put_matrix": _put_matrix, "put_rows": _put_rows, "RAISED": RAISED}
    names.update({f"f{i}": f for i, f in enumerate(fns)})
    exec(_source(slot, fns, rows, nrows), names)  # noqa: S102 - our own template
    return cfunc(SIGNATURE)(names["slot"])


_ARRAY = types.Array(types.float64, 1, "C")
#: the arguments each slot's callables are called with
_ARGTYPES = {"mass": (_ARRAY,), "bias": (_ARRAY, _ARRAY), "forces": (types.float64, _ARRAY, _ARRAY),
             "gaps": (_ARRAY,), "jacobians": (_ARRAY,)}


#: what numba types a list or a tuple of one item type as, and real numbers as
_SEQUENCE = (types.List, types.UniTuple)
_REAL = (types.Float, types.Integer)


def _returns(slot: str, jit: Any) -> list:
    """numba's return types of a compiled callable for its slot's arguments."""
    argtypes = _ARGTYPES[slot]
    return [cres.signature.return_type for sig, cres in jit.overloads.items() if tuple(sig[:len(argtypes)]) == argtypes]


def _returned(slot: str, jit: Any) -> str:
    """Why the slot cannot take what a compiled callable returns (a vector slot takes an
    array, a tuple or a list of numbers; a matrix slot an array of rank 2 or its rows as a
    list or tuple, not a 1-D Jacobian), naming numba's type of it; "" when it can."""
    matrix = _SLOTS[slot][2] == "put_matrix"
    for rt in _returns(slot, jit):
        if isinstance(rt, types.Array) and rt.ndim == (2 if matrix else 1) and isinstance(rt.dtype, _REAL):
            continue
        if isinstance(rt, _SEQUENCE) and (matrix or isinstance(rt.dtype, _REAL)):
            continue
        shown = re.sub(r"<iv=[^>]*>", "", str(rt))  # (numba's initial values of a list: noise here)
        return f"it returns {shown}, and the loop takes an array of shape {_SLOTS[slot][0]}"
    return ""


def _slot(slot: str, fns: tuple, names: tuple[str, ...], rows: tuple[int, ...] = (),
          nrows: tuple[int, ...] = ()) -> Any:
    """The slot's wrapper: one ``cfunc`` when numba compiles every callable in it (plain
    functions are compiled as they are), else a :class:`SlotCallback` (logged, one line per
    callable, with numba's reason)."""
    from numba.core.errors import NumbaError

    jitted, reasons = [], []
    for f in fns:
        jit, why = (None, "") if f is None else compile_or_reason(f, _ARGTYPES[slot])
        jitted.append(jit)
        reasons.append(why)
    if all(f is None or j is not None for f, j in zip(fns, jitted)):
        try:
            return _compile(slot, tuple(jitted), rows, nrows)
        except NumbaError as exc:  # the callables compile, the slot does not (e.g. a list returned)
            reasons = [(_returned(slot, j) or first_reason(exc)) if f is not None else "" for f, j in zip(fns, jitted)]
    for name, f, why in zip(names, fns, reasons):
        if f is not None:
            log.warning("user %s %r runs as a Python callback in the compiled loop, several µs a call; "
                        "numba could not compile it: %s", SLOT_WORDS[slot], name, why or "another callable of its slot")
    return SlotCallback(slot, fns, rows, nrows)


@dataclass(frozen=True)
class UserKernels:
    """A scene's user slots: ``addresses`` (5,) int64 for the loop, and the compiled
    wrappers (or callbacks) kept alive with them."""

    addresses: np.ndarray
    wrappers: tuple

    @property
    def callbacks(self) -> tuple[SlotCallback, ...]:
        """The slots that call back into Python."""
        return tuple(w for w in self.wrappers if isinstance(w, SlotCallback))


_lock = threading.Lock()
#: fingerprints -> (the slots, the callables they were built from)
_memo: dict[tuple, tuple[UserKernels, tuple]] = {}


def user_kernels(mass: Any, bias: Any, forces: tuple, barriers: tuple, rows: tuple[int, ...],
                 nrows: tuple[int, ...], names: dict[str, tuple[str, ...]] | None = None) -> UserKernels:
    """The slot wrappers of a scene's callables (built once per process for each
    combination and each value of what a plain callable reads: a scene simulated again
    reuses them).

    Parameters
    ----------
    mass, bias : callable or None
        ``M(q) -> (n, n)`` and ``b(q, v) -> (n,)``.
    forces : tuple of callables
        Each ``f(t, q, v) -> (n,)``, added.
    barriers : tuple of (gap, jacobian) pairs
        ``g(q) -> (k,)``, ``G(q) -> (k, n)`` written at rows ``rows[i]`` ... ``+ nrows[i]``;
        a gap of None (tangent rows) is not evaluated.
    names : dict, optional
        Per slot, the callables' names for the log.
    """
    names = names or {}
    key = (fingerprint(mass), fingerprint(bias), tuple(map(fingerprint, forces)),
           tuple((fingerprint(g), fingerprint(j)) for g, j in barriers), rows, nrows)
    fns = (mass, bias, forces, barriers)
    with _lock:
        got, built_from = _memo.get(key, (None, None))
        # compiled slots serve every function of the same code and values; a callback calls
        # the very functions it was built from
        if got is not None and (not got.callbacks or _same_functions(built_from, fns)):
            return got

        def label(slot: str, count: int) -> tuple[str, ...]:  # the names given, else "gaps[0]", ...
            return tuple(names.get(slot, ())) + tuple(f"{slot}[{i}]" for i in range(len(names.get(slot, ())), count))

        wrappers: list[Any] = [None] * 5
        if mass is not None:
            wrappers[U_MASS] = _slot("mass", (mass,), label("mass", 1))
        if bias is not None:
            wrappers[U_BIAS] = _slot("bias", (bias,), label("bias", 1))
        if forces:
            wrappers[U_FORCES] = _slot("forces", forces, label("forces", len(forces)))
        if barriers:
            wrappers[U_GAPS] = _slot("gaps", tuple(b[0] for b in barriers), label("gaps", len(barriers)), rows, nrows)
            wrappers[U_JACOBIANS] = _slot("jacobians", tuple(b[1] for b in barriers),
                                          label("jacobians", len(barriers)), rows, nrows)
        addresses = np.array([0 if w is None else w.address for w in wrappers], dtype=np.int64)
        got = UserKernels(addresses, tuple(wrappers))
        _memo[key] = (got, fns)
        return got


def _same_functions(a: Any, b: Any) -> bool:
    """Whether two nests of tuples hold the very same callables, place by place."""
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same_functions(x, y) for x, y in zip(a, b))
    return a is b


def decode(status: int) -> tuple[str, int, str]:
    """``(slot name, index of the callable in its slot, what went wrong)`` of a loop's
    user status (``code * 8 + slot``, see :mod:`moreau.compiled.evaluate`)."""
    slot, code = status % 8, status // 8
    return SLOTS[slot], code // 8 - 1, _KINDS.get(code % 8, f"failed (code {code})")
