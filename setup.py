"""One build step beyond what pyproject.toml declares: the time loop is compiled for the
machine that installs the package, so that the first run loads it instead of compiling for
a minute and a half (issues 23 and 42).

- A wheel (``pip install .``) carries the machine code (``moreau/_prebuilt``); the first
  run copies it into numba's cache.
- An editable install (``pip install -e .``, the README's command) compiles into the
  checkout's own cache (its ``__pycache__``, or ``$NUMBA_CACHE_DIR`` when set), where its
  runs load it.

The package's build requirements (pyproject.toml) therefore include its run-time ones:
the step imports the package. ``MOREAU_PREBUILD=0`` skips it; when it fails, the package
is installed without the machine code and says so (the first run then compiles, as it
would have anyway).
"""

import os
import subprocess
import sys
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = os.path.dirname(os.path.abspath(__file__))
# the checkout's moreau, with its problems/ folder as moreau.problems (as installed), warmed up in place
_IN_PLACE = """
import importlib.util, os, sys
root = sys.argv[1]
sys.path.insert(0, root)
import moreau
here = os.path.join(root, "problems")
spec = importlib.util.spec_from_file_location("moreau.problems", os.path.join(here, "__init__.py"),
                                              submodule_search_locations=[here])
problems = importlib.util.module_from_spec(spec)
sys.modules["moreau.problems"] = moreau.problems = problems
spec.loader.exec_module(problems)
from moreau.problems.prebuild import warm_up
warm_up()
"""


class BuildPyWithMachineCode(build_py):
    """``build_py``, then the time loop compiled: into ``<build_lib>/moreau/_prebuilt``
    (``python -m moreau.problems.prebuild``), or, editable, into the checkout's cache."""

    def run(self) -> None:
        super().run()
        if os.environ.get("MOREAU_PREBUILD", "1") == "0":
            return
        print("moreau: compiling the time loop for this machine (about 90 s; MOREAU_PREBUILD=0 skips it)",
              flush=True)
        env = dict(os.environ, MPLBACKEND="Agg")
        if getattr(self, "editable_mode", False):
            done = self._run([sys.executable, "-c", _IN_PLACE, ROOT], env, ROOT)
        else:
            lib = os.path.abspath(self.build_lib)
            out = os.path.join(lib, "moreau", "_prebuilt")
            with tempfile.TemporaryDirectory(prefix="moreau-build-cache-") as cache:
                path = [lib] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
                env.update(NUMBA_CACHE_DIR=cache, PYTHONPATH=os.pathsep.join(path))
                # the working directory is the empty cache: the checkout must not shadow build_lib
                done = self._run([sys.executable, "-m", "moreau.problems.prebuild", out], env, cache)
        if not done:
            print("moreau: WARNING: the time loop could not be compiled while installing; the first run "
                  "compiles it instead", file=sys.stderr, flush=True)

    @staticmethod
    def _run(cmd: list, env: dict, cwd: str) -> bool:
        try:
            return subprocess.run(cmd, env=env, cwd=cwd, check=False).returncode == 0
        except OSError as exc:
            print(f"moreau: {exc}", file=sys.stderr)
            return False


setup(cmdclass={"build_py": BuildPyWithMachineCode})
