"""The piston's step against another build of moreau, measured interleaved.

Checks out ``REV`` into a temporary git worktree (its own numba cache: the first run there
compiles the loop, about 100 s), then alternates new processes of the two builds,
``--rounds`` times each, and prints µs per step of the piston over one engine cycle at
h = 1e-4 (best of 3 runs in each process): e = 0.9 without and with the engine's drift
control, e = 0 with it. Alternating spreads this shared machine's slow and fast phases
over both builds; compare the ranges, not one pair.

    python benchmarks/interleaved.py 5cad02a --rounds 3
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator

_PROBE = """
import numpy as np
import moreau as mo
from moreau.problems.piston import piston_model
mo.ensure_compiled()
out = []
for e, drift in ((0.9, False), (0.9, True), (0.0, True)):
    m = piston_model(e=e)
    best = min(m.simulate(4 * np.pi, 1e-4, drift_control=m.drift_control() if drift else None, energy=False,
                          record_every=100).stats.us_per_step for _ in range(3))
    out.append(best)
print(" ".join(f"{x:.3f}" for x in out))
"""
CASES = ("e = 0.9", "e = 0.9 + engine drift", "e = 0 + engine drift")


def probe(tree: str) -> list[float]:
    """µs per step of the cases in a new process importing moreau from ``tree``."""
    env = dict(os.environ, PYTHONPATH=tree)
    out = subprocess.run([sys.executable, "-c", _PROBE], cwd=tree, env=env, capture_output=True, text=True,
                         check=True)
    return [float(x) for x in out.stdout.split()[-len(CASES):]]


@contextlib.contextmanager
def worktree(rev: str) -> Iterator[tuple[str, str]]:
    """``(this checkout, a temporary git worktree of rev)``, the worktree removed after."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory() as tmp:
        other = os.path.join(tmp, "other")
        subprocess.run(["git", "-C", here, "worktree", "add", "--detach", "-q", other, rev], check=True)
        try:
            yield here, other
        finally:
            subprocess.run(["git", "-C", here, "worktree", "remove", "--force", other], check=False)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev", help="the other build: a git revision of this repository")
    ap.add_argument("--rounds", type=int, default=3, help="alternations (default 3)")
    args = ap.parse_args(argv)
    with worktree(args.rev) as (here, other):
        probe(other)  # its compile, outside the measurement
        probe(here)
        runs: dict[str, list[list[float]]] = {args.rev: [], "this tree": []}
        for _ in range(args.rounds):
            runs[args.rev].append(probe(other))
            runs["this tree"].append(probe(here))
    print(f"\nµs per step, piston over one cycle at h = 1e-4 (best of 3 per process, {args.rounds} processes "
          "per build, alternating)")
    print(f"{'case':28s} " + " ".join(f"{name:>22s}" for name in runs))
    for i, case in enumerate(CASES):
        cells = []
        for values in runs.values():
            col = [r[i] for r in values]
            cells.append(f"{min(col):.3f} - {max(col):.3f}")
        print(f"{case:28s} " + " ".join(f"{c:>22s}" for c in cells))


if __name__ == "__main__":
    main()
