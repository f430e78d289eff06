"""The Python one-step integrators (Moreau–Jean midpoint, predictor–corrector) and drift
control: the readable reference of a step, which the compiled loop mirrors.

A new integrator or drift control goes here (and its twin in :mod:`moreau.compiled`).

May import: :mod:`moreau.core`, :mod:`moreau.model`, :mod:`moreau.contact`.
"""
