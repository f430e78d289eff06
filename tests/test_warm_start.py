"""A persistent contact solved from the last step's factor (moreau.compiled.warm_start): the
answer it accepts is the fresh solve's, and it refuses when the kept rows are no longer
the problem's active set."""

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.compiled.warm_start import warm_solve
from moreau.contact.one_step import solve_one_step, workspace
from moreau.core import kernels as K
from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow

N = 12


def lying_chain(N=N):
    """N rods of 1/N m hanging from the origin, a floor row under each tip at y = 0."""
    chain = PendulumChain([Link.rod(m=1.0 / N, l=1.0 / N) for _ in range(N)])
    rows = [PointLineRow(i, (1.0 / N, 0.0), line_point=(0.0, 0.0), normal=(0.0, 1.0)) for i in range(N)]
    barrier = PointLineBarrier(chain, rows)
    scene = mo.Scene(chain, [ChainGravity(chain)], [mo.Contact(barrier, 0.0, name="floor")], name="lying chain")
    return scene, chain, barrier


def problem(chain, barrier, q, load):
    """The one-step problem at q from rest, with ``load`` (k,) pushing each row's point
    down (> 0) or up (< 0) over h = 1e-3: M, L, b, G, c and the chain's kernels' data."""
    M = chain.mass_matrix(q)
    G = np.ascontiguousarray(barrier.jacobian(q))
    L = np.zeros_like(M)
    K.cholesky(M, L, len(q))
    c, s = K.cos_sin(q)
    gen = np.empty((4, len(q)))
    K.chain_factor(chain._pm, 0, c, s, gen, np.empty_like(M))
    return M, L, 1e-3 * (G.T @ -load), G, np.zeros(G.shape[0]), (chain._pm, 0, c, s, gen)


def fresh(M, L, b, G, c):
    """The dual active-set method's answer, with the work arrays it leaves (its factor)."""
    n, k = G.shape[1], G.shape[0]
    ws, P, v = workspace(n, k), np.zeros(k), np.zeros(n)
    assert solve_one_step(M, L, b, G, c, P, v, k, 0, 1e-12, ws, True, False) == 0  # the loop's own signature
    return ws, P, v


def warm(ws, prob):
    M, L, b, G, c, cd = prob
    K.chain_solve(*cd, b, ws.vfree)
    P, v = np.zeros(G.shape[0]), np.zeros(G.shape[1])
    return warm_solve(*cd, G, c, G.shape[0], ws, v, P), P, v


def test_the_kept_factor_gives_the_fresh_answer_on_a_nearby_configuration():
    scene, chain, barrier = lying_chain()
    q0 = np.full(N, np.pi / 2)
    load = np.linspace(0.5, 1.5, N)
    ws, _, _ = fresh(*problem(chain, barrier, q0, load)[:5])
    for dq in (0.0, 1e-6, 1e-3):  # the same, a step at rest, a visible change of shape
        prob = problem(chain, barrier, q0 + dq * np.sin(np.arange(N)), load * (1 + dq))
        _, P_ref, v_ref = fresh(*prob[:5])
        ok, P, v = warm(ws, prob)
        assert ok, dq
        np.testing.assert_allclose(P, P_ref, rtol=1e-10, atol=1e-12 * np.abs(P_ref).max())
        np.testing.assert_allclose(v, v_ref, rtol=0, atol=1e-10 * np.abs(np.linalg.solve(prob[0], prob[2])).max())


def test_it_refuses_when_the_active_set_changed():
    scene, chain, barrier = lying_chain()
    q0 = np.full(N, np.pi / 2)
    ws, _, _ = fresh(*problem(chain, barrier, q0, np.ones(N))[:5])
    lift = np.ones(N)
    lift[4] = -30.0  # row 4 pulled up: it must open, its kept impulse would turn negative
    assert not warm(ws, problem(chain, barrier, q0, lift))[0]
    ws, P, _ = fresh(*problem(chain, barrier, q0, lift)[:5])
    assert P[4] == 0.0 and not ws.inA[4]  # kept without row 4 ...
    assert not warm(ws, problem(chain, barrier, q0, np.ones(N)))[0]  # ... which now penetrates


def test_a_chain_lying_and_kicked_runs_as_the_reference_step():
    """Rows open and close again under kicks (the kept rows change), the
    chain lies still elsewhere (the kept factor serves): the loop equals the numpy
    reference step, contact decisions included."""
    scene, _, _ = lying_chain()
    q0 = np.full(N, np.pi / 2)
    v0 = np.zeros(N)
    v0[[3, 7, 11]] = 1.0, -1.5, 3.0
    runs = [oracle.simulate(scene, (0.0, 0.3), q0, v0, 1e-3, backend=b, solver="exact") for b in ("compiled", "python")]
    c, p = runs
    assert c.stats.backend == "compiled" and c.completed and p.completed
    closed = {tuple(a) for a in c.active[1:]}  # (the first record is the initial state)
    assert len(c.impacts) >= 1 and c.active[1:].any(axis=1).all() and len(closed) >= 3
    np.testing.assert_array_equal(c.active, p.active)
    scale = np.abs(p.q).max() + np.abs(p.v).max()
    assert np.abs(c.q - p.q).max() <= 1e-9 * scale and np.abs(c.v - p.v).max() <= 1e-9 * scale


def test_a_warm_start_address_for_other_types_is_never_called(monkeypatch):
    """The loop calls a chain's warm start and its Delassus matrix through their addresses
    (``step.warm_start_addresses``) only when the key of each address's argument types is
    its own call's; else the lying chain's run fails at its first contact step, naming the
    bug, and with the right keys it runs."""
    from moreau.compiled import runner

    scene, _, _ = lying_chain()
    q0, v0 = np.full(N, np.pi / 2), np.zeros(N)
    right = runner.warm_start_addresses
    monkeypatch.setattr(runner, "warm_start_addresses", lambda model, work: (0, 12345, 0, 12345))  # 0: a crash
    with pytest.raises(mo.SimulationError, match="internal error") as caught:
        mo.simulate(scene, (0.0, 0.05), q0, v0, 1e-3, solver="exact")
    assert caught.value.trajectory.status == "failed"
    monkeypatch.setattr(runner, "warm_start_addresses", right)
    assert mo.simulate(scene, (0.0, 0.05), q0, v0, 1e-3, solver="exact").completed
