"""Forces on a pendulum chain: gravity, joint damping and springs, link torques, point forces."""

from __future__ import annotations

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_vector
from moreau.model.chain.links import PendulumChain, _require_chain
from moreau.model.forces import Effect, FourierLoad


# ----------------------------------------------------------------------------------------
# effects
# ----------------------------------------------------------------------------------------
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
        return "user", self.force

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
