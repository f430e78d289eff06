"""The one-step non-smooth problem: the contact problem of a single time step, as data.

With the k active rows of the step (gaps closed at the midpoint), the velocity-level
problem is the convex QP

    minimize ½ vᵀ M v − vᵀ b   subject to   G v >= c,

with ``b = M v_k + h f`` and ``c = −e ∘ U_k``; the contact impulses P >= 0 are the
multipliers of the inequalities, so that ``M v = b + Gᵀ P`` and ``0 <= P ⟂ G v − c >= 0``.
Equivalent LCP: ``W = G M⁻¹ Gᵀ``, ``w = G M⁻¹ b − c``, ``0 <= P ⟂ w + W P >= 0``.
M is symmetric positive definite, so v is unique even when rows of G are redundant
(P then is not: compare ``Gᵀ P``, never P, between solvers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OneStepProblem", "Residuals", "kkt_residuals"]


@dataclass
class OneStepProblem:
    """Contact problem of one step, restricted to its k active rows.

    Attributes
    ----------
    M : ndarray, shape (n, n)
        Mass matrix at the midpoint.
    b : ndarray, shape (n,)
        ``M v_k + h f`` (momentum units).
    G : ndarray, shape (k, n)
        Jacobian of the active rows.
    c : ndarray, shape (k,)
        Lower bounds ``−e ∘ U_k`` on the post-step normal velocities.
    """

    M: np.ndarray
    b: np.ndarray
    G: np.ndarray
    c: np.ndarray

    def lcp(self) -> tuple[np.ndarray, np.ndarray]:
        """The LCP form ``(W, w)`` with ``W = G M⁻¹ Gᵀ`` and ``w = G M⁻¹ b − c``."""
        sol = np.linalg.solve(self.M, np.column_stack([self.b, self.G.T]))
        return self.G @ sol[:, 1:], self.G @ sol[:, 0] - self.c

    def residuals(self, v: np.ndarray, P: np.ndarray) -> Residuals:
        return kkt_residuals(self.M, self.b, self.G, self.c, v, P)


@dataclass(frozen=True)
class Residuals:
    """Scaled KKT residuals of a candidate ``(v, P)``; each is dimensionless.

    Attributes
    ----------
    primal : float
        Largest violation of ``G v >= c``, relative to the normal-velocity scale.
    dual : float
        Largest negative impulse, as the normal velocity it makes, relative to the
        velocity scale.
    complementarity : float
        Largest ``|P_i w_i (G v − c)_i|``, relative to the velocity scale squared.
    stationarity : float
        ``|M v − b − Gᵀ P|_∞`` relative to the momentum scale.
    """

    primal: float
    dual: float
    complementarity: float
    stationarity: float

    @property
    def worst(self) -> float:
        return max(self.primal, self.dual, self.complementarity, self.stationarity)

    def as_dict(self) -> dict[str, float]:
        return {
            "primal": self.primal,
            "dual": self.dual,
            "complementarity": self.complementarity,
            "stationarity": self.stationarity,
        }




def kkt_residuals(M: np.ndarray, b: np.ndarray, G: np.ndarray, c: np.ndarray, v: np.ndarray,
                  P: np.ndarray, L: np.ndarray | None = None) -> Residuals:
    """Scaled KKT residuals of the one-step QP (see module docstring), the same check
    the compiled loop runs (:func:`moreau.contact.lcp.kkt_residuals_kernel`).

    Contact rows are measured as normal velocities against the contact's own velocity
    scale: the largest of ``|c|``, ``|G v|`` and the normal velocity change the impulses
    make, ``|G| (|Gᵀ P| / diag M)``, with a floor of 1e-9 ``|G| |v|`` for round-off. An
    impulse P_i counts through the velocity it makes, ``P_i Σ_j G_ij² / M_jj``: a
    negative impulse of round-off size passes, a wrong-sign impulse that moves the
    contact does not. Stationarity is the velocity error ``M⁻¹ (M v − b − Gᵀ P)`` per
    coordinate, against that coordinate's own velocity scale, so every measure is
    invariant under rescaling any single coordinate (a change of units): a light
    coordinate's error is not hidden behind the momenta of heavy ones.

    ``L``: the lower Cholesky factor of M when the caller has it (else M is factorized
    here; a matrix that is not positive definite gives infinite residuals).
    """
    from moreau.contact.lcp import kkt_residuals_kernel
    from moreau.core.kernels import cholesky

    M = np.ascontiguousarray(M, dtype=float)
    n = M.shape[0]
    if L is None:
        L = np.empty((n, n))
        if cholesky(M, L, n) >= 0:
            inf = float("inf")
            return Residuals(inf, inf, inf, inf)
    else:
        L = np.ascontiguousarray(L, dtype=float)
    out = np.empty(4)
    kkt_residuals_kernel(M, L, np.ascontiguousarray(b, dtype=float), np.ascontiguousarray(G, dtype=float),
                         np.ascontiguousarray(c, dtype=float), np.ascontiguousarray(v, dtype=float),
                         np.ascontiguousarray(P, dtype=float), np.shape(G)[0], out,
                         *(np.empty(max(n, np.shape(G)[0])) for _ in range(5)), np.empty((n, n)), np.zeros(n + 1),
                         False, np.empty(0), 0, np.empty(0), np.empty(0), np.empty((4, 0)), False)
    return Residuals(*(float(x) for x in out))
