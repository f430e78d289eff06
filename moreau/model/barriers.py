"""Barriers: unilateral constraints g(q) >= 0 with their Jacobians G(q) = dg/dq.

Sign convention (used everywhere in moreau): a gap ``g >= 0`` is admissible, the normal
velocity is ``U = G v`` and a contact impulse ``P >= 0`` pushes the gap open; the
generalized impulse is ``Gᵀ P``.

A barrier may have several rows (m). Jacobians are analytic where known;
:func:`check_jacobian` compares one against central finite differences.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_matrix, as_vector, is_number

__all__ = [
    "Barrier",
    "LinearBarrier",
    "FunctionBarrier",
    "JacobianCheck",
    "check_jacobian",
    "finite_difference_jacobian",
]


class Barrier(ABC):
    """Base class of a unilateral constraint with ``nrows`` rows on ``ndof`` coordinates.

    Attributes
    ----------
    nrows : int
        Number of rows m.
    ndof : int or None
        Number of coordinates the barrier expects (None: any).
    constant_jacobian : bool
        True when G does not depend on q.
    """

    nrows: int = 1
    ndof: int | None = None
    constant_jacobian: bool = False
    #: True when the barrier gives tangent rows (:meth:`tangent_jacobian`): a friction
    #: law needs them
    has_tangents: bool = False

    @abstractmethod
    def gap(self, q: np.ndarray) -> np.ndarray:
        """Gaps g(q), shape (m,), in the barrier's length unit; g >= 0 is admissible."""

    @abstractmethod
    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Jacobian G(q) = dg/dq, shape (m, n)."""

    def tangent_jacobian(self, q: np.ndarray) -> np.ndarray:
        """Tangent rows T(q), shape (m, n): row i maps v to the tangential velocity of the
        point of row i along the barrier, in the plane and in the gap's length unit (a
        unit tangent when the gap is a distance), so that ``|P_T| <= mu P_N`` compares
        like with like. Either sign: Coulomb's law does not depend on it.

        Raises ``NotImplementedError`` for a barrier without tangents (``has_tangents``
        False): a friction law on it is refused when the :class:`~moreau.model.scene.Contact`
        is built."""
        raise NotImplementedError(f"{type(self).__name__} has no tangent rows")

    def tangent_kernel(self):
        """``(kind, params)`` of the compiled kernel whose Jacobian is the tangent rows
        (:meth:`~moreau.model.barriers.Barrier.tangent_jacobian`; the barrier kernels' layout,
        gaps unused), ``("user", (None, tangent_jacobian))``, or None: the compiled loop then
        calls ``tangent_jacobian`` back."""
        return None

    def row_names(self, prefix: str) -> list[str]:
        """Labels of the rows, e.g. ``["floor"]`` or ``["corner[0]", ...]``."""
        if self.nrows == 1:
            return [prefix]
        return [f"{prefix}[{i}]" for i in range(self.nrows)]

    def describe(self) -> dict:
        return {"type": type(self).__name__, "nrows": self.nrows}

    def gap_scale(self) -> np.ndarray:
        """Magnitude of the terms summed in each gap, shape (m,) (gap units): its round-off
        is about ε times this. A row closes when ``g <= 4 ε · gap_scale`` (0: unknown,
        then exactly ``g <= 0``)."""
        return np.zeros(self.nrows)

    def kernel(self):
        """``(kind, params)`` of the compiled gap and Jacobian kernels (see
        :mod:`moreau.core.kernels`), ``("user", (gap, jacobian))`` for user callables
        (compiled by numba when they can be), or None: the compiled loop then calls
        :meth:`gap` and :meth:`jacobian` back."""
        return None


class LinearBarrier(Barrier):
    """Gaps affine in q: ``g(q) = A q + b`` (constant Jacobian A).

    A floor ``y >= 0`` for q = (x, y) is ``LinearBarrier([[0, 1]], [0])``; a joint stop
    ``phi_1 <= 0.3`` is ``LinearBarrier([[-1, 0, 0]], [0.3])``.

    Parameters
    ----------
    A : array_like, shape (m, n) or (n,)
        Constant Jacobian; a vector is one row.
    b : array_like, shape (m,) or scalar
        Offsets (default 0).
    tangent : array_like, shape (m, n) or (n,), optional
        Constant tangent rows (see :meth:`Barrier.tangent_jacobian`), needed by a friction
        law: for the floor above, ``tangent=[[1, 0]]``.
    """

    constant_jacobian = True

    def __init__(self, A, b=0.0, tangent=None) -> None:
        try:
            one_row = np.ndim(A) == 1
        except ValueError:  # ragged: as_matrix names it
            one_row = False
        self.A = as_matrix([A] if one_row else A, "LinearBarrier.A")
        self.nrows, self.ndof = self.A.shape
        if is_number(b):
            b = np.full(self.nrows, float(b))
        self.b = as_vector(b, "LinearBarrier.b", self.nrows)
        if np.any(np.all(self.A == 0.0, axis=1)):
            raise ValueError(f"LinearBarrier.A has an all-zero row: {self.A.tolist()}")
        self.A.setflags(write=False)
        self._p = _k.flat(self.A, self.b)  # layout of kernels.gaps_linear
        self.T: np.ndarray | None = None
        if tangent is not None:
            one_row = np.ndim(tangent) == 1
            self.T = as_matrix([tangent] if one_row else tangent, "LinearBarrier.tangent")
            if self.T.shape != self.A.shape:
                raise ValueError(f"LinearBarrier.tangent has shape {self.T.shape}, expected {self.A.shape} "
                                 "(one tangent row per row of A)")
            self.T.setflags(write=False)
            self._pt = _k.flat(self.T, np.zeros(self.nrows))  # the tangent rows' kernel: gaps unused
            self.has_tangents = True

    def tangent_jacobian(self, q):
        if self.T is None:
            return super().tangent_jacobian(q)
        return self.T

    def gap(self, q):
        out = np.empty(self.nrows)
        _k.gaps_linear(self._p, 0, self.nrows, q, out, 0)
        return out

    def jacobian(self, q):
        return self.A

    def kernel(self):
        return _k.BAR_LINEAR, (self._p,)

    def tangent_kernel(self):
        if self.T is None:
            return None
        return _k.BAR_LINEAR, (self._pt,)

    def gap_scale(self):
        return np.abs(self.b) + np.abs(self.A).sum(axis=1)

    def describe(self):
        return {**super().describe(), "A": self.A.tolist(), "b": self.b.tolist()}


class FunctionBarrier(Barrier):
    """A barrier from plain callables.

    Parameters
    ----------
    gap : callable ``gap(q) -> (m,)``
        The gap functions.
    jacobian : callable ``jacobian(q) -> (m, n)``
        Their analytic Jacobian. Check it once with :func:`check_jacobian`.
    nrows : int
        Number of rows m (default 1).
    ndof : int, optional
        Number of coordinates; checked by the scene.
    tangent_jacobian : callable ``tangent_jacobian(q) -> (m, n)``, optional
        Tangent rows (see :meth:`Barrier.tangent_jacobian`), needed by a friction law.
    """

    def __init__(
        self,
        gap: Callable[[np.ndarray], np.ndarray],
        jacobian: Callable[[np.ndarray], np.ndarray],
        nrows: int = 1,
        ndof: int | None = None,
        tangent_jacobian: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        if not callable(gap) or not callable(jacobian):
            raise ValueError("FunctionBarrier: gap and jacobian must be callables")
        if tangent_jacobian is not None:
            if not callable(tangent_jacobian):
                raise ValueError(f"FunctionBarrier: tangent_jacobian must be a callable, got {tangent_jacobian!r}")
            self.tangent_jacobian = tangent_jacobian  # type: ignore[method-assign,assignment]
            self.has_tangents = True
        if isinstance(nrows, bool) or not isinstance(nrows, (int, np.integer)) or nrows < 1:
            raise ValueError(f"FunctionBarrier: nrows must be a positive integer, got {nrows!r}")
        self.gap = gap  # type: ignore[method-assign]  # bound directly: no extra call layer
        self.jacobian = jacobian  # type: ignore[method-assign]
        self.nrows = int(nrows)
        self.ndof = ndof

    def gap(self, q):  # pragma: no cover - replaced per instance
        raise NotImplementedError

    def jacobian(self, q):  # pragma: no cover - replaced per instance
        raise NotImplementedError

    def kernel(self):
        return "user", (self.gap, self.jacobian)

    def tangent_kernel(self):
        return ("user", (None, self.tangent_jacobian)) if self.has_tangents else None


def finite_difference_jacobian(fun: Callable[[np.ndarray], np.ndarray], q: np.ndarray, eps: float = 1e-6, *,
                               relative: bool = True) -> np.ndarray:
    """Central finite-difference Jacobian of ``fun`` at ``q``, shape (m, n); steps
    ``eps·max(1, |q_j|)`` (``relative``) or ``eps``."""
    q = np.asarray(q, dtype=float)
    f0 = np.atleast_1d(fun(q))
    J = np.empty((f0.shape[0], q.shape[0]))
    for j in range(q.shape[0]):
        step = eps * max(1.0, abs(q[j])) if relative else eps
        qp = q.copy()
        qm = q.copy()
        qp[j] += step
        qm[j] -= step
        J[:, j] = (np.atleast_1d(fun(qp)) - np.atleast_1d(fun(qm))) / (2 * step)
    return J


def near_point(q: np.ndarray) -> np.ndarray:
    """A point a little off ``q`` (by ``1e-3·max(1, |q_k|)`` along a fixed direction of uneven
    entries), where the checks of :func:`moreau.simulate` look as well: at a symmetric start
    (a chain hanging straight down) the terms of a Jacobian or a bias force that a mistake
    leaves out or swaps may all vanish (those of first order in q − q0 show there at O(1)
    of the row; second-order ones, at 1e-6, do not)."""
    k = np.arange(1.0, q.shape[0] + 1.0)
    return q + 1e-3 * np.maximum(1.0, np.abs(q)) * np.sin(2.4 * k)


@dataclass(frozen=True)
class JacobianCheck:
    """Result of :func:`check_jacobian`.

    Attributes
    ----------
    max_abs_error : float
        Largest ``|G_analytic - G_fd|`` entry.
    max_rel_error : float
        ``max_abs_error`` divided by ``max(1e-300, max |G_fd|)``.
    analytic, numeric : ndarray, shape (m, n)
    """

    max_abs_error: float
    max_rel_error: float
    analytic: np.ndarray
    numeric: np.ndarray

    def ok(self, rtol: float = 1e-6) -> bool:
        return self.max_rel_error <= rtol


def check_jacobian(barrier: Barrier, q, eps: float = 1e-6) -> JacobianCheck:
    """Compare a barrier's analytic Jacobian with central finite differences at ``q``.

    Raises ``ValueError`` when the analytic Jacobian has the wrong shape.
    """
    q = as_vector(q, "q")
    G = np.atleast_2d(np.asarray(barrier.jacobian(q), dtype=float))
    expected = (barrier.nrows, q.shape[0])
    if G.shape != expected:
        raise ValueError(f"{type(barrier).__name__}.jacobian returned shape {G.shape}, expected {expected}")
    Gfd = finite_difference_jacobian(barrier.gap, q, eps)
    err = float(np.max(np.abs(G - Gfd)))
    return JacobianCheck(err, err / max(1e-300, float(np.max(np.abs(Gfd)))), G, Gfd)
