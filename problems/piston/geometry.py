"""Slider-crank geometry and kinematics of the piston engine's pressure model.

The ideal (centred) slider-crank of :mod:`moreau.problems.piston.pressure`: piston-pin
height y(phi1), its derivative, the rod angle phi2(phi1) and the cylinder volume V(phi1)
used by the synthetic pressure curve, the indicated work and the damping work. See the
conventions in :mod:`moreau.problems.piston.pressure`.

Lengths in m, angles in rad, volumes in m^3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["TWO_PI", "FOUR_PI", "EngineGeometry", "DEFAULT_GEOMETRY"]

TWO_PI = 2.0 * math.pi
FOUR_PI = 4.0 * math.pi


@dataclass(frozen=True)
class EngineGeometry:
    """Slider-crank geometry.

    Parameters
    ----------
    bore : float
        Cylinder bore d [m].
    crank_radius : float
        Crank radius l1 [m] (stroke = 2 l1).
    rod_length : float
        Connecting-rod length l2 [m] (pin to pin).
    """

    bore: float = 0.08
    crank_radius: float = 0.04
    rod_length: float = 0.15

    @property
    def area(self) -> float:
        """Piston area A = pi d^2 / 4 [m^2]."""
        return math.pi * self.bore**2 / 4.0

    @property
    def stroke(self) -> float:
        """Stroke 2 l1 [m]."""
        return 2.0 * self.crank_radius

    @property
    def swept_volume(self) -> float:
        """Swept (displacement) volume A * stroke [m^3]."""
        return self.area * self.stroke

    @property
    def lam(self) -> float:
        """Crank-to-rod ratio lambda = l1 / l2 [-]."""
        return self.crank_radius / self.rod_length

    def pin_height(self, phi1: ArrayLike) -> np.ndarray | float:
        """Piston-pin height above the crank axis y(phi1) [m].

        Parameters
        ----------
        phi1 : float or array_like
            Crank angle [rad].
        """
        l1, l2 = self.crank_radius, self.rod_length
        s = np.sin(phi1)
        return l1 * np.cos(phi1) + np.sqrt(l2 * l2 - (l1 * s) ** 2)

    def pin_height_derivative(self, phi1: ArrayLike) -> np.ndarray | float:
        """dy/dphi1 [m/rad] of :meth:`pin_height`."""
        l1, l2 = self.crank_radius, self.rod_length
        s = np.sin(phi1)
        c = np.cos(phi1)
        return -l1 * s - l1 * l1 * s * c / np.sqrt(l2 * l2 - (l1 * s) ** 2)

    def rod_angle(self, phi1: ArrayLike) -> np.ndarray | float:
        """Absolute rod angle phi2 = -arcsin(lambda sin phi1) [rad]."""
        return -np.arcsin(self.lam * np.sin(phi1))

    def rod_angle_derivative(self, phi1: ArrayLike) -> np.ndarray | float:
        """dphi2/dphi1 = -lambda cos phi1 / sqrt(1 - lambda^2 sin^2 phi1) [-]."""
        lam = self.lam
        s = np.sin(phi1)
        return -lam * np.cos(phi1) / np.sqrt(1.0 - (lam * s) ** 2)

    def volume(self, phi1: ArrayLike, compression_ratio: float = 10.0) -> np.ndarray | float:
        """Cylinder volume V = Vc + A (y_TDC - y) [m^3].

        Parameters
        ----------
        phi1 : float or array_like
            Crank angle [rad].
        compression_ratio : float
            Geometric compression ratio (Vs + Vc) / Vc [-]; Vc = Vs / (eps - 1).
        """
        vc = self.swept_volume / (compression_ratio - 1.0)
        y_tdc = self.crank_radius + self.rod_length
        return vc + self.area * (y_tdc - self.pin_height(phi1))


#: Geometry of the paper's engine (d = 0.08 m, l1 = 0.04 m, l2 = 0.15 m).
DEFAULT_GEOMETRY = EngineGeometry()
