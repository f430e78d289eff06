"""Compiled evaluation of a lowered scene: M(q) and its factor, f(t, q, v), g(q), G(q), energies.

Each function walks the records of a :class:`~moreau.compiled.lowering.CompiledScene` and calls
the kernels of :mod:`moreau.core.kernels` for exactly the effects and contacts the scene
holds; a scene's ``@numba.njit`` callables are called through their slot addresses
(:mod:`moreau.compiled.usercalls`), so one compiled loop serves every scene. ``mass``, ``force``,
``gaps`` and ``jacobian`` return 0, or a user callable's status ``code * 8 + slot``
(the loop stops on it; :func:`moreau.compiled.usercalls.decode` reads it).
"""

from __future__ import annotations

from numba import njit

from moreau.compiled.layout import (
    SC_FIRST_EQ,
    SC_HAS_BIAS,
    SC_M,
    SC_MASS_KIND,
    SC_MASS_OFF,
    SC_N,
    SC_N_CONTACTS,
    SC_N_EFFECTS,
)
from moreau.compiled.usercalls import U_BIAS, U_FORCES, U_GAPS, U_JACOBIANS, U_MASS, call_user
from moreau.core import kernels as _k

# allocation-free, so without reference counting (see moreau.core.kernels.jit)
_jit = njit(cache=True, nogil=True, _nrt=False)  # type: ignore[call-overload]
# called from the loop only, inlined into it by numba (see moreau.compiled.loop): no CPython or C
# entry points to build
_internal = njit(cache=True, nogil=True, _nrt=False, inline="always",  # type: ignore[call-overload]
                 no_cpython_wrapper=True, no_cfunc_wrapper=True)
# the chain's dense M and factor and its momentum, in a step with rows closed: calls,
# compiled apart from the loop (inlined into it, the steps of the piston, the four-bar and
# the 3-link chain on a floor were 13-15 % slower than before the O(n) algebra, as calls
# 5-7 %, measured interleaved; every chain takes it: the dense algebra inlined for chains
# under 6 links was 6-9 % slower still)
_apart = njit(cache=True, nogil=True, _nrt=False,  # type: ignore[call-overload]
              no_cpython_wrapper=True, no_cfunc_wrapper=True)


# -- the scene ----------------------------------------------------------------------------
@_internal
def mass(ints, pool, user, q, c, s, M):
    """M(q) into ``M`` (n x n); ``c, s`` = cos q, sin q."""
    n, kind, off = ints[SC_N], ints[SC_MASS_KIND], ints[SC_MASS_OFF]
    if kind == _k.MASS_CHAIN:
        _k.chain_mass(pool, off, c, s, M)
    elif kind == _k.MASS_CONST:
        for i in range(n):
            for j in range(n):
                M[i, j] = pool[off + i * n + j]
    else:
        st = call_user(user[U_MASS], 0.0, q, q, M, n, ints[SC_M])
        return 0 if st == 0 else st * 8 + U_MASS
    return 0


@_internal
def factor(ints, pool, M, c, s, L, gen):
    """The lower Cholesky factor of M (n x n, just evaluated at the configuration whose
    cos/sin are ``c, s``) into ``L``: the chain's from its O(n) generators, kept in ``gen``
    (4, n) (:func:`moreau.core.kernels.chain_factor`, O(n²) against O(n³)), others from M.
    Returns the index of the first non-positive pivot, or −1."""
    if ints[SC_MASS_KIND] == _k.MASS_CHAIN:
        return _k.chain_factor(pool, ints[SC_MASS_OFF], c, s, gen, L)
    return _k.cholesky(M, L, ints[SC_N])


@_apart
def chain_dense(ints, pool, c, s, gen, M, L):
    """The chain's M (n x n) and its dense factor L from the generators ``gen``."""
    _k.chain_mass(pool, ints[SC_MASS_OFF], c, s, M)
    _k.chain_fill(pool, ints[SC_MASS_OFF], c, s, gen, L)


@_apart
def chain_momentum(ints, pool, h, c, s, v, f, b):
    """b = M v + h f (n,) for the chain, M v in O(n)."""
    _k.chain_product(pool, ints[SC_MASS_OFF], c, s, v, b)
    for i in range(ints[SC_N]):
        b[i] += h * f[i]


@_apart
def chain_kinetic(ints, pool, c, s, v, Mv):
    """½ vᵀ M v for the chain, M v in O(n) into ``Mv`` (n,) (a call: inlined into the
    record, it made the steps of the piston and the 3-link chain 15-20 % slower)."""
    _k.chain_product(pool, ints[SC_MASS_OFF], c, s, v, Mv)
    ke = 0.0
    for i in range(ints[SC_N]):
        ke += v[i] * Mv[i]
    return 0.5 * ke


@_internal
def force(ints, ekind, eoff, pool, user, t, q, c, s, v, f, fb):
    """f(t, q, v) into ``f`` (n,): the bias terms and exactly the scene's effects; the bias
    terms alone also into ``fb`` (n,) (for the energy ledger: they do no work); ``c, s`` =
    cos q, sin q."""
    st = _bias(ints, pool, user, t, q, c, s, v, fb)
    if st != 0:
        return st
    for i in range(f.shape[0]):
        f[i] = fb[i]
    _add_effects(ints, ekind, eoff, pool, t, q, c, s, v, f, True, True)
    return _user_forces(ints, user, t, q, v, f)


@_internal
def position_forces(ints, ekind, eoff, pool, t, q, c, s, v, fq):
    """The sum of the scene's effects that do not depend on v into ``fq`` (n,): every
    built-in kind but ``LINEAR_V``. The later passes of a step (same t and q, another v)
    add it to theirs (:func:`velocity_forces`) instead of evaluating it again."""
    for i in range(fq.shape[0]):
        fq[i] = 0.0
    _add_effects(ints, ekind, eoff, pool, t, q, c, s, v, fq, True, False)


@_internal
def velocity_forces(ints, ekind, eoff, pool, user, t, q, c, s, v, fq, f, fb):
    """f(t, q, v) into ``f`` (n,) from ``fq`` (:func:`position_forces` at this t and q):
    f_bias(q, v) + fq + the effects that depend on v (``LINEAR_V``) + the user's forces
    (which may); the bias terms alone into ``fb`` (n,). Equal to :func:`force` up to the
    order of the sum (round-off). Returns 0 or the failed user callable's status."""
    st = _bias(ints, pool, user, t, q, c, s, v, fb)
    if st != 0:
        return st
    for i in range(f.shape[0]):
        f[i] = fb[i] + fq[i]
    _add_effects(ints, ekind, eoff, pool, t, q, c, s, v, f, False, True)
    return _user_forces(ints, user, t, q, v, f)


@_internal
def _bias(ints, pool, user, t, q, c, s, v, fb):
    """The bias terms f_bias(q, v) into ``fb`` (n,); 0 or the user callable's status."""
    for i in range(fb.shape[0]):
        fb[i] = 0.0
    if ints[SC_HAS_BIAS]:
        if ints[SC_MASS_KIND] == _k.MASS_CHAIN:  # inlined (as a call the piston's step was 5-10 % slower)
            _k.add_chain_bias(pool, ints[SC_MASS_OFF], c, s, v, fb)
        else:
            st = call_user(user[U_BIAS], t, q, v, fb, ints[SC_N], ints[SC_M])
            if st != 0:
                return st * 8 + U_BIAS
    return 0


@_internal
def _add_effects(ints, ekind, eoff, pool, t, q, c, s, v, f, position, velocity):
    """Add the scene's built-in effects to ``f`` (n,), in the scene's order: those that do
    not depend on v if ``position``, those that do (``LINEAR_V``) if ``velocity``."""
    for e in range(ints[SC_N_EFFECTS]):
        kind, o = ekind[e], eoff[e]
        if kind == _k.LINEAR_V:
            if velocity:
                _k.add_linear_v(pool, o, v, f)
        elif not position:
            continue
        elif kind == _k.CONST:
            _k.add_constant(pool, o, f)
        elif kind == _k.AFFINE_Q:
            _k.add_affine_q(pool, o, q, f)
        elif kind == _k.TRIG:
            _k.add_trig(pool, o, c, s, f)
        elif kind == _k.HARMONIC:
            _k.add_harmonic(pool, o, t, f)
        elif kind == _k.FOURIER_PT:
            _k.add_point_fourier(pool, o, q, c, s, f)


@_internal
def _user_forces(ints, user, t, q, v, f):
    """Add the user's forces to ``f`` (n,); 0 or the callable's status."""
    if user[U_FORCES] != 0:
        st = call_user(user[U_FORCES], t, q, v, f, ints[SC_N], ints[SC_M])
        return 0 if st == 0 else st * 8 + U_FORCES
    return 0


@_internal
def gaps(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, g):
    """g(q) into ``g`` (m, then the bilateral rows at m + mf ...); ``c, s`` = cos q, sin q."""
    for ic in range(bkind.shape[0]):
        if ints[SC_N_CONTACTS] <= ic < ints[SC_FIRST_EQ]:  # tangent rows: no gaps
            continue
        kind = bkind[ic]
        if kind == _k.BAR_LINEAR:
            _k.gaps_linear(pool, boff[ic], bnrows[ic], q, g, brow[ic])
        elif kind == _k.BAR_TRIG:
            _k.gaps_trig(pool, boff[ic], bnrows[ic], c, s, g, brow[ic])
        elif kind == _k.BAR_CHAIN_POINT:
            _k.gaps_chain_point(pool, boff[ic], bnrows[ic], c, s, g, brow[ic])
    if user[U_GAPS] != 0:
        st = call_user(user[U_GAPS], 0.0, q, q, g, ints[SC_N], g.shape[0])
        return 0 if st == 0 else st * 8 + U_GAPS
    return 0


@_internal
def jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, G):
    """G(q) into ``G`` (m + mf + me, n): the contacts' rows, then the tangent rows of
    friction, then the bilateral rows; ``c, s`` = cos q, sin q."""
    for ic in range(bkind.shape[0]):
        kind = bkind[ic]
        if kind == _k.BAR_LINEAR:
            _k.jacobian_linear(pool, boff[ic], bnrows[ic], G, brow[ic])
        elif kind == _k.BAR_TRIG:
            _k.jacobian_trig(pool, boff[ic], bnrows[ic], c, s, G, brow[ic])
        elif kind == _k.BAR_CHAIN_POINT:
            _k.jacobian_chain_point(pool, boff[ic], bnrows[ic], c, s, G, brow[ic])
    if user[U_JACOBIANS] != 0:
        st = call_user(user[U_JACOBIANS], 0.0, q, q, G, ints[SC_N], G.shape[0])
        return 0 if st == 0 else st * 8 + U_JACOBIANS
    return 0


# the sites that run in few steps (the drift projection, the energy check, a chunk's first
# step) call one compiled copy of the evaluations instead of each inlining its own
@_apart
def mass_apart(ints, pool, user, q, c, s, M):
    """:func:`mass`, as a call."""
    return mass(ints, pool, user, q, c, s, M)


@_apart
def gaps_apart(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, g):
    """:func:`gaps`, as a call."""
    return gaps(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, g)


@_apart
def jacobian_apart(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, G):
    """:func:`jacobian`, as a call."""
    return jacobian(ints, bkind, boff, brow, bnrows, pool, user, q, c, s, G)


@_jit
def potential(ints, ekind, eoff, pool, q, c, s):
    """Potential energy of the built-in conservative effects, up to a constant (J)."""
    n = ints[SC_N]
    nn = n * n
    V = 0.0
    for e in range(ints[SC_N_EFFECTS]):
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
