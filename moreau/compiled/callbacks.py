"""Plain Python callables in the compiled loop: compiled by numba when it can, else called back.

A scene's callables (a :class:`~moreau.FunctionSystem`'s mass and bias, a
:class:`~moreau.FunctionForce`, a :class:`~moreau.FunctionBarrier`'s gaps and Jacobians, or the
Python methods of a system, effect or barrier with no kernel) fill the slots of
:mod:`moreau.compiled.usercalls`. A slot is one numba ``cfunc`` when numba compiles every
callable in it (the README's numpy lambdas do, as they are); otherwise it is a C callback into
the interpreter (:class:`SlotCallback`, a ``ctypes.CFUNCTYPE`` of the slot signature), which the
loop calls through its address like any other slot. A callback costs a few µs a call
against well under one for compiled code; :func:`compile_or_reason` says why numba refused.

numba freezes the globals and closure variables a function reads when it compiles it; a
compiled plain callable is therefore kept per *value* of those variables
(:func:`fingerprint`): change one and the next run compiles it again.
"""

from __future__ import annotations

import ctypes
import hashlib
import math
import re
import types as pytypes
import warnings
from typing import Any

import numpy as np

from moreau.contact.base import ContactSolver, SolveFailed

__all__ = ["SlotCallback", "SolverCallback", "compile_or_reason", "fingerprint", "first_reason", "is_dispatcher"]

#: codes a slot returns (the low 3 bits; the callable's index above them), as usercalls'
RAISED, WRONG_SHAPE, NONFINITE, INTERRUPTED = 1, 2, 3, 4

_CFUNC = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                          ctypes.c_int64, ctypes.c_int64)


def is_dispatcher(fun: Any) -> bool:
    """True for a numba ``@njit`` dispatcher (callable from compiled code)."""
    from numba.core.registry import CPUDispatcher

    return isinstance(fun, CPUDispatcher)


class _Same:
    """A key equal only to one for the same object; it holds the object, so that its id
    cannot pass to another while the key lives."""

    __slots__ = ("obj",)

    def __init__(self, obj: Any) -> None:
        self.obj = obj

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Same) and other.obj is self.obj

    def __hash__(self) -> int:
        return id(self.obj)


def _value_key(x: Any) -> Any:
    """A hashable stand-in for the value of a global or closure variable."""
    if isinstance(x, (float, complex)):  # repr: -0.0 is not 0.0 to a compiled function
        return (type(x).__name__, repr(x))
    if isinstance(x, (bool, int, str, bytes, type(None))):
        return (type(x).__name__, x)
    if isinstance(x, np.ndarray) and x.size <= 1 << 16:
        return ("ndarray", x.shape, x.dtype.str, hashlib.sha1(np.ascontiguousarray(x).tobytes()).hexdigest())
    if isinstance(x, np.generic):
        return ("scalar", x.dtype.str, x.tobytes())
    if isinstance(x, tuple) and len(x) <= 64:
        return ("tuple",) + tuple(_value_key(y) for y in x)
    return _Same(x)


def fingerprint(fun: Any) -> Any:
    """The key of a callable's compiled form: the function's code, its module and defaults,
    and the values of the globals and closure variables it reads (what numba freezes), or
    the object itself. A function made again with the same values (a scene built again)
    has the same key: its compiled form is reused."""
    if not isinstance(fun, pytypes.FunctionType):
        return fun
    cells = tuple(_value_key(c.cell_contents) for c in (fun.__closure__ or ()))
    names = tuple((nm, _value_key(fun.__globals__[nm])) for nm in fun.__code__.co_names if nm in fun.__globals__)
    return (fun.__code__, _Same(fun.__globals__), _value_key(fun.__defaults__),
            _value_key(tuple(sorted((fun.__kwdefaults__ or {}).items()))), cells, names)


def compile_or_reason(fun: Any, argtypes: tuple) -> tuple[Any, str]:
    """``(dispatcher, "")`` when numba compiles ``fun`` for ``argtypes``, else ``(None,
    reason)``: the first line of numba's message (or of the exception)."""
    import numba
    from numba.core.errors import NumbaWarning

    if is_dispatcher(fun):
        jit = fun
    elif isinstance(fun, pytypes.FunctionType):  # called from its slot's wrapper only: no Python entry to build
        jit = numba.njit(fun, no_cpython_wrapper=True, no_cfunc_wrapper=True)  # type: ignore[call-overload]
    else:
        return None, f"a {type(fun).__name__}, not a plain function"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=NumbaWarning)
            jit.compile(tuple(argtypes) + _defaults(jit.py_func, len(argtypes)))
    except Exception as exc:  # noqa: BLE001 - any failure means: call it back
        return None, first_reason(exc)
    return jit, ""


def _defaults(fun: Any, given: int) -> tuple:
    """numba's types of the defaults of ``fun``'s parameters after the first ``given``
    (``lambda q, n=n: ...``: the loop calls it with q alone, numba takes n as a constant,
    as it takes a closure variable); () when there are none to fill."""
    from numba import types

    defaults = fun.__defaults__ or ()
    missing = fun.__code__.co_argcount - given
    if missing <= 0 or missing > len(defaults):
        return ()
    return tuple(types.Omitted(d) for d in defaults[len(defaults) - missing:])


def first_reason(exc: BaseException) -> str:
    """The line of numba's message that says why (its colour codes and the pipeline's
    heading dropped), at most 200 characters."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("Failed in ")]
    return (lines[0] if lines else type(exc).__name__)[:200]


class SlotCallback:
    """One slot as a C callback into Python: ``address`` for the loop, the callables in
    order, the rows of a gap or Jacobian slot's barriers.

    ``interrupted`` is set when a Ctrl-C (or SIGTERM as an interrupt) arrived during a
    call: the loop then stops with the code ``INTERRUPTED`` and the runner raises it.
    """

    def __init__(self, slot: str, fns: tuple, rows: tuple[int, ...] = (), nrows: tuple[int, ...] = ()) -> None:
        self.slot, self.fns, self.rows, self.nrows = slot, fns, rows, nrows
        self.interrupted = False
        #: the exception the last failing call raised (named in the run's error)
        self.error: BaseException | None = None
        self._views: dict[tuple[int, int], np.ndarray] = {}
        self._c = _CFUNC(self._call)  # kept alive with the slot: the loop holds only its address
        self.address = int(ctypes.cast(self._c, ctypes.c_void_p).value or 0)

    def _view(self, ptr: int, size: int) -> np.ndarray:
        """The loop's array at ``ptr`` as numpy (views kept per address: the loop's work
        arrays live through a run)."""
        key = (ptr, size)
        a = self._views.get(key)
        if a is None:
            if len(self._views) > 64:
                self._views.clear()
            a = np.ctypeslib.as_array((ctypes.c_double * max(size, 1)).from_address(ptr))[:size]
            self._views[key] = a
        return a

    def _call(self, t: float, qp: int, vp: int, outp: int, n: int, m: int) -> int:
        try:
            return self._run(t, qp, vp, outp, n, m)
        except KeyboardInterrupt:
            self.interrupted = True
            return 8 + INTERRUPTED
        except BaseException:  # noqa: BLE001 - a callback must not raise into C
            return 8 + RAISED

    def _run(self, t: float, qp: int, vp: int, outp: int, n: int, m: int) -> int:
        q = self._view(qp, n).copy()  # the user may keep what it is given
        slot = self.slot
        if slot == "mass":
            return self._put(self.fns[0], (q,), self._view(outp, n * n), (n, n), 8, False)
        if slot == "bias":
            return self._put(self.fns[0], (q, self._view(vp, n).copy()), self._view(outp, n), (n,), 8, True)
        if slot == "forces":
            v, out = self._view(vp, n).copy(), self._view(outp, n)
            for i, f in enumerate(self.fns):
                st = self._put(f, (t, q, v), out, (n,), 8 * (i + 1), True)
                if st:
                    return st
            return 0
        out = self._view(outp, m if slot == "gaps" else m * n)
        for i, f in enumerate(self.fns):
            if f is None:  # tangent rows have no gaps
                continue
            r0, k = self.rows[i], self.nrows[i]
            part = out[r0:r0 + k] if slot == "gaps" else out[r0 * n:(r0 + k) * n]
            st = self._put(f, (q,), part, (k,) if slot == "gaps" else (k, n), 8 * (i + 1), False)
            if st:
                return st
        return 0

    def _put(self, f: Any, args: tuple, out: np.ndarray, shape: tuple[int, ...], code: int, add: bool) -> int:
        """Call ``f(*args)`` and write (or add) its result of ``shape`` into the flat ``out``;
        0, or ``code`` plus what went wrong (an exception kept in ``error``)."""
        try:
            r = np.asarray(f(*args), dtype=float)
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # noqa: BLE001 - reported by code, kept to be named
            self.error = exc
            return code + RAISED
        return _write(r, out, shape, code, add)


def _array(ptr: int, size: int) -> np.ndarray:
    """The loop's ``size`` doubles at ``ptr`` as numpy, without a copy."""
    return np.ctypeslib.as_array((ctypes.c_double * max(size, 1)).from_address(ptr))[:size]


#: the C signature of a called-back solver
_SOLVER_CFUNC = ctypes.CFUNCTYPE(ctypes.c_int64, *([ctypes.c_void_p] * 6), ctypes.c_int64, ctypes.c_int64)


class SolverCallback:
    """A one-step contact solver as a C callback at ``address``, for a scene of ``n``
    coordinates and ``m`` contact rows. In C::

        int64 solve(double *M, double *b, double *G, double *c, double *v, double *P, int64 n, int64 k)

    ``M`` (n, n), ``b`` (n,), ``G`` (k, n), ``c`` (k,): the QP ``min ½ vᵀMv − bᵀv s.t. G v >= c``
    of the step's closed rows; it writes ``v`` (n,) and ``P`` (k,) and returns 0, 1 when the
    solver gave up (the loop checks every answer and falls back as for its own methods), or
    2 when interrupted.

    ``error`` keeps why the last failed solve failed (named in the run's error);
    ``interrupted`` is set when a Ctrl-C arrived during a solve (the loop then stops and the
    runner raises the interrupt).
    """

    def __init__(self, solver: ContactSolver, n: int, m: int) -> None:
        self.solver, self.n, self.m = solver, n, m
        # no constant mass at setup: the loop also solves reduced problems (M = I) and
        # drift projections with the same solver
        solver.setup(n, m, None)
        self.error = ""
        self.interrupted = False
        self._G = np.zeros((m, n))
        self._c = np.zeros(m)
        self._cfunc = _SOLVER_CFUNC(self._call)  # kept alive with the object: the loop holds its address
        self.address = int(ctypes.cast(self._cfunc, ctypes.c_void_p).value or 0)

    def _call(self, Mp: int, bp: int, Gp: int, cp: int, vp: int, Pp: int, n: int, k: int) -> int:
        self.error = ""
        try:
            G, c = self._G, self._c
            G[:k] = _array(Gp, k * n).reshape(k, n)
            c[:k] = _array(cp, k)
            v, P = self.solver.solve(_array(Mp, n * n).reshape(n, n).copy(), _array(bp, n).copy(), G, c, np.arange(k))
            v, P = np.asarray(v, dtype=float), np.asarray(P, dtype=float)
            if v.shape != (n,) or P.shape != (k,):
                raise SolveFailed(f"{self.solver.name} returned v of shape {v.shape} and P of shape {P.shape}, "
                                  f"expected ({n},) and ({k},)")
            _array(vp, n)[:] = v
            _array(Pp, k)[:] = P
            return 0
        except KeyboardInterrupt:
            self.interrupted = True
            return 2
        except BaseException as exc:  # noqa: BLE001 - a callback must not raise into C
            self.error = f"{self.solver.name}: {type(exc).__name__}: {exc}"
            return 1


def _write(r: np.ndarray, out: np.ndarray, shape: tuple[int, ...], code: int, add: bool) -> int:
    """Write (or add) ``r`` of ``shape`` into the flat ``out``; 0 or ``code`` plus what is wrong."""
    if r.shape != shape:
        return code + WRONG_SHAPE
    flat = r.ravel()
    finite = all(map(math.isfinite, flat)) if flat.size < 16 else bool(np.isfinite(flat).all())  # small: faster
    if not finite:
        return code + NONFINITE
    if add:
        out += flat
    else:
        out[:] = flat
    return 0
