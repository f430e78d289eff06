"""The friction solve at many contacts: Lemke's method against projected Gauss–Seidel
with an exact polish (moreau.contact.pgs), side by side on the same one-step problems.

The problems: piles of rods on a floor (moreau.contact.testing.rod_pile: a pile of base
``w`` has w (w + 1) contacts, mu = 0.3, each rod moving at random for one step of h = 1e-3
under gravity; the two ends of a rod on the floor have identical tangent rows, redundant,
as in a real pile). Prints, per pile, the contacts, the time of each method (best of
``--repeat``) and the worst law residual of its answer (dimensionless,
moreau.contact.friction.friction_residuals), and which one ``method="auto"`` takes.

    python benchmarks/many_contacts.py                 # 56 ... 992 contacts, about 4 minutes
    python benchmarks/many_contacts.py --widths 10 20
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from moreau.contact.friction import PGS_MIN_CONTACTS, friction_one_step, friction_residuals
from moreau.contact.testing import rod_pile


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
    ap.add_argument("--widths", type=int, nargs="+", default=[7, 10, 14, 20, 26, 31],
                    help="bases of the piles (56, 110, 210, 420, 702, 992 contacts)")
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    _timed(rod_pile(4, rng), "lemke", 1), _timed(rod_pile(4, rng), "pgs", 1)  # compile
    print("\nfriction solve of piles of rods, one step (best of", args.repeat, "runs; residual: the law's, scaled)")
    print(f"{'contacts':>8} {'coords':>7} {'Lemke (s)':>10} {'residual':>9} {'PGS+polish (s)':>15} {'residual':>9}"
          f" {'ratio':>6}  auto")
    for width in args.widths:
        problem = rod_pile(width, rng)
        k, n = problem[2].shape[0], problem[0].shape[0]
        tl, rl, sl = _timed(problem, "lemke", args.repeat)
        tp, rp, sp = _timed(problem, "pgs", args.repeat)
        auto = "PGS+polish" if k >= PGS_MIN_CONTACTS else "Lemke"
        print(f"{k:8d} {n:7d} {tl:10.4f} {rl:9.1e} {tp:15.4f} {rp:9.1e} {tp / tl:6.2f}  {auto}"
              + ("" if sl == 0 and sp == 0 else f"  (status Lemke {sl}, PGS {sp})"))


if __name__ == "__main__":
    main()
