"""Scenes: a system with exactly the effects and contacts asked for, nothing else.

A scene is what the integrator steps. It is composed once; its ``force``, ``gaps`` and
``jacobian`` are specialized at construction so that a scene with one effect calls that
effect directly, a scene without effects returns a constant zero force, and a scene
without contacts has no gap functions at all (the integrator never builds a contact
problem for it).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from moreau.model.barriers import Barrier
from moreau.model.constraints import Bilateral, check_constraints, constrained_velocity
from moreau.model.forces import Effect
from moreau.model.laws import NewtonImpact, NewtonImpactFriction
from moreau.model.overrides import kernel_of, users
from moreau.model.system import MechanicalSystem, check_spd
from moreau.model.units import complete_units

__all__ = ["Contact", "Scene"]

#: f(t, q, v): a force (the sum of a scene's effects)
ForceFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
#: g(q) or G(q): gaps or their Jacobian
GapFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Contact:
    """A barrier with its impact law (Siconos: an interaction = relation + law).

    Parameters
    ----------
    barrier : Barrier
        The unilateral constraint g(q) >= 0 (one or several rows).
    law : NewtonImpact or NewtonImpactFriction or float or sequence of float
        Newton restitution; a number is ``NewtonImpact(e)`` for every row, a sequence
        gives one coefficient per row. :class:`~moreau.model.laws.NewtonImpactFriction`
        adds Coulomb friction; its barrier must give tangent rows
        (``barrier.has_tangents``), else ``ValueError``.
    name : str
        Label of the contact in results and impact logs.
    """

    barrier: Barrier
    law: NewtonImpact | NewtonImpactFriction | float | Sequence[float] = field(
        default_factory=lambda: NewtonImpact(0.0))
    name: str = "contact"

    def __post_init__(self) -> None:
        if not isinstance(self.barrier, Barrier):
            raise ValueError(f"Contact {self.name!r}: barrier must be a Barrier, got {self.barrier!r}")
        law = self.law
        mu = np.zeros(self.barrier.nrows)
        if isinstance(law, NewtonImpactFriction):
            e, mu = law.per_row(self.barrier.nrows, self.name)
            if np.any(mu > 0.0) and not self.barrier.has_tangents:
                raise ValueError(
                    f"Contact {self.name!r}: friction (mu = {law.mu}) needs tangent rows, and "
                    f"{type(self.barrier).__name__} has none (LinearBarrier(A, b, tangent=T), "
                    "FunctionBarrier(..., tangent_jacobian=...), or a chain's PointLineBarrier)")
        elif isinstance(law, NewtonImpact):
            e = np.full(self.barrier.nrows, law.e)
        elif np.ndim(law) == 0:
            e = np.full(self.barrier.nrows, NewtonImpact(cast(float, law)).e)
        else:
            e = np.array([NewtonImpact(x).e for x in cast(Sequence[float], law)], dtype=float)
            if e.shape != (self.barrier.nrows,):
                raise ValueError(
                    f"Contact {self.name!r}: {e.shape[0]} restitution coefficients for "
                    f"{self.barrier.nrows} rows"
                )
        object.__setattr__(self, "restitution", e)
        object.__setattr__(self, "friction", mu)
        object.__setattr__(self, "frictional", bool(np.any(mu > 0.0)))

    restitution: np.ndarray = field(init=False, repr=False, compare=False)
    #: friction coefficient per row, shape (m,) (zeros without a friction law)
    friction: np.ndarray = field(init=False, repr=False, compare=False)
    #: some row has friction (mu > 0): its tangent rows are built and solved
    frictional: bool = field(init=False, repr=False, compare=False)


class Scene:
    """A mechanical system with a chosen set of effects and contacts.

    Parameters
    ----------
    system : MechanicalSystem
        Coordinates and mass matrix.
    effects : sequence of Effect
        Smooth forces; only these are ever evaluated.
    contacts : sequence of Contact
        Unilateral constraints with their impact laws.
    constraints : sequence of Bilateral
        Rows g(q) = 0 held both ways (joints, closed loops); see
        :mod:`moreau.model.constraints`.
    name : str
        Label in results.
    units : dict, optional
        The units the scene is written in (``t``, ``q``, ``v``, ``gaps``, ``impulses``,
        ``energy``, ``description``, ``scales``, ``si``; see ``moreau.model.units``), carried
        by its trajectories as ``traj.units``. moreau converts nothing: this only labels
        the numbers. Undeclared entries are ``""``.

    Attributes
    ----------
    ndof : int
        Number of coordinates n.
    nrows : int
        Total number of contact rows m (sum over contacts).
    restitution : ndarray, shape (m,)
        Restitution per row.
    friction : ndarray, shape (m,)
        Friction coefficient per row (0: frictionless).
    has_friction : bool
        True when some row has friction; only then are tangent rows built and solved.
    tangent_jacobian : callable or None
        ``T(q)`` (m, n), the tangent rows of all contacts (zero rows where mu = 0); None
        without friction.
    row_names : list of str
        Label per row.
    row_contact : ndarray of int, shape (m,)
        Index of the contact each row belongs to.
    velocity_dependent : bool
        True when some force depends on v (an effect, or the system's bias terms).
    conservative : bool
        True when every effect has a potential and there are no velocity-dependent
        effects: then :meth:`energy` is the conserved total energy.
    nconstraints : int
        Number of bilateral rows k_E (sum over ``constraints``).
    constraint_names : list of str
        Label per bilateral row.
    constraint_gaps, constraint_jacobian : callable or None
        ``g_E(q)`` (k_E,) and ``G_E(q)`` (k_E, n) of all bilateral rows; None without.
    constraint_hold_tol : ndarray, shape (k_E,)
        Per bilateral row, the ``|g_E|`` positions are held to after every step.
    """

    def __init__(
        self,
        system: MechanicalSystem,
        effects: Sequence[Effect] = (),
        contacts: Sequence[Contact] = (),
        name: str = "scene",
        units: Mapping[str, Any] | None = None,
        constraints: Sequence[Bilateral] = (),
    ) -> None:
        if not isinstance(system, MechanicalSystem):
            raise ValueError(f"Scene: system must be a MechanicalSystem, got {system!r}")
        self.system = system
        self.ndof = system.ndof
        self.effects = _as_tuple(effects, Effect, "effects")
        self.contacts = _as_tuple(contacts, Contact, "contacts")
        self.name = name
        names = [c.name for c in self.contacts]
        for c in self.contacts:
            if c.barrier.ndof is not None and c.barrier.ndof != self.ndof:
                raise ValueError(
                    f"Scene: contact {c.name!r} expects {c.barrier.ndof} coordinates, "
                    f"the system has {self.ndof}"
                )
        if len(set(names)) != len(names):
            raise ValueError(f"Scene: contact names must be unique, got {names}")
        self.constraints = _as_tuple(constraints, Bilateral, "constraints")
        cnames = [c.name for c in self.constraints]
        if len(set(cnames)) != len(cnames):
            raise ValueError(f"Scene: constraint names must be unique, got {cnames}")
        for c in self.constraints:
            if c.geometry.ndof is not None and c.geometry.ndof != self.ndof:
                raise ValueError(f"Scene: constraint {c.name!r} expects {c.geometry.ndof} coordinates, "
                                 f"the system has {self.ndof}")
        self.nconstraints = sum(c.nrows for c in self.constraints)
        self.constraint_names = [r for c in self.constraints for r in c.row_names()]
        self.constraint_hold_tol = (np.concatenate([c.hold_tol() for c in self.constraints])
                                    if self.constraints else np.zeros(0))
        self.constraint_gaps, self.constraint_jacobian = _stacked([c.geometry for c in self.constraints])

        self.nrows = sum(c.barrier.nrows for c in self.contacts)
        self.units = complete_units(units, self.ndof, self.nrows)
        self.restitution = (
            np.concatenate([c.restitution for c in self.contacts]) if self.contacts else np.zeros(0)
        )
        self.friction = (
            np.concatenate([c.friction for c in self.contacts]) if self.contacts else np.zeros(0)
        )
        self.has_friction = bool(np.any(self.friction > 0.0))
        self.row_contact = np.concatenate(
            [np.full(c.barrier.nrows, i) for i, c in enumerate(self.contacts)]
        ).astype(int) if self.contacts else np.zeros(0, dtype=int)
        self.row_names = [n for c in self.contacts for n in c.barrier.row_names(c.name)]
        #: a row is closed at the midpoint when g <= activation_tol (its gap's round-off)
        self.activation_tol = 4.0 * np.finfo(float).eps * (
            np.concatenate([np.asarray(c.barrier.gap_scale(), dtype=float) for c in self.contacts])
            if self.contacts else np.zeros(0))
        self.velocity_dependent = system.has_bias or any(e.velocity_dependent for e in self.effects)
        self.time_dependent = any(e.time_dependent for e in self.effects)
        self.conservative = all(e.has_potential for e in self.effects) and not any(
            e.velocity_dependent for e in self.effects
        )
        self.constant_jacobian = all(c.barrier.constant_jacobian for c in self.contacts)
        self.force = self._build_force()
        self.gaps, self.jacobian = self._build_barrier_calls()
        self.tangent_jacobian = self._build_tangent_call() if self.has_friction else None

    # -- specialized evaluation -------------------------------------------------------
    def _build_force(self) -> ForceFn:
        fs: list[ForceFn] = [e.force for e in self.effects]
        bias = self.system.bias_force if self.system.has_bias else None
        if bias is None and not fs:
            zero = np.zeros(self.ndof)
            zero.setflags(write=False)
            return lambda t, q, v: zero
        if bias is None and len(fs) == 1:
            return fs[0]
        if bias is not None and not fs:
            return lambda t, q, v: bias(q, v)
        if bias is None:
            def force(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
                f = fs[0](t, q, v) + fs[1](t, q, v)
                for fi in fs[2:]:
                    f = f + fi(t, q, v)
                return f
            return force

        def force_with_bias(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
            f = bias(q, v)
            for fi in fs:
                f = f + fi(t, q, v)
            return f
        return force_with_bias

    def _build_barrier_calls(self) -> tuple[GapFn | None, GapFn | None]:
        bars = [c.barrier for c in self.contacts]
        if not bars:
            return None, None
        if len(bars) == 1:
            return bars[0].gap, bars[0].jacobian
        gaps = [b.gap for b in bars]
        jacs = [b.jacobian for b in bars]
        if self.constant_jacobian:
            Gc = np.vstack([np.atleast_2d(j(np.zeros(self.ndof))) for j in jacs])
            Gc.setflags(write=False)
            return (lambda q: np.concatenate([g(q) for g in gaps])), (lambda q: Gc)
        return (lambda q: np.concatenate([g(q) for g in gaps])), (
            lambda q: np.vstack([j(q) for j in jacs])
        )

    def _build_tangent_call(self) -> GapFn:
        """T(q) of all rows: each frictional contact's tangent rows, zeros elsewhere."""
        n = self.ndof
        parts = [(c.barrier.tangent_jacobian if c.frictional else None, c.barrier.nrows)
                 for c in self.contacts]
        only = parts[0][0]
        if len(parts) == 1 and only is not None:
            return cast(GapFn, only)

        def tangent_jacobian(q: np.ndarray) -> np.ndarray:
            return np.vstack([np.asarray(t(q), dtype=float) if t is not None else np.zeros((m, n))
                              for t, m in parts])
        return tangent_jacobian

    # -- energy -----------------------------------------------------------------------
    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """½ vᵀ M(q) v (the scene's energy unit, J in SI)."""
        return self.system.kinetic_energy(q, v)

    def potential_energy(self, q: np.ndarray) -> float:
        """Sum of the potentials of the effects that have one (the scene's energy unit)."""
        return float(sum(e.potential(q) for e in self.effects if e.has_potential))

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic plus potential energy (J); conserved when ``conservative`` and e = 1."""
        return self.kinetic_energy(q, v) + self.potential_energy(q)

    # -- checks -----------------------------------------------------------------------
    def check_state(self, t: float, q: np.ndarray, v: np.ndarray, where: str = "") -> None:
        """Evaluate every part given by the user once at (t, q, v) and check shapes and
        finiteness (a built-in part, one with a kernel of moreau's own, is checked when it
        is built: its shapes are fixed there, its parameters finite, a chain's or a constant
        mass matrix symmetric positive definite).

        Raises ``ValueError`` naming the part, the bad shape or value, and ``where``.
        """
        n = self.ndof
        if users(kernel_of(self.system, "mass_kernel")):
            M = np.asarray(self.system.mass_matrix(q), dtype=float)
            if M.shape != (n, n):
                raise ValueError(f"mass matrix{where} has shape {M.shape}, expected ({n}, {n})")
            check_spd(M, "mass matrix", where)
            if self.system.has_bias:
                _check_vec(self.system.bias_force(q, v), n, f"bias force{where}")
        for e in self.effects:
            if users(kernel_of(e)):
                _check_vec(e.force(t, q, v), n, f"force of effect {e.name!r}{where}")
        for c in self.contacts:
            b = c.barrier
            if not users(kernel_of(b)):
                continue
            g = np.asarray(b.gap(q), dtype=float)
            if g.shape != (b.nrows,):
                raise ValueError(f"gap of contact {c.name!r}{where} has shape {g.shape}, expected ({b.nrows},)")
            if not np.all(np.isfinite(g)):
                raise ValueError(f"gap of contact {c.name!r}{where} is not finite: {g.tolist()}")
            G = np.asarray(b.jacobian(q), dtype=float)
            if G.shape != (b.nrows, n):
                raise ValueError(
                    f"Jacobian of contact {c.name!r}{where} has shape {G.shape}, expected ({b.nrows}, {n})"
                )
            if not np.all(np.isfinite(G)):
                raise ValueError(f"Jacobian of contact {c.name!r}{where} is not finite: {G.tolist()}")
            if c.frictional and users(kernel_of(b, "tangent_kernel")):
                T = np.asarray(b.tangent_jacobian(q), dtype=float)
                if T.shape != (b.nrows, n) or not np.all(np.isfinite(T)):
                    raise ValueError(f"tangent rows of contact {c.name!r}{where} have shape {T.shape}, "
                                     f"expected ({b.nrows}, {n}), or are not finite: {T.tolist()}")
        for bc in self.constraints:
            geo = bc.geometry
            if not users(kernel_of(geo)):
                continue
            g = np.asarray(geo.gap(q), dtype=float)
            if g.shape != (geo.nrows,) or not np.all(np.isfinite(g)):
                raise ValueError(f"gap of constraint {bc.name!r}{where} has shape {g.shape}, expected "
                                 f"({geo.nrows},), or is not finite: {g.tolist()}")
            G = np.asarray(geo.jacobian(q), dtype=float)
            if G.shape != (geo.nrows, n) or not np.all(np.isfinite(G)):
                raise ValueError(f"Jacobian of constraint {bc.name!r}{where} has shape {G.shape}, expected "
                                 f"({geo.nrows}, {n}), or is not finite: {G.tolist()}")

    def check_constraints(self, q: np.ndarray, v: np.ndarray, tol: float = 1e-8, where: str = "") -> None:
        """Refuse a state off the bilateral constraints (see
        :func:`moreau.model.constraints.check_constraints`)."""
        check_constraints(self, q, v, tol, where)

    def constrained_velocity(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The velocity closest to v in the metric of M(q) with ``G_E(q) v = 0`` (see
        :func:`moreau.model.constraints.constrained_velocity`)."""
        return constrained_velocity(self, q, v)

    def describe(self) -> dict[str, Any]:
        """The scene's parameters as JSON-serializable data (saved with results)."""
        return {
            "name": self.name,
            "system": self.system.describe(),
            "effects": [e.describe() for e in self.effects],
            "contacts": [
                {"name": c.name, "barrier": c.barrier.describe(), "restitution": c.restitution.tolist(),
                 **({"friction": c.friction.tolist()} if c.frictional else {})}
                for c in self.contacts
            ],
            "units": self.units,
            **({"constraints": [c.describe() for c in self.constraints]} if self.constraints else {}),
        }

    def __repr__(self) -> str:
        eff = ", ".join(e.name for e in self.effects) or "none"
        con = ", ".join(c.name for c in self.contacts) or "none"
        bil = f", constraints=[{', '.join(c.name for c in self.constraints)}]" if self.constraints else ""
        return f"Scene({self.name!r}, ndof={self.ndof}, effects=[{eff}], contacts=[{con}]{bil})"


def _stacked(bars: list[Barrier]) -> tuple[GapFn | None, GapFn | None]:
    """``(g(q), G(q))`` of several barriers stacked (None, None for none)."""
    if not bars:
        return None, None
    if len(bars) == 1:
        return bars[0].gap, bars[0].jacobian
    gaps = [b.gap for b in bars]
    jacs = [b.jacobian for b in bars]
    return (lambda q: np.concatenate([np.asarray(g(q), dtype=float) for g in gaps])), (
        lambda q: np.vstack([np.asarray(j(q), dtype=float) for j in jacs]))


def _as_tuple(items: Any, kind: type, what: str) -> tuple[Any, ...]:
    try:
        out = tuple(items)
    except TypeError:
        raise ValueError(f"Scene: {what} must be a sequence of {kind.__name__} objects, got {items!r}") from None
    for x in out:
        if not isinstance(x, kind):
            raise ValueError(f"Scene: {what} must be {kind.__name__} objects, got {x!r}")
    return out


def _check_vec(x: Any, n: int, what: str) -> None:
    a = np.asarray(x, dtype=float)
    if a.shape != (n,):
        raise ValueError(f"{what} has shape {a.shape}, expected ({n},)")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} is not finite: {a.tolist()}")
