"""The ground floor every path stands on: errors, input checks, the package version, the
compile cache and the physics kernels (:mod:`moreau.core.kernels`).

May import: nothing of moreau outside ``moreau.core``.
"""
