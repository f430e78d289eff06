"""Bilateral constraints of a pendulum chain: a point of a link pinned to a fixed point,
held on a line, or joined to a point of another link — so a four-bar linkage or a
slider-crank written as a closed chain is a few lines::

    crank_rod_rocker = PendulumChain([...3 links...])
    closure = pin_point(chain, link=2, local=(l2, 0.0), point=(d, 0.0))
    scene = Scene(chain, [ChainGravity(chain)], constraints=[closure])

Every row is ``g = g0 + A cos q + B sin q`` (m), the form of the chain's point/line
barriers, so the compiled loop evaluates them with the same kernel.
"""

from __future__ import annotations

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_vector
from moreau.model.barriers import Barrier
from moreau.model.chain.links import PendulumChain, _require_chain
from moreau.model.constraints import Bilateral

__all__ = ["ChainRows", "pin_point", "point_on_line", "join_points"]

_AXES = (np.array([1.0, 0.0]), np.array([0.0, 1.0]))


class ChainRows(Barrier):
    """Rows ``g = g0 + A cos q + B sin q`` of a chain (m), ``G = B ∘ cos q − A ∘ sin q``:
    the geometry of the chain's joints (see :func:`pin_point`, :func:`point_on_line`,
    :func:`join_points`).

    Parameters
    ----------
    g0 : array_like, shape (k,)
    A, B : array_like, shape (k, N)
    names : sequence of str
        One label per row (appended to the constraint's name).
    """

    def __init__(self, g0, A, B, names) -> None:
        self._g0 = np.asarray(g0, dtype=float)
        self._A = np.atleast_2d(np.asarray(A, dtype=float))
        self._B = np.atleast_2d(np.asarray(B, dtype=float))
        self.nrows, n = self._A.shape
        self.ndof = n
        self._names = list(names)
        self._p = _k.flat(self._g0, self._A, self._B)  # layout of kernels.gaps_trig

    def gap(self, q):
        out = np.empty(self.nrows)
        _k.gaps_trig(self._p, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def jacobian(self, q):
        out = np.empty((self.nrows, self._A.shape[1]))
        _k.jacobian_trig(self._p, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def kernel(self):
        return _k.BAR_TRIG, (self._p,)

    def gap_scale(self):
        return np.abs(self._g0) + np.abs(self._A).sum(axis=1) + np.abs(self._B).sum(axis=1)

    def row_names(self, prefix):
        return [f"{prefix}[{n}]" for n in self._names] if self.nrows > 1 else [prefix]

    def describe(self):
        return {**super().describe(), "g0": self._g0.tolist(), "A": self._A.tolist(), "B": self._B.tolist()}


def _levers(chain: PendulumChain, link, local, what: str):
    try:
        return chain.levers(chain.check_link(link, f"{what}: link"), local)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None


def pin_point(chain: PendulumChain, link: int, local, point, name: str = "pin") -> Bilateral:
    """A point of ``link`` (``local = (along, across)`` in its frame, m) held at the fixed
    ``point`` (m): two rows, the x and y offsets (a revolute joint to the ground)."""
    chain = _require_chain(chain, "pin_point")
    C, S = _levers(chain, link, local, f"pin_point {name!r}")
    a = as_vector(point, f"pin_point {name!r}: point", 2)
    rows = [chain._projection(d, C, S) for d in _AXES]
    g0 = [float(d @ (chain.pivot - a)) for d in _AXES]
    return Bilateral(ChainRows(g0, [r[0] for r in rows], [r[1] for r in rows], ["x", "y"]), name=name)


def point_on_line(chain: PendulumChain, link: int, local, line_point, normal, name: str = "slider") -> Bilateral:
    """A point of ``link`` held on the line through ``line_point`` with normal ``normal``
    (m): one row (a prismatic joint's guide, e.g. the piston pin on the cylinder axis)."""
    chain = _require_chain(chain, "point_on_line")
    C, S = _levers(chain, link, local, f"point_on_line {name!r}")
    nrm = as_vector(normal, f"point_on_line {name!r}: normal", 2)
    length = float(np.hypot(*nrm))
    if length == 0.0:
        raise ValueError(f"point_on_line {name!r}: the normal must be non-zero, got {nrm.tolist()}")
    nrm = nrm / length
    a = as_vector(line_point, f"point_on_line {name!r}: line_point", 2)
    A, B = chain._projection(nrm, C, S)
    return Bilateral(ChainRows([float(nrm @ (chain.pivot - a))], [A], [B], ["n"]), name=name)


def join_points(chain: PendulumChain, first, second, name: str = "joint") -> Bilateral:
    """Two points of the chain held together, ``first = (link, local)`` and ``second =
    (link, local)``: two rows (a revolute joint closing a loop)."""
    chain = _require_chain(chain, "join_points")
    Ca, Sa = _levers(chain, first[0], first[1], f"join_points {name!r} (first)")
    Cb, Sb = _levers(chain, second[0], second[1], f"join_points {name!r} (second)")
    rows = [chain._projection(d, Ca - Cb, Sa - Sb) for d in _AXES]
    return Bilateral(ChainRows([0.0, 0.0], [r[0] for r in rows], [r[1] for r in rows], ["x", "y"]), name=name)
