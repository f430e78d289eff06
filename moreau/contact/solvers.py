"""Contact solvers: backends that solve the one-step QP and know no mechanics.

Every solver takes the step's data for *all* m rows of the scene and the indices of the
active ones, and returns ``(v, P)`` with P for the active rows only:

``solve(M, b, G, c, rows) -> (v (n,), P (k,))``

where G (m, n) and c (m,) are full-size (entries of inactive rows are ignored).

Backends
--------
``"exact"`` : :class:`ExactSolver` (the default), exact: block principal pivoting from 8
    rows, the dual active-set method (Goldfarb–Idnani) below that, in the loop.
``"osqp"`` : :class:`OSQPSolver`. Set up once per scene, changed each step with
    OSQP's ``update()`` on a fixed sparsity pattern (inactive rows opened with l = −∞),
    warm-started, eps 1e-9 with polishing, on the QP in mass-normalized units (identity
    Hessian, rows of unit length); its active set is then made exact (and corrected where
    it is not complementary). Rebuilding OSQP every step through ``qpsolvers.solve_qp``
    costs ~20x more (see ``benchmarks/step_cost.py``).
``"enum"`` : :class:`EnumerationSolver`, exact: enumerates the active sets of the LCP,
    smallest first. Fast for the few active rows of a typical step; the default fallback.
``"daqp"``, ``"quadprog"``, ``"qpsolvers:<name>"`` : :class:`QpsolversSolver`, exact
    active-set QPs through qpsolvers.

The backends live in modules by job — ``moreau.contact.base`` (the interface),
``moreau.contact.osqp``, ``moreau.contact.refine`` (OSQP's exact refinement),
``moreau.contact.exact``, ``moreau.contact.qp`` — and are imported from here.
"""

from __future__ import annotations

# the backends, and (``x as x``: re-exported) the private helpers that lived in this module
from moreau.contact.base import ContactSolver, SolveFailed
from moreau.contact.exact import EnumerationSolver, ExactSolver
from moreau.contact.exact import _CompiledLCPSolver as _CompiledLCPSolver
from moreau.contact.osqp import OSQPSolver
from moreau.contact.qp import QpsolversSolver
from moreau.contact.qp import _unconstrained_if_feasible as _unconstrained_if_feasible
from moreau.contact.refine import _cholesky as _cholesky
from moreau.contact.refine import _exact_from_proposed_set as _exact_from_proposed_set
from moreau.contact.refine import _nonnegative_on as _nonnegative_on
from moreau.contact.refine import _normalized as _normalized
from moreau.contact.refine import _solve_on as _solve_on
from moreau.contact.refine import _upper_solve as _upper_solve

__all__ = [
    "ContactSolver",
    "OSQPSolver",
    "EnumerationSolver",
    "ExactSolver",
    "QpsolversSolver",
    "SolveFailed",
    "make_solver",
    "available_solvers",
    "SOLVER_NAMES",
]

_SIMPLE = {
    "osqp": lambda: OSQPSolver(),
    "enum": lambda: EnumerationSolver(),
    "exact": lambda: ExactSolver(),
}
#: the exact active-set QPs of qpsolvers that :func:`make_solver` knows by name
_EXACT_QP = ("daqp", "quadprog")

#: the names :func:`make_solver` knows, without asking which of qpsolvers' back-ends are
#: installed (:func:`available_solvers` does, importing qpsolvers: half a second)
SOLVER_NAMES = tuple(sorted([*_SIMPLE, *_EXACT_QP]))


def available_solvers() -> list[str]:
    """Names accepted by :func:`make_solver`."""
    import qpsolvers

    exact_qp = [s for s in _EXACT_QP if s in qpsolvers.available_solvers]
    return sorted(_SIMPLE) + exact_qp


def make_solver(spec: str | ContactSolver) -> ContactSolver:
    """A solver from a name (``"osqp"``, ``"enum"``, ``"daqp"``, ``"quadprog"``,
    ``"qpsolvers:<backend>"``) or an instance (returned as is).

    Raises
    ------
    ValueError
        For an unknown name.
    """
    if isinstance(spec, ContactSolver):
        return spec
    if not isinstance(spec, str):
        raise ValueError(f"solver must be a name or a ContactSolver, got {spec!r}")
    if spec in _SIMPLE:
        return _SIMPLE[spec]()
    name = spec.split(":", 1)[1] if spec.startswith("qpsolvers:") else spec
    if name in _EXACT_QP or spec.startswith("qpsolvers:"):
        return QpsolversSolver(name)
    raise ValueError(f"unknown solver {spec!r}; choose one of {available_solvers()}")
