"""The piston – connecting rod – crankshaft engine as a moreau scene.

Built only from moreau's public API: a three-link inverted :class:`~moreau.model.chain.PendulumChain`
in the paper's non-dimensional units (length l1, time 1/ω, M_11 = 1; see
:mod:`moreau.problems.piston.params`), with the effects the scene asks for — any of
``"gravity"``, ``"damping"`` (joint damping), ``"gas"`` (gas force on the pin),
``"brake"`` (brake moment on the crank) — and the four corner contacts of eq. (2.3).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

import moreau as mo
from moreau.model.chain import (
    ChainGravity,
    JointDamping,
    Link,
    LinkTorque,
    PendulumChain,
    PointForce,
    PointLineBarrier,
    PointLineRow,
    Units,
)

from .params import PistonParameters
from .pressure import EngineGeometry, FourierPressure, calibrate
from .units import scene_units

__all__ = ["EFFECTS", "CORNERS", "FLIGHT_FRACTION", "PROJECTION_FRACTION", "PistonModel", "piston_model"]

EFFECTS = ("gravity", "damping", "gas", "brake")
CORNERS = ("top-right", "bottom-right", "top-left", "bottom-left")
#: A corner's contact onset is an impact when, since it last touched, it left the wall by
#: more than this fraction of the clearance D − d (the flight gap, see moreau.ImpactLog).
#: Measured: the flight counts per cycle then agree within a few % from h = 1e-3 to 1e-5.
FLIGHT_FRACTION = 0.02

#: The engine's drift control (:meth:`PistonModel.drift_control`) accepts a corner this
#: fraction of the clearance inside the wall before it projects: 4 nm for the paper's
#: 40 µm. Measured (``benchmarks/piston_convergence.py --tol 0`` against the default,
#: e = 0 … 0.9, h = 1e-3 … 1e-5): the same side changes with angles within 1°, energy lost
#: per cycle within 0.001 J, flight impacts within one for e <= 0.3; for e = 0.9 the
#: impacts differ by up to 7 % (145.5 … 153.5 against 142 … 153.5 per cycle), within the
#: chattering piston's cycle-to-cycle scatter. The projection runs on 3 % instead of 80 %
#: of the steps of the plastic piston at h = 1e-4 (0.94 instead of 1.70 µs per step,
#: ``benchmarks/step_cost.py``).
PROJECTION_FRACTION = 1e-4


@dataclass
class PistonModel:
    """The engine scene with everything needed to run and read it.

    Attributes
    ----------
    params : PistonParameters
        Physical parameters (SI).
    pressure : FourierPressure or None
        Gauge pressure p̄(φ1) (Pa), when the gas force is in the scene.
    chain : PendulumChain
        The non-dimensional chain (M_11 = 1).
    units : Units
        Scales: divide SI quantities by them (time unit 1/ω, length l1).
    scene : moreau.Scene
        The scene: coordinates (φ1, φ2, φ3), time τ = ω t.
    effects : tuple of str
        The effects in the scene.
    """

    params: PistonParameters
    pressure: FourierPressure | None
    chain: PendulumChain
    units: Units
    scene: mo.Scene
    effects: tuple

    def initial_state(self, phi1: float = 0.0, speed: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """A consistent start: pin on the cylinder axis, piston upright, crank at ``phi1``
        (rad) turning at ``speed`` (non-dimensional, 1 = the reference rpm)."""
        lam = self.params.l2 / self.params.l1
        s = np.sin(phi1) / lam
        phi2 = -np.arcsin(s)
        dphi2 = -np.cos(phi1) * speed / (lam * np.cos(phi2))
        return np.array([phi1, phi2, 0.0]), np.array([speed, dphi2, 0.0])

    def simulate(self, cycles: float, h: float = 1e-4, *, phi1: float = 0.0, **kwargs) -> mo.Trajectory:
        """Run ``cycles`` engine cycles (4π of non-dimensional time each, at speed 1) from
        :meth:`initial_state`; ``kwargs`` go to :func:`moreau.simulate`. Defaults set
        here: ``penetration_limit`` = the clearance and ``flight_gap`` =
        ``FLIGHT_FRACTION`` × the clearance (both in units of l1, the gaps' unit), so
        ``traj.impacts`` counts the onsets after a corner left the wall by 2 % of the
        clearance.

        Warns (``RuntimeWarning``, naming h and the clearance) when the step is too coarse
        for the clearance: when ``h > (D − d) / l1``. In non-dimensional units the crank
        pin moves at speed 1 (l1 ω), the velocity scale of the piston's lateral motion,
        so in one step it travels h·l1; the criterion asks that this not exceed the
        clearance D − d that the contact geometry lives in. It is also where the
        midpoint drift of a sliding contact stops being small: the penetration of the
        plastic (e = 0) piston is measured at ≈ h·l1, i.e. ≈ 10 %, 50 % and 100 % of the
        paper's 40 µm clearance at h = 1e-4, 5e-4 and 1e-3 — past the limit the corners
        go deeper into the wall than the whole clearance. Limits: h <= 1e-3 for
        D = 80.04 mm, 1e-4 for a 4 µm clearance, 5e-3 for D = 80.2 mm. The run still
        happens (the scheme stays stable); the warning says its contact results are not
        resolved. With ``step_control`` h is the largest step and the tolerance sizes the
        steps where the contacts switch (docs/guide/accuracy.md: which tol for which
        error), so h is not checked; the penetration limit still is.
        """
        p = self.params
        limit = p.clearance / p.l1  # non-dimensional time for the pin to cross the clearance
        adaptive = kwargs.get("step_control") is not None
        if not adaptive and float(h) > limit * (1.0 + 1e-9):  # 1e-9: the round-off of D − d, not a margin
            warnings.warn(
                f"step h = {float(h):g} (non-dimensional time) is too coarse for the clearance "
                f"D - d = {1e6 * p.clearance:.4g} um: the crank pin moves h*l1 = "
                f"{1e6 * float(h) * p.l1:.4g} um per step, more than the clearance, and the contact "
                f"geometry is not resolved; use h <= {limit:.3g}",
                RuntimeWarning,
                stacklevel=2,
            )
        q0, v0 = self.initial_state(phi1)
        # a corner deeper than the clearance is a contact the step does not resolve
        kwargs.setdefault("penetration_limit", p.clearance / p.l1)  # gaps are in units of l1
        # an impact is a contact onset after the corner left the wall by 2 % of the clearance
        kwargs.setdefault("flight_gap", FLIGHT_FRACTION * p.clearance / p.l1)
        return mo.simulate(self.scene, (0.0, 4 * np.pi * cycles), q0, v0, h, **kwargs)

    def drift_control(self) -> mo.CombinedProjection:
        """The engine's drift control: :class:`moreau.CombinedProjection` accepting a
        penetration of ``PROJECTION_FRACTION`` × the clearance (in units of l1, the
        gaps' unit)."""
        p = self.params
        return mo.CombinedProjection(tol=PROJECTION_FRACTION * p.clearance / p.l1)


def piston_model(
    params: PistonParameters | None = None,
    effects: Iterable[str] = EFFECTS,
    e: float | Sequence[float] | None = None,
    pressure: FourierPressure | None = None,
    mu: float | None = None,
) -> PistonModel:
    """Build the engine scene.

    Parameters
    ----------
    params : PistonParameters, optional
        Physical parameters (default: the paper's, e = 0, D = 80.04 mm).
    effects : iterable of str
        Subset of ``EFFECTS`` to include; the others are not in the scene at all.
    e : float or sequence of 4 floats, optional
        Restitution (overrides ``params.e``); four values give one per corner in the
        order of ``CORNERS``.
    pressure : FourierPressure, optional
        Gauge pressure curve (default: the synthetic curve calibrated for 2000 rpm with
        the brake moment ``params.M0``).
    mu : float, optional
        Coulomb friction of the skirt at the cylinder wall (overrides ``params.mu``; 0,
        the default, is the paper's frictionless wall: the scene then has no tangent rows).
    """
    p = PistonParameters() if params is None else params
    if mu is not None:
        p = p.with_(mu=mu)
    effects = tuple(effects)
    unknown = [x for x in effects if x not in EFFECTS]
    if unknown:
        raise ValueError(f"unknown piston effect(s) {unknown}; choose from {EFFECTS}")
    physical = PendulumChain(
        [Link(m=p.m1, J=p.J1, l=p.l1, com=p.e1), Link(m=p.m2, J=p.J2, l=p.l2, com=p.e2),
         Link(m=p.m3, J=p.J3, l=p.h, com=p.e3)],
        orientation="inverted",
    )
    nd = physical.nondimensional(length_scale=p.l1, time_scale=1.0 / p.omega)
    chain, u = nd.chain, nd.units

    fx = []
    if "gravity" in effects:
        fx.append(ChainGravity(chain, g=p.g / u.acceleration, direction=(0.0, -1.0)))
    if "damping" in effects:
        fx.append(JointDamping(chain, np.array([1.0, p.c21, p.c31]) * p.c1 / u.damping, name="damping"))
    if "gas" in effects:
        if pressure is None:
            pressure = calibrate(
                omega=p.omega, M0=p.M0, c1=p.c1, c2=p.c21 * p.c1, c3=p.c31 * p.c1, p_max=p.p_max,
                geometry=EngineGeometry(bore=p.d, crank_radius=p.l1, rod_length=p.l2),
            ).pressure
        k = p.area / u.force  # Pa → non-dimensional force on the pin
        # F = (0, −p̄(φ1) A) on the pin, along the cylinder axis towards the crank
        load = mo.FourierLoad((0.0, -k), pressure.a0, pressure.a, pressure.b, omega=0.5, coordinate=0)
        fx.append(PointForce(chain, 2, (0.0, 0.0), load,
                             velocity_dependent=False, time_dependent=False, name="gas"))
    else:
        pressure = None
    if "brake" in effects:
        fx.append(LinkTorque(chain, [-p.M0 / u.torque, 0.0, 0.0], name="brake"))

    L = p.l1
    top, bottom = p.h / L, -(p.s - p.h) / L
    half_d, half_D = 0.5 * p.d / L, 0.5 * p.D / L
    rows = [
        PointLineRow(2, (top, half_d), (half_D, 0.0), (-1.0, 0.0), name=CORNERS[0]),
        PointLineRow(2, (bottom, half_d), (half_D, 0.0), (-1.0, 0.0), name=CORNERS[1]),
        PointLineRow(2, (top, -half_d), (-half_D, 0.0), (1.0, 0.0), name=CORNERS[2]),
        PointLineRow(2, (bottom, -half_d), (-half_D, 0.0), (1.0, 0.0), name=CORNERS[3]),
    ]
    law = p.e if e is None else e
    if p.mu > 0.0:  # skirt friction: the corners slide along the wall (tangents from the wall's direction)
        law = mo.NewtonImpactFriction(law.e if isinstance(law, mo.NewtonImpact) else law, p.mu)
    contact = mo.Contact(PointLineBarrier(chain, rows), law, name="cylinder")
    scene = mo.Scene(chain, fx, [contact], name="piston", units=scene_units(p, u))
    return PistonModel(params=p, pressure=pressure, chain=chain, units=u, scene=scene, effects=effects)
