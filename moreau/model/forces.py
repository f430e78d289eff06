"""Effects: smooth generalized forces f(t, q, v) that a scene may include.

Every effect is a small object with

* ``force(t, q, v) -> (n,)``: the generalized force on the right-hand side of
  ``M dv/dt = ... + f`` (units of generalized force: N for lengths, N m for angles);
* ``potential(q) -> float`` (J) when the effect is conservative (``has_potential``);
* flags ``velocity_dependent`` and ``time_dependent`` that tell integrators and
  diagnostics what the force depends on.

A scene evaluates exactly the effects it was given and nothing else. Effects specific to
a model (gravity on a pendulum chain, a force at a point of a link) live with the model
(:mod:`moreau.model.chain`); the ones here work on any system.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_matrix, as_positive, as_vector

__all__ = ["Effect", "ConstantForce", "LinearDamping", "LinearSpring", "FunctionForce", "HarmonicForce", "FourierLoad"]


class Effect(ABC):
    """Base class of a smooth generalized force.

    Attributes
    ----------
    name : str
        Label of the effect (``"gravity"``, ``"damping"``, ...).
    velocity_dependent : bool
        True when the force depends on v (damping). A scene of position-only effects and
        a constant mass matrix is integrated to order 2 by the midpoint scheme.
    time_dependent : bool
        True when the force depends explicitly on t.
    has_potential : bool
        True when :meth:`potential` is available (conservative effect).
    """

    name: str = "effect"
    velocity_dependent: bool = False
    time_dependent: bool = False
    has_potential: bool = False

    @abstractmethod
    def force(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Generalized force, shape (n,)."""

    def potential(self, q: np.ndarray) -> float:
        """Potential energy (J) of a conservative effect."""
        raise NotImplementedError(f"effect {self.name!r} has no potential energy")

    def power(self, t: float, q: np.ndarray, v: np.ndarray) -> float:
        """Power vᵀ f (W) the effect puts into the system."""
        return float(v @ self.force(t, q, v))

    def describe(self) -> dict:
        """Parameters as JSON-serializable data."""
        return {"type": type(self).__name__, "name": self.name}

    def kernel(self):
        """``(kind, params)`` of the compiled kernel that evaluates this effect (see
        :mod:`moreau.core.kernels`), ``("user", fun)`` for a user callable (compiled by numba
        when it can be), or None: the compiled loop then calls :meth:`force` back."""
        return None


class ConstantForce(Effect):
    """A constant generalized force f (n,), e.g. uniform gravity on point masses.

    Its potential is ``-fᵀ q``.

    Parameters
    ----------
    f : array_like, shape (n,)
        Generalized force.
    name : str
        Label (``"gravity"`` by default).
    """

    has_potential = True

    def __init__(self, f, name: str = "gravity") -> None:
        self.f = as_vector(f, f"{type(self).__name__}.f")
        self.f.setflags(write=False)
        self.name = name

    def force(self, t, q, v):
        return self.f

    def kernel(self):
        return _k.CONST, (self.f,)

    def potential(self, q):
        return -float(self.f @ q)

    def describe(self):
        return {**super().describe(), "f": self.f.tolist()}


class LinearDamping(Effect):
    """Viscous damping ``f = -C v`` with C symmetric positive semi-definite (n x n).

    Parameters
    ----------
    C : array_like, shape (n, n) or scalar
        Damping matrix (N s/m, N m s/rad). A scalar c means c·I.
    """

    velocity_dependent = True

    def __init__(self, C, ndof: int | None = None, name: str = "damping") -> None:
        C = np.array(C, dtype=float)
        if C.ndim == 0:
            if ndof is None:
                raise ValueError("LinearDamping: ndof is required for a scalar C")
            C = C * np.eye(ndof)
        self.C = as_matrix(C, "LinearDamping.C")
        if self.C.shape[0] != self.C.shape[1]:
            raise ValueError(f"LinearDamping.C must be square, got shape {self.C.shape}")
        if np.linalg.eigvalsh(0.5 * (self.C + self.C.T))[0] < -1e-12 * max(1.0, np.abs(self.C).max()):
            raise ValueError(f"LinearDamping.C must be positive semi-definite, got {self.C.tolist()}")
        self._p = _k.flat(self.C)
        self.name = name

    def force(self, t, q, v):
        return _k.force_of(_k.add_linear_v, v.shape[0], self._p, 0, v)

    def kernel(self):
        return _k.LINEAR_V, (self._p,)

    def describe(self):
        return {**super().describe(), "C": self.C.tolist()}


class LinearSpring(Effect):
    """Linear spring ``f = -K (q - q_ref)``, K symmetric positive semi-definite.

    Parameters
    ----------
    K : array_like, shape (n, n)
        Stiffness (N/m, N m/rad).
    q_ref : array_like, shape (n,), optional
        Rest configuration (zeros by default).
    """

    has_potential = True

    def __init__(self, K, q_ref=None, name: str = "spring") -> None:
        self.K = as_matrix(K, "LinearSpring.K")
        n = self.K.shape[0]
        if self.K.shape != (n, n) or np.max(np.abs(self.K - self.K.T)) > 1e-12 * max(1.0, np.abs(self.K).max()):
            raise ValueError(f"LinearSpring.K must be square and symmetric, got {self.K.tolist()}")
        self.q_ref = np.zeros(n) if q_ref is None else as_vector(q_ref, "LinearSpring.q_ref", n)
        self._p = _k.flat(self.K, self.K @ self.q_ref)
        self.name = name

    def force(self, t, q, v):
        return _k.force_of(_k.add_affine_q, q.shape[0], self._p, 0, q)

    def kernel(self):
        return _k.AFFINE_Q, (self._p,)

    def potential(self, q):
        dq = q - self.q_ref
        return 0.5 * float(dq @ self.K @ dq)

    def describe(self):
        return {**super().describe(), "K": self.K.tolist(), "q_ref": self.q_ref.tolist()}


class FunctionForce(Effect):
    """A user force from a callable ``fun(t, q, v) -> (n,)``.

    Parameters
    ----------
    fun : callable
        The generalized force.
    potential : callable ``potential(q) -> float``, optional
        Its potential energy, when conservative.
    velocity_dependent, time_dependent : bool
        What ``fun`` depends on (default: both True, the safe assumption).
    name : str
        Label.
    """

    def __init__(
        self,
        fun: Callable[[float, np.ndarray, np.ndarray], np.ndarray],
        potential: Callable[[np.ndarray], float] | None = None,
        velocity_dependent: bool = True,
        time_dependent: bool = True,
        name: str = "force",
    ) -> None:
        if not callable(fun):
            raise ValueError(f"FunctionForce: fun must be callable, got {fun!r}")
        self.force = fun  # type: ignore[method-assign]  # bound directly: no extra call layer
        self._potential = potential
        self.has_potential = potential is not None
        self.velocity_dependent = bool(velocity_dependent)
        self.time_dependent = bool(time_dependent)
        self.name = name

    def force(self, t, q, v):  # pragma: no cover - replaced per instance
        raise NotImplementedError

    def kernel(self):
        return "user", self.force

    def potential(self, q):
        if self._potential is None:
            return super().potential(q)
        return float(self._potential(q))


class FourierLoad:
    """A planar force whose magnitude is a Fourier series of one coordinate,
    ``F(q) = d · s(q_j)`` with ``s(x) = a0 + Σ_k a_k cos(k ω x) + b_k sin(k ω x)``.

    Given as the ``force`` of a :class:`moreau.model.chain.PointForce` it runs compiled: the
    periodic loads of rotating machinery (the gas force of an engine over its cycle in
    the crank angle, a cam's reaction) are of this form.

    Parameters
    ----------
    direction : array_like, shape (2,)
        The force per unit of s (N per unit of s).
    a0 : float
        Mean of the series.
    a, b : array_like, shape (K,)
        Cosine and sine coefficients for k = 1..K.
    omega : float
        Fundamental frequency in the coordinate (rad⁻¹ for an angle; 0.5 for a series in
        φ/2, i.e. period 4π).
    coordinate : int
        Index j of the coordinate the series is a function of.
    """

    def __init__(self, direction, a0: float, a, b, omega: float, coordinate: int) -> None:
        self.direction = as_vector(direction, "FourierLoad.direction", 2)
        self.a0 = float(as_vector(a0, "FourierLoad.a0", 1)[0])
        self.a = as_vector(a, "FourierLoad.a")
        self.b = as_vector(b, "FourierLoad.b", self.a.shape[0])
        self.omega = float(as_vector(omega, "FourierLoad.omega", 1)[0])
        if isinstance(coordinate, bool) or not isinstance(coordinate, (int, np.integer)) or coordinate < 0:
            raise ValueError(f"FourierLoad.coordinate must be a non-negative integer, got {coordinate!r}")
        self.coordinate = int(coordinate)
        self._p = _k.flat(self.a, self.b)

    def series(self, x: float) -> float:
        """s(x)."""
        K = self.a.shape[0]
        return float(_k.fourier_series(self.a0, self._p, 0, K, K, self.omega, float(x)))

    def __call__(self, t, q, v) -> np.ndarray:
        """F(q), shape (2,)."""
        return self.direction * self.series(q[self.coordinate])


class HarmonicForce(Effect):
    """A harmonic generalized force ``f(t) = amplitude * sin(omega t + phase)``.

    Parameters
    ----------
    amplitude : array_like, shape (n,)
        Amplitude per coordinate (generalized force units: N, or N m for angles).
    omega : float
        Angular frequency (rad per time unit), > 0.
    phase : float
        Phase (rad) at t = 0.
    name : str
        Label (``"harmonic"`` by default).
    """

    time_dependent = True

    def __init__(self, amplitude, omega: float, phase: float = 0.0, name: str = "harmonic") -> None:
        self.amplitude = as_vector(amplitude, "HarmonicForce.amplitude")
        self.amplitude.setflags(write=False)
        self.omega = as_positive(omega, "HarmonicForce.omega")
        self.phase = float(as_vector(phase, "HarmonicForce.phase", 1)[0])
        self._p = _k.flat(self.amplitude, [self.omega, self.phase])  # layout of kernels.add_harmonic
        self.name = name

    def force(self, t, q, v):
        return _k.force_of(_k.add_harmonic, self.amplitude.shape[0], self._p, 0, float(t))

    def kernel(self):
        return _k.HARMONIC, (self._p,)

    def describe(self):
        return {**super().describe(), "amplitude": self.amplitude.tolist(), "omega": self.omega,
                "phase": self.phase}
