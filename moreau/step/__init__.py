"""The one-step integrators (Moreau–Jean midpoint, predictor–corrector, energy-consistent)
and drift control, as the schemes and settings :func:`moreau.simulate` takes; the compiled
loop (:mod:`moreau.compiled`) runs them, each phase of the step written once there.

May import: :mod:`moreau.core`, :mod:`moreau.model`, :mod:`moreau.contact`.
"""
