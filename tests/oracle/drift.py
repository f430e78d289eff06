"""The numpy reference of drift control: the projections of :mod:`moreau.step.drift` with
their step (``project``), applied by the reference integrators after each step."""

from __future__ import annotations

import numpy as np

import moreau as mo

__all__ = ["PositionProjection", "CombinedProjection", "reference_projection"]


class PositionProjection(mo.PositionProjection):
    """:class:`moreau.PositionProjection` with its step."""

    def project(self, integ, q: np.ndarray) -> np.ndarray:
        """The projected q⁺ for the integrator ``integ`` (its scene, solver and last step)."""
        scene = integ.scene
        if getattr(self, '_scene', None) is not scene:  # rows this projection may move, once per scene
            self._scene, self._eligible = scene, self.eligible_rows(scene)
        eligible = self._eligible
        if not eligible.any():
            return q
        g = scene.gaps(q)
        # a held row stays held while it carries an impulse without bouncing and its gap has
        # not grown beyond where the projection left it (see CombinedProjection)
        integ.pinned &= (integ.P > 0.0) & ~integ.bounced & (g <= integ.pin_gap)
        if not (self._rows(integ, g, eligible) & (g < -self.tol)).any():
            return q
        zero = np.zeros(scene.ndof)
        for _ in range(self.max_iter):
            rows = np.flatnonzero(self._rows(integ, g, eligible))
            M = integ._M if integ._constant_mass else scene.system.mass_matrix(q)
            if integ._eq is not None:  # along the bilateral rows (moreau.step.bilateral)
                dq, mu = integ._eq.project_contacts(integ, q, M, scene.jacobian(q), -g, rows)
            else:
                dq, mu = integ._solve_contact(M, zero, scene.jacobian(q), -g, rows, kind="projection")
            q = q + dq
            g = scene.gaps(q)
            held = rows[mu > 0.0]
            integ.pinned[held] = True
            integ.pin_gap[held] = np.maximum(g[held], 0.0)
            if not (self._rows(integ, g, eligible) & (g < -self.tol)).any():
                break
        integ.n_projections += 1
        return q

    @staticmethod
    def _rows(integ, g: np.ndarray, eligible: np.ndarray) -> np.ndarray:
        """Rows of the projection QP: eligible rows that penetrate or were closed."""
        return ((g < 0.0) | integ.active) & eligible


class CombinedProjection(PositionProjection, mo.CombinedProjection):
    """:class:`moreau.CombinedProjection` with its step."""

    def __init__(self, *args, **kwargs) -> None:
        mo.CombinedProjection.__init__(self, *args, **kwargs)

    def eligible_rows(self, scene) -> np.ndarray:
        return np.ones(scene.nrows, dtype=bool)

    @staticmethod
    def _rows(integ, g: np.ndarray, eligible: np.ndarray) -> np.ndarray:
        """Rows of the projection QP: the persistent contacts of the step (closed, no bounce)."""
        return integ.active & ~integ.bounced


def reference_projection(dc):
    """The reference twin of the drift control ``dc`` given to :func:`moreau.simulate`."""
    if dc is None or isinstance(dc, PositionProjection):
        return dc
    if getattr(dc, "velocity", False):  # not mirrored here: tests/test_drift_velocity.py checks it analytically
        raise NotImplementedError("the numpy reference has no PositionProjection(velocity=True)")
    if isinstance(dc, mo.CombinedProjection):
        return CombinedProjection(dc.max_iter, dc.tol, dc.memory, dc.locate_impacts)
    return PositionProjection(dc.max_iter, dc.tol, dc.max_restitution)
