"""A compiled function called through its address, in numba's own calling convention.

A direct call of one ``@njit`` function from another links the callee's code into the
caller's, and LLVM optimizes and generates it again there. The loop calls its drift
projection through the projection's address instead (``call_checked``, with a key of the
argument types checked first): the loop's compile neither compiles nor waits for it, and
the loop's module holds only the call.
"""

from __future__ import annotations

import zlib
from typing import Any

from llvmlite import ir  # type: ignore[import-untyped]
from numba._dispatcher import compute_fingerprint
from numba.core import cgutils, types
from numba.core.callconv import excinfo_t
from numba.extending import intrinsic

__all__ = ["MISMATCH", "address_and_key", "call_checked", "type_key"]


#: (id of the dispatcher, numba's fingerprint of the arguments' types) -> (address, key of
#: the types): typing some thirty arrays in Python takes about a millisecond, their
#: fingerprint a microsecond
_addresses: dict[tuple[int, bytes], tuple[int, int]] = {}


def address_and_key(dispatcher: Any, args: tuple) -> tuple[int, int]:
    """The address of ``dispatcher``'s machine code for the numba types of ``args`` (the
    Python values it will be called with; it must return an int64), loaded from numba's
    cache or compiled when the process has not got it, and the :func:`type_key` of those
    types, for :func:`call_checked`."""
    key = (id(dispatcher), compute_fingerprint(args))
    found = _addresses.get(key)
    if found is not None:
        return found
    sig = tuple(dispatcher.typeof_pyval(a) for a in args)
    cres = dispatcher.overloads.get(sig)
    if cres is None:
        dispatcher.compile(sig)
        cres = dispatcher.overloads[sig]
    if cres.signature.return_type != types.int64:
        raise TypeError(f"{dispatcher.py_func.__name__} returns {cres.signature.return_type}, not int64")
    _addresses[key] = found = (cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name), type_key(sig))
    return found


#: what :func:`call_checked` returns for a key that is not its arguments' types
MISMATCH = -(1 << 40)


def type_key(argtypes: tuple) -> int:
    """A key of a call's argument types (numba types), the same in every process."""
    return zlib.crc32(str(tuple(argtypes)).encode()) & 0x7FFFFFFF


def _emit_call(context, builder, addr, argtys, packed_args):
    """The call of the int64 function at ``addr`` on the tuple value ``packed_args``."""
    conv = context.call_conv
    vals = cgutils.unpack_tuple(builder, packed_args, len(argtys))
    fn = builder.inttoptr(addr, conv.get_function_type(types.int64, argtys).as_pointer())
    ret = cgutils.alloca_once(builder, conv.get_return_type(types.int64).pointee)
    builder.store(cgutils.get_null_value(ret.type.pointee), ret)
    excinfo = cgutils.alloca_once(builder, ir.PointerType(excinfo_t), name="excinfo")
    packed = list(conv._get_arg_packer(argtys).as_arguments(builder, vals))
    status = conv._get_return_status(builder, builder.call(fn, [ret, excinfo] + packed), builder.load(excinfo))
    with cgutils.if_unlikely(builder, status.is_error):
        conv.return_status_propagate(builder, status)
    return builder.load(ret)


def _call_checked(typingctx, addr, key, args):
    """``call_checked(addr, key, args)``: the int64 function at ``addr`` called on the
    tuple ``args`` when ``key`` is the :func:`type_key` of ``args``' types here (from
    :func:`address_and_key`), else ``MISMATCH`` without a call: an address made for
    other types is never called. An exception the callee raised is raised on in the caller."""
    argtys = tuple(args.types)
    sig = types.int64(types.int64, types.int64, args)
    expected = type_key(argtys)

    def codegen(context, builder, signature, llargs):
        out = cgutils.alloca_once_value(builder, context.get_constant(types.int64, MISMATCH))
        same = builder.icmp_signed("==", llargs[1], context.get_constant(types.int64, expected))
        with builder.if_then(same, likely=True):
            builder.store(_emit_call(context, builder, llargs[0], argtys, llargs[2]), out)
        return builder.load(out)

    return sig, codegen


#: ``call_checked(addr, key, args) -> int64`` in compiled code
call_checked: Any = intrinsic(_call_checked)
