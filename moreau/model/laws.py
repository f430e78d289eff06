"""Non-smooth laws: what a closed contact does to the normal velocity in a step."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from moreau.core.validation import is_number

__all__ = ["NewtonImpact", "NewtonImpactFriction"]


@dataclass(frozen=True)
class NewtonImpact:
    """Newton's impact law with restitution coefficient e in [0, 1].

    For a contact closed at the step's midpoint, the post-step normal velocity obeys
    ``0 <= P ⟂ U⁺ + e U⁻ >= 0`` (U⁻ before, U⁺ after the step). e = 0: plastic (no
    rebound, the contact may slide along the barrier); e = 1: elastic.

    Parameters
    ----------
    e : float
        Restitution coefficient, dimensionless, 0 <= e <= 1.
    """

    e: float

    def __post_init__(self) -> None:
        if not is_number(self.e):  # bools and strings are refused, not converted
            raise ValueError(f"restitution e must be a number in [0, 1], got {self.e!r}")
        e = float(self.e)
        if not np.isfinite(e) or e < 0.0 or e > 1.0:
            raise ValueError(f"restitution e must be in [0, 1], got {self.e!r}")
        object.__setattr__(self, "e", e)


@dataclass(frozen=True)
class NewtonImpactFriction:
    """Newton's impact law on the normal velocity with planar Coulomb friction on the
    tangential one (Moreau 1988; Glocker & Pfeiffer): per closed contact a normal impulse
    ``P_N >= 0`` with ``0 <= P_N ⟂ U_N⁺ + e U_N⁻ >= 0`` and a tangential impulse with
    ``|P_T| <= mu P_N``: sticking (``U_T⁺ = 0``) inside the cone, sliding against the
    post-step tangential velocity on its edge (``P_T = −mu P_N sign(U_T⁺)``).

    Parameters
    ----------
    e : float or sequence of float
        Restitution coefficient(s), dimensionless, in [0, 1]: one for every row, or one
        per row of the contact's barrier.
    mu : float or sequence of float
        Friction coefficient(s), dimensionless, >= 0: one for every row, or one per row.
        ``mu = 0`` is the frictionless law (no tangential row is built for it).
    """

    e: float | tuple[float, ...]
    mu: float | tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "e", _coefficients(self.e, "restitution e", 1.0))
        object.__setattr__(self, "mu", _coefficients(self.mu, "friction coefficient mu", None))

    def per_row(self, nrows: int, contact: str) -> tuple[np.ndarray, np.ndarray]:
        """``(e, mu)`` as arrays of shape (nrows,); a length other than 1 or ``nrows`` is a
        ``ValueError`` naming the contact."""
        out = []
        for what, x in (("restitution coefficients", self.e), ("friction coefficients", self.mu)):
            a = np.asarray(x, dtype=float)
            if a.ndim == 0:
                a = np.full(nrows, float(a))
            elif a.shape != (nrows,):
                raise ValueError(f"Contact {contact!r}: {a.shape[0]} {what} for {nrows} rows")
            out.append(a)
        return out[0], out[1]


def _coefficients(x: Any, what: str, upper: float | None) -> float | tuple[float, ...]:
    """A law's coefficient(s) checked: numbers (not bools, not strings), finite, >= 0 and
    <= ``upper``; a scalar stays a float, a sequence becomes a tuple."""
    scalar = np.ndim(x) == 0
    items = [x] if scalar else list(x)
    if not items:
        raise ValueError(f"{what} must be a number or a non-empty sequence of numbers, got {x!r}")
    vals = []
    for i, a in enumerate(items):
        where = "" if scalar else f" (entry {i})"
        if not is_number(a):
            raise ValueError(f"{what} must be a number, got {a!r}{where}")
        a = float(a)
        if not np.isfinite(a) or a < 0.0 or (upper is not None and a > upper):
            bound = f"in [0, {upper:g}]" if upper is not None else ">= 0 and finite"
            raise ValueError(f"{what} must be {bound}, got {items[i]!r}{where}")
        vals.append(a)
    return vals[0] if scalar else tuple(vals)
