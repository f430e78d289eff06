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
from typing import Any

import numpy as np

from moreau.core.validation import as_matrix

__all__ = ["MechanicalSystem", "FunctionSystem", "check_spd"]


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

        It stands on the right-hand side: ``M(q) dv/dt = bias_force(q, v) + ...``.
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
        Velocity-squared generalized force on the right-hand side (see
        :class:`MechanicalSystem`). Omit it for a constant mass matrix.
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


def _positive_int(x: Any, name: str) -> int:
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x <= 0:
        raise ValueError(f"{name} must be a positive integer, got {x!r}")
    return int(x)

