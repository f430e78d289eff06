"""Many contacts with friction (issue 43): projected Gauss–Seidel with an exact polish
(moreau.contact.pgs) on piles of rods, checked against Coulomb's law in numpy."""

import numpy as np
import oracle
import pytest

from moreau.contact.friction import PGS_MIN_CONTACTS, friction_one_step
from moreau.contact.testing import rod_pile


def coulomb_violation(M, b, GA, TA, muA, v, PN, PT):
    """The worst violation of the law by (v, PN, PT), in numpy, relative to the velocity
    and impulse scales: momentum, 0 <= P_N ⟂ U_N >= 0, |P_T| <= mu P_N, and a slipping
    contact's impulse at the cone's edge against its slip."""
    UN, UT = GA @ v, TA @ v
    vel, imp = np.abs(GA @ np.linalg.solve(M, b)).max(), max(PN.max(), 1e-300)
    out = [np.abs(M @ v - b - GA.T @ PN - TA.T @ PT).max() / (imp * np.abs(GA).max()),
           -PN.min() / imp, -UN.min() / vel, np.abs(PN * UN).max() / (imp * vel),
           (np.abs(PT) - muA * PN).max() / imp]
    slipping = np.abs(UT) > 1e-9 * vel
    out.append(np.abs(PT[slipping] + muA[slipping] * PN[slipping] * np.sign(UT[slipping])).max(initial=0.0) / imp)
    return max(out)


@pytest.mark.parametrize("method", ["pgs", "auto"])
def test_a_pile_of_300_contacts_is_solved_exactly(rng, method):
    """A pyramid of 17 rods at its base (306 contacts, 459 coordinates): the relaxation
    and its polish meet the law to 1e-9 in numpy's own terms, and so does "auto" (which
    takes it from PGS_MIN_CONTACTS contacts on)."""
    M, b, GA, cA, TA, muA = rod_pile(17, rng)
    assert GA.shape[0] == 306 >= PGS_MIN_CONTACTS
    st, v, PN, PT = friction_one_step(M, b, GA, cA, TA, muA, method=method)
    assert st == 0
    assert coulomb_violation(M, b, GA, TA, muA, v, PN, PT) < 1e-9
    sliding = np.abs(TA @ v) > 1e-6
    assert (PN > 0).sum() > 100 and sliding.any() and (~sliding & (PN > 0)).any()  # both stick and slip


def test_the_relaxation_agrees_with_lemke_where_the_answer_is_unique(rng):
    """Two rods on the floor and one on them (six contacts, the floor's tangent rows
    redundant in pairs), 20 draws of the state and mu: the velocities are the same by
    either method to 1e-10 (the split of a redundant impulse is not determined, the
    motion is)."""
    for _ in range(20):
        M, b, GA, cA, TA, muA = rod_pile(2, rng, mu=float(rng.uniform(0.05, 1.0)))
        results = [friction_one_step(M, b, GA, cA, TA, muA, method=m) for m in ("lemke", "pgs")]
        assert [r[0] for r in results] == [0, 0]
        np.testing.assert_allclose(results[1][1], results[0][1], atol=1e-10 * np.abs(np.linalg.solve(M, b)).max())


def test_an_unknown_method_is_refused(rng):
    M, b, GA, cA, TA, muA = rod_pile(2, rng)
    with pytest.raises(ValueError, match="method must be one of .* got 'gauss'"):
        friction_one_step(M, b, GA, cA, TA, muA, method="gauss")


def rough_floor_chain(n: int = 80):
    """A 1 m chain of n links pinned at one end, released nearly horizontal 5 cm above a
    floor with mu = 0.3 (e = 0), its links moving down faster towards the free end."""
    import moreau as mo
    from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow

    chain = PendulumChain([Link.rod(m=1.0 / n, l=1.0 / n) for _ in range(n)])
    rows = [PointLineRow(i, (1.0 / n, 0.0), line_point=(0.0, -0.05), normal=(0.0, 1.0)) for i in range(n)]
    scene = mo.Scene(chain, [ChainGravity(chain)],
                     [mo.Contact(PointLineBarrier(chain, rows), mo.NewtonImpactFriction(0.0, 0.3), name="floor")])
    return scene, np.pi / 2 + 0.02 * np.sin(np.arange(n)), np.linspace(0.0, -1.0, n)


@pytest.mark.parametrize(("backend", "T"), [("compiled", 0.5), ("python", 0.12)])
def test_an_80_link_chain_landing_on_a_rough_floor_completes(backend, T):
    """Lemke's method met a ray on this chain's landing (38 closed contacts at t = 0.089 s:
    a SolverError); the relaxation solves that step exactly, and the run completes with
    every solve passing the law check, up to 73 contacts closed at once (compiled)."""

    scene, q0, v0 = rough_floor_chain()
    traj = oracle.simulate(scene, (0.0, T), q0, v0, 1e-3, backend=backend, solver="exact", progress=False)
    assert traj.completed and traj.stats.backend == backend
    assert traj.stats.fallbacks == 0 and traj.stats.worst_residual < 1e-8
    assert traj.active.sum(axis=1).max() >= (60 if T > 0.3 else 38)
