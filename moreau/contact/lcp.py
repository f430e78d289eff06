"""Compiled exact contact solvers and the KKT check shared by every backend.

The one-step problem (see :mod:`moreau.contact.problem`) on its k active rows,

    minimize ½ vᵀ M v − vᵀ b   subject to   G v >= c,

is solved through its LCP ``0 <= P ⟂ s = w + W P >= 0`` with ``W = G M⁻¹ Gᵀ`` (k x k,
symmetric positive semi-definite, singular for redundant rows) and
``w = G M⁻¹ b − c``; then ``v = M⁻¹ (b + Gᵀ P)``.

:func:`lcp_dual_active_set` is the dual active-set method of Goldfarb & Idnani (1983,
"A numerically stable dual method for solving strictly convex quadratic programs",
Math. Programming 27, 1–33; the algorithm of quadprog) written on W: starting from the
unconstrained minimum (P = 0), it adds the most violated row, moves the impulses of the
active rows along the direction that keeps their slacks zero, and drops a row whose
impulse reaches zero before the new one is satisfied. The active rows stay linearly
independent (a dependent row is satisfied by the others or the problem is infeasible),
so redundant contacts are handled exactly; every step is a solve with the Cholesky
factor of W on the active rows. It terminates in a finite number of steps for any k.
:func:`lcp_enumerate` (active sets smallest first, k <= 12) is the independent fallback.
Both are plain loops on small dense arrays: they run inside the compiled time loop and,
called from Python, as the ``"exact"`` backend (:class:`moreau.contact.solvers.ExactSolver`).

The pieces live in modules by job and are imported from here: the LCP methods in
``moreau.contact.active_set``, :func:`solve_one_step` and :func:`workspace` in
``moreau.contact.one_step``, the KKT check :func:`kkt_residuals_kernel` in
``moreau.contact.kkt``.
"""

from __future__ import annotations

from moreau.contact.active_set import FAILED, OK, lcp_dual_active_set, lcp_enumerate
from moreau.contact.kkt import kkt_residuals_kernel
from moreau.contact.one_step import solve_one_step, workspace

__all__ = ["lcp_dual_active_set", "lcp_enumerate", "kkt_residuals_kernel", "solve_one_step", "workspace",
           "OK", "FAILED"]
