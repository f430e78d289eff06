"""The pendulum chain: links and the chain's mass matrix, bias terms and point kinematics
(the model is described in :mod:`moreau.model.chain`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_vector
from moreau.model.chain.scaling import Nondimensional, Units
from moreau.model.system import MechanicalSystem

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
        # the generators of M's semiseparable structure (see moreau.core.kernels.chain)
        beyond = np.concatenate([np.cumsum(m[::-1])[::-1][1:], [0.0]])  # Σ_{k>j} m_k
        beta = self.lengths * beyond + m * np.array([k.com for k in self.links])
        gamma = m * np.array([k.com_lateral for k in self.links])
        self._pm = _k.flat(nu, nu_s, np.diag(nu), self.lengths, beta, gamma)  # layout of kernels.chain
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


def _require_chain(chain, who: str) -> PendulumChain:
    if not isinstance(chain, PendulumChain):
        raise ValueError(f"{who}: chain must be a PendulumChain, got {chain!r}")
    return chain
