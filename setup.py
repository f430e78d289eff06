"""One build step beyond what pyproject.toml declares: the wheel carries the time loop
compiled for the machine that builds it (``moreau/_prebuilt``), so that the first run
after ``pip install .`` loads it instead of compiling for a minute (issue 23).

The package's build requirements (pyproject.toml) therefore include its run-time ones:
the step imports the freshly built package. It is skipped for an editable install (the
checkout's own ``__pycache__`` keeps the compile of the first run) and with
``MOREAU_PREBUILD=0``; when it fails, the package is built without the machine code and
says so (the first run then compiles, as it would have anyway).
"""

import os
import subprocess
import sys
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithMachineCode(build_py):
    """``build_py``, then ``python -m moreau.problems.prebuild <build_lib>/moreau/_prebuilt``."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False) or os.environ.get("MOREAU_PREBUILD", "1") == "0":
            return
        lib = os.path.abspath(self.build_lib)
        out = os.path.join(lib, "moreau", "_prebuilt")
        print("moreau: compiling the time loop for this machine into the package (about a minute; "
              "MOREAU_PREBUILD=0 skips it)", flush=True)
        with tempfile.TemporaryDirectory(prefix="moreau-build-cache-") as cache:
            path = [lib] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=os.pathsep.join(path), MPLBACKEND="Agg")
            try:  # the working directory is the empty cache: the checkout must not shadow build_lib
                done = subprocess.run([sys.executable, "-m", "moreau.problems.prebuild", out], env=env,
                                      cwd=cache, check=False).returncode == 0
            except OSError as exc:
                print(f"moreau: {exc}", file=sys.stderr)
                done = False
        if not done:
            print("moreau: WARNING: the time loop could not be compiled into the package; the first run "
                  "compiles it instead", file=sys.stderr, flush=True)


setup(cmdclass={"build_py": BuildPyWithMachineCode})
