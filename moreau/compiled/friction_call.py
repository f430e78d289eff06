"""The friction solve called through an address: compiled only when a scene has friction.

The time loop is compiled once for every scene, so whatever it calls directly is
compiled on every machine, friction or not: Lemke's method, the enumeration of contact
states and the law check took about 9 s of the first compile. Instead the loop calls
the friction solve through the address of a C function (a numba ``cfunc``) of one fixed
signature, as it calls user callables (:mod:`moreau.compiled.usercalls`): that function
is compiled the first time a scene with friction is lowered (its callee,
:func:`moreau.contact.friction.solve_friction_step`, is kept in numba's cache like the
loop), and a scene without friction passes the address 0 and never builds it.

The work arrays of the solve live in two flat buffers (:func:`work_buffers`), carved by
the C function into the arrays :func:`~moreau.contact.friction.solve_friction_step`
takes (:func:`layout` gives their offsets). In C::

    int64 solve(double *M, double *L, double *b, double *G, double *c, double *mu,
                int64 *fidx, int64 n, int64 k, int64 kf, double *P, double *v, double tol,
                double *res, double *fbuf, int64 *ibuf, int64 r, int64 p)
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

from moreau.contact.friction import solve_friction_step

__all__ = ["SIGNATURE", "layout", "work_buffers", "friction_address", "call_friction"]

_D = types.CPointer(types.float64)
_I = types.CPointer(types.int64)
#: the C signature of the friction solve
SIGNATURE = types.int64(_D, _D, _D, _D, _D, _D, _I, types.int64, types.int64, types.int64, _D, _D, types.float64,
                        _D, _D, _I, types.int64, types.int64)


@njit(cache=True, nogil=True)
def layout(n, r, p):
    """Offsets into the float buffer of the solve's arrays, in the order of
    :func:`~moreau.contact.friction.friction_workspace` (its int array, Lemke's basis, is
    the int buffer), and its total size: r rows (normal + tangential), p LCP rows, n
    coordinates."""
    sizes = (r * n, n, r * r, r, p * p, p, p, p * (2 * p + 2), p, n, r, n, n, n, n, n, 6, 6, r, n)
    off = np.empty(len(sizes) + 1, dtype=np.int64)
    off[0] = 0
    for i in range(len(sizes)):
        off[i + 1] = off[i] + sizes[i]
    return off


def work_buffers(n: int, m: int, mf: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """``(fbuf, ibuf, r, p)`` for up to m normal and mf tangential rows on n coordinates."""
    r, p = max(m + mf, 1), max(m + 3 * mf, 1)
    return np.zeros(int(layout(n, r, p)[-1])), np.zeros(p, dtype=np.int64), r, p


def _entry(Mp, Lp, bp, Gp, cp, mup, fidxp, n, k, kf, Pp, vp, tol, resp, fbufp, ibufp, r, p):
    off = layout(n, r, p)
    f = carray(fbufp, (off[-1],))
    ws = (f[off[0]:off[1]].reshape((r, n)), f[off[1]:off[2]], f[off[2]:off[3]].reshape((r, r)), f[off[3]:off[4]],
          f[off[4]:off[5]].reshape((p, p)), f[off[5]:off[6]], f[off[6]:off[7]],
          f[off[7]:off[8]].reshape((p, 2 * p + 2)), carray(ibufp, (p,)), f[off[8]:off[9]], f[off[9]:off[10]],
          f[off[10]:off[11]], f[off[11]:off[12]], f[off[12]:off[13]], f[off[13]:off[14]], f[off[14]:off[15]],
          f[off[15]:off[16]], f[off[16]:off[17]], f[off[17]:off[18]], f[off[18]:off[19]], f[off[19]:off[20]])
    return solve_friction_step(carray(Mp, (n, n)), carray(Lp, (n, n)), carray(bp, (n,)), carray(Gp, (r, n)),
                               carray(cp, (r,)), carray(mup, (r,)), carray(fidxp, (r,)), k, kf, carray(Pp, (r,)),
                               carray(vp, (n,)), tol, carray(resp, (6,)), ws)


_lock = threading.Lock()
_compiled: list[Any] = []


def friction_address() -> int:
    """The address of the compiled friction solve (compiled at the first call in a
    process: its callees load from numba's cache)."""
    with _lock:
        if not _compiled:
            _compiled.append(cfunc(SIGNATURE, cache=True)(_entry))
        return int(_compiled[0].address)


def _call_friction(typingctx, addr, M, L, b, G, c, mu, fidx, n, k, kf, P, v, tol, res, fbuf, ibuf, r, p):
    """Call the friction solve at ``addr`` on the data of the arrays (C-contiguous)."""
    sig = types.int64(types.int64, M, L, b, G, c, mu, fidx, types.int64, types.int64, types.int64, P, v,
                      types.float64, res, fbuf, ibuf, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        dp = ir.DoubleType().as_pointer()
        i64 = ir.IntType(64)
        ip = i64.as_pointer()
        fn_t = ir.FunctionType(i64, [dp, dp, dp, dp, dp, dp, ip, i64, i64, i64, dp, dp, ir.DoubleType(), dp, dp,
                                     ip, i64, i64])
        fn = builder.inttoptr(args[0], fn_t.as_pointer())

        def data(i, ptr):
            return builder.bitcast(context.make_array(signature.args[i])(context, builder, args[i]).data, ptr)

        call_args = [data(1, dp), data(2, dp), data(3, dp), data(4, dp), data(5, dp), data(6, dp), data(7, ip),
                     args[8], args[9], args[10], data(11, dp), data(12, dp), args[13], data(14, dp), data(15, dp),
                     data(16, ip), args[17], args[18]]
        return builder.call(fn, call_args)

    return sig, codegen


#: ``call_friction(addr, M, L, b, G, c, mu, fidx, n, k, kf, P, v, tol, res, fbuf, ibuf, r, p)`` in compiled code
call_friction: Any = intrinsic(_call_friction)
