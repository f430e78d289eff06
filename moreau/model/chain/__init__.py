"""Planar serial chain of physical pendulums: M(q), bias terms, point kinematics, effects
and barriers.

The model is the triple physical pendulum of Awrejcewicz & Kudra (eq. (2.1)–(2.3)),
generalized to N >= 1 links. Link i (0-based: link 0 hangs from the fixed pivot) has
mass m_i, central moment of inertia J_i (about its centre of mass), joint-to-joint
length l_i and its centre of mass at ``(com_i, com_lateral_i)`` in the link frame.
The generalized coordinates are the ABSOLUTE angles φ_i of the links, measured from a
reference axis u; positive φ turns the link from u towards a lateral axis w:

.. math:: e(φ) = \\cos φ\\, u + \\sin φ\\, w, \\qquad e^\\perp(φ) = -\\sin φ\\, u + \\cos φ\\, w.

``"hanging"``: u = (0, −1), w = (1, 0), so e(φ) = (sin φ, −cos φ);
``"inverted"``: u = (0, 1), w = (1, 0), so e(φ) = (sin φ, cos φ) (the paper's engine).

A point fixed on link k at link-frame coordinates ``local = (a, b)`` (``a`` along the
link from its proximal joint, ``b`` across it, along e⊥) is at

.. math:: p = p_0 + \\sum_{i<k} l_i e(φ_i) + a\\, e(φ_k) + b\\, e^\\perp(φ_k).

Every quantity below is of the form ``Σ_i [C_i cos φ_i + S_i sin φ_i]`` with constant
coefficients, which are precomputed once so that the per-step evaluations are a handful
of vectorized numpy operations.

Mass matrix and bias force (derived from ``T = ½ Σ_k m_k |v_Ck|² + ½ J_k φ̇_k²``):

.. math:: M_{ij} = ν_{ij} \\cos(φ_i - φ_j) + ν^s_{ij} \\sin(φ_i - φ_j),
.. math:: f_{\\mathrm{bias}} = -N(φ)\\,\\dot φ^2,\\quad
          N_{ij} = ν_{ij} \\sin(φ_i - φ_j) - ν^s_{ij} \\cos(φ_i - φ_j),

where ν (symmetric, ν_ii = M_ii) and ν^s (antisymmetric, zero without lateral offsets)
are constant. Without lateral offsets this is exactly the paper's eq. (2.1)–(2.2) in
physical units; :meth:`PendulumChain.nondimensional` gives the paper's scaling M_11 = 1.
"""

from __future__ import annotations

from moreau.model.chain.barriers import JointStop, PointLineBarrier, PointLineRow
from moreau.model.chain.effects import ChainGravity, JointDamping, JointSprings, LinkTorque, PointForce
from moreau.model.chain.joints import ChainRows, join_points, pin_point, point_on_line
from moreau.model.chain.links import Link, PendulumChain
from moreau.model.chain.scaling import Nondimensional, Units

__all__ = [
    "Link",
    "PendulumChain",
    "Units",
    "Nondimensional",
    "ChainGravity",
    "JointDamping",
    "JointSprings",
    "LinkTorque",
    "PointForce",
    "PointLineRow",
    "PointLineBarrier",
    "JointStop",
    "ChainRows",
    "pin_point",
    "point_on_line",
    "join_points",
]

