"""A user model's derivatives, checked before a run.

The bias force against the mass matrix: ``simulate`` refuses a bias that is not
−Ṁv + ½∇(vᵀMv) of M(q) (the Lagrange equations), and a q-dependent M without one. A wrong
sign there otherwise shows only as energy growing at every h, which the energy check
reports as a step too large. A barrier's Jacobian against its gap: at the initial state
and, for a user's barrier, a little off it, where a symmetric start does not hide a term."""

import warnings

import numpy as np
import pytest

import moreau as mo
from moreau.model.system import check_bias

L1, L2, M1, M2, G0 = 1.0, 0.8, 1.0, 0.5, 9.81


def dp_mass(q):
    c = np.cos(q[0] - q[1])
    return np.array([[(M1 + M2) * L1**2, M2 * L1 * L2 * c], [M2 * L1 * L2 * c, M2 * L2**2]])


def dp_bias(q, v):  # the double pendulum's centrifugal terms, on the right-hand side
    s = np.sin(q[0] - q[1])
    return np.array([-M2 * L1 * L2 * s * v[1] ** 2, M2 * L1 * L2 * s * v[0] ** 2])


def dp_bias_lhs(q, v):  # the same terms with the sign of the equations' left-hand side
    return -dp_bias(q, v)


def dp_gravity(t, q, v):
    return np.array([-(M1 + M2) * G0 * L1 * np.sin(q[0]), -M2 * G0 * L2 * np.sin(q[1])])


def double_pendulum(bias=dp_bias):
    system = mo.FunctionSystem(dp_mass, ndof=2, bias=bias, name="double pendulum")
    return mo.Scene(system, [mo.FunctionForce(dp_gravity, name="gravity")])


def run(scene, h=1e-3, **kw):
    return mo.simulate(scene, (0.0, 2.0), [0.0, 0.0], [3.0, 0.0], h, record_every=100, **kw)


def energy_spread(traj):
    """max − min of T + V over the records (gravity is a force here: V by hand)."""
    T = np.array([0.5 * v @ dp_mass(q) @ v for q, v in zip(traj.q, traj.v)])
    V = -(M1 + M2) * G0 * L1 * np.cos(traj.q[:, 0]) - M2 * G0 * L2 * np.cos(traj.q[:, 1])
    return np.ptp(T + V)


def test_the_right_bias_runs_and_its_energy_error_falls_with_h():
    # the Lagrange equations conserve T + V; the midpoint step with a velocity-dependent
    # force keeps it to first order in h (measured 0.015, 0.0015 of 6.75 J)
    coarse, fine = (run(double_pendulum(), h=h) for h in (1e-3, 1e-4))
    assert coarse.completed and fine.completed
    assert energy_spread(fine) < 0.12 * energy_spread(coarse) < 0.12 * 0.01 * 6.75


def test_a_bias_of_the_wrong_sign_is_refused_at_a_symmetric_start():
    # every term vanishes at q = (0, 0): the check looks a little off it
    with pytest.raises(ValueError, match=r"bias force of system 'double pendulum' does not match its mass matrix.*"
                                         r"right-hand side, M dv/dt = bias \+ forces"):
        run(double_pendulum(dp_bias_lhs))
    # without the check the run stops on its energy at every h, blaming the step
    for h in (1e-3, 1e-4):
        with warnings.catch_warnings(), pytest.raises(mo.SimulationError, match="the energy grew"):
            warnings.simplefilter("ignore", RuntimeWarning)
            run(double_pendulum(dp_bias_lhs), h=h, check_jacobian=False)


def test_a_mass_matrix_that_depends_on_q_needs_a_bias():
    with pytest.raises(ValueError, match=r"mass matrix of system 'double pendulum' depends on q but the system has "
                                         r"no bias force: at q = \[.*\] the velocity-squared terms"):
        run(double_pendulum(None))
    # a callable returning a constant matrix needs none, and has none: a damping force given
    # as the bias of a constant M is refused (it belongs in an effect)
    const = mo.Scene(mo.FunctionSystem(lambda q: 2.0 * np.eye(2), ndof=2), [mo.ConstantForce([0.0, -1.0])])
    assert run(const).completed
    damped = mo.Scene(mo.FunctionSystem(2.0 * np.eye(2), bias=lambda q, v: -0.1 * v), [mo.ConstantForce([0.0, -1.0])])
    with pytest.raises(ValueError, match=r"are \[0, 0\], bias_force gives \[.*belong in an effect"):
        run(damped)


class Cart(mo.MechanicalSystem):
    """A bead on a rod of mass moment growing with its position r: M = diag(1, J + r²),
    q = (r, θ). Bias: centrifugal r θ'² on r, Coriolis −2 r r' θ' on θ."""

    ndof, has_bias = 2, True

    def __init__(self, half_coriolis: bool = False) -> None:
        self.half = half_coriolis

    def mass_matrix(self, q):
        return np.diag([1.0, 0.5 + q[0] ** 2])

    def bias_force(self, q, v):
        coriolis = (1.0 if self.half else 2.0) * q[0] * v[0] * v[1]
        return np.array([q[0] * v[1] ** 2, -coriolis])


def test_check_bias_against_the_analytic_terms_and_a_subclass_with_a_factor_off():
    c = check_bias(Cart(), [0.3, 0.0])
    r, (dr, dth) = c.q[0], c.v
    np.testing.assert_allclose(c.numeric, [r * dth**2, -2.0 * r * dr * dth], rtol=1e-8)
    assert c.ok() and c.max_rel_error < 1e-8
    assert not check_bias(Cart(half_coriolis=True), [0.3, 0.0]).ok()
    scene = mo.Scene(Cart(half_coriolis=True), [])
    with pytest.raises(ValueError, match=r"bias force of system 'Cart' does not match"):
        mo.simulate(scene, (0.0, 0.1), [0.3, 0.0], [0.0, 1.0], 1e-3)
    assert mo.simulate(scene, (0.0, 0.1), [0.3, 0.0], [0.0, 1.0], 1e-3, check_jacobian=False).completed


def test_coordinates_of_thousands_raise_no_false_alarm():
    # relative difference steps of 3e-3 there; absolute ones where those disagree
    assert check_bias(mo.FunctionSystem(dp_mass, ndof=2, bias=dp_bias), [3000.0, 2000.5]).ok()
    assert check_bias(mo.FunctionSystem(lambda q: np.diag([1.0, 2.0 + np.cos(q[1])]), ndof=2,
                                        bias=lambda q, v: np.array([0.0, 0.5 * np.sin(q[1]) * v[1] ** 2])),
                      [0.0, 1e5]).ok()


def test_the_built_in_chains_bias_is_that_of_their_mass_matrix():
    # simulate trusts the chains' own terms (not checked per run): checked here once
    from moreau.dynamics.benchmarks import forced_triple_pendulum
    from moreau.problems.piston import PistonParameters, piston_model

    triple = forced_triple_pendulum(6.0).system
    piston = piston_model(PistonParameters(e=0.0)).scene.system
    for system, q in ((triple, [0.3, -0.2, 0.5]), (piston, [1.0, 0.1, 1e-3])):
        c = check_bias(system, q)
        assert c.ok(1e-6) and np.abs(c.numeric).max() > 1e-3, (system, c)


def floor(jacobian):
    """A floor under the hanging double pendulum's tip: g = 1.9 − l1 cos θ1 − l2 cos θ2."""
    return mo.FunctionBarrier(lambda q: np.array([1.9 - L1 * np.cos(q[0]) - L2 * np.cos(q[1])]), jacobian)


def test_a_jacobian_right_only_at_a_symmetric_start_is_refused():
    right = floor(lambda q: np.array([[L1 * np.sin(q[0]), L2 * np.sin(q[1])]]))
    pasted = floor(lambda q: np.array([[L1 * np.sin(q[0]), L2 * np.sin(q[0])]]))  # θ1 for θ2: both 0 at θ = 0
    scene = lambda barrier: mo.Scene(double_pendulum().system, double_pendulum().effects,  # noqa: E731
                                     [mo.Contact(barrier, 0.5, name="floor")])
    assert run(scene(right)).completed
    assert mo.check_jacobian(pasted, [0.0, 0.0]).max_abs_error == 0.0  # where the run starts, it is right
    with pytest.raises(ValueError, match=r"Jacobian of contact row 'floor' \(row 0\) does not match its gap near "
                                         r"the initial state \(at q = \[.*\]\)"):
        run(scene(pasted))


def test_a_bilateral_constraints_jacobian_is_checked_too():
    # a pendulum as a point on a rod; the rod's Jacobian with its entries swapped used to run
    # until the hold failed at step 94, "a singular configuration, or a step too large"
    def rod(jacobian):
        return mo.Bilateral(mo.FunctionBarrier(lambda q: np.array([np.hypot(q[0], q[1]) - 1.0]), jacobian), name="rod")

    def scene(constraint):
        return mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([0.0, -G0])], [], constraints=[constraint])

    q0 = [-np.sin(0.5), -np.cos(0.5)]
    right = rod(lambda q: np.array([[q[0], q[1]]]) / np.hypot(q[0], q[1]))
    swapped = rod(lambda q: np.array([[q[1], q[0]]]) / np.hypot(q[0], q[1]))
    assert mo.simulate(scene(right), (0.0, 0.5), q0, [0.0, 0.0], 1e-3).completed
    with pytest.raises(ValueError, match=r"Jacobian of constraint row 'rod' \(row 0\) does not match its gap at the "
                                         r"initial state"):
        mo.simulate(scene(swapped), (0.0, 0.5), q0, [0.0, 0.0], 1e-3)
