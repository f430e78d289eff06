"""Units of a chain's coordinates and the paper's non-dimensional scaling."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from moreau.model.chain.links import PendulumChain


# ----------------------------------------------------------------------------------------
# non-dimensional view
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Units:
    """Scales of a non-dimensional chain: divide a physical quantity by its scale.

    Parameters
    ----------
    length : float
        Length unit L (m).
    time : float
        Time unit T (s).
    mass : float
        Mass unit μ (kg), chosen so that M_00 = 1.
    """

    length: float
    time: float
    mass: float

    @property
    def velocity(self) -> float:
        """L/T (m/s)."""
        return self.length / self.time

    @property
    def acceleration(self) -> float:
        """L/T² (m/s²): non-dimensional gravity is g / acceleration."""
        return self.length / self.time**2

    @property
    def force(self) -> float:
        """μ L/T² (N)."""
        return self.mass * self.length / self.time**2

    @property
    def torque(self) -> float:
        """μ L²/T² (N m); also the energy unit (J)."""
        return self.mass * self.length**2 / self.time**2

    @property
    def energy(self) -> float:
        """μ L²/T² (J)."""
        return self.torque

    @property
    def damping(self) -> float:
        """Torque·time μ L²/T (N m s): unit of joint damping coefficients."""
        return self.mass * self.length**2 / self.time

    @property
    def stiffness(self) -> float:
        """Torque per radian μ L²/T² (N m/rad): unit of torsional springs."""
        return self.torque

    @property
    def impulse(self) -> float:
        """Force·time μ L/T (N s): unit of contact impulses on length gaps."""
        return self.mass * self.length / self.time

    @property
    def angular_impulse(self) -> float:
        """Torque·time μ L²/T (N m s): unit of impulses on angle gaps (joint stops)."""
        return self.damping


@dataclass(frozen=True)
class Nondimensional:
    """A chain in non-dimensional units with the paper's dimensionless groups.

    Attributes
    ----------
    chain : PendulumChain
        The scaled chain: its mass matrix has M_00 = 1.
    units : Units
        The scales.
    beta : ndarray, shape (N,)
        β_i = M_ii / M_00 (β_0 = 1).
    nu : ndarray, shape (N, N)
        ν_ij / M_00: the paper's ν_ij off the diagonal, β_i on it.
    nu_lateral : ndarray, shape (N, N)
        Lateral-offset coefficients / M_00 (zero in the paper's model).
    lam : ndarray, shape (N,)
        Length ratios λ_i = l_i / L (λ_0 = 1 with the default length scale).
    """

    chain: PendulumChain
    units: Units
    beta: np.ndarray
    nu: np.ndarray
    nu_lateral: np.ndarray
    lam: np.ndarray
