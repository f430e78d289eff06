"""Compiled evaluation of a lowered scene: M(q), f(t, q, v), g(q), G(q), energies.

Each function walks the records of a :class:`~moreau.lowering.CompiledScene` and calls
the kernels of :mod:`moreau.kernels` for exactly the effects and contacts the scene
holds; numba-compiled user callables are called through small overloads that compile
to nothing for a built-in scene.
"""

from __future__ import annotations

from numba import literal_unroll, njit
from numba.core import types
from numba.extending import overload

from . import kernels as _k

_jit = njit(cache=True, nogil=True, inline="always")


# -- user callables (specialized per tuple type; empty tuples compile to nothing) --------
def user_mass(fns, q, out):  # pragma: no cover - replaced by the overload
    raise NotImplementedError


def user_bias(fns, q, v, out):  # pragma: no cover
    raise NotImplementedError


def user_forces(fns, t, q, v, out):  # pragma: no cover
    raise NotImplementedError


def user_gaps(fns, rows, q, out):  # pragma: no cover
    raise NotImplementedError


def user_jacobians(fns, rows, q, out):  # pragma: no cover
    raise NotImplementedError


def _slot_is_none(fns, i):
    return len(fns) <= i or isinstance(fns[i], (types.NoneType, types.Omitted))


@overload(user_mass, jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_mass(fns, q, out):
    if _slot_is_none(fns, 0):
        return lambda fns, q, out: None

    def impl(fns, q, out):
        out[:, :] = fns[0](q)
    return impl


@overload(user_bias, jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_bias(fns, q, v, out):
    if _slot_is_none(fns, 1):
        return lambda fns, q, v, out: None

    def impl(fns, q, v, out):
        out += fns[1](q, v)
    return impl


@overload(user_forces, jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_forces(fns, t, q, v, out):
    if len(fns) == 0:
        return lambda fns, t, q, v, out: None

    def impl(fns, t, q, v, out):
        for fun in literal_unroll(fns):
            out += fun(t, q, v)
    return impl


@overload(user_gaps, jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_gaps(fns, rows, q, out):
    if len(fns) == 0:
        return lambda fns, rows, q, out: None

    def impl(fns, rows, q, out):
        i = 0
        for pair in literal_unroll(fns):
            g = pair[0](q)
            r0 = rows[i]
            for j in range(g.shape[0]):
                out[r0 + j] = g[j]
            i += 1
    return impl


@overload(user_jacobians, jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_jac(fns, rows, q, out):
    if len(fns) == 0:
        return lambda fns, rows, q, out: None

    def impl(fns, rows, q, out):
        i = 0
        for pair in literal_unroll(fns):
            G = pair[1](q)
            r0 = rows[i]
            for j in range(G.shape[0]):
                out[r0 + j, :] = G[j]
            i += 1
    return impl


# -- the scene ----------------------------------------------------------------------------
@_jit
def mass(ints, pool, user, q, c, s, M):
    """M(q) into ``M`` (n x n); ``c, s`` = cos q, sin q."""
    n, kind, off = ints[0], ints[2], ints[4]
    if kind == _k.MASS_CHAIN:
        _k.chain_mass(pool, off, c, s, M)
    elif kind == _k.MASS_CONST:
        for i in range(n):
            for j in range(n):
                M[i, j] = pool[off + i * n + j]
    else:
        user_mass(user[0], q, M)


@_jit
def force(ints, ekind, eoff, pool, user, t, q, c, s, v, f):
    """f(t, q, v) into ``f`` (n,): the bias terms and exactly the scene's effects;
    ``c, s`` = cos q, sin q."""
    for i in range(f.shape[0]):
        f[i] = 0.0
    if ints[3]:
        if ints[2] == _k.MASS_CHAIN:
            _k.add_chain_bias(pool, ints[4], c, s, v, f)
        else:
            user_bias(user[0], q, v, f)
    for e in range(ints[5]):
        kind, o = ekind[e], eoff[e]
        if kind == _k.CONST:
            _k.add_constant(pool, o, f)
        elif kind == _k.LINEAR_V:
            _k.add_linear_v(pool, o, v, f)
        elif kind == _k.AFFINE_Q:
            _k.add_affine_q(pool, o, q, f)
        elif kind == _k.TRIG:
            _k.add_trig(pool, o, c, s, f)
        elif kind == _k.HARMONIC:
            _k.add_harmonic(pool, o, t, f)
        elif kind == _k.FOURIER_PT:
            _k.add_point_fourier(pool, o, q, c, s, f)
    user_forces(user[1], t, q, v, f)


@_jit
def gaps(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, g):
    """g(q) into ``g`` (m,); ``c, s`` = cos q, sin q."""
    for ic in range(ints[6]):
        kind = bkind[ic]
        if kind == _k.BAR_LINEAR:
            _k.gaps_linear(pool, boff[ic], bnrows[ic], q, g, brow[ic])
        elif kind == _k.BAR_TRIG:
            _k.gaps_trig(pool, boff[ic], bnrows[ic], c, s, g, brow[ic])
    user_gaps(user[2], user[3], q, g)


@_jit
def jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, G):
    """G(q) into ``G`` (m, n); ``c, s`` = cos q, sin q."""
    for ic in range(ints[6]):
        kind = bkind[ic]
        if kind == _k.BAR_LINEAR:
            _k.jacobian_linear(pool, boff[ic], bnrows[ic], G, brow[ic])
        elif kind == _k.BAR_TRIG:
            _k.jacobian_trig(pool, boff[ic], bnrows[ic], c, s, G, brow[ic])
    user_jacobians(user[2], user[3], q, G)


@_jit
def potential(ints, ekind, eoff, pool, q, c, s):
    """Potential energy of the built-in conservative effects, up to a constant (J)."""
    n = ints[0]
    nn = n * n
    V = 0.0
    for e in range(ints[5]):
        kind, o = ekind[e], eoff[e]
        if kind == _k.CONST:
            for i in range(n):
                V -= pool[o + i] * q[i]
        elif kind == _k.AFFINE_Q:
            for i in range(n):
                Kq = 0.0
                for j in range(n):
                    Kq += pool[o + i * n + j] * q[j]
                V += 0.5 * q[i] * Kq - pool[o + nn + i] * q[i]
        elif kind == _k.TRIG:
            for i in range(n):
                V -= pool[o + i] * c[i] + pool[o + n + i] * s[i]
    return V
