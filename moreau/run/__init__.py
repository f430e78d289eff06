"""The front door: :func:`~moreau.simulate` validates once, chooses the
backend, runs the Python step loop or the compiled one, and returns a Trajectory; the
checks a run makes of its model (Jacobians, penetration) live beside it.

May import: every layer below (core, model, contact, results, step, compiled).
"""
