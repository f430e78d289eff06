"""The friction solve at many contacts: Lemke's method against projected Gauss–Seidel
with an exact polish (moreau.contact.pgs), side by side on the same one-step problems.

The problems: rods (1 m, 1 kg) stacked in staggered layers on a floor, every rod touching
the floor or two rods below at its two ends, mu = 0.3, each rod moving at random (0.3 m/s
per coordinate, 1 m/s down) for one step of h = 1e-3 under gravity; the two ends of a rod
on the floor have identical tangent rows (redundant, as in a real pile). Prints, per size,
the contacts, the time of each method (best of ``--repeat``) and the worst law residual
of its answer (dimensionless, moreau.contact.friction.friction_residuals), and which one
``method="auto"`` takes.

    python benchmarks/many_contacts.py                 # 50 ... 1000 contacts, about a minute
    python benchmarks/many_contacts.py --sizes 100 400
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from moreau.contact.friction import PGS_MIN_CONTACTS, friction_one_step, friction_residuals


def stacked_rods(n_contacts: int, rng: np.random.Generator, mu: float = 0.3, h: float = 1e-3) -> tuple:
    """``(M, b, GA, cA, TA, muA)`` of n_contacts contacts of stacked rods (module docstring)."""
    a, m = 0.5, 1.0
    J = m * (2 * a) ** 2 / 12
    width = max(2, int(np.ceil(np.sqrt(n_contacts))))  # a pyramid of base w has w (w + 1) contacts
    rods: list[tuple[float, int]] = []  # (x, layer)
    contacts: list[tuple[int, int, float, float]] = []  # (rod, rod below or -1, its arm, the arm below)
    layer = 0
    while len(contacts) < n_contacts:
        below = [r for r in range(len(rods)) if rods[r][1] == layer - 1]
        if layer == 0:
            for i in range(width):
                rods.append((1.2 * i, 0))
                contacts += [(len(rods) - 1, -1, -a, 0.0), (len(rods) - 1, -1, a, 0.0)]
        elif len(below) < 2:
            break
        for i in range(len(below) - 1 if layer else 0):
            x = 0.5 * (rods[below[i]][0] + rods[below[i + 1]][0])
            rods.append((x, layer))
            contacts += [(len(rods) - 1, below[i], -a, x - a - rods[below[i]][0]),
                         (len(rods) - 1, below[i + 1], a, x + a - rods[below[i + 1]][0])]
        layer += 1
    contacts = contacts[:n_contacts]
    n, k = 3 * len(rods), len(contacts)
    M = np.diag(np.tile([m, m, J], len(rods)))
    GA, TA = np.zeros((k, n)), np.zeros((k, n))
    for j, (u, lo, ru, rl) in enumerate(contacts):
        GA[j, 3 * u + 1], GA[j, 3 * u + 2], TA[j, 3 * u] = 1.0, ru, 1.0
        if lo >= 0:
            GA[j, 3 * lo + 1], GA[j, 3 * lo + 2], TA[j, 3 * lo] = -1.0, -rl, -1.0
    v = 0.3 * rng.standard_normal(n)
    v[1::3] -= 1.0
    f = np.zeros(n)
    f[1::3] = -9.81 * m
    return M, M @ v + h * f, GA, np.zeros(k), TA, np.full(k, mu)


def _timed(problem: tuple, method: str, repeat: int) -> tuple[float, float, int]:
    """(best seconds, worst residual, status) of one method on one problem."""
    M, b, GA, cA, TA, muA = problem
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        st, v, PN, PT = friction_one_step(M, b, GA, cA, TA, muA, method=method)
        best = min(best, time.perf_counter() - t)
    return best, float(friction_residuals(M, b, GA, cA, TA, muA, v, PN, PT).max()), st


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 400, 700, 1000])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    _timed(stacked_rods(20, rng), "lemke", 1), _timed(stacked_rods(20, rng), "pgs", 1)  # compile
    print("\nfriction solve of stacked rods, one step (best of", args.repeat, "runs; residual: the law's, scaled)")
    print(f"{'contacts':>8} {'coords':>7} {'Lemke (s)':>10} {'residual':>9} {'PGS+polish (s)':>15} {'residual':>9}"
          f" {'ratio':>6}  auto")
    for size in args.sizes:
        problem = stacked_rods(size, rng)
        k, n = problem[2].shape[0], problem[0].shape[0]
        tl, rl, sl = _timed(problem, "lemke", args.repeat)
        tp, rp, sp = _timed(problem, "pgs", args.repeat)
        auto = "PGS+polish" if k >= PGS_MIN_CONTACTS else "Lemke"
        print(f"{k:8d} {n:7d} {tl:10.4f} {rl:9.1e} {tp:15.4f} {rp:9.1e} {tp / tl:6.2f}  {auto}"
              + ("" if sl == 0 and sp == 0 else f"  (status Lemke {sl}, PGS {sp})"))


if __name__ == "__main__":
    main()
