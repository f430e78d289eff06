"""Keep numba's on-disk cache of moreau's compiled code keyed by all of its source.

numba keys a cached function by the timestamp of the file that defines it, not by the
files of the functions it calls or inlines: after an edit of a kernel, the cached time
loop would still run the old kernel. Before any compiled module is used, this module
hashes the source of every module that takes part in the compiled loop (and numba's
version) and, when the digest differs from the one stored beside the cache, deletes
moreau's cached machine code there so that it is compiled afresh.
"""

from __future__ import annotations

import glob
import hashlib
import logging
import os

log = logging.getLogger(__name__)

#: the modules whose code ends up in the compiled loop
COMPILED_MODULES = ("kernels", "lcp", "evaluate", "loop")
_STAMP = "moreau-jit.digest"


def source_digest() -> str:
    """SHA-256 of the compiled modules' source and numba's version."""
    import numba

    here = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha256(numba.__version__.encode())
    for name in COMPILED_MODULES:
        with open(os.path.join(here, name + ".py"), "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def _cache_dirs() -> list[str]:
    here = os.path.dirname(os.path.abspath(__file__))
    dirs = [os.path.join(here, "__pycache__")]
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env:  # numba mirrors the package path under NUMBA_CACHE_DIR
        dirs.append(os.path.join(env, os.path.splitdrive(here)[1].lstrip(os.sep)))
    try:  # the user-wide fallback numba uses when the package is not writable
        from numba.core.caching import _UserWideCacheLocator  # type: ignore[attr-defined]

        loc = _UserWideCacheLocator(os.path.join(here, "loop.py"), os.path.join(here, "loop.py"))
        dirs.append(loc.get_cache_path())
    except Exception:  # noqa: BLE001 - an internal API: skip when it changes
        pass
    return dirs


def ensure_fresh() -> None:
    """Delete moreau's cached machine code wherever its digest is not the current one."""
    digest = source_digest()
    for d in _cache_dirs():
        stamp = os.path.join(d, _STAMP)
        try:
            with open(stamp) as f:
                if f.read().strip() == digest:
                    continue
        except OSError:
            pass
        stale = [p for name in COMPILED_MODULES for ext in ("nbi", "nbc")
                 for p in glob.glob(os.path.join(d, f"{name}.*.{ext}"))]
        for p in stale:
            try:
                os.remove(p)
            except OSError:
                pass
        if stale:
            log.info("moreau: source changed, removed %d stale numba cache files in %s", len(stale), d)
        try:
            os.makedirs(d, exist_ok=True)
            tmp = f"{stamp}.{os.getpid()}.tmp"
            with open(tmp, "w") as f:
                f.write(digest)
            os.replace(tmp, stamp)
        except OSError:
            pass  # not writable: numba will not cache there either
