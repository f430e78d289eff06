"""Tools for testing code that uses moreau: fault injection into the contact solve, and
one-step friction problems of many contacts (:func:`rod_pile`).

:class:`FaultInjectingSolver` wraps a real :class:`~moreau.contact.solvers.ContactSolver` and
makes chosen calls fail, either loudly (``mode="raise"``: the backend reports a failure)
or quietly (``mode="wrong"``: it returns an inaccurate answer that looks like a
solution). The integrator must catch both — the first by the exception, the second by
its KKT check — and fall back to its exact backend, counting the fallback in
``traj.stats.fallbacks``::

    faulty = FaultInjectingSolver("enum", fail_on={0, 10, 20}, mode="wrong")
    traj = moreau.simulate(scene, (0, 1), q0, v0, 1e-3, solver=faulty, fallback="enum")
    assert traj.stats.fallbacks == len(faulty.injected)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import cast

import numpy as np

from moreau.contact.solvers import ContactSolver, SolveFailed, make_solver

__all__ = ["FaultInjectingSolver", "rod_pile"]

_MODES = ("raise", "wrong")


class FaultInjectingSolver(ContactSolver):
    """A contact solver that fails on chosen calls and delegates the others.

    Parameters
    ----------
    inner : str or ContactSolver
        The real backend (a name for :func:`moreau.contact.solvers.make_solver`, or an instance).
    fail_on : iterable of int, or callable ``fail_on(call) -> bool``
        0-based indices of the calls to :meth:`solve` that fail (call 0 is the first
        contact solve of the run; drift-control projections, when used, are solves too
        and are counted). A callable decides per call.
    mode : {"raise", "wrong"}
        ``"raise"``: raise :class:`~moreau.contact.solvers.SolveFailed`, as a backend that gives
        up does. ``"wrong"``: return the inner solution with the velocity perturbed so
        that the momentum balance ``M v = b + Gᵀ P`` is off by ``error`` relative to the
        momentum scale of the step — a plausible, finite, wrong answer that only a KKT
        check can tell from a right one.
    error : float
        Relative size of the momentum error of a ``"wrong"`` answer (default 1e-3, far
        above the integrator's default KKT tolerance 1e-6).

    Attributes
    ----------
    calls : int
        Number of calls to :meth:`solve` so far.
    injected : list of int
        Indices of the calls that were made to fail.

    Raises
    ------
    ValueError
        For an unknown mode, a negative or non-integer call index, or a non-positive error.
    """

    exact = False

    def __init__(self, inner: str | ContactSolver, fail_on: Iterable[int] | object = (),
                 mode: str = "raise", error: float = 1e-3) -> None:
        if mode not in _MODES:
            raise ValueError(f"FaultInjectingSolver: mode must be one of {_MODES}, got {mode!r}")
        self.inner = make_solver(inner)
        self._fail: Callable[[int], bool]
        self.fail_on: frozenset[int] | None
        if callable(fail_on):
            self._fail = fail_on
            self.fail_on = None
        else:
            idx = set()
            for i in cast(Iterable[object], fail_on):
                if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or i < 0:
                    raise ValueError(f"FaultInjectingSolver: call indices must be integers >= 0, got {i!r}")
                idx.add(int(i))
            self.fail_on = frozenset(idx)
            self._fail = self.fail_on.__contains__
        if not (np.isfinite(error) and error > 0):
            raise ValueError(f"FaultInjectingSolver: error must be finite and > 0, got {error!r}")
        self.mode = mode
        self.error = float(error)
        self.name = f"faulty({self.inner.name},{mode})"
        self.calls = 0
        self.injected: list[int] = []

    def setup(self, ndof: int, nrows: int, mass: np.ndarray | None = None) -> None:
        self.inner.setup(ndof, nrows, mass)

    def solve(self, M, b, G, c, rows):
        call = self.calls
        self.calls += 1
        if not self._fail(call):
            return self.inner.solve(M, b, G, c, rows)
        self.injected.append(call)
        if self.mode == "raise":
            raise SolveFailed(f"injected failure on call {call}")
        v, P = self.inner.solve(M, b, G, c, rows)
        GtP = P @ G[rows]
        scale = max(float(np.abs(b).max(initial=0.0)), float(np.abs(GtP).max(initial=0.0)))
        if scale == 0.0:
            scale = 1.0  # any momentum error is infinitely wrong relative to a zero scale
        # M δ = error · scale · (1, …, 1): the stationarity residual becomes exactly `error`
        delta = np.linalg.solve(M, np.full(v.shape[0], self.error * scale))
        return v + delta, P

    def describe(self) -> dict:
        return {"name": self.name, "inner": self.inner.describe(), "mode": self.mode,
                "fail_on": sorted(self.fail_on) if self.fail_on is not None else "callable",
                "error": self.error}


def rod_pile(width: int, rng: np.random.Generator, mu: float = 0.3, h: float = 1e-3) -> tuple:
    """The one-step friction problem of a pile of rods: ``width`` rods (1 m, 1 kg) on a
    floor, and on every two neighbours one more, up to a single rod at the top; each rod
    touches the floor or the two rods below at its ends (``width (width + 1)`` contacts; the
    two floor rows of a rod share one tangent row: redundant), every coordinate moving at
    random (0.3 m/s, 1 m/s down) for one step of ``h`` (s) under gravity.

    Returns ``(M, b, GA, cA, TA, muA)`` as :func:`moreau.contact.friction.friction_one_step`
    takes them: M (n, n), b = M v + h f (n,), the normal and tangent rows (k, n), zero
    lower bounds (e = 0) and ``mu`` (k,)."""
    rods, layer = [(1.2 * i, 0) for i in range(width)], 1
    contacts = [(i, -1, s, 0.0) for i in range(width) for s in (-0.5, 0.5)]  # (rod, rod below, arms)
    below = list(range(width))
    while len(below) > 1:
        above = []
        for i in range(len(below) - 1):
            x = 0.5 * (rods[below[i]][0] + rods[below[i + 1]][0])
            rods.append((x, layer))
            above.append(len(rods) - 1)
            contacts += [(len(rods) - 1, below[i], -0.5, x - 0.5 - rods[below[i]][0]),
                         (len(rods) - 1, below[i + 1], 0.5, x + 0.5 - rods[below[i + 1]][0])]
        below, layer = above, layer + 1
    n, k = 3 * len(rods), len(contacts)
    M = np.diag(np.tile([1.0, 1.0, 1.0 / 12], len(rods)))
    GA, TA = np.zeros((k, n)), np.zeros((k, n))
    for j, (u, lo, ru, rl) in enumerate(contacts):
        GA[j, 3 * u + 1], GA[j, 3 * u + 2], TA[j, 3 * u] = 1.0, ru, 1.0
        if lo >= 0:
            GA[j, 3 * lo + 1], GA[j, 3 * lo + 2], TA[j, 3 * lo] = -1.0, -rl, -1.0
    v = 0.3 * rng.standard_normal(n)
    v[1::3] -= 1.0
    b = M @ v
    b[1::3] -= h * 9.81
    return M, b, GA, np.zeros(k), TA, np.full(k, mu)
