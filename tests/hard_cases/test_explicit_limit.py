"""A step beyond the explicit forces' stability limit on a system of constant mass.

The midpoint step applies the forces explicitly: a linear spring of angular frequency ω
grows without bound beyond h ω = 2 (the Störmer–Verlet bound), a damper of rate ρ beyond
h ρ = 2. With a constant mass matrix the energy check cannot see it (a step's kinetic
energy change is exactly the work of the forces it applied), so ``simulate`` warns before
the run and says so in ``traj.warnings``."""

import warnings

import numpy as np
import pytest

import moreau as mo
from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

K, M = 400.0, 1.0  # ω = 20 per second


def oscillator(damping=0.0):
    effects = [mo.LinearSpring([[K]])] + ([mo.LinearDamping([[damping]])] if damping else [])
    return mo.Scene(mo.FunctionSystem([[M]]), effects)


def energy(traj):
    return 0.5 * M * traj.v[:, 0] ** 2 + 0.5 * K * traj.q[:, 0] ** 2


def quiet(scene, h, **kw):
    """The run, asserting it warns of nothing."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        traj = mo.simulate(scene, (0.0, 2.0), [0.1], [0.0], h, **kw)
    assert traj.warnings == []
    return traj


def test_a_spring_beyond_h_omega_2_warns_and_grows_within_it_stays_bounded():
    omega = np.sqrt(K / M)
    inside = quiet(oscillator(), 1.9 / omega)
    assert energy(inside).max() < 20 * energy(inside)[0]  # bounded (leapfrog: a modified energy)
    with pytest.warns(RuntimeWarning, match=r"h = 0.105 is beyond the stability limit of the midpoint step.*"
                                            r"angular frequency ω = 20 per time unit gives h·ω = 2.1 > 2.*"
                                            r"take h < 0.1 ") as rec:
        beyond = mo.simulate(oscillator(), (0.0, 2.0), [0.1], [0.0], 2.1 / omega)
    assert len(rec) == 1 and beyond.warnings == [str(rec[0].message)]
    assert energy(beyond)[-1] > 1e6 * energy(beyond)[0]  # what the warning says: it grows without bound
    assert beyond.completed  # and the energy check cannot see it


def test_a_damper_beyond_h_rho_2_warns():
    rho = 50.0 / M
    quiet(mo.Scene(mo.FunctionSystem([[M]]), [mo.LinearDamping([[50.0]])]), 1.5 / rho)
    with pytest.warns(RuntimeWarning, match=r"velocity-dependent rate ρ = 50 per time unit gives h·ρ = 2.5 > 2"):
        traj = mo.simulate(mo.Scene(mo.FunctionSystem([[M]]), [mo.LinearDamping([[50.0]])]), (0.0, 1.0), [0.0],
                           [1.0], 2.5 / rho)
    assert traj.v[-1, 0] == pytest.approx((1.0 - 2.5) ** 20, rel=1e-9)  # v ← (1 − h ρ) v, 20 steps


def test_the_woodpecker_spring_at_a_coarse_step():
    scene, (q0, v0) = woodpecker(), GLOCKER_STATE
    with pytest.warns(RuntimeWarning) as rec:  # its bird's spring: ω = 458 per second
        traj = mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-2)
    assert "h·ω = 4.58 > 2" in traj.warnings[0] and any("h·ω = 4.58" in str(w.message) for w in rec)
    assert not any("stability limit" in w for w in mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-3).warnings)


def test_no_warning_where_the_check_does_not_apply():
    h = 2.1 / np.sqrt(K / M)
    quiet(oscillator(), h, energy_growth=None)  # the stability checks are off
    # the energy-consistent step is implicit in the forces
    quiet(oscillator(), h, integrator=mo.MoreauJeanEnergyConsistent)
