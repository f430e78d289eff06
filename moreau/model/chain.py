"""Planar serial chain of physical pendulums: M(q), bias terms, point kinematics, effects
and barriers.

The model is the triple physical pendulum of Awrejcewicz & Kudra (eq. (2.1)–(2.3)),
generalized to N >= 1 links. Link i (0-based: link 0 hangs from the fixed pivot) has
mass m_i, central moment of inertia J_i (about its centre of mass), joint-to-joint
length l_i and its centre of mass at ``(com_i, com_lateral_i)`` in the link frame.
The generalized coordinates are the ABSOLUTE angles φ_i of the links, measured from a
reference axis u; positive φ turns the link from u towards a lateral axis w:

.. math:: e(φ) = \\cos φ\\, u + \\sin φ\\, w, \\qquad e^\\perp(φ) = -\\sin φ\\, u + \\cos φ\\, w.

``"hanging"``: u = (0, −1), w = (1, 0), so e(φ) = (sin φ, −cos φ);
``"inverted"``: u = (0, 1), w = (1, 0), so e(φ) = (sin φ, cos φ) (the paper's engine).

A point fixed on link k at link-frame coordinates ``local = (a, b)`` (``a`` along the
link from its proximal joint, ``b`` across it, along e⊥) is at

.. math:: p = p_0 + \\sum_{i<k} l_i e(φ_i) + a\\, e(φ_k) + b\\, e^\\perp(φ_k).

Every quantity below is of the form ``Σ_i [C_i cos φ_i + S_i sin φ_i]`` with constant
coefficients, which are precomputed once so that the per-step evaluations are a handful
of vectorized numpy operations.

Mass matrix and bias force (derived from ``T = ½ Σ_k m_k |v_Ck|² + ½ J_k φ̇_k²``):

.. math:: M_{ij} = ν_{ij} \\cos(φ_i - φ_j) + ν^s_{ij} \\sin(φ_i - φ_j),
.. math:: f_{\\mathrm{bias}} = -N(φ)\\,\\dot φ^2,\\quad
          N_{ij} = ν_{ij} \\sin(φ_i - φ_j) - ν^s_{ij} \\cos(φ_i - φ_j),

where ν (symmetric, ν_ii = M_ii) and ν^s (antisymmetric, zero without lateral offsets)
are constant. Without lateral offsets this is exactly the paper's eq. (2.1)–(2.2) in
physical units; :meth:`PendulumChain.nondimensional` gives the paper's scaling M_11 = 1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_vector
from moreau.model.barriers import Barrier
from moreau.model.forces import Effect, FourierLoad, _is_compiled
from moreau.model.system import MechanicalSystem

__all__ = [
    "Link",
    "PendulumChain",
    "Units",
    "Nondimensional",
    "ChainGravity",
    "JointDamping",
    "JointSprings",
    "LinkTorque",
    "PointForce",
    "PointLineRow",
    "PointLineBarrier",
    "JointStop",
]

_ORIENTATIONS = {
    "hanging": ((0.0, -1.0), (1.0, 0.0)),
    "inverted": ((0.0, 1.0), (1.0, 0.0)),
}


# ----------------------------------------------------------------------------------------
# links and the chain
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Link:
    """One rigid link of a planar pendulum chain.

    Parameters
    ----------
    m : float
        Mass (kg), > 0.
    J : float
        Central moment of inertia about the axis through the centre of mass normal to
        the plane (kg m²), > 0 (the paper's J_zi, "principal central axes").
    l : float
        Joint-to-joint length (m), >= 0: distance from the link's proximal joint to the
        joint of the next link. Irrelevant for the dynamics of the last link (used only
        by :meth:`PendulumChain.joint_positions`).
    com : float
        Centre-of-mass offset along the link from its proximal joint (m; the paper's e_yi).
    com_lateral : float
        Centre-of-mass offset across the link, along e⊥ (m), default 0.

    Raises
    ------
    ValueError
        For a non-finite or non-positive mass or inertia, a negative or non-finite
        length, or a non-finite offset (the message names the field and the value).
    """

    m: float
    J: float
    l: float
    com: float
    com_lateral: float = 0.0

    def __post_init__(self) -> None:
        for name in ("m", "J", "l", "com", "com_lateral"):
            raw = getattr(self, name)
            try:
                val = float(raw)
            except (TypeError, ValueError):
                raise ValueError(f"Link.{name} must be a number, got {raw!r}") from None
            if not np.isfinite(val):
                raise ValueError(f"Link.{name} must be finite, got {raw!r}")
            object.__setattr__(self, name, val)
        if self.m <= 0.0:
            raise ValueError(f"Link.m (mass, kg) must be > 0, got {self.m!r}")
        if self.J <= 0.0:
            raise ValueError(f"Link.J (central moment of inertia, kg m^2) must be > 0, got {self.J!r}")
        if self.l < 0.0:
            raise ValueError(f"Link.l (joint-to-joint length, m) must be >= 0, got {self.l!r}")

    @classmethod
    def rod(cls, m: float, l: float) -> Link:
        """A uniform slender rod: J = m l²/12, centre of mass at l/2."""
        return cls(m=m, J=m * l * l / 12.0, l=l, com=0.5 * l)

    def as_dict(self) -> dict:
        return {"m": self.m, "J": self.J, "l": self.l, "com": self.com, "com_lateral": self.com_lateral}


class PendulumChain(MechanicalSystem):
    """Planar serial chain of N >= 1 physical pendulums with a fixed first pivot.

    Coordinates q = (φ_0, …, φ_{N−1}) are absolute link angles (rad) from the reference
    axis (see the module docstring); velocities are the angular velocities (rad/s).
    Link indices are 0-based.

    Parameters
    ----------
    links : sequence of Link (or mappings of Link's fields)
        The links, from the pivot outwards.
    pivot : array_like, shape (2,)
        Position of the fixed first joint (m), default the origin.
    orientation : {"hanging", "inverted"} or (axis, lateral)
        Reference axis of the angles. ``"hanging"``: φ from the downward vertical,
        e(φ) = (sin φ, −cos φ); ``"inverted"``: φ from the upward vertical,
        e(φ) = (sin φ, cos φ), as in the paper's engine. A pair of orthonormal
        2-vectors ``(u, w)`` gives a general axis: e(φ) = cos φ u + sin φ w.

    Attributes
    ----------
    ndof : int
        N.
    links : tuple of Link
    nu : ndarray, shape (N, N)
        Constant symmetric coefficients ν of the cos terms of M (kg m²); ν_ii = M_ii.
    nu_lateral : ndarray, shape (N, N)
        Constant antisymmetric coefficients of the sin terms of M (kg m²); zero when no
        centre of mass is off the link axis.
    has_bias : bool
        True for N >= 2 (a single link has a constant mass matrix and no bias).

    Raises
    ------
    ValueError
        For zero links, an invalid link (the message names the link index), a bad pivot
        or orientation.

    Examples
    --------
    >>> chain = PendulumChain([Link.rod(1.0, 0.5), Link.rod(1.0, 0.5)])
    >>> chain.mass_matrix(np.zeros(2)).shape
    (2, 2)
    """

    constant_mass = False

    def __init__(
        self,
        links: Sequence[Link | Mapping],
        pivot=(0.0, 0.0),
        orientation: str | tuple = "hanging",
    ) -> None:
        try:
            links = list(links)
        except TypeError:
            raise ValueError(f"PendulumChain: links must be a sequence of Link objects, got {links!r}") from None
        if not links:
            raise ValueError("PendulumChain needs at least one link, got zero links")
        checked = []
        for i, link in enumerate(links):
            if isinstance(link, Link):
                checked.append(link)
                continue
            try:
                checked.append(Link(**link))
            except (TypeError, ValueError) as exc:
                raise ValueError(f"link {i}: {exc}") from None
        self.links = tuple(checked)
        n = len(self.links)
        self.ndof = n
        self.pivot = as_vector(pivot, "PendulumChain.pivot", 2)
        self.orientation, self.axis, self.lateral = _orientation(orientation)
        self.masses = np.array([k.m for k in self.links])
        self.inertias = np.array([k.J for k in self.links])
        self.lengths = np.array([k.l for k in self.links])
        for a in (self.pivot, self.masses, self.inertias, self.lengths):
            a.setflags(write=False)

        # levers of the centres of mass: row k = coefficients of e(φ_i), e⊥(φ_i) in p_Ck
        LC = np.zeros((n, n))
        LS = np.zeros((n, n))
        for k, link in enumerate(self.links):
            LC[k, :k] = self.lengths[:k]
            LC[k, k] = link.com
            LS[k, k] = link.com_lateral
        self._com_levers = (LC, LS)
        m = self.masses
        nu = np.einsum("k,ki,kj->ij", m, LC, LC) + np.einsum("k,ki,kj->ij", m, LS, LS)
        nu += np.diag(self.inertias)
        nu = 0.5 * (nu + nu.T)  # exactly symmetric (einsum's rounding is not)
        nu_s = np.einsum("k,ki,kj->ij", m, LC, LS)
        nu_s = nu_s - nu_s.T
        self.nu = nu
        self.nu_lateral = nu_s
        self.nu.setflags(write=False)
        self.nu_lateral.setflags(write=False)
        self._lateral = bool(np.any(nu_s != 0.0))
        # hot-path constants
        self._nu_c = np.array(nu)
        self._nu_s = np.array(nu_s)
        self._pm = _k.flat(nu, nu_s)  # layout of kernels.chain_mass
        self.has_bias = n > 1

    @classmethod
    def from_arrays(cls, m, J, l, com, com_lateral=None, pivot=(0.0, 0.0),
                    orientation: str | tuple = "hanging") -> PendulumChain:
        """A chain from per-link arrays of shape (N,) (same units as :class:`Link`).

        Raises ``ValueError`` naming the link index and the bad value.
        """
        arrays = [np.atleast_1d(np.asarray(a, dtype=float)) for a in (m, J, l, com)]
        n = arrays[0].shape[0]
        lat = np.zeros(n) if com_lateral is None else np.atleast_1d(np.asarray(com_lateral, dtype=float))
        for name, a in zip(("m", "J", "l", "com", "com_lateral"), (*arrays, lat)):
            if a.shape != (n,):
                raise ValueError(f"PendulumChain.from_arrays: {name} has shape {a.shape}, expected ({n},)")
        return cls(
            [dict(m=arrays[0][i], J=arrays[1][i], l=arrays[2][i], com=arrays[3][i], com_lateral=lat[i])
             for i in range(n)],
            pivot=pivot, orientation=orientation,
        )

    # -- dynamics (hot path) ----------------------------------------------------------------
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q) = ν ∘ cos(φ_i − φ_j) + ν^s ∘ sin(φ_i − φ_j), shape (N, N) (kg m²).

        ``q`` must be a float ndarray of shape (N,) (hot path: no conversion).
        """
        out = np.empty((self.ndof, self.ndof))
        _k.chain_mass(self._pm, 0, *_k.cos_sin(q), out)
        return out

    def bias_force(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Centrifugal terms −N(q) φ̇², shape (N,) (N m), on the right-hand side.

        ``q`` and ``v`` must be float ndarrays of shape (N,) (hot path: no conversion).
        """
        return _k.force_of(_k.add_chain_bias, self.ndof, self._pm, 0, *_k.cos_sin(q), v)

    def mass_kernel(self):
        """``(kind, params)`` of the compiled mass matrix and bias (see :mod:`moreau.core.kernels`)."""
        return _k.MASS_CHAIN, (self._pm,)

    def kinetic_energy(self, q, v) -> float:
        """Kinetic energy ½ vᵀ M(q) v (J) = ``Σ_k ½ m_k |v_Ck|² + ½ J_k φ̇_k²``."""
        v = np.asarray(v, dtype=float)
        return 0.5 * float(v @ self.mass_matrix(np.asarray(q, dtype=float)) @ v)

    def n_matrix(self, q: np.ndarray) -> np.ndarray:
        """The paper's N(q) of eq. (2.2), shape (N, N): ``M φ̈ + N φ̇² = Q``."""
        q = np.asarray(q, dtype=float)
        d = q[:, None] - q[None, :]
        return self._nu_c * np.sin(d) - self._nu_s * np.cos(d)

    # -- kinematics -------------------------------------------------------------------------
    def check_link(self, link, what: str = "link") -> int:
        """The link index as an int in [0, N), or ``ValueError`` naming it."""
        if isinstance(link, bool) or not isinstance(link, (int, np.integer)):
            raise ValueError(f"{what} index must be an integer, got {link!r}")
        if not 0 <= link < self.ndof:
            raise ValueError(f"{what} index {link} is out of range for a chain of {self.ndof} links "
                             f"(0..{self.ndof - 1})")
        return int(link)

    def levers(self, link: int, local) -> tuple[np.ndarray, np.ndarray]:
        """Constant coefficients (C, S), each (N,), of a point fixed on a link:
        ``p = pivot + Σ_i C_i e(φ_i) + S_i e⊥(φ_i)`` (m)."""
        k = self.check_link(link)
        a, b = as_vector(local, "local (along, across)", 2)
        C = np.zeros(self.ndof)
        S = np.zeros(self.ndof)
        C[:k] = self.lengths[:k]
        C[k] = a
        S[k] = b
        return C, S

    def _basis(self, q):
        c, s = np.cos(q), np.sin(q)
        u, w = self.axis, self.lateral
        return c, s, u, w

    def point_position(self, q, link: int, local) -> np.ndarray:
        """Position (m), shape (2,), of the point at ``local = (along, across)`` (m) in the
        frame of ``link`` (origin at its proximal joint)."""
        C, S = self.levers(link, local)
        c, s, u, w = self._basis(np.asarray(q, dtype=float))
        return self.pivot + u * (C @ c - S @ s) + w * (C @ s + S @ c)

    def point_jacobian(self, q, link: int, local) -> np.ndarray:
        """Jacobian ∂p/∂q (m/rad), shape (2, N), of a point fixed on a link."""
        C, S = self.levers(link, local)
        c, s, u, w = self._basis(np.asarray(q, dtype=float))
        return np.outer(u, -C * s - S * c) + np.outer(w, C * c - S * s)

    def point_velocity(self, q, v, link: int, local) -> np.ndarray:
        """Velocity (m/s), shape (2,), of a point fixed on a link."""
        return self.point_jacobian(q, link, local) @ np.asarray(v, dtype=float)

    def joint_positions(self, q) -> np.ndarray:
        """Positions (m), shape (N + 1, 2): the pivot, the joints, and the end of the last
        link (at distance l_{N−1} from its joint)."""
        c, s, u, w = self._basis(np.asarray(q, dtype=float))
        e = np.outer(c, u) + np.outer(s, w)
        out = np.empty((self.ndof + 1, 2))
        out[0] = self.pivot
        out[1:] = self.pivot + np.cumsum(self.lengths[:, None] * e, axis=0)
        return out

    def com_positions(self, q) -> np.ndarray:
        """Positions of the centres of mass (m), shape (N, 2)."""
        LC, LS = self._com_levers
        c, s, u, w = self._basis(np.asarray(q, dtype=float))
        return self.pivot + np.outer(LC @ c - LS @ s, u) + np.outer(LC @ s + LS @ c, w)

    def _projection(self, direction, C, S) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients (A, B) with ``direction · (p − pivot) = A·cos q + B·sin q``."""
        du = float(direction @ self.axis)
        dw = float(direction @ self.lateral)
        return C * du + S * dw, C * dw - S * du

    # -- scaling ----------------------------------------------------------------------------
    def nondimensional(self, length_scale: float | None = None, time_scale: float = 1.0) -> Nondimensional:
        """The chain in the paper's non-dimensional units and its dimensionless groups.

        Lengths are divided by ``length_scale`` (default l_0, the paper's l_1), times by
        ``time_scale`` (s), and masses by the mass unit M_00 / L², chosen so that the
        (configuration-independent) ``M_00 = J_0 + m_0 |c_0|² + (Σ_{k>0} m_k) l_0²`` becomes 1,
        as in eq. (2.1). A scene built from the returned chain runs in non-dimensional time
        τ = t / time_scale; convert its effects with :class:`Units`.

        Raises
        ------
        ValueError
            For a non-positive scale (or l_0 = 0 with no ``length_scale``).
        """
        L = float(self.lengths[0]) if length_scale is None else float(length_scale)
        if not (np.isfinite(L) and L > 0.0):
            raise ValueError(f"length_scale must be finite and > 0, got {L!r}")
        T = float(time_scale)
        if not (np.isfinite(T) and T > 0.0):
            raise ValueError(f"time_scale must be finite and > 0, got {time_scale!r}")
        M11 = float(self.nu[0, 0])
        units = Units(length=L, time=T, mass=M11 / (L * L))
        mu = units.mass
        scaled = PendulumChain(
            [Link(m=k.m / mu, J=k.J / (mu * L * L), l=k.l / L, com=k.com / L, com_lateral=k.com_lateral / L)
             for k in self.links],
            pivot=self.pivot / L,
            orientation=(self.axis, self.lateral),
        )
        scaled.orientation = self.orientation
        return Nondimensional(
            chain=scaled,
            units=units,
            beta=np.diag(self.nu) / M11,
            nu=self.nu / M11,
            nu_lateral=self.nu_lateral / M11,
            lam=self.lengths / L,
        )

    def describe(self) -> dict:
        return {
            **super().describe(),
            "orientation": self.orientation,
            "axis": self.axis.tolist(),
            "lateral": self.lateral.tolist(),
            "pivot": self.pivot.tolist(),
            "links": [k.as_dict() for k in self.links],
        }

    def __repr__(self) -> str:
        return f"PendulumChain(N={self.ndof}, orientation={self.orientation!r})"


def _orientation(spec) -> tuple[str, np.ndarray, np.ndarray]:
    if isinstance(spec, str):
        if spec not in _ORIENTATIONS:
            raise ValueError(f"orientation must be one of {sorted(_ORIENTATIONS)} or (axis, lateral), got {spec!r}")
        u0, w0 = _ORIENTATIONS[spec]
        u, w, name = np.array(u0), np.array(w0), spec
    else:
        try:
            u1, w1 = spec
        except (TypeError, ValueError):
            raise ValueError(f"orientation must be a name or a pair (axis, lateral), got {spec!r}") from None
        u = as_vector(u1, "orientation axis", 2)
        w = as_vector(w1, "orientation lateral", 2)
        if abs(u @ u - 1.0) > 1e-9 or abs(w @ w - 1.0) > 1e-9 or abs(u @ w) > 1e-9:
            raise ValueError(f"orientation (axis, lateral) must be orthonormal, got {u.tolist()}, {w.tolist()}")
        name = "custom"
    u.setflags(write=False)
    w.setflags(write=False)
    return name, u, w


# ----------------------------------------------------------------------------------------
# non-dimensional view
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Units:
    """Scales of a non-dimensional chain: divide a physical quantity by its scale.

    Parameters
    ----------
    length : float
        Length unit L (m).
    time : float
        Time unit T (s).
    mass : float
        Mass unit μ (kg), chosen so that M_00 = 1.
    """

    length: float
    time: float
    mass: float

    @property
    def velocity(self) -> float:
        """L/T (m/s)."""
        return self.length / self.time

    @property
    def acceleration(self) -> float:
        """L/T² (m/s²): non-dimensional gravity is g / acceleration."""
        return self.length / self.time**2

    @property
    def force(self) -> float:
        """μ L/T² (N)."""
        return self.mass * self.length / self.time**2

    @property
    def torque(self) -> float:
        """μ L²/T² (N m); also the energy unit (J)."""
        return self.mass * self.length**2 / self.time**2

    @property
    def energy(self) -> float:
        """μ L²/T² (J)."""
        return self.torque

    @property
    def damping(self) -> float:
        """Torque·time μ L²/T (N m s): unit of joint damping coefficients."""
        return self.mass * self.length**2 / self.time

    @property
    def stiffness(self) -> float:
        """Torque per radian μ L²/T² (N m/rad): unit of torsional springs."""
        return self.torque

    @property
    def impulse(self) -> float:
        """Force·time μ L/T (N s): unit of contact impulses on length gaps."""
        return self.mass * self.length / self.time

    @property
    def angular_impulse(self) -> float:
        """Torque·time μ L²/T (N m s): unit of impulses on angle gaps (joint stops)."""
        return self.damping


@dataclass(frozen=True)
class Nondimensional:
    """A chain in non-dimensional units with the paper's dimensionless groups.

    Attributes
    ----------
    chain : PendulumChain
        The scaled chain: its mass matrix has M_00 = 1.
    units : Units
        The scales.
    beta : ndarray, shape (N,)
        β_i = M_ii / M_00 (β_0 = 1).
    nu : ndarray, shape (N, N)
        ν_ij / M_00: the paper's ν_ij off the diagonal, β_i on it.
    nu_lateral : ndarray, shape (N, N)
        Lateral-offset coefficients / M_00 (zero in the paper's model).
    lam : ndarray, shape (N,)
        Length ratios λ_i = l_i / L (λ_0 = 1 with the default length scale).
    """

    chain: PendulumChain
    units: Units
    beta: np.ndarray
    nu: np.ndarray
    nu_lateral: np.ndarray
    lam: np.ndarray


# ----------------------------------------------------------------------------------------
# effects
# ----------------------------------------------------------------------------------------
def _require_chain(chain, who: str) -> PendulumChain:
    if not isinstance(chain, PendulumChain):
        raise ValueError(f"{who}: chain must be a PendulumChain, got {chain!r}")
    return chain


def _relative_matrix(n: int) -> np.ndarray:
    """D (N x N) with (D φ)_0 = φ_0 and (D φ)_i = φ_i − φ_{i−1}: joint rotations."""
    return np.eye(n) - np.eye(n, k=-1)


def _per_joint(x, n: int, what: str, nonneg: bool = True) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    a = as_vector(a, what, n)
    if nonneg and np.any(a < 0.0):
        i = int(np.flatnonzero(a < 0.0)[0])
        raise ValueError(f"{what}[{i}] must be >= 0, got {a[i]!r}")
    return a


class ChainGravity(Effect):
    """Uniform gravity on every link of a chain.

    Force ``f_i = −∂V/∂φ_i`` with ``V = −g d · Σ_k m_k p_Ck(q)`` (J).

    Parameters
    ----------
    chain : PendulumChain
    g : float
        Gravitational acceleration (m/s², or the chain's acceleration unit).
    direction : array_like, shape (2,)
        Direction of gravity (normalized), default (0, −1).
    """

    has_potential = True
    name = "gravity"

    def __init__(self, chain: PendulumChain, g: float = 9.81, direction=(0.0, -1.0), name: str = "gravity") -> None:
        chain = _require_chain(chain, "ChainGravity")
        self.g = float(g)
        if not np.isfinite(self.g):
            raise ValueError(f"ChainGravity: g must be finite, got {g!r}")
        d = as_vector(direction, "ChainGravity.direction", 2)
        nd = float(np.hypot(*d))
        if nd == 0.0:
            raise ValueError("ChainGravity.direction must be non-zero")
        self.direction = d / nd
        LC, LS = chain._com_levers
        m = chain.masses
        A, B = chain._projection(self.direction, m @ LC, m @ LS)
        self._A = self.g * A
        self._B = self.g * B
        self._p = _k.flat(self._A, self._B)
        self._V0 = -self.g * float(m.sum()) * float(self.direction @ chain.pivot)
        self.name = name

    def force(self, t, q, v):
        return _k.force_of(_k.add_trig, q.shape[0], self._p, 0, *_k.cos_sin(q))

    def kernel(self):
        return _k.TRIG, (self._p,)

    def potential(self, q):
        return self._V0 - float(self._A @ np.cos(q) + self._B @ np.sin(q))

    def describe(self):
        return {**super().describe(), "g": self.g, "direction": self.direction.tolist()}


class JointDamping(Effect):
    """Viscous damping in the joints: ``f = −C φ̇``.

    Joint 0 connects link 0 to the ground (relative velocity φ̇_0), joint i links i−1
    and i (relative velocity φ̇_i − φ̇_{i−1}); C = Dᵀ diag(c) D is tridiagonal. For
    N = 3 and c = c̄_1 (1, c_21, c_31) it is the paper's
    c̄_1 [[1 + c_21, −c_21, 0], [−c_21, c_21 + c_31, −c_31], [0, −c_31, c_31]].

    Parameters
    ----------
    chain : PendulumChain
    c : array_like, shape (N,), or float
        Viscous coefficients of the joints (N m s), >= 0.
    """

    velocity_dependent = True

    def __init__(self, chain: PendulumChain, c, name: str = "joint damping") -> None:
        chain = _require_chain(chain, "JointDamping")
        n = chain.ndof
        self.c = _per_joint(c, n, "JointDamping.c")
        D = _relative_matrix(n)
        self.C = D.T @ (self.c[:, None] * D)
        self.C.setflags(write=False)
        self._p = _k.flat(self.C)
        self.name = name

    def force(self, t, q, v):
        return _k.force_of(_k.add_linear_v, q.shape[0], self._p, 0, v)

    def kernel(self):
        return _k.LINEAR_V, (self._p,)

    def describe(self):
        return {**super().describe(), "c": self.c.tolist()}


class JointSprings(Effect):
    """Linear torsional springs in the joints: torque −k_i (θ_i − rest_i) on the joint
    rotation θ = D φ (θ_0 = φ_0, θ_i = φ_i − φ_{i−1}); f = −Dᵀ diag(k) (D φ − rest).

    Parameters
    ----------
    chain : PendulumChain
    k : array_like, shape (N,), or float
        Stiffnesses (N m/rad), >= 0.
    rest : array_like, shape (N,), optional
        Rest joint rotations (rad), zeros by default.
    """

    has_potential = True

    def __init__(self, chain: PendulumChain, k, rest=None, name: str = "joint springs") -> None:
        chain = _require_chain(chain, "JointSprings")
        n = chain.ndof
        self.k = _per_joint(k, n, "JointSprings.k")
        self.rest = np.zeros(n) if rest is None else as_vector(rest, "JointSprings.rest", n)
        self._D = _relative_matrix(n)
        self.K = self._D.T @ (self.k[:, None] * self._D)
        self.K.setflags(write=False)
        self._negK = -self.K
        self._b = self._D.T @ (self.k * self.rest)
        self._p = _k.flat(self.K, self._b)
        self.name = name

    def force(self, t, q, v):
        return _k.force_of(_k.add_affine_q, q.shape[0], self._p, 0, q)

    def kernel(self):
        return _k.AFFINE_Q, (self._p,)

    def potential(self, q):
        th = self._D @ q - self.rest
        return 0.5 * float(self.k @ (th * th))

    def describe(self):
        return {**super().describe(), "k": self.k.tolist(), "rest": self.rest.tolist()}


class LinkTorque(Effect):
    """Torques applied to the links (positive in the sense of increasing φ).

    Since the coordinates are absolute angles, the generalized force is the torque
    vector itself. The brake of the paper's engine is ``LinkTorque(chain, [-M0, 0, 0])``.

    Parameters
    ----------
    chain : PendulumChain
    torques : array_like, shape (N,), or callable ``torques(t, q, v) -> (N,)``
        Constant torques (N m; potential −τ·q) or a function of the state.
    velocity_dependent, time_dependent : bool
        What a callable depends on (default True, the safe assumption); ignored for a
        constant.
    """

    def __init__(self, chain: PendulumChain, torques, velocity_dependent: bool = True,
                 time_dependent: bool = True, name: str = "torque") -> None:
        chain = _require_chain(chain, "LinkTorque")
        self.name = name
        if callable(torques):
            self.tau = None
            self.force = torques  # type: ignore[method-assign]  # bound directly: no extra call layer
            self.velocity_dependent = bool(velocity_dependent)
            self.time_dependent = bool(time_dependent)
            self.has_potential = False
        else:
            self.tau = as_vector(torques, "LinkTorque.torques", chain.ndof)
            self.tau.setflags(write=False)
            self.velocity_dependent = self.time_dependent = False
            self.has_potential = True

    def force(self, t, q, v):
        return self.tau

    def kernel(self):
        if self.tau is not None:
            return _k.CONST, (self.tau,)
        return ("user", self.force) if _is_compiled(self.force) else None

    def potential(self, q):
        if self.tau is None:
            return super().potential(q)
        return -float(self.tau @ q)

    def describe(self):
        d = super().describe()
        d["torques"] = self.tau.tolist() if self.tau is not None else "callable"
        return d


class PointForce(Effect):
    """A force applied at a point fixed on a link: generalized force J_pᵀ F.

    Parameters
    ----------
    chain : PendulumChain
    link : int
        Index of the link carrying the point.
    local : array_like, shape (2,)
        (along, across) coordinates of the point in the link frame (m).
    force : array_like, shape (2,), or callable ``force(t, q, v) -> (2,)``
        The force in the plane (N). A constant force has the potential −F·p(q).
    velocity_dependent, time_dependent : bool
        What a callable depends on (default True); ignored for a constant. The piston's
        gas force F(φ_0) is ``time_dependent=False, velocity_dependent=False``.
    """

    def __init__(self, chain: PendulumChain, link: int, local, force,
                 velocity_dependent: bool = True, time_dependent: bool = True,
                 name: str = "point force") -> None:
        chain = _require_chain(chain, "PointForce")
        self.link = chain.check_link(link)
        self.local = as_vector(local, "PointForce.local", 2)
        C, S = chain.levers(self.link, self.local)
        u, w = chain.axis, chain.lateral
        # J_pᵀ F = cos q ∘ (X F) + sin q ∘ (Y F): column i of J_p is C_i e⊥_i − S_i e_i
        self._X = np.outer(C, w) - np.outer(S, u)
        self._Y = -np.outer(C, u) - np.outer(S, w)
        self.name = name
        self._pf = None
        if callable(force):
            self.F = None
            self._fun = force
            self.velocity_dependent = bool(velocity_dependent)
            self.time_dependent = bool(time_dependent)
            self.has_potential = False
            self.force = self._force_callable  # type: ignore[method-assign]
            if isinstance(force, FourierLoad):  # layout of kernels.add_point_fourier
                self._pf = _k.flat(self._X, self._Y, force.direction,
                                   [force.a0, force.omega, force.coordinate, force.a.shape[0]], force.a, force.b)
        else:
            self.F = as_vector(force, "PointForce.force", 2)
            self.velocity_dependent = self.time_dependent = False
            self.has_potential = True
            self._A, self._B = chain._projection(self.F, C, S)
            self._p = _k.flat(self._A, self._B)
            self._V0 = -float(self.F @ chain.pivot)

    def force(self, t, q, v):
        return _k.force_of(_k.add_trig, q.shape[0], self._p, 0, *_k.cos_sin(q))

    def kernel(self):
        if self.F is not None:
            return _k.TRIG, (self._p,)
        if self._pf is not None:
            return _k.FOURIER_PT, (self._pf,)
        return None

    def _force_callable(self, t, q, v):
        if self._pf is not None:  # the compiled kernel, also here
            return _k.force_of(_k.add_point_fourier, q.shape[0], self._pf, 0, q, *_k.cos_sin(q))
        F = self._fun(t, q, v)
        return np.cos(q) * (self._X @ F) + np.sin(q) * (self._Y @ F)

    def potential(self, q):
        if self.F is None:
            return super().potential(q)
        return self._V0 - float(self._A @ np.cos(q) + self._B @ np.sin(q))

    def describe(self):
        return {**super().describe(), "link": self.link, "local": self.local.tolist(),
                "force": self.F.tolist() if self.F is not None else "callable"}


# ----------------------------------------------------------------------------------------
# barriers
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PointLineRow:
    """One row of a :class:`PointLineBarrier`: a point fixed on a link against a line.

    Parameters
    ----------
    link : int
        Index of the link carrying the point.
    local : array_like, shape (2,)
        (along, across) coordinates of the point in the link frame (m).
    line_point : array_like, shape (2,)
        A point of the line (m).
    normal : array_like, shape (2,)
        Normal of the line pointing into the admissible side (normalized on use).
    name : str, optional
        Label of the row in results.
    """

    link: int
    local: tuple
    line_point: tuple
    normal: tuple
    name: str | None = None


class PointLineBarrier(Barrier):
    """Points fixed on links kept on one side of straight lines (walls).

    Row r: ``g_r(q) = n_r · (p_r(q) − a_r)`` (m), the signed distance of the point p_r
    from the line through a_r with unit normal n_r; ``G_r = n_rᵀ J_{p_r}(q)``. All rows
    are evaluated together: ``g = g_0 + A cos q + B sin q``, ``G = B ∘ cos q − A ∘ sin q``
    with constant (m, N) matrices A, B.

    Parameters
    ----------
    chain : PendulumChain
    rows : PointLineRow or sequence of PointLineRow (or of tuples
        ``(link, local, line_point, normal)``)
        The point/line pairs.

    Raises
    ------
    ValueError
        For no rows, a zero normal, or a link index out of range (named).
    """

    def __init__(self, chain: PendulumChain, rows) -> None:
        chain = _require_chain(chain, "PointLineBarrier")
        if isinstance(rows, PointLineRow):
            rows = [rows]
        rows = list(rows)
        if not rows:
            raise ValueError("PointLineBarrier needs at least one row")
        self.rows = tuple(r if isinstance(r, PointLineRow) else PointLineRow(*r) for r in rows)
        m, n = len(self.rows), chain.ndof
        A = np.empty((m, n))
        B = np.empty((m, n))
        g0 = np.empty(m)
        self.normals = np.empty((m, 2))
        for r, row in enumerate(self.rows):
            where = f"PointLineBarrier row {r}"
            try:
                C, S = chain.levers(chain.check_link(row.link, f"{where}: link"), row.local)
            except ValueError as exc:
                msg = str(exc)
                raise ValueError(msg if msg.startswith(where) else f"{where}: {msg}") from None
            nrm = as_vector(row.normal, f"{where}: normal", 2)
            length = float(np.hypot(*nrm))
            if length == 0.0:
                raise ValueError(f"{where}: the normal of the line must be non-zero, got {nrm.tolist()}")
            nrm = nrm / length
            a = as_vector(row.line_point, f"{where}: line_point", 2)
            A[r], B[r] = chain._projection(nrm, C, S)
            g0[r] = float(nrm @ (chain.pivot - a))
            self.normals[r] = nrm
        self.nrows, self.ndof = m, n
        self._n = n
        self._A, self._B, self._g0 = A, B, g0
        self._p = _k.flat(g0, A, B)  # layout of kernels.gaps_trig
        self.normals.setflags(write=False)

    def gap(self, q):
        out = np.empty(self.nrows)
        _k.gaps_trig(self._p, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def jacobian(self, q):
        out = np.empty((self.nrows, self._n))
        _k.jacobian_trig(self._p, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def kernel(self):
        return _k.BAR_TRIG, (self._p,)

    def gap_scale(self):
        return np.abs(self._g0) + np.abs(self._A).sum(axis=1) + np.abs(self._B).sum(axis=1)

    def row_names(self, prefix):
        if self.nrows == 1 and self.rows[0].name is None:
            return [prefix]
        return [f"{prefix}[{r.name if r.name is not None else i}]" for i, r in enumerate(self.rows)]

    def describe(self):
        return {
            **super().describe(),
            "rows": [
                {"link": int(r.link), "local": np.asarray(r.local, float).tolist(),
                 "line_point": np.asarray(r.line_point, float).tolist(),
                 "normal": self.normals[i].tolist(), "name": r.name}
                for i, r in enumerate(self.rows)
            ],
        }


class JointStop(Barrier):
    """Angle stops: ``lower <= θ <= upper`` with θ = φ_i, or θ = φ_i − φ_j when
    ``relative_to = j`` (the joint between links j and i when j = i − 1).

    Rows (rad): ``θ − lower`` and/or ``upper − θ``; the Jacobian is constant.

    Parameters
    ----------
    chain : PendulumChain
    link : int
        Index i of the link whose angle is stopped.
    lower, upper : float, optional
        Bounds (rad); at least one, and lower < upper when both.
    relative_to : int, optional
        Index j: stop the relative angle φ_i − φ_j instead of φ_i.
    """

    constant_jacobian = True

    def __init__(self, chain: PendulumChain, link: int, lower: float | None = None,
                 upper: float | None = None, relative_to: int | None = None) -> None:
        chain = _require_chain(chain, "JointStop")
        self.link = chain.check_link(link, "JointStop: link")
        self.relative_to = None if relative_to is None else chain.check_link(relative_to, "JointStop: relative_to link")
        if self.relative_to == self.link:
            raise ValueError(f"JointStop: relative_to must differ from link, got {link} twice")
        if lower is None and upper is None:
            raise ValueError("JointStop needs a lower or an upper bound (or both)")
        self.lower = None if lower is None else _finite(lower, "JointStop.lower")
        self.upper = None if upper is None else _finite(upper, "JointStop.upper")
        if self.lower is not None and self.upper is not None and not self.lower < self.upper:
            raise ValueError(f"JointStop: lower must be < upper, got {self.lower!r} >= {self.upper!r}")
        a = np.zeros(chain.ndof)
        a[self.link] = 1.0
        if self.relative_to is not None:
            a[self.relative_to] = -1.0
        rows, b, self._names = [], [], []
        if self.lower is not None:
            rows.append(a)
            b.append(-self.lower)
            self._names.append("lower")
        if self.upper is not None:
            rows.append(-a)
            b.append(self.upper)
            self._names.append("upper")
        self.G = np.array(rows)
        self.G.setflags(write=False)
        self._b = np.array(b)
        self.nrows, self.ndof = self.G.shape
        self._p = _k.flat(self.G, self._b)

    def gap(self, q):
        out = np.empty(self.nrows)
        _k.gaps_linear(self._p, 0, self.nrows, q, out, 0)
        return out

    def jacobian(self, q):
        return self.G

    def kernel(self):
        return _k.BAR_LINEAR, (self._p,)

    def gap_scale(self):
        return np.abs(self._b) + np.abs(self.G).sum(axis=1)

    def row_names(self, prefix):
        if self.nrows == 1:
            return [prefix]
        return [f"{prefix}[{n}]" for n in self._names]

    def describe(self):
        return {**super().describe(), "link": self.link, "relative_to": self.relative_to,
                "lower": self.lower, "upper": self.upper}


def _finite(x, name: str) -> float:
    try:
        val = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not np.isfinite(val):
        raise ValueError(f"{name} must be finite, got {x!r}")
    return val
