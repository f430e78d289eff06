"""The first `moreau piston` after a fresh install against the second (issue 23).

Makes a new virtual environment in a temporary folder, installs this checkout into it as a
user would (`pip install <checkout>`: the wheel's build step compiles the time loop into the
package; with `--editable`, `pip install -e`: the build step compiles it into the cache),
with `NUMBA_CACHE_DIR` on a new empty folder, then runs `moreau piston` twice, each under
`/usr/bin/time -v`, and prints wall time and peak resident memory (the largest
single process: the parent or a worker) of the install and of both runs, and their ratio.

    python benchmarks/first_run.py            # about 3-4 minutes on 2 cores
    python benchmarks/first_run.py --editable # the same with `pip install -e` (the README's
                                              # command; MOREAU_PREBUILD=0: the first run compiles)

Needs the package index (or pip's cache) for the dependencies, and GNU time.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
TIME = "/usr/bin/time"


def _timed(cmd: list[str], env: dict[str, str], cwd: str) -> tuple[float, float, str]:
    """(wall s, peak RSS MB, stderr) of ``cmd`` under GNU time -v; raises when it fails."""
    t = time.perf_counter()
    r = subprocess.run([TIME, "-v", *cmd], env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"first_run: {' '.join(cmd[:3])} ... failed ({r.returncode}):\n{r.stderr[-2000:]}")
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr)
    return wall, (int(rss.group(1)) / 1024 if rss else float("nan")), r.stderr


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--editable", action="store_true", help="install with pip install -e (no prebuilt code)")
    args = ap.parse_args()
    if not os.path.exists(TIME):
        raise SystemExit(f"first_run: {TIME} (GNU time) is needed")
    with tempfile.TemporaryDirectory(prefix="moreau-first-run-") as tmp:
        venv = os.path.join(tmp, "venv")
        subprocess.run([sys.executable, "-m", "venv", venv], check=True)
        py = os.path.join(venv, "bin", "python")
        env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH", "VIRTUAL_ENV"))}
        env["MPLBACKEND"] = "Agg"
        target = ["-e", str(ROOT)] if args.editable else [str(ROOT)]
        cache = os.path.join(tmp, "numba-cache")  # empty; the editable install compiles into it
        os.makedirs(cache)
        env["NUMBA_CACHE_DIR"] = cache
        inst = _timed([py, "-m", "pip", "install", "--quiet", *target], env, tmp)
        moreau = os.path.join(venv, "bin", "moreau")
        first = _timed([moreau, "piston", "--no-progress", "--out", "out1"], env, tmp)
        second = _timed([moreau, "piston", "--no-progress", "--out", "out2"], env, tmp)
    said = "compiling the time loop" in first[2]
    print(f"\nfirst `moreau piston` after `pip install {'-e ' if args.editable else ''}<checkout>`, "
          "empty NUMBA_CACHE_DIR (GNU time -v)")
    print(f"{'':34}{'wall (s)':>10}{'peak RSS (MB)':>16}")
    for name, (wall, rss, _) in (("pip install", inst), ("first moreau piston", first),
                                 ("second moreau piston", second)):
        print(f"{name:34}{wall:10.1f}{rss:16.0f}")
    print(f"first / second wall time: {first[0] / second[0]:.2f}x; the first run "
          f"{'said it compiles the time loop' if said else 'compiled nothing (machine code from the install)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
