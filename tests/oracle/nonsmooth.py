"""The one-step non-smooth problem of a step, solved with its checks: the main solver, the
KKT check (the full law's with friction), the fallback, and the error naming the rows
when both fail (:class:`NonsmoothSolve`, a base of
:class:`~moreau.step.base.OneStepIntegrator`)."""

from __future__ import annotations

import logging

import numpy as np

from moreau.contact.friction import FRICTION_RESIDUALS, friction_residuals
from moreau.contact.painleve import painleve_message, painleve_rows
from moreau.contact.problem import kkt_residuals
from moreau.contact.solvers import ContactSolver, SolveFailed
from moreau.core.errors import SolverError
from moreau.model.scene import Scene

__all__ = ["NonsmoothSolve"]

log = logging.getLogger(__name__)


class NonsmoothSolve:
    """The contact solve of :class:`~moreau.step.base.OneStepIntegrator` (which holds the
    state these methods read: ``solver``, ``fallback``, ``tol``, ``scene``, ``k``, ``t``
    and the counters)."""

    # set by OneStepIntegrator.__init__ and init
    scene: Scene
    solver: ContactSolver
    fallback: ContactSolver | None
    tol: float
    k: int
    t: float
    n_solves: int
    n_fallbacks: int
    n_painleve: int
    painleve: str | None
    worst_residual: float
    _mu: np.ndarray
    _PT_active: np.ndarray
    _defer_check: bool
    _unchecked: tuple | None

    def _solve_contact(self, M, b, G, c, rows, kind: str = "contact", L=None, T=None, cT=None):
        """Solve the step's QP with the main solver, check it, fall back if needed.

        ``kind`` names the problem in errors (``"contact"``, or ``"projection"`` for drift
        control, whose solves are not counted in ``n_solves``). ``L``: the Cholesky factor
        of M when the step has it (the check then does not factorize M again). ``T``: the
        tangent rows (m, n) of a scene with friction; the solve is then the friction
        problem, checked against the full law (cone and stick/slip too), and its
        tangential impulses of the active rows are left in ``self._PT_active``; ``cT`` (m,)
        the offsets of the slip velocities ``T v − cT`` (the reduced problem of a scene
        with bilateral rows; None: 0).
        """
        if kind == "contact":
            self.n_solves += 1
        if T is not None:
            return self._solve_friction(M, b, G, c, T, rows, L, cT)
        GA, cA = G[rows], c[rows]
        failures: dict[str, dict[str, float] | str] = {}
        for solver in (self.solver, self.fallback):
            if solver is None:
                break
            if failures:  # the main solver failed: this is the fallback
                self.n_fallbacks += 1
                log.debug("step %d: %s failed (%s), falling back to %s", self.k, self.solver.name,
                          failures[self.solver.name], solver.name)
            try:
                v, P = solver.solve(M, b, G, c, rows)
                if self._defer_check and kind == "contact":
                    self._unchecked = (M, b, GA, cA, v, P, L, rows)
                    return v, P
                res = kkt_residuals(M, b, GA, cA, v, P, L=L)
                if res.worst <= self.tol:
                    if res.worst > self.worst_residual:
                        self.worst_residual = res.worst
                    return v, P
                failures[solver.name] = res.as_dict()
            except (SolveFailed, np.linalg.LinAlgError, ValueError) as exc:
                failures[solver.name] = str(exc)
        names = [self.scene.row_names[i] for i in rows]
        raise SolverError(
            f"{kind} solve failed at step {self.k} (t = {self.t:.9g}), active rows {names}: {failures}",
            step=self.k, t=self.t, rows=names, residuals=failures,
        )

    def _check_deferred(self) -> bool:
        """The KKT check of the last unchecked contact solve (see ``_defer_check``): True
        when there was none or it passes; False when it fails (the caller solves that
        problem again with the check and the fallback)."""
        if self._unchecked is None:
            return True
        M, b, GA, cA, v, P, L, rows = self._unchecked
        self._unchecked = None
        res = kkt_residuals(M, b, GA, cA, v, P, L=L)
        if res.worst <= self.tol:
            self.worst_residual = max(self.worst_residual, res.worst)
            return True
        log.debug("step %d: %s's converged answer failed its check (%s); solving it again with the check",
                  self.k, self.solver.name, res.as_dict())
        return False

    def _solve_friction(self, M, b, G, c, T, rows, L, cT=None):
        """The friction problem of :meth:`_solve_contact`: main solver, law check, fallback."""
        GA, cA, TA, muA = G[rows], c[rows], T[rows], self._mu[rows]
        cTA = None if cT is None else cT[rows]
        failures: dict[str, dict[str, float] | str] = {}
        for solver in (self.solver, self.fallback):
            if solver is None:
                break
            if failures:
                self.n_fallbacks += 1
                log.debug("step %d: %s failed (%s), falling back to %s", self.k, self.solver.name,
                          failures[self.solver.name], solver.name)
            try:
                v, PN, PT = solver.solve_friction(M, b, G, c, T, self._mu, rows, cT=cT)
                res = friction_residuals(M, b, GA, cA, TA, muA, v, PN, PT, L=L, cT=cTA)
                worst = float(res.max())
                if worst <= self.tol:
                    self.worst_residual = max(self.worst_residual, worst)
                    self._PT_active = PT
                    self._check_painleve(M, L, GA, TA, muA, PN, PT, v, rows, cTA)
                    return v, PN
                failures[solver.name] = dict(zip(FRICTION_RESIDUALS, res.tolist()))
            except (SolveFailed, np.linalg.LinAlgError, ValueError) as exc:
                failures[solver.name] = str(exc)
        names = [self.scene.row_names[i] for i in rows]
        raise SolverError(
            f"contact solve with friction failed at step {self.k} (t = {self.t:.9g}), active rows {names}, "
            f"mu = {muA.tolist()}: {failures}", step=self.k, t=self.t, rows=names, residuals=failures,
        )

    def _check_painleve(self, M, L, GA, TA, muA, PN, PT, v, rows, cTA=None) -> None:
        """Count the steps with a sliding contact in Painlevé's region (see
        :func:`moreau.contact.painleve.painleve_rows`) and keep the first one's message."""
        if L is None:
            L = np.linalg.cholesky(M)
        bad = painleve_rows(L, GA, TA, muA, PN, PT, TA @ v if cTA is None else TA @ v - cTA)
        if bad.size:
            self.n_painleve += 1
            if self.painleve is None:
                names = [self.scene.row_names[rows[j]] for j in bad]
                self.painleve = painleve_message(self.t, self.k, names, muA[bad].tolist())
