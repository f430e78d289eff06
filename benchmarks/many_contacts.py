"""The contact solve at many rows: the frictionless one-step problem by each solver, and the
friction solve by Lemke's method against projected Gauss–Seidel with an exact polish
(moreau.contact.pgs), side by side on the same one-step problems.

Frictionless: chains of N rods lying on a floor (one row per link, moreau's step_cost
scene), shaken (angles 0.05 rad and velocities 0.3 rad/s at random, gravity over h = 1e-3),
so that some rows are pushed and some leave; every solver named in ``simulate(solver=)``
answers the same problem, timed from Python (best of ``--repeat``), with the worst scaled
KKT residual of its answer (moreau.contact.problem.kkt_residuals).

The problems: piles of rods on a floor (moreau.contact.testing.rod_pile: a pile of base
``w`` has w (w + 1) contacts, mu = 0.3, each rod moving at random for one step of h = 1e-3
under gravity; the two ends of a rod on the floor have identical tangent rows, redundant,
as in a real pile). Prints, per pile, the contacts, the time of each method (best of
``--repeat``) and the worst law residual of its answer (dimensionless,
moreau.contact.friction.friction_residuals), and which one ``method="auto"`` takes.

A long chain lying on a rough floor (``--long-chain N``: N links, one contact each, mu =
0.3, shaken at 0.3 rad/s, h = 1e-3) is run over one second of motion: seconds, steps, the
most contacts closed at once and the worst law residual of its steps' friction solves
(``traj.stats.worst_residual``).

    python benchmarks/many_contacts.py                 # about 5 minutes
    python benchmarks/many_contacts.py --widths 10 20 --links 8 40
    python benchmarks/many_contacts.py --long-chain 500 --widths --links   # about 2.5 minutes
    python benchmarks/many_contacts.py --chain-contacts 200 1000 --widths --links
                                       # the friction solve of chains (N contacts) on a rough floor
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from step_cost import chain_scene  # noqa: E402  (the chains of the step-cost table)

from moreau.contact.friction import PGS_MIN_CONTACTS, friction_one_step, friction_residuals  # noqa: E402
from moreau.contact.testing import rod_pile  # noqa: E402


def _timed(problem: tuple, method: str, repeat: int) -> tuple[float, float, int]:
    """(best seconds, worst residual, status) of one method on one problem."""
    M, b, GA, cA, TA, muA = problem
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        st, v, PN, PT = friction_one_step(M, b, GA, cA, TA, muA, method=method)
        best = min(best, time.perf_counter() - t)
    return best, float(friction_residuals(M, b, GA, cA, TA, muA, v, PN, PT).max()), st


def chain_problem(N: int, rng: np.random.Generator, mu: float = 0.0) -> tuple:
    """One step of an N-link chain lying on a floor, shaken: ``(M, b, G, c)``, and with
    ``mu`` > 0 ``(M, b, G, c, T, mu)`` (its tangent rows) as ``friction_one_step`` takes."""
    scene = chain_scene(N, True)[0]
    chain, floor = scene.system, scene.contacts[0].barrier
    q = np.pi / 2 + 0.05 * rng.normal(size=N)
    v = 0.3 * rng.normal(size=N)
    M = chain.mass_matrix(q)
    b = M @ v + 1e-3 * scene.force(0.0, q, v)  # (gravity and the bias terms)
    G, c = floor.jacobian(q), np.zeros(N)
    return (M, b, G, c) if mu == 0.0 else (M, b, G, c, floor.tangent_jacobian(q), np.full(N, mu))


def _each_solver(problem: tuple, names: list[str], repeat: int) -> list[tuple[float, float, int]]:
    """(best seconds, KKT residual, active rows) of each named solver on ``(M, b, G, c)``."""
    from moreau.contact.problem import kkt_residuals
    from moreau.contact.solvers import make_solver

    M, b, G, c = problem
    k = G.shape[0]
    out = []
    for name in names:
        solver, best = make_solver(name), np.inf
        if name == "osqp":
            solver.setup(M.shape[0], k)
        for _ in range(repeat):
            t = time.perf_counter()
            v, P = solver.solve(M, b, G, c, np.arange(k))
            best = min(best, time.perf_counter() - t)
        out.append((best, kkt_residuals(M, b, G, c, v, P).worst, int((P > 0).sum())))
    return out


def frictionless_table(links: list[int], repeat: int, rng: np.random.Generator) -> None:
    """Seconds and KKT residual of each solver on a chain's one-step problem."""
    import qpsolvers

    from moreau.contact.active_set import BLOCK_MIN

    names = ["exact", "osqp"] + [s for s in ("daqp", "quadprog") if s in qpsolvers.available_solvers]
    _each_solver(chain_problem(8, rng), names, 1)  # compile and load
    print("\nfrictionless one-step problem of an N-link chain lying on a floor, shaken (best of", repeat,
          "runs, seconds from Python; residual: the KKT check's, scaled)")
    print(f"{'rows':>5} {'active':>6}" + "".join(f" {n + ' (s)':>14} {'residual':>9}" for n in names) + "  auto")
    for N in links:
        cells = _each_solver(chain_problem(N, rng), names, repeat)
        auto = "block pivoting" if N >= BLOCK_MIN else "dual active set"
        print(f"{N:5d} {cells[0][2]:6d}" + "".join(f" {t:14.5f} {r:9.1e}" for t, r, _ in cells) + f"  {auto}")


def pile_table(widths: list[int], repeat: int, rng: np.random.Generator, chains: bool = False) -> None:
    """Lemke against PGS + polish on piles of rods of the given bases (``chains``: on
    chains of that many links lying on a rough floor, mu = 0.3)."""
    _timed(rod_pile(4, rng), "lemke", 1), _timed(rod_pile(4, rng), "pgs", 1)  # compile
    what = "chains of N links on a rough floor" if chains else "piles of rods"
    print(f"\nfriction solve of {what}, one step (best of", repeat, "runs; residual: the law's, scaled)")
    print(f"{'contacts':>8} {'coords':>7} {'Lemke (s)':>10} {'residual':>9} {'PGS+polish (s)':>15} {'residual':>9}"
          f" {'ratio':>6}  auto")
    for width in widths:
        problem = chain_problem(width, rng, mu=0.3) if chains else rod_pile(width, rng)
        k, n = problem[2].shape[0], problem[0].shape[0]
        tl, rl, sl = _timed(problem, "lemke", repeat)
        tp, rp, sp = _timed(problem, "pgs", repeat)
        auto = "PGS+polish" if k >= PGS_MIN_CONTACTS else "Lemke"
        print(f"{k:8d} {n:7d} {tl:10.4f} {rl:9.1e} {tp:15.4f} {rp:9.1e} {tp / tl:6.2f}  {auto}"
              + ("" if sl == 0 and sp == 0 else f"  (status Lemke {sl}, PGS {sp})"))


def long_chain(N: int) -> None:
    """One second of an N-link chain lying on a rough floor (mu = 0.3), shaken."""
    import moreau as mo

    scene, q0, _ = chain_scene(N, True, mu=0.3)
    v0 = 0.3 * np.random.default_rng(0).normal(size=N)
    t = time.perf_counter()
    traj = mo.simulate(scene, (0.0, 1.0), q0, v0, 1e-3, progress=False)
    secs = time.perf_counter() - t
    print(f"\n{N}-link chain on a rough floor (mu = 0.3), 1 s at h = 1e-3: {traj.status} in {secs:.0f} s, "
          f"{traj.stats.steps} steps, up to {int(traj.active.sum(axis=1).max())} contacts closed at once, "
          f"worst friction-law residual {traj.stats.worst_residual:.1e}, {traj.stats.fallbacks} fallbacks")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--widths", type=int, nargs="*", default=[7, 10, 14, 20, 26, 31],
                    help="bases of the piles (56, 110, 210, 420, 702, 992 contacts)")
    ap.add_argument("--links", type=int, nargs="*", default=[8, 20, 40, 80, 160, 320],
                    help="chains lying on a floor: rows of the frictionless problems")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--chain-contacts", type=int, nargs="*", default=[], metavar="N",
                    help="also the friction solve of N-link chains on a rough floor (N contacts)")
    ap.add_argument("--long-chain", type=int, default=0, metavar="N",
                    help="also run an N-link chain on a rough floor over a second")
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    if args.links:
        frictionless_table(args.links, args.repeat, rng)
    if args.widths:
        pile_table(args.widths, args.repeat, rng)
    if args.chain_contacts:
        pile_table(args.chain_contacts, args.repeat, rng, chains=True)
    if args.long_chain:
        long_chain(args.long_chain)


if __name__ == "__main__":
    main()
