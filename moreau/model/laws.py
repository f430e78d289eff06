"""Non-smooth laws: what a closed contact does to the normal velocity in a step."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from moreau.core.validation import is_number

__all__ = ["NewtonImpact"]


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
