"""InstCombine before LLVM's function passes on moreau's large compiled functions
(moreau.core.llvm_prepass): in place on the numba the project installs, run on moreau's
functions of at least ``LARGE`` instructions only, never on a user's."""

import llvmlite.binding as llvm
import numpy as np
from numba import njit
from numba.core import codegen

from moreau.core import llvm_prepass

_IR = """
define i64 @"{name}"(i64 %x) {{
entry:
  %a = add i64 %x, 0
  %b = mul i64 %a, 1
  ret i64 %b
}}
"""


def _module(*names):
    return llvm.parse_assembly("\n".join(_IR.format(name=n) for n in names))


def _instructions(func):
    return [str(i).strip() for b in func.blocks for i in b.instructions]


def test_it_is_in_place_and_user_functions_compile_as_before():
    import moreau  # noqa: F401  (installs it)

    assert llvm_prepass.installed()

    @njit
    def user(x):  # a user's function still compiles and runs
        return x + 1.0

    assert user(np.float64(1.0)) == 2.0


def test_only_moreaus_large_functions_get_the_instcombine(monkeypatch):
    ours, large_theirs = "_ZN6moreau8compiled4loop1fB2v1E", "_ZN4user1gB2v1E"
    seen = []
    run = llvm_prepass._with_prepass(lambda lib, mod: seen.append([_instructions(f) for f in mod.functions]))
    lib = codegen.JITCPUCodegen("probe").create_library("probe")
    for large, simplified in ((0, True), (10, False)):  # LARGE: every function, then only those of >= 10
        monkeypatch.setattr(llvm_prepass, "LARGE", large)
        seen.clear()
        run(lib, _module(ours, large_theirs))
        mine, theirs = seen[0]
        assert (mine == ["ret i64 %x"]) is simplified  # the add and mul of 0 and 1 folded away, or not
        assert len(theirs) == 3  # a user's function as numba lowered it


def test_is_moreaus_reads_numbas_mangling():
    assert llvm_prepass.is_moreaus("_ZN6moreau8compiled4loop10_run_chunkB2v1E")
    assert llvm_prepass.is_moreaus("_ZN7cpython6moreau8compiled4loop10_run_chunkB2v1E")
    assert not llvm_prepass.is_moreaus("_ZN8__main__4userB2v1E")
    assert not llvm_prepass.is_moreaus("_ZN7moreaux1fE")
