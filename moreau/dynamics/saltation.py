"""The pieces of the tangent dynamics of :mod:`moreau.dynamics.tangent`: the scene's vector
field ``F(t, x)``, its Jacobian ``A = ∂F/∂x`` by finite differences, the Newton impact map
and its saltation matrix (:class:`_Flow`), and the matrix exponential of a step (:func:`_expm`).
"""

from __future__ import annotations

import numpy as np

import moreau as mo
from moreau.core import kernels as _k

from .maps import split_state


class _Flow:
    """``F(t, x)`` of a scene, its Jacobian, the Newton map and the saltation matrix."""

    def __init__(self, scene: mo.Scene, eps: float) -> None:
        self.scene = scene
        self.n = scene.ndof
        self.eps = eps
        # M⁻¹ by the kernels' Cholesky factor, as the compiled smooth steps: the forward
        # differences of A divide its round-off by eps, so the two paths agree only when
        # they solve alike (numpy's LU or inverse left them 1e-7 apart on the triple pendulum)
        self.L = self._factor(np.zeros(self.n)) if scene.system.constant_mass else None

    def _factor(self, q: np.ndarray) -> np.ndarray:
        """The lower Cholesky factor of M(q) (:func:`moreau.core.kernels.cholesky`)."""
        M = np.ascontiguousarray(self.scene.system.mass_matrix(q), dtype=float)
        L = np.empty((self.n, self.n))
        if _k.cholesky(M, L, self.n) >= 0:
            raise RuntimeError(f"lyapunov_spectrum_tangent: M(q) not positive definite at q = {q}")
        return L

    def _solve(self, L: np.ndarray, b: np.ndarray) -> np.ndarray:
        out = np.empty(self.n)
        _k.cho_solve(L, np.ascontiguousarray(b, dtype=float), out, self.n)
        return out

    def jac(self, q: np.ndarray) -> np.ndarray:
        """Contact Jacobian G(q), shape (m, n)."""
        assert self.scene.jacobian is not None  # only called at contact steps
        return np.asarray(self.scene.jacobian(q), float)

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Gaps g(q), shape (m,)."""
        assert self.scene.gaps is not None  # only called at contact steps
        return np.asarray(self.scene.gaps(q), float)

    def solve_M(self, q: np.ndarray, b: np.ndarray) -> np.ndarray:
        """M(q)⁻¹ b, shape (n,)."""
        return self._solve(self.L if self.L is not None else self._factor(q), b)

    def accel(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``M(q)⁻¹ f(t, q, v)``, shape (n,)."""
        return self.solve_M(q, np.asarray(self.scene.force(t, q, v), float))

    def field(self, t: float, x: np.ndarray) -> np.ndarray:
        """``F(t, x) = (v, M⁻¹ f)``, shape (2n,)."""
        q, v = split_state(x)
        return np.concatenate([v, self.accel(t, q, v)])

    def jacobian(self, t: float, x: np.ndarray) -> np.ndarray:
        """``A = ∂F/∂x`` by forward differences, shape (2n, 2n)."""
        n = self.n
        q, v = split_state(x)
        force = self.scene.force
        L = self.L if self.L is not None else self._factor(q)
        f0 = np.asarray(force(t, q, v), float)
        a0 = self._solve(L, f0)
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        for j in range(n):
            d = self.eps * max(1.0, abs(q[j]))
            y = q.copy()
            y[j] += d
            A[n:, j] = (self.accel(t, y, v) - a0) / d
            d = self.eps * max(1.0, abs(v[j]))
            y = v.copy()
            y[j] += d
            A[n:, n + j] = self._solve(L, np.asarray(force(t, q, y), float) - f0) / d
        return A

    def newton(self, q: np.ndarray, v: np.ndarray, row: int) -> np.ndarray:
        """Post-impact velocity of one row, shape (n,)."""
        G = self.jac(q)[row]
        w = self.solve_M(q, G)
        return v - (1.0 + self.scene.restitution[row]) * w * (G @ v) / (G @ w)

    def saltation(self, t: float, x: np.ndarray, row: int) -> tuple[np.ndarray, np.ndarray]:
        """``(S, x⁺)`` at the pre-impact state x of ``row``: S (2n, 2n), x⁺ (2n,)."""
        n = self.n
        q, v = split_state(x)
        e = self.scene.restitution[row]
        G = self.jac(q)[row]
        w = self.solve_M(q, G)
        U = float(G @ v)
        vp = self.newton(q, v, row)
        J = np.eye(2 * n)
        J[n:, n:] -= (1.0 + e) * np.outer(w, G) / (G @ w)
        for j in range(n):  # ∂v⁺/∂q by central differences
            d = self.eps ** 0.5 * max(1.0, abs(q[j]))  # O(d²) error, d ~ 3e-4
            qp, qm = q.copy(), q.copy()
            qp[j] += d
            qm[j] -= d
            J[n:, j] = (self.newton(qp, v, row) - self.newton(qm, v, row)) / (2 * d)
        Fm = np.concatenate([v, self.accel(t, q, v)])
        Fp = np.concatenate([vp, self.accel(t, q, vp)])
        nvec = np.concatenate([G, np.zeros(n)])
        S = J + np.outer(Fp - J @ Fm, nvec) / U
        return S, np.concatenate([q, vp])

    def scheme_step(self, t: float, x: np.ndarray, h: float, rows: np.ndarray) -> np.ndarray:
        """The midpoint step with the contact rows ``rows`` held closed (their law
        ``G v⁺ = −e G v``), shape (2n,)."""
        q, v = split_state(x)
        qm = q + 0.5 * h * v
        vf = v + h * self.accel(t + 0.5 * h, qm, v)
        G = self.jac(qm)[rows]
        W = np.column_stack([self.solve_M(qm, g) for g in G])  # M⁻¹Gᵀ, (n, r)
        lam = np.linalg.solve(G @ W, G @ vf + self.scene.restitution[rows] * (G @ v))
        vp = vf - W @ lam
        return np.concatenate([qm + 0.5 * h * vp, vp])


def _expm(B: np.ndarray) -> np.ndarray:
    """exp(B) by scaling and squaring of a degree-6 Taylor polynomial
    (:func:`moreau.core.kernels.expm_taylor`, the kernel the compiled tangent steps use)."""
    B = np.ascontiguousarray(B, dtype=float)
    E, W, V = np.empty_like(B), np.empty_like(B), np.empty_like(B)
    _k.expm_taylor(B, E, W, V)
    return E
