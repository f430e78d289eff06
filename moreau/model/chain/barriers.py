"""Barriers of a pendulum chain: a point of a link against a line, and joint stops."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from moreau.core import kernels as _k
from moreau.core.validation import as_vector
from moreau.model.barriers import Barrier
from moreau.model.chain.links import PendulumChain, _require_chain


# ----------------------------------------------------------------------------------------
# barriers
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PointLineRow:
    """One row of a :class:`PointLineBarrier`: a point fixed on a link against a line.

    Parameters
    ----------
    link : int
        Index of the link carrying the point.
    local : array_like, shape (2,)
        (along, across) coordinates of the point in the link frame (m).
    line_point : array_like, shape (2,)
        A point of the line (m).
    normal : array_like, shape (2,)
        Normal of the line pointing into the admissible side (normalized on use).
    name : str, optional
        Label of the row in results.
    """

    link: int
    local: tuple
    line_point: tuple
    normal: tuple
    name: str | None = None


class PointLineBarrier(Barrier):
    """Points fixed on links kept on one side of straight lines (walls).

    Row r: ``g_r(q) = n_r · (p_r(q) − a_r)`` (m), the signed distance of the point p_r
    from the line through a_r with unit normal n_r; ``G_r = n_rᵀ J_{p_r}(q)``. All rows
    are ``g = g_0 + A cos q + B sin q``, ``G = B ∘ cos q − A ∘ sin q`` with constant (m, N)
    matrices A, B, whose rows are the chain's lengths up to the point's link: on a chain of
    ``CHAIN_STRUCTURED_MIN`` (8) links or more evaluated from the joints' positions, summed once for all rows, in
    O(N + m) (``moreau.core.kernels.gaps_chain_point``); on a shorter one from A and B
    (``moreau.core.kernels.gaps_trig``: the piston's drift-controlled steps, which
    evaluate the gaps several times a step, were 12-18 % slower with the other).

    Parameters
    ----------
    chain : PendulumChain
    rows : PointLineRow or sequence of PointLineRow (or of tuples
        ``(link, local, line_point, normal)``)
        The point/line pairs.

    Raises
    ------
    ValueError
        For no rows, a zero normal, or a link index out of range (named).
    """

    def __init__(self, chain: PendulumChain, rows) -> None:
        chain = _require_chain(chain, "PointLineBarrier")
        if isinstance(rows, PointLineRow):
            rows = [rows]
        rows = list(rows)
        if not rows:
            raise ValueError("PointLineBarrier needs at least one row")
        self.rows = tuple(r if isinstance(r, PointLineRow) else PointLineRow(*r) for r in rows)
        m, n = len(self.rows), chain.ndof
        A = np.empty((m, n))
        B = np.empty((m, n))
        At = np.empty((m, n))  # the tangent rows: the same projection on the line's direction
        Bt = np.empty((m, n))
        g0 = np.empty(m)
        kk = np.empty(m, dtype=int)  # each row's link
        self.normals = np.empty((m, 2))
        for r, row in enumerate(self.rows):
            where = f"PointLineBarrier row {r}"
            try:
                kk[r] = chain.check_link(row.link, f"{where}: link")
                C, S = chain.levers(kk[r], row.local)
            except ValueError as exc:
                msg = str(exc)
                raise ValueError(msg if msg.startswith(where) else f"{where}: {msg}") from None
            nrm = as_vector(row.normal, f"{where}: normal", 2)
            length = float(np.hypot(*nrm))
            if length == 0.0:
                raise ValueError(f"{where}: the normal of the line must be non-zero, got {nrm.tolist()}")
            nrm = nrm / length
            a = as_vector(row.line_point, f"{where}: line_point", 2)
            A[r], B[r] = chain._projection(nrm, C, S)
            At[r], Bt[r] = chain._projection(np.array([nrm[1], -nrm[0]]), C, S)
            g0[r] = float(nrm @ (chain.pivot - a))
            self.normals[r] = nrm
        self.nrows, self.ndof = m, n
        self._n = n
        self._A, self._B, self._g0 = A, B, g0
        du = self.normals @ chain.axis
        dw = self.normals @ chain.lateral
        self._structured = n >= _k.CHAIN_STRUCTURED_MIN
        if self._structured:  # layout of kernels.gaps_chain_point: g0, k, du, dw, a, b, the rows by k, l
            self._p = _k.flat(g0, kk.astype(float), du, dw, A[np.arange(m), kk], B[np.arange(m), kk],
                              np.argsort(kk, kind="stable").astype(float), chain.lengths)
        else:
            self._p = _k.flat(g0, A, B)  # layout of kernels.gaps_trig
        self._pt = _k.flat(np.zeros(m), At, Bt)  # the tangent rows, same layout
        self.normals.setflags(write=False)
        self.has_tangents = True

    def gap(self, q):
        out = np.empty(self.nrows)
        gaps = _k.gaps_chain_point if self._structured else _k.gaps_trig
        gaps(self._p, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def jacobian(self, q):
        out = np.empty((self.nrows, self._n))
        jacobian = _k.jacobian_chain_point if self._structured else _k.jacobian_trig
        jacobian(self._p, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def tangent_jacobian(self, q):
        """Row r: the velocity of the point along its line, direction (n_y, −n_x) (m/s
        per unit of q̇)."""
        out = np.empty((self.nrows, self._n))
        _k.jacobian_trig(self._pt, 0, self.nrows, *_k.cos_sin(q), out, 0)
        return out

    def kernel(self):
        return (_k.BAR_CHAIN_POINT if self._structured else _k.BAR_TRIG), (self._p,)

    def tangent_kernel(self):
        return _k.BAR_TRIG, (self._pt,)

    def gap_scale(self):
        return np.abs(self._g0) + np.abs(self._A).sum(axis=1) + np.abs(self._B).sum(axis=1)

    def row_names(self, prefix):
        if self.nrows == 1 and self.rows[0].name is None:
            return [prefix]
        return [f"{prefix}[{r.name if r.name is not None else i}]" for i, r in enumerate(self.rows)]

    def describe(self):
        return {
            **super().describe(),
            "rows": [
                {"link": int(r.link), "local": np.asarray(r.local, float).tolist(),
                 "line_point": np.asarray(r.line_point, float).tolist(),
                 "normal": self.normals[i].tolist(), "name": r.name}
                for i, r in enumerate(self.rows)
            ],
        }


class JointStop(Barrier):
    """Angle stops: ``lower <= θ <= upper`` with θ = φ_i, or θ = φ_i − φ_j when
    ``relative_to = j`` (the joint between links j and i when j = i − 1).

    Rows (rad): ``θ − lower`` and/or ``upper − θ``; the Jacobian is constant.

    Parameters
    ----------
    chain : PendulumChain
    link : int
        Index i of the link whose angle is stopped.
    lower, upper : float, optional
        Bounds (rad); at least one, and lower < upper when both.
    relative_to : int, optional
        Index j: stop the relative angle φ_i − φ_j instead of φ_i.
    """

    constant_jacobian = True

    def __init__(self, chain: PendulumChain, link: int, lower: float | None = None,
                 upper: float | None = None, relative_to: int | None = None) -> None:
        chain = _require_chain(chain, "JointStop")
        self.link = chain.check_link(link, "JointStop: link")
        self.relative_to = None if relative_to is None else chain.check_link(relative_to, "JointStop: relative_to link")
        if self.relative_to == self.link:
            raise ValueError(f"JointStop: relative_to must differ from link, got {link} twice")
        if lower is None and upper is None:
            raise ValueError("JointStop needs a lower or an upper bound (or both)")
        self.lower = None if lower is None else _finite(lower, "JointStop.lower")
        self.upper = None if upper is None else _finite(upper, "JointStop.upper")
        if self.lower is not None and self.upper is not None and not self.lower < self.upper:
            raise ValueError(f"JointStop: lower must be < upper, got {self.lower!r} >= {self.upper!r}")
        a = np.zeros(chain.ndof)
        a[self.link] = 1.0
        if self.relative_to is not None:
            a[self.relative_to] = -1.0
        rows, b, self._names = [], [], []
        if self.lower is not None:
            rows.append(a)
            b.append(-self.lower)
            self._names.append("lower")
        if self.upper is not None:
            rows.append(-a)
            b.append(self.upper)
            self._names.append("upper")
        self.G = np.array(rows)
        self.G.setflags(write=False)
        self._b = np.array(b)
        self.nrows, self.ndof = self.G.shape
        self._p = _k.flat(self.G, self._b)

    def gap(self, q):
        out = np.empty(self.nrows)
        _k.gaps_linear(self._p, 0, self.nrows, q, out, 0)
        return out

    def jacobian(self, q):
        return self.G

    def kernel(self):
        return _k.BAR_LINEAR, (self._p,)

    def gap_scale(self):
        return np.abs(self._b) + np.abs(self.G).sum(axis=1)

    def row_names(self, prefix):
        if self.nrows == 1:
            return [prefix]
        return [f"{prefix}[{n}]" for n in self._names]

    def describe(self):
        return {**super().describe(), "link": self.link, "relative_to": self.relative_to,
                "lower": self.lower, "upper": self.upper}


def _finite(x, name: str) -> float:
    try:
        val = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not np.isfinite(val):
        raise ValueError(f"{name} must be finite, got {x!r}")
    return val
