"""The one set of numba options every physics kernel is compiled with.

Importing this module first checks the compile cache (:func:`moreau.core.jitcache.ensure_fresh`),
so no stale machine code of moreau is loaded, and makes two of numba's compile steps
cheaper on the loop's large function, with the same results (:mod:`moreau.core.numba_patches`),
and runs InstCombine before LLVM's function passes on moreau's functions (:mod:`moreau.core.llvm_prepass`).
"""

from numba import njit

from moreau.core import llvm_prepass, numba_patches
from moreau.core.jitcache import ensure_fresh

__all__ = ["jit"]

ensure_fresh()  # before any cached machine code of moreau is loaded
numba_patches.install()  # numba's inlining and liveness, cheaper on the loop's large function
llvm_prepass.install()  # InstCombine before LLVM's function passes on moreau's functions

# Each kernel is compiled once and inlined where it is called by LLVM (forceinline): as
# calls, the piston step costs a quarter more; inlined by numba (inline="always") at
# every level, the loop took minutes and gigabytes to compile (see moreau.compiled.loop).
# _nrt=False (numba's internal flag): kernels allocate nothing, so they need no reference
# counting, and Python callers and the loop (compiled without it) share one version.
jit = njit(cache=True, nogil=True, forceinline=True, _nrt=False)  # type: ignore[call-overload]
