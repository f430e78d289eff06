"""A step beyond the explicit forces' stability limit on a system of constant mass.

The midpoint step applies the forces explicitly: a linear spring of angular frequency ω
grows without bound beyond h ω = 2 (the Störmer–Verlet bound), a damper of rate ρ beyond
h ρ = 2. With a constant mass matrix the energy ledger cannot see it (a step's kinetic
energy change is exactly the work of the forces it applied): ``simulate`` warns before the
run, and the energy check's runaway test stops it."""

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


RUNAWAY = r"the kinetic energy rose above its largest so far by a factor of .* a step .* at two energy checks in a row"


def test_a_spring_beyond_h_omega_2_warns_and_the_runaway_stops_within_it_stays_bounded():
    omega = np.sqrt(K / M)
    inside = quiet(oscillator(), 1.9 / omega)
    assert energy(inside).max() < 20 * energy(inside)[0]  # bounded (leapfrog: a modified energy)
    with pytest.warns(RuntimeWarning, match=r"h = 0.105 is beyond the stability limit of the midpoint step.*"
                                            r"angular frequency ω = 20 per time unit gives h·ω = 2.1 > 2.*"
                                            r"take h < 0.1 ") as rec, pytest.raises(mo.SimulationError,
                                                                                   match=RUNAWAY) as info:
        mo.simulate(oscillator(), (0.0, 4.0), [0.1], [0.0], 2.1 / omega, record_every=1)
    assert len(rec) == 1
    # the energy check's runaway test stops it (the ledger cannot: the kinetic energy change is
    # exactly the work of the spring's explicit force); what is kept grows as the linear
    # analysis says, |λ| = 1.85 a step in amplitude (λ + 1/λ = 2 − (h ω)²)
    kept = info.value.trajectory
    lam = abs(np.roots([1.0, -(2.0 - 2.1**2), 1.0])).max()
    assert 0.0 < kept.t[-1] < 4.0 and energy(kept)[-1] > 0.1 * lam ** (2 * (len(kept) - 1)) * energy(kept)[0]


def test_a_damper_beyond_h_rho_2_warns_and_stops():
    rho = 50.0 / M
    quiet(mo.Scene(mo.FunctionSystem([[M]]), [mo.LinearDamping([[50.0]])]), 1.5 / rho)
    with pytest.warns(RuntimeWarning, match=r"velocity-dependent rate ρ = 50 per time unit gives h·ρ = 2.5 > 2"), \
            pytest.raises(mo.SimulationError, match=RUNAWAY) as info:
        mo.simulate(mo.Scene(mo.FunctionSystem([[M]]), [mo.LinearDamping([[50.0]])]), (0.0, 1.0), [0.0], [1.0],
                    2.5 / rho, record_every=1)
    # v ← (1 − h ρ) v: the kinetic energy grows by |1 − h ρ|² = 2.25 a step, which the stop quotes;
    # the first check (step 8) already found it, so the run is kept up to its start
    assert "factor of 2.25 a step" in str(info.value)
    kept = info.value.trajectory
    assert kept.t.tolist() == [0.0] and kept.v[0, 0] == 1.0


def test_the_woodpecker_spring_at_a_coarse_step():
    scene, (q0, v0) = woodpecker(), GLOCKER_STATE
    # its bird's spring: ω = 458 per second; 45 steps reached 1e52 and said "completed"
    with pytest.warns(RuntimeWarning, match=r"h·ω = 4.58 > 2"), pytest.raises(mo.SimulationError, match=RUNAWAY):
        mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-2)
    assert not any("stability limit" in w for w in mo.simulate(scene, (0.0, 0.45), q0, v0, 1e-3).warnings)


def test_no_warning_where_the_check_does_not_apply():
    h = 2.1 / np.sqrt(K / M)
    quiet(oscillator(), h, energy_growth=None)  # the stability checks are off
    # the energy-consistent step is implicit in the forces
    quiet(oscillator(), h, integrator=mo.MoreauJeanEnergyConsistent)


def test_the_limit_is_named_exactly_where_h_omega_or_h_rho_reaches_2():
    # linear springs and dampers of random 3-dof systems: the message appears exactly where the
    # eigenvalues (computed here) put max(h ω, h ρ) >= 2, whether or not the norm bound the
    # check tries first decides it
    from moreau.model.stability import explicit_limit_message

    rng = np.random.default_rng(7)
    for _ in range(20):
        R = rng.standard_normal((3, 3))
        Mm = R @ R.T + 3 * np.eye(3)
        S = rng.standard_normal((3, 3))
        Kk = S @ S.T + 0.1 * np.eye(3)
        Cc = np.diag(rng.uniform(0.0, 5.0, 3))
        scene = mo.Scene(mo.FunctionSystem(Mm), [mo.LinearSpring(Kk), mo.LinearDamping(Cc)])
        omega = np.sqrt(np.linalg.eigvals(np.linalg.solve(Mm, Kk)).real.max())
        rho = np.abs(np.linalg.eigvals(np.linalg.solve(Mm, -Cc))).max()
        limit = 2.0 / max(omega, rho)
        for f in (0.5, 0.98, 1.02, 3.0):
            said = explicit_limit_message(scene, 0.0, np.full(3, 0.1), np.zeros(3), f * limit)
            assert (said is not None) == (f > 1.0), (f, omega, rho)
