"""The compiled loop's variants: which one a scene runs, and the work arrays of each.

The loop (:func:`moreau.compiled.loop.run_chunk`) takes the arrays of friction, of the
bilateral rows and of the step's later passes as arguments that are None in a variant
without them: numba prunes their branches, so a variant compiles none of their code, and
each variant is compiled (and cached) once per machine and version."""

from __future__ import annotations

import numpy as np

from moreau.compiled.bilateral import equality_work
from moreau.compiled.friction import friction_work
from moreau.compiled.implicit import velocity_passes
from moreau.compiled.layout import (
    N_SETTINGS,
    S_ITER,
    S_STEP,
    SC_ME,
    SC_MF,
    LoopWork,
    PassWork,
    StepWork,
)
from moreau.contact.lcp import workspace

__all__ = ["VARIANTS", "loop_workspace", "named", "variant", "variant_of"]


#: the loop's compiled variants (:func:`variant`), each with the code of the features named
#: and no other: the frictionless midpoint step, with friction (tangent rows), and with
#: friction, bilateral rows and the step's later passes
VARIANTS = ("plain", "friction", "full")


def loop_workspace(n: int, m: int, mf: int, mu: np.ndarray, tangent_row: np.ndarray, me: int = 0,
                   variant: str = "full") -> tuple:
    """The work arrays of :func:`~moreau.compiled.loop.run_chunk` for n coordinates, m rows, mf tangent rows
    (friction; mu (m,) and tangent_row (m,) from the lowered scene) and me bilateral rows,
    allocated once per run, outside the loop: the loop itself allocates nothing.

    ``(own, ws, lw, fr, eqw, ec)``: the arrays of friction (``fr``, in the ``"friction"``
    and ``"full"`` variants), of the bilateral rows (``eqw``) and of the step's later passes
    (``ec``, both only in ``"full"``) or None, and the loop run on them is the variant
    compiled without the code of those that are None (numba prunes the branches on
    ``is None``; :func:`variant` says which a scene takes). Plain numpy: allocating
    compiles nothing."""
    if variant not in VARIANTS:
        raise ValueError(f"variant={variant!r}: expected one of {VARIANTS}")
    mm = max(m, 1)
    mt = m + mf + me  # the rows of the gaps and the Jacobian: contacts, tangents, bilateral
    ma = max(mt, 1)
    own = StepWork(np.empty((n, n)), np.empty((n, n)), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n),
           np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.zeros(mt), np.zeros(mt),
           np.zeros(m), np.zeros(m, dtype=np.bool_), np.empty((mt, n)), np.empty(n), np.empty(n))
    lw = LoopWork(np.empty((ma, n)), np.empty(ma), np.empty(n), np.empty(n), np.empty(ma),
                  np.empty((ma, n)), np.empty(n), np.zeros(n), np.zeros(mm, dtype=np.bool_), np.empty((4, n)),
                  np.zeros(n), np.zeros(n), np.zeros(mm, dtype=np.bool_))
    if variant == "plain":
        return own, workspace(n, m), lw, None, None, None
    fr = friction_work(n, m, mf, mu, tangent_row)
    if variant == "friction":
        return own, workspace(n, m), lw, fr, None, None
    ec = PassWork(np.empty((n, n)), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.zeros(n),
                  np.zeros(n), np.empty(n), np.zeros(n))
    return own, workspace(n, m), lw, fr, equality_work(n, me, m + mf), ec


def variant(ints: np.ndarray, step: int, iterations: int = 1) -> str:
    """The variant of the loop (:data:`VARIANTS`) a lowered scene (its ``ints``,
    ``lowering.CompiledScene.ints``) stepped with ``step`` (``layout.STEP_*``;
    ``iterations``: the energy-consistent step's iterates) runs: ``"full"`` with bilateral
    rows or a step of more than one velocity update
    (``moreau.compiled.implicit.velocity_passes``), else ``"friction"`` with tangent rows,
    else ``"plain"`` (the frictionless midpoint step).

    Three variants, not one per feature set: each compiles the loop function anew
    (benchmarks/compile_cost.py), and the test suite, which runs every feature, would
    compile up to eight. Friction has its own because it is the bundled piston's and the
    woodpecker's one feature beyond the plain step: its variant compiles in about half the
    time of the full one."""
    iset = np.zeros(N_SETTINGS, dtype=np.int64)
    iset[S_STEP], iset[S_ITER] = step, iterations
    passes = velocity_passes.py_func(iset, ints)[0]  # the compiled rule, run here
    if ints[SC_ME] > 0 or passes > 1:
        return "full"
    return "friction" if ints[SC_MF] > 0 else "plain"


def named(no_fr: bool, no_eqw: bool, no_ec: bool) -> str:
    """The variant (:data:`VARIANTS`) whose friction, bilateral and later-pass arrays are
    None as flagged (the loop's last three arguments)."""
    return "plain" if no_fr else "friction" if no_eqw and no_ec else "full"


def variant_of(work: tuple) -> str:
    """The variant (:data:`VARIANTS`) a loop workspace (:func:`loop_workspace`) was made for."""
    return named(*(a is None for a in work[3:6]))
