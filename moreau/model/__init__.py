"""What a user describes: a mechanical system q, M(q) (:mod:`~moreau.model.system`), its
smooth forces (:mod:`~moreau.model.forces`), its barriers g(q) ≥ 0
(:mod:`~moreau.model.barriers`), their impact laws (:mod:`~moreau.model.laws`), the
pendulum chains of the founding paper (:mod:`~moreau.model.chain`), units, and the
:class:`~moreau.model.scene.Scene` that holds exactly the effects and contacts asked for.

A new force, barrier or law goes here, with its kernel in :mod:`moreau.core.kernels`.

May import: :mod:`moreau.core`. Knows nothing of how a step is taken or solved.
"""
