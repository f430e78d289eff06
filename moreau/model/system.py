"""Mechanical systems: generalized coordinates, mass matrix and velocity-squared terms.

A *system* (Siconos: dynamical system) is the Lagrangian part of a model,

.. math:: M(q)\\,\\dot v = f_{\\mathrm{bias}}(q, v) + \\sum f_{\\mathrm{effects}}(t, q, v),

where :math:`M(q)` (n x n) is symmetric positive definite and the *bias* force collects
the gyroscopic/centrifugal terms that come with a configuration-dependent mass matrix
(for a pendulum chain, :math:`-N(q)\\,\\dot\\varphi^2`). External and dissipative forces
are not part of the system: they are *effects* (:mod:`moreau.model.forces`) that a scene adds.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from moreau.core.validation import as_matrix
from moreau.model.barriers import near_point

__all__ = ["MechanicalSystem", "FunctionSystem", "BiasCheck", "check_bias", "check_spd"]


class MechanicalSystem(ABC):
    """Base class of a Lagrangian system with ``ndof`` generalized coordinates.

    Subclasses implement :meth:`mass_matrix` and, when the mass matrix depends on q,
    :meth:`bias_force`. Set ``constant_mass = True`` when M does not depend on q: the
    integrator then factorizes it once.

    Attributes
    ----------
    ndof : int
        Number of generalized coordinates n.
    constant_mass : bool
        True when M(q) does not depend on q.
    has_bias : bool
        True when :meth:`bias_force` is not identically zero. When False the step never
        calls it.
    """

    ndof: int
    constant_mass: bool = False
    has_bias: bool = False

    @abstractmethod
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Mass matrix M(q), shape (n, n), symmetric positive definite (units of the
        generalized inertia, e.g. kg or kg m^2)."""

    def bias_force(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Velocity-squared generalized force (Coriolis, centrifugal), shape (n,).

        It stands on the right-hand side: ``M(q) dv/dt = bias_force(q, v) + ...``, and
        equals ``−Ṁ v + ½ ∇_q(vᵀ M v)`` (the Lagrange equations); :func:`moreau.simulate`
        compares it with M(q)'s derivatives before a run (:func:`check_bias`).
        """
        return np.zeros(self.ndof)

    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic energy ½ vᵀ M(q) v (J)."""
        return 0.5 * float(v @ self.mass_matrix(q) @ v)

    def describe(self) -> dict[str, Any]:
        """Parameters of the system as plain JSON-serializable data (for saved results)."""
        return {"type": type(self).__name__, "ndof": self.ndof}

    def mass_kernel(self) -> tuple[Any, Any] | None:
        """``(kind, params)`` of the compiled mass matrix (see :mod:`moreau.core.kernels`),
        ``("user", (mass, bias))`` for callables, or None: the compiled loop then calls
        :meth:`mass_matrix` and :meth:`bias_force` back (:mod:`moreau.compiled.callbacks`)."""
        return None


class FunctionSystem(MechanicalSystem):
    """A system given by plain callables, no subclassing needed.

    Parameters
    ----------
    mass : array_like of shape (n, n) or callable ``mass(q) -> (n, n)``
        The mass matrix. An array means a constant mass matrix (factorized once).
    ndof : int, optional
        Number of coordinates; inferred from a constant ``mass``. Required when ``mass``
        is a callable.
    bias : callable ``bias(q, v) -> (n,)``, optional
        Velocity-squared generalized force on the right-hand side, ``−Ṁ v + ½ ∇_q(vᵀ M v)``
        (see :class:`MechanicalSystem`; :func:`moreau.simulate` refuses one that is not
        that of ``mass``, and a ``mass`` that depends on q without one). Omit it for a
        constant mass matrix.
    name : str
        Label used in results.

    Examples
    --------
    A point of mass 2 kg moving in a vertical plane:

    >>> sys = FunctionSystem(2.0 * np.eye(2))
    >>> sys.ndof, sys.constant_mass
    (2, True)
    """

    def __init__(
        self,
        mass: np.ndarray | Callable[[np.ndarray], np.ndarray],
        ndof: int | None = None,
        bias: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
        name: str = "system",
    ) -> None:
        self.name = name
        if callable(mass):
            if ndof is None:
                raise ValueError("FunctionSystem: ndof is required when mass is a callable")
            self.ndof = _positive_int(ndof, "ndof")
            self._mass_fun: Callable[[np.ndarray], np.ndarray] | None = mass
            self._mass: np.ndarray | None = None
            self.constant_mass = False
        else:
            M = as_matrix(mass, "mass")
            if M.shape[0] != M.shape[1]:
                raise ValueError(f"FunctionSystem: mass must be square, got shape {M.shape}")
            if ndof is not None and _positive_int(ndof, "ndof") != M.shape[0]:
                raise ValueError(
                    f"FunctionSystem: ndof={ndof} does not match mass of shape {M.shape}"
                )
            check_spd(M, "mass")
            self.ndof = M.shape[0]
            self._mass = M
            self._mass_fun = None
            self.constant_mass = True
        self._bias = bias
        self.has_bias = bias is not None

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        if self._mass is not None:
            return self._mass
        assert self._mass_fun is not None  # one of the two is set
        return self._mass_fun(q)

    def bias_force(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        if self._bias is None:
            return np.zeros(self.ndof)
        return self._bias(q, v)

    def mass_kernel(self) -> tuple[Any, Any] | None:
        from moreau.core import kernels as _k

        if self._mass is not None and self._bias is None:
            return _k.MASS_CONST, (self._mass,)
        return "user", (self._mass_fun, self._bias)

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d["name"] = self.name
        if self._mass is not None:
            d["mass"] = self._mass.tolist()
        return d


def check_spd(M: np.ndarray, what: str = "M", where: str = "") -> None:
    """Raise ``ValueError`` unless M is finite, symmetric and positive definite."""
    if not np.all(np.isfinite(M)):
        raise ValueError(f"{what}{where} has non-finite entries: {M.tolist()}")
    scale = max(float(np.max(np.abs(M))), np.finfo(float).tiny)
    asym = float(np.max(np.abs(M - M.T)))
    if asym > 1e-10 * scale:
        raise ValueError(f"{what}{where} is not symmetric (max |M - Mᵀ| = {asym:.3g}): {M.tolist()}")
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        eig = np.linalg.eigvalsh(0.5 * (M + M.T))
        raise ValueError(
            f"{what}{where} is not positive definite (smallest eigenvalue {eig[0]:.3g}): {M.tolist()}"
        ) from None


def lagrangian_bias(mass: Callable[[np.ndarray], np.ndarray], q: np.ndarray, v: np.ndarray, eps: float = 1e-6, *,
                    relative: bool = True) -> tuple[np.ndarray, float, float]:
    """The velocity-squared force of a Lagrangian system with mass matrix ``mass(q)``,
    ``f = −Ṁ v + ½ ∇_q(vᵀ M v)`` (Ṁ = Σ_k ∂M/∂q_k v_k), from central differences of M at
    ``q`` (steps ``eps·max(1, |q_k|)``, or ``eps``): ``(f (n,), size, noise)``, ``size`` the
    largest sum of the magnitudes of the terms that make up an entry of f, ``noise`` the
    differences' round-off floor there (both in f's units)."""
    n = q.shape[0]
    a = np.abs(v)
    mdot, mdot_abs = np.zeros((n, n)), np.zeros((n, n))  # Σ_k v_k ∂M/∂q_k, and of |terms|
    grad, grad_abs = np.empty(n), np.empty(n)  # vᵀ ∂M/∂q_k v, and of |terms|
    noise = 0.0
    for k in range(n):  # one ∂M/∂q_k at a time: O(n²) memory
        step = eps * max(1.0, abs(q[k])) if relative else eps
        qp, qm = q.copy(), q.copy()
        qp[k] += step
        qm[k] -= step
        Dk = (np.asarray(mass(qp), dtype=float) - np.asarray(mass(qm), dtype=float)) / (2.0 * step)
        mdot += v[k] * Dk
        mdot_abs += a[k] * np.abs(Dk)
        grad[k] = v @ Dk @ v
        grad_abs[k] = a @ np.abs(Dk) @ a
        noise += a[k] / step
    f = -(mdot @ v) + 0.5 * grad
    size = float((mdot_abs @ a + 0.5 * grad_abs).max(initial=0.0))
    scale_m = float(np.abs(np.asarray(mass(q), dtype=float)).max(initial=0.0))
    noise *= 150.0 * np.finfo(float).eps * scale_m * float(a.sum())
    return f, size, noise


@dataclass(frozen=True)
class BiasCheck:
    """Result of :func:`check_bias`.

    Attributes
    ----------
    q, v : ndarray, shape (n,)
        Where the bias force was compared (a point near the given q, a fixed velocity).
    analytic : ndarray, shape (n,)
        The system's ``bias_force(q, v)`` (zeros for a system without one).
    numeric : ndarray, shape (n,)
        ``−Ṁ v + ½ ∇_q(vᵀ M v)`` from central differences of ``mass_matrix``.
    max_abs_error : float
        Largest ``|analytic − numeric|`` entry.
    max_rel_error : float
        ``max_abs_error`` over the size of the terms (theirs and the analytic force's);
        0 when it is below the differences' round-off.
    """

    q: np.ndarray
    v: np.ndarray
    analytic: np.ndarray
    numeric: np.ndarray
    max_abs_error: float
    max_rel_error: float

    def ok(self, rtol: float = 1e-5) -> bool:
        return self.max_rel_error <= rtol


def check_bias(system: MechanicalSystem, q: ArrayLike, eps: float = 1e-6) -> BiasCheck:
    """Compare a system's bias force with the velocity-squared terms of its mass matrix.

    For a Lagrangian system with kinetic energy ½ vᵀ M(q) v the bias force (right-hand
    side: ``M dv/dt = bias + forces``) is ``−Ṁ v + ½ ∇_q(vᵀ M v)``, fixed by M(q). It is
    compared at a point a little off ``q`` (by ``1e-3·max(1, |q_k|)`` along a fixed direction:
    a symmetric configuration such as a hanging chain zeroes every term) and a fixed
    velocity of O(1) entries, with central differences of M; where the relative steps
    disagree (a coordinate of thousands), with absolute steps of ``eps``.
    """
    q = np.asarray(q, dtype=float)
    n = system.ndof
    k = np.arange(1.0, n + 1.0)
    qc = near_point(q)
    v = np.cos(1.7 * k) + np.sign(np.cos(1.7 * k))  # entries in ±(1, 2)
    analytic = np.asarray(system.bias_force(qc, v), dtype=float) if system.has_bias else np.zeros(n)
    best: BiasCheck | None = None
    for relative in (True, False):
        numeric, size, noise = lagrangian_bias(system.mass_matrix, qc, v, eps, relative=relative)
        err = float(np.abs(analytic - numeric).max(initial=0.0))
        rel = 0.0 if err <= noise else err / max(size, float(np.abs(analytic).max(initial=0.0)), np.finfo(float).tiny)
        if best is None or rel < best.max_rel_error:
            best = BiasCheck(qc, v, analytic, numeric, err, rel)
        if best.ok():
            break
    assert best is not None
    return best


def _positive_int(x: Any, name: str) -> int:
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x <= 0:
        raise ValueError(f"{name} must be a positive integer, got {x!r}")
    return int(x)

