"""The benchmark scripts load: no test runs them (they print tables, and take minutes), so a
name they import from the library or from each other that went away would go unseen."""

import subprocess
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"

# each script's module code, without its main (run_name is not "__main__"), in one interpreter
_LOAD = """
import runpy, sys
sys.path.insert(0, sys.argv[1])
for path in sys.argv[2:]:
    runpy.run_path(path, run_name="benchmark")
"""


def test_every_benchmark_script_loads():
    scripts = sorted(str(p) for p in BENCHMARKS.glob("*.py"))
    assert len(scripts) >= 10
    done = subprocess.run([sys.executable, "-c", _LOAD, str(BENCHMARKS), *scripts],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
