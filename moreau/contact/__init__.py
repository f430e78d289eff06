"""The one-step non-smooth problem and its solvers: matrices and vectors, not bodies.

:mod:`~moreau.contact.problem` states the problem a step hands over (the LCP of the
velocity-level contact conditions, in its QP form) and its KKT residuals;
:mod:`~moreau.contact.lcp` holds the exact pivoting/enumeration kernels the compiled loop
calls (with their work arrays, ``moreau.contact.one_step.OneStepWork``; friction's in
``moreau.contact.friction_work``); :mod:`~moreau.contact.solvers` the solver objects (exact, enumeration, OSQP,
qpsolvers), each backend in its own module (``moreau.contact.base``,
``moreau.contact.osqp`` with ``moreau.contact.refine``, ``moreau.contact.exact``,
``moreau.contact.qp``). A new solver, or new kinds of rows (friction, equality), go here.

May import: :mod:`moreau.core`. Knows nothing of systems, scenes or integrators.
"""
