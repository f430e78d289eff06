"""Lowering a scene to the data of the compiled time loop.

A :class:`~moreau.model.scene.Scene` becomes a :class:`CompiledScene`: one record per effect and
per contact of the scene — its kernel code (:mod:`moreau.core.kernels`) and the offset of its
parameters in one flat float pool — and nothing else. The compiled loop walks these
records, so a scene without damping never evaluates damping and a scene without
barriers never builds a contact problem, in machine code as on the Python path. Every
scene lowers to arrays only, so one loop, compiled once per machine and loaded from
numba's cache by every later process, serves them all; numba-compiled user callables
(``@numba.njit``) are called through the addresses of small wrappers compiled for the
scene alone (:mod:`moreau.compiled.usercalls`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from moreau.compiled.usercalls import UserKernels, user_kernels
from moreau.core import kernels as _k
from moreau.model.scene import Scene

__all__ = ["CompiledScene", "NotCompilable", "lower"]


class NotCompilable(ValueError):
    """A part of the scene has no compiled form; the message names it."""


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

    def arrays(self) -> tuple:
        return (self.ints, self.ekind, self.eoff, self.bkind, self.boff, self.brow, self.bnrows,
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

    Raises
    ------
    NotCompilable
        Naming the system, effect or contact (and its callable) that has no compiled
        kernel: plain Python callables run on the Python path only; wrap them with
        ``numba.njit`` to run compiled.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a Scene, got {scene!r}")
    n = scene.ndof
    pool = _Pool()
    sysm = scene.system
    mk = sysm.mass_kernel()
    if mk is None:
        raise NotCompilable(
            f"system {type(sysm).__name__} has no compiled mass matrix (a plain Python callable "
            "for mass or bias: decorate it with @numba.njit to run compiled)")
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
    for e in scene.effects:
        spec = e.kernel()
        if spec is None:
            raise NotCompilable(
                f"effect {e.name!r} ({type(e).__name__}) has no compiled kernel: its force is a plain "
                "Python callable; decorate it with @numba.njit to run compiled")
        kind, params = spec
        if kind == "user":
            ekind.append(_k.USER)
            eoff.append(len(force_fns))
            force_fns.append(params)
            force_names.append(e.name)
        else:
            ekind.append(kind)
            eoff.append(pool.add(*params))

    bkind: list[int] = []
    boff: list[int] = []
    brow: list[int] = []
    bnrows: list[int] = []
    bar_fns: list[Any] = []
    bar_rows: list[int] = []
    bar_nrows: list[int] = []
    bar_names: list[str] = []
    row = 0
    for c in scene.contacts:
        spec = c.barrier.kernel()
        if spec is None:
            raise NotCompilable(
                f"contact {c.name!r} ({type(c.barrier).__name__}) has no compiled kernel: its gap or "
                "Jacobian is a plain Python callable; decorate both with @numba.njit to run compiled")
        kind, params = spec
        if kind == "user":
            bkind.append(_k.BAR_USER)
            boff.append(len(bar_fns))
            bar_fns.append(tuple(params))
            bar_rows.append(row)
            bar_nrows.append(c.barrier.nrows)
            bar_names.append(c.name)
        else:
            bkind.append(kind)
            boff.append(pool.add(*params))
        brow.append(row)
        bnrows.append(c.barrier.nrows)
        row += c.barrier.nrows

    # friction: each frictional contact's tangent rows as one more barrier whose Jacobian
    # (rows m, m + 1, ... of G) the same evaluation computes; its gaps are never evaluated
    tmap = np.full(scene.nrows, -1, dtype=np.int64)
    mf = 0
    for c, first in zip(scene.contacts, brow[:len(scene.contacts)]):
        if not np.any(c.friction > 0.0):
            continue
        spec = c.barrier.tangent_kernel()
        if spec is None:
            raise NotCompilable(f"contact {c.name!r} ({type(c.barrier).__name__}): its tangent rows have no "
                                "compiled kernel, so friction on it runs on the Python path")
        bkind.append(spec[0])
        boff.append(pool.add(*spec[1]))
        brow.append(scene.nrows + mf)
        bnrows.append(c.barrier.nrows)
        tmap[first:first + c.barrier.nrows] = scene.nrows + mf + np.arange(c.barrier.nrows)
        mf += c.barrier.nrows
    first_eq = len(bkind)
    me = _lower_constraints(scene, scene.nrows + mf, pool, bkind, boff, brow, bnrows, bar_fns, bar_rows, bar_nrows,
                            bar_names)
    i64 = lambda x: np.array(x, dtype=np.int64)  # noqa: E731
    needs_trig = (mass_kind == _k.MASS_CHAIN or any(k in (_k.TRIG, _k.FOURIER_PT) for k in ekind)
                  or any(k in (_k.BAR_TRIG, _k.BAR_CHAIN_POINT) for k in bkind))
    ints = i64([n, scene.nrows, mass_kind, int(has_bias), mass_off, len(ekind), len(scene.contacts),
                int(scene.velocity_dependent), int(needs_trig), mf, me, first_eq])
    return CompiledScene(
        ints=ints, ekind=i64(ekind), eoff=i64(eoff), bkind=i64(bkind), boff=i64(boff),
        brow=i64(brow), bnrows=i64(bnrows), pool=pool.array(),
        restitution=np.ascontiguousarray(scene.restitution, dtype=float),
        activation_tol=np.ascontiguousarray(np.concatenate([scene.activation_tol, scene.constraint_hold_tol]),
                                            dtype=float),
        friction=np.ascontiguousarray(scene.friction, dtype=float), tangent_row=tmap,
        user=_user(scene, mass_fun, bias_fun, force_fns, force_names, bar_fns, bar_rows, bar_nrows, bar_names),
        user_callables={"mass": [(type(sysm).__name__ + ".mass", mass_fun)],
                        "bias": [(type(sysm).__name__ + ".bias", bias_fun)],
                        "forces": list(zip(force_names, force_fns)),
                        "gaps": [(name, pair[0]) for name, pair in zip(bar_names, bar_fns)],
                        "jacobians": [(name, pair[1]) for name, pair in zip(bar_names, bar_fns)]},
    )


def _lower_constraints(scene: Scene, row0: int, pool: _Pool, bkind: list, boff: list, brow: list, bnrows: list,
                       bar_fns: list, bar_rows: list, bar_nrows: list, bar_names: list) -> int:
    """Append each bilateral constraint as one more barrier record, its rows from ``row0``
    (= m + mf: after the contact and the tangent rows of the gaps and the Jacobian);
    returns the number of bilateral rows."""
    me = 0
    for bc in scene.constraints:
        spec = bc.geometry.kernel()
        rows_at = row0 + me
        if spec is None:
            raise NotCompilable(
                f"constraint {bc.name!r} ({type(bc.geometry).__name__}) has no compiled kernel: its gap or "
                "Jacobian is a plain Python callable; decorate both with @numba.njit to run compiled")
        kind, params = spec
        if kind == "user":
            bkind.append(_k.BAR_USER)
            boff.append(len(bar_fns))
            bar_fns.append(tuple(params))
            bar_rows.append(rows_at)
            bar_nrows.append(bc.nrows)
            bar_names.append(bc.name)
        else:
            bkind.append(kind)
            boff.append(pool.add(*params))
        brow.append(rows_at)
        bnrows.append(bc.nrows)
        me += bc.nrows
    return me


def _user(scene, mass_fun, bias_fun, force_fns, force_names, bar_fns, bar_rows, bar_nrows, bar_names) -> UserKernels:
    """The slot wrappers of the scene's user callables; a callable numba cannot compile
    (a typing error) is refused by name."""
    from numba.core.errors import NumbaError

    try:
        return user_kernels(mass_fun, bias_fun, tuple(force_fns), tuple(bar_fns), tuple(bar_rows),
                            tuple(bar_nrows))
    except NumbaError as exc:
        names = [f"effect {x!r}" for x in force_names] + [f"contact {x!r}" for x in bar_names]
        if mass_fun is not None or bias_fun is not None:
            names.insert(0, f"system {type(scene.system).__name__}")
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise NotCompilable(f"the @njit callables of {', '.join(names)} do not compile with the "
                            f"signatures the compiled loop calls them with ({first})") from exc


def compiles(scene: Scene) -> tuple[bool, str]:
    """``(True, "")`` when the scene lowers, else ``(False, reason)``."""
    try:
        lower(scene)
    except NotCompilable as exc:
        return False, str(exc)
    return True, ""
