"""The kind codes a scene is lowered to (see :mod:`moreau.core.kernels` for the table)."""

__all__ = [
    "CONST", "LINEAR_V", "AFFINE_Q", "TRIG", "HARMONIC", "FOURIER_PT", "USER",
    "BAR_LINEAR", "BAR_TRIG", "BAR_CHAIN_POINT", "BAR_USER", "MASS_CONST", "MASS_CHAIN", "MASS_USER",
]

# effect kinds
CONST, LINEAR_V, AFFINE_Q, TRIG, HARMONIC, FOURIER_PT, USER = 0, 1, 2, 3, 4, 5, 99
# barrier kinds
BAR_LINEAR, BAR_TRIG, BAR_CHAIN_POINT, BAR_USER = 0, 1, 2, 99
# mass kinds
MASS_CONST, MASS_CHAIN, MASS_USER = 0, 1, 99
