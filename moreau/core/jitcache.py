"""moreau's compiled code on disk: keyed by all of its source, compiled by one process at a time.

numba keys a cached function by the timestamp of the file that defines it, not by the
files of the functions it calls: after an edit of a kernel, the cached time loop would
still run the old kernel. Before any compiled module is used, :func:`ensure_fresh`
hashes the source of every module that takes part in the compiled loop (and numba's
version) and, when the digest differs from the one stored in the cache directory,
deletes moreau's cached machine code there so that it is compiled afresh.

:func:`compile_lock` serializes the compile between processes (an advisory file lock in
the cache directory): a second process started while the first compiles waits, then
loads the machine code the first one saved, instead of compiling it again.

A package built with ``pip install .`` carries machine code compiled while it was built
(``moreau/_prebuilt``, written by ``setup.py``'s build step through :func:`export`);
:func:`ensure_fresh` copies it into an empty cache (:func:`seed`) when it was built from
the same source and numba, so the first run loads the loop instead of compiling it.

The cache lives where numba puts it: ``$NUMBA_CACHE_DIR`` when set, else the package's
``__pycache__`` when writable, else a folder in the user's cache directory
(:func:`cache_dir` says which). When none of these is writable, a temporary directory of
the process, with one warning (:func:`use_process_cache_when_none_is_writable`).
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import logging
import os
import shutil
import threading
from collections.abc import Iterator

log = logging.getLogger(__name__)

#: the folders (relative to the package) whose modules hold compiled code: the physics
#: kernels, the contact numerics and the compiled loop; an edit anywhere in them clears
#: the cached machine code
COMPILED_DIRS = ("core/kernels", "contact", "compiled")
#: modules that change how moreau's code is compiled (hashed into the digest with the above)
CODEGEN_FILES = ("core/llvm_prepass.py",)
_STAMP = "moreau-jit.digest"
_LOCK = "moreau-jit.lock"
_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: the module whose cache directory holds the digest and the lock
_ANCHOR = os.path.join(_PACKAGE, "compiled", "loop.py")
#: machine code compiled when the package was built (``setup.py``'s build hook), per
#: compiled folder; absent in a source checkout or an editable install
PREBUILT = os.path.join(_PACKAGE, "_prebuilt")


def compiled_sources() -> list[str]:
    """The source files of every module that may hold compiled code, sorted."""
    return sorted(p for d in COMPILED_DIRS for p in glob.glob(os.path.join(_PACKAGE, d, "*.py")))


def source_digest() -> str:
    """SHA-256 of the compiled modules' source and of the codegen's (:data:`CODEGEN_FILES`;
    with their paths) and numba's version."""
    import numba

    h = hashlib.sha256(numba.__version__.encode())
    for path in compiled_sources() + [os.path.join(_PACKAGE, f) for f in CODEGEN_FILES]:
        h.update(os.path.relpath(path, _PACKAGE).encode())
        with open(path, "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def _cache_impl():
    """numba's cache implementation class, which holds its list of cache locators (an
    internal API, renamed across numba versions)."""
    from numba.core import caching

    return getattr(caching, "CacheImpl", None) or caching._CacheImpl  # type: ignore[attr-defined]


def cache_dir(source: str = _ANCHOR) -> str | None:
    """The directory where numba caches the machine code of the module ``source`` (default:
    the compiled loop's; found with numba's own rules, first usable wins), or None when none
    is usable."""
    try:
        for cls in _cache_impl()._locator_classes:
            loc = cls.from_function(source_digest, source)
            if loc is not None:
                return str(loc.get_cache_path())
    except Exception as exc:  # noqa: BLE001 - an internal API of numba: say so, go on
        log.warning("moreau: could not locate numba's cache directory (%s); the compiled loop may be "
                    "compiled in every process", exc)
    return None


def _cached_files() -> list[str]:
    """moreau's cached machine code: per compiled module, ``<module>.*.nbi|nbc`` in its cache directory."""
    found = []
    for src in compiled_sources():
        d = cache_dir(src)
        stem = os.path.splitext(os.path.basename(src))[0]
        if d is not None:
            found += [p for ext in ("nbi", "nbc") for p in glob.glob(os.path.join(d, f"{stem}.*.{ext}"))]
    return found


def damaged_files(exc: BaseException) -> list[str]:
    """The cache files of the function whose cached machine code numba was loading when
    ``exc`` was raised (its index and data files, found in the traceback), or []."""
    tb = exc.__traceback__
    while tb is not None:
        owner = tb.tb_frame.f_locals.get("self")
        index = getattr(owner, "_index_path", None)
        if isinstance(index, str) and index.endswith(".nbi"):
            return [index] + sorted(glob.glob(glob.escape(index[:-4]) + ".*.nbc"))
        tb = tb.tb_next
    return []


def call_recovering(fun, *args):
    """``fun(*args)``; when it fails while numba loads a cache file (damaged, truncated,
    from another build), that function's cache files are removed with a warning and the
    call is made again (numba then compiles the function afresh)."""
    try:
        return fun(*args)
    except Exception as exc:
        files = damaged_files(exc)
        if not files:
            raise
        for p in files:
            with contextlib.suppress(OSError):
                os.remove(p)
        log.warning("moreau: a numba cache file could not be read (%s: %s); removed %s and compiling that "
                    "function again", type(exc).__name__, str(exc)[:200], ", ".join(map(os.path.basename, files)))
    return fun(*args)


def clear() -> int:
    """Delete moreau's cached machine code; returns the number of files removed."""
    removed = 0
    for p in _cached_files():
        try:
            os.remove(p)
            removed += 1
        except OSError:
            pass
    return removed


def ensure_fresh() -> None:
    """Delete moreau's cached machine code when its digest is not the current one; then,
    when the cache lacks the compiled loop and the package carries machine code compiled
    when it was built (``moreau/_prebuilt``, for this source), copy that in (:func:`seed`)."""
    d = cache_dir()
    if d is None:
        return
    digest = source_digest()
    stamp = os.path.join(d, _STAMP)
    try:
        with open(stamp) as f:
            if f.read().strip() == digest:
                if not glob.glob(os.path.join(d, "loop._run_chunk-*.nbi")):
                    seed(digest)
                return
    except OSError:
        pass
    removed = clear()
    if removed:
        log.info("moreau: source changed, removed %d stale numba cache files in %s", removed, d)
    seed(digest)
    try:
        os.makedirs(d, exist_ok=True)
        tmp = f"{stamp}.{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            f.write(digest)
        os.replace(tmp, stamp)
    except OSError as exc:
        log.warning("moreau: numba's cache directory %s is not writable (%s); compiled code is not kept", d, exc)


def export(out: str) -> int:
    """Copy moreau's cached machine code (compiled in this process's cache) into ``out``
    (per compiled folder, with the source digest), for :func:`seed`; returns the number of
    files copied. The build hook (``setup.py``) calls it after compiling the loop."""
    n = 0
    for src in compiled_sources():
        d = cache_dir(src)
        if d is None:
            continue
        stem = os.path.splitext(os.path.basename(src))[0]
        dest = os.path.join(out, os.path.dirname(os.path.relpath(src, _PACKAGE)))
        for p in glob.glob(os.path.join(d, f"{stem}.*.nb[ic]")):
            os.makedirs(dest, exist_ok=True)
            shutil.copyfile(p, os.path.join(dest, os.path.basename(p)))
            n += 1
    if n:
        with open(os.path.join(out, _STAMP), "w") as f:
            f.write(source_digest())
    return n


def seed(digest: str | None = None, prebuilt: str | None = None) -> int:
    """Copy the machine code the package was built with (``moreau/_prebuilt``, or the folder
    ``prebuilt`` written by :func:`export`) into numba's cache when it was compiled from
    this very source and numba (its digest equals ``digest``, default
    ``source_digest()``); files already there are kept. ``prebuilt`` None: the module's
    ``PREBUILT`` at the time of the call. numba itself still checks each file against its
    source file's content, its Python and numba versions and this machine's processor,
    and compiles what does not match.
    Each file is written through a unique temporary name and renamed. Returns the number
    of files copied (0 when there is nothing to copy or the cache is not writable)."""
    if prebuilt is None:
        prebuilt = PREBUILT
    try:
        with open(os.path.join(prebuilt, _STAMP)) as f:
            built = f.read().strip()
    except OSError:
        return 0
    if built != (digest or source_digest()):
        log.info("moreau: the machine code built with the package is for another source or numba; not used")
        return 0
    n = 0
    try:
        for src in compiled_sources():
            d = cache_dir(src)
            stem = os.path.splitext(os.path.basename(src))[0]
            here = os.path.join(prebuilt, os.path.dirname(os.path.relpath(src, _PACKAGE)))
            for p in glob.glob(os.path.join(here, f"{stem}.*.nb[ic]")):
                target = os.path.join(d, os.path.basename(p)) if d is not None else None
                if target is None or os.path.exists(target):
                    continue
                tmp = f"{target}.{os.getpid()}.{threading.get_ident()}.tmp"
                shutil.copyfile(p, tmp)
                os.replace(tmp, target)
                n += 1
    except OSError as exc:
        log.warning("moreau: could not copy the machine code built with the package into numba's cache (%s); "
                    "the time loop is compiled instead", exc)
    if n:
        log.info("moreau: copied %d files of machine code built with the package into numba's cache", n)
    return n


@contextlib.contextmanager
def compile_lock(name: str = "") -> Iterator[None]:
    """Hold moreau's compile lock ``name`` (an exclusive ``flock`` on a file in the cache
    directory) while the body runs; without a usable directory (or ``fcntl``), no lock."""
    d = cache_dir()
    with _file_lock(None if d is None else os.path.join(d, f"{_LOCK}{name}")):
        yield


@contextlib.contextmanager
def _file_lock(path: str | None) -> Iterator[None]:
    """An exclusive ``flock`` on ``path`` while the body runs (none when path is None, or
    without ``fcntl``; a file that cannot be locked: a warning, and no lock)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        fcntl = None  # type: ignore[assignment]
    fd = None
    if path is not None and fcntl is not None:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError as exc:
            log.warning("moreau: cannot lock %s (%s); going on without the lock", path, exc)
            if fd is not None:
                os.close(fd)
            fd = None
    try:
        yield
    finally:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)


def lock_cache_saves() -> None:
    """Make each save into numba's cache of a function of moreau's compiled modules hold a
    lock on its cache directory. numba names a new entry's data file from the index it
    has just read, so two processes saving entries of one function at once (two variants
    of the loop compiled side by side, each under its own :func:`compile_lock`) could
    both pick one file; under the lock each reads the other's index. Idempotent; called
    when moreau is imported (numba's ``IndexDataCacheFile.save``, an internal API)."""
    from numba.core import caching

    cls = caching.IndexDataCacheFile
    if getattr(cls.save, "_moreau_locked", False):
        return
    plain = cls.save
    stems = {os.path.splitext(os.path.basename(p))[0] for p in compiled_sources()}

    def save(self, key, data):
        index = self._index_path
        ours = os.path.basename(index).split(".", 1)[0] in stems
        with _file_lock(os.path.join(os.path.dirname(index), f"{_LOCK}.save") if ours else None):
            plain(self, key, data)

    save._moreau_locked = True  # type: ignore[attr-defined]
    setattr(cls, "save", save)  # noqa: B010 - numba's class, patched once


_PROCESS_DIR: list[str] = []  # this process's temporary cache directory, once made
_PROCESS_LOCK = threading.Lock()


def _process_cache_dir() -> str:
    """A temporary directory for this process's machine code, made on first use and
    removed at its exit (by the process that made it)."""
    with _PROCESS_LOCK:
        if not _PROCESS_DIR:
            import atexit
            import tempfile
            import warnings

            path = tempfile.mkdtemp(prefix="moreau-numba-")
            owner = os.getpid()

            def remove() -> None:  # by the process that made it, not by a forked worker
                if os.getpid() == owner:
                    shutil.rmtree(path, ignore_errors=True)

            atexit.register(remove)
            _PROCESS_DIR.append(path)
            warnings.warn(f"moreau: no writable numba cache directory (NUMBA_CACHE_DIR, the package's __pycache__ "
                          f"and the user's cache directory were tried); compiled code is kept in {path} for this "
                          "process only, and every new process compiles again (50-85 s for the time loop). "
                          "Set NUMBA_CACHE_DIR to a writable directory to keep it", RuntimeWarning, stacklevel=2)
        return _PROCESS_DIR[0]


def use_process_cache_when_none_is_writable() -> None:
    """Give numba a last cache locator: when none of its own finds a writable directory
    for a function's cached machine code (which makes ``cache=True`` raise "no locator
    available" at import), a temporary directory of this process, with one
    ``RuntimeWarning``. Idempotent; called when moreau is imported."""
    from numba.core import caching

    impl = _cache_impl()
    if any(getattr(cls, "_moreau_last_resort", False) for cls in impl._locator_classes):
        return

    class ProcessCacheLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
        """numba's cache locator of last resort (moreau's): this process's temporary directory."""

        _moreau_last_resort = True

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = os.path.join(_process_cache_dir(), self.get_suitable_cache_subpath(py_file))

        def get_cache_path(self) -> str:
            return self._cache_path

        @classmethod
        def from_function(cls, py_func, py_file):
            try:
                return super().from_function(py_func, py_file)
            except OSError:  # no temporary directory either: numba says "no locator available"
                return None

    impl._locator_classes.append(ProcessCacheLocator)
