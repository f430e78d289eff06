"""Lowering a scene to the data of the compiled time loop.

A :class:`~moreau.model.scene.Scene` becomes a :class:`CompiledScene`: one record per effect and
per contact of the scene — its kernel code (:mod:`moreau.core.kernels`) and the offset of its
parameters in one flat float pool — and nothing else. The compiled loop walks these
records, so a scene without damping never evaluates damping and a scene without
barriers never builds a contact problem. Every
scene lowers to arrays only, so one loop, compiled once per machine and loaded from
numba's cache by every later process, serves them all; user callables are called through
the addresses of small wrappers compiled for the scene alone, or of callbacks into Python
where numba cannot compile them (:mod:`moreau.compiled.usercalls`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from moreau.compiled.layout import ModelArrays
from moreau.compiled.usercalls import UserKernels, user_kernels
from moreau.core import kernels as _k
from moreau.model.overrides import kernel_of
from moreau.model.scene import Scene

__all__ = ["CompiledScene", "NotCompilable", "lower"]


class NotCompilable(ValueError):
    """A part of the scene has no compiled form; the message names it. (Every scene lowers
    now: kept for code that catches it.)"""


@dataclass
class CompiledScene:
    """A scene as arrays for :func:`moreau.compiled.loop.run_chunk`.

    Attributes
    ----------
    ints : ndarray of int64
        ``[n, m, mass_kind, has_bias, mass_off, n_effects, n_contacts, velocity_dependent,
        needs_trig, mf, me, first_eq]`` (needs_trig: some kernel uses cos q, sin q; mf: the
        number of tangent rows, 0 without friction; me: the number of bilateral rows, rows
        m + mf ... of the gaps and the Jacobian; first_eq: the index of the first
        constraint's barrier record).
    ekind, eoff : ndarray of int64, shape (n_effects,)
        Kernel code and pool offset of each effect.
    bkind, boff, brow : ndarray of int64, shape (n_contacts + n_frictional + n_constraints,)
        Kernel code, pool offset and first row of each contact's barrier, then of the
        tangent rows of each contact with friction (rows m, m + 1, ... of the Jacobian),
        then of each bilateral constraint (rows m + mf, ...).
    bnrows : ndarray of int64, shape (n_contacts + n_frictional + n_constraints,)
        Rows of each barrier.
    pool : ndarray of float64
        All parameters, flattened.
    restitution : ndarray, shape (m,)
    activation_tol : ndarray, shape (m + me,)
        A row is closed when its gap is at most this (see ``Scene.activation_tol``); then
        per bilateral row the ``|g|`` positions are held to (``Scene.constraint_hold_tol``).
    friction : ndarray, shape (m,)
        Friction coefficient per row.
    tangent_row : ndarray of int64, shape (m,)
        The Jacobian row of each row's tangent (−1 without friction).
    user : UserKernels
        The addresses of the scene's user slots (mass, bias, forces, gaps, Jacobians;
        0 for an empty slot, all 0 for a built-in scene) and the wrappers behind them.
    user_callables : dict
        Per slot (``usercalls.SLOTS``), ``(name, callable)`` of each of its user
        callables in order: what an error message names, and reruns to show what it raised.
    python_potentials : bool
        Some effect evaluated by a user callable has a potential (evaluated in Python at
        the records).
    """

    ints: np.ndarray
    ekind: np.ndarray
    eoff: np.ndarray
    bkind: np.ndarray
    boff: np.ndarray
    brow: np.ndarray
    bnrows: np.ndarray
    pool: np.ndarray
    restitution: np.ndarray
    activation_tol: np.ndarray
    friction: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tangent_row: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    user: UserKernels = field(default_factory=lambda: UserKernels(np.zeros(5, dtype=np.int64), (None,) * 5))
    user_callables: dict = field(default_factory=dict)
    python_potentials: bool = False

    def arrays(self) -> ModelArrays:
        return ModelArrays(self.ints, self.ekind, self.eoff, self.bkind, self.boff, self.brow, self.bnrows,
                           self.pool, self.restitution, self.activation_tol)


class _Pool:
    def __init__(self) -> None:
        self.chunks: list[np.ndarray] = []
        self.size = 0

    def add(self, *params) -> int:
        off = self.size
        for p in params:
            a = np.ascontiguousarray(p, dtype=float).ravel()
            self.chunks.append(a)
            self.size += a.size
        return off

    def array(self) -> np.ndarray:
        return np.concatenate(self.chunks) if self.chunks else np.zeros(1)


def lower(scene: Scene) -> CompiledScene:
    """The compiled form of ``scene``.

    Every scene lowers: a callable numba compiles runs as machine code, any other part is
    called back into Python (:mod:`moreau.compiled.callbacks`).
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a Scene, got {scene!r}")
    n = scene.ndof
    pool = _Pool()
    sysm = scene.system
    # a part without a kernel of its own is called through its Python methods
    mk: tuple[Any, Any] = kernel_of(sysm, "mass_kernel") or ("user", (sysm.mass_matrix,
                                                            sysm.bias_force if sysm.has_bias else None))
    mass_fun = bias_fun = None
    if mk[0] == "user":
        mass_fun, bias_fun = mk[1]
        mass_kind = _k.MASS_USER if mass_fun is not None else _k.MASS_CONST
        mass_off = pool.add(sysm.mass_matrix(np.zeros(n))) if mass_fun is None else 0
    else:
        mass_kind = mk[0]
        mass_off = pool.add(*mk[1])
    has_bias = bool(sysm.has_bias)

    ekind: list[int] = []
    eoff: list[int] = []
    force_fns: list[Any] = []
    force_names: list[str] = []
    python_potentials = False
    for e in scene.effects:
        kind: Any
        kind, params = kernel_of(e) or ("user", e.force)
        if kind == "user":
            python_potentials = python_potentials or bool(e.has_potential)
            ekind.append(_k.USER)
            eoff.append(len(force_fns))
            force_fns.append(params)
            force_names.append(e.name)
        else:
            ekind.append(kind)
            eoff.append(pool.add(*params))

    bars = _Barriers(pool)
    row = 0
    for c in scene.contacts:
        bars.add(kernel_of(c.barrier) or ("user", (c.barrier.gap, c.barrier.jacobian)), row, c.barrier.nrows, c.name)
        row += c.barrier.nrows
    # friction: each frictional contact's tangent rows as one more barrier whose Jacobian
    # (rows m, m + 1, ... of G) the same evaluation computes; its gaps are never evaluated
    tmap = np.full(scene.nrows, -1, dtype=np.int64)
    mf = 0
    for c, first in zip(scene.contacts, bars.brow[:len(scene.contacts)]):
        if not c.frictional:
            continue
        spec = kernel_of(c.barrier, "tangent_kernel") or ("user", (None, c.barrier.tangent_jacobian))
        bars.add(spec, scene.nrows + mf, c.barrier.nrows, f"{c.name} (tangent rows)")
        tmap[first:first + c.barrier.nrows] = scene.nrows + mf + np.arange(c.barrier.nrows)
        mf += c.barrier.nrows
    # the bilateral constraints after the contact and the tangent rows (rows m + mf, ...)
    first_eq = len(bars.bkind)
    me = 0
    for bc in scene.constraints:
        bars.add(kernel_of(bc.geometry) or ("user", (bc.geometry.gap, bc.geometry.jacobian)), scene.nrows + mf + me,
                 bc.nrows, bc.name)
        me += bc.nrows
    bkind, bar_fns, bar_names = bars.bkind, bars.fns, bars.names
    callables = {"mass": [(type(sysm).__name__ + ".mass", mass_fun)],
                 "bias": [(type(sysm).__name__ + ".bias", bias_fun)],
                 "forces": list(zip(force_names, force_fns)),
                 "gaps": [(name, pair[0]) for name, pair in zip(bar_names, bar_fns)],
                 "jacobians": [(name, pair[1]) for name, pair in zip(bar_names, bar_fns)]}
    i64 = lambda x: np.array(x, dtype=np.int64)  # noqa: E731
    needs_trig = (mass_kind == _k.MASS_CHAIN or any(k in (_k.TRIG, _k.FOURIER_PT) for k in ekind)
                  or any(k in (_k.BAR_TRIG, _k.BAR_CHAIN_POINT) for k in bkind))
    ints = i64([  # in the order of layout.SC_*
                n, scene.nrows, mass_kind, int(has_bias), mass_off, len(ekind), len(scene.contacts),
                int(scene.velocity_dependent), int(needs_trig), mf, me, first_eq])
    return CompiledScene(
        ints=ints, ekind=i64(ekind), eoff=i64(eoff), bkind=i64(bkind), boff=i64(bars.boff),
        brow=i64(bars.brow), bnrows=i64(bars.bnrows), pool=pool.array(),
        restitution=np.ascontiguousarray(scene.restitution, dtype=float),
        activation_tol=np.ascontiguousarray(np.concatenate([scene.activation_tol, scene.constraint_hold_tol]),
                                            dtype=float),
        friction=np.ascontiguousarray(scene.friction, dtype=float), tangent_row=tmap,
        user=user_kernels(mass_fun, bias_fun, tuple(force_fns), tuple(bar_fns), tuple(bars.rows), tuple(bars.nrows),
                          {slot: tuple(name for name, _ in pairs) for slot, pairs in callables.items()}),
        python_potentials=python_potentials, user_callables=callables,
    )


class _Barriers:
    """The barrier records of a scene being lowered: kernel code, pool offset, first row and
    rows of each; for user callables their index in ``fns`` and their rows and names."""

    def __init__(self, pool: _Pool) -> None:
        self.pool = pool
        self.bkind: list[int] = []
        self.boff: list[int] = []
        self.brow: list[int] = []
        self.bnrows: list[int] = []
        self.fns: list[tuple] = []
        self.rows: list[int] = []
        self.nrows: list[int] = []
        self.names: list[str] = []

    def add(self, spec: tuple[Any, Any], row: int, nrows: int, name: str) -> None:
        """One record at Jacobian rows ``row ... row + nrows``; ``spec`` = ``(kind, params)``
        or ``("user", (gap or None, jacobian))``."""
        kind, params = spec
        if kind == "user":
            self.bkind.append(_k.BAR_USER)
            self.boff.append(len(self.fns))
            self.fns.append(tuple(params))
            self.rows.append(row)
            self.nrows.append(nrows)
            self.names.append(name)
        else:
            self.bkind.append(kind)
            self.boff.append(self.pool.add(*params))
        self.brow.append(row)
        self.bnrows.append(nrows)
