"""The machine code a built package carries, so that its first run does not compile (an
editable install compiles into the checkout's own cache instead: :func:`warm_up`).

``setup.py``'s build hook runs ``python -m moreau.problems.prebuild DIR`` with the freshly
built package first on ``sys.path`` and an empty ``NUMBA_CACHE_DIR``: it loads (compiles)
the time loop, runs one short cycle of the bundled piston (so that the kernels its
analysis calls from Python are compiled too), and copies the machine code into ``DIR``
(the package's ``moreau/_prebuilt``). On first use, :func:`moreau.core.jitcache.seed`
copies it into numba's cache when it was built from the same source and numba; numba
itself checks each file's source, Python version and processor, and compiles whatever
does not match, so a package built on another machine is no worse than one without it.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence

__all__ = ["prebuild", "warm_up", "main"]

log = logging.getLogger(__name__)


_FULL = "import sys; sys.path.insert(0, sys.argv[1]); from moreau.compiled.cache import ensure_compiled; " \
        "ensure_compiled('full')"


def warm_up() -> None:
    """Compile every variant of the time loop and the piston's kernels into numba's cache
    (the editable install's build step calls this alone: its runs load them from there).
    The full variant compiles in a second process, beside the plain one, the piston's
    cycle and the friction variant (each under its own lock:
    :func:`moreau.compiled.cache.ensure_compiled`)."""
    import moreau
    from moreau.compiled.cache import ensure_compiled
    from moreau.problems.piston.job import Case, run_cases

    root = os.path.dirname(os.path.dirname(os.path.abspath(moreau.__file__)))
    full = subprocess.Popen([sys.executable, "-c", _FULL, root])
    try:
        ensure_compiled("plain")
        with tempfile.TemporaryDirectory(prefix="moreau-prebuild-") as tmp:
            rows = run_cases([Case(e=0.9, D=0.08004, h=1e-3, cycles=1, transient=0)], tmp, progress=False,
                             workers=1)
        if rows[0]["status"] != "completed":
            log.warning("moreau prebuild: the piston's warm-up run ended %r", rows[0]["status"])
        ensure_compiled("friction")
        if full.wait() != 0:
            log.warning("moreau prebuild: compiling the loop's full variant failed (exit %d); its first run "
                        "compiles it", full.returncode)
    finally:
        if full.poll() is None:  # interrupted: the helper does not outlive this process
            full.kill()
            full.wait()


def prebuild(out: str) -> int:
    """Compile the time loop and the piston's kernels into numba's cache (:func:`warm_up`)
    and copy them into ``out``; returns the number of files copied."""
    from moreau.core.jitcache import export

    warm_up()
    return export(out)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m moreau.problems.prebuild DIR``: exit code 0 when files were copied."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m moreau.problems.prebuild DIR", file=sys.stderr)
        return 2
    t = time.perf_counter()
    n = prebuild(args[0])
    print(f"moreau prebuild: {n} files of machine code in {args[0]} ({time.perf_counter() - t:.0f} s)")
    return 0 if n else 1


if __name__ == "__main__":
    sys.exit(main())
