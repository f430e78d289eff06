"""The record of a sweep on disk (``<out>.parts/``): keys, identities, checks, lock.

Used by :func:`moreau.sweeps.sweep`; see its module docstring for the rule.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import json
import logging
import math
import os
import socket
import time
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

log = logging.getLogger("moreau.sweeps")

_MANIFEST = "sweep.json"
_LOCK = "sweep.lock"
_RECORD_FORMAT = 2


def _canonical(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_canonical(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return value
    x = float(value)
    if math.isfinite(x) and x.is_integer() and abs(x) < 1e15:
        return int(x)
    return format(x, ".12g")


def point_key(point: Mapping[str, Any]) -> str:
    """The identity of a point: a hash of its parameter names and values.

    Numbers are compared as floats to 12 significant digits (``1`` and ``1.0`` are the
    same value); the order of the parameters does not matter.
    """
    canon = json.dumps({k: _canonical(v) for k, v in point.items()}, sort_keys=True)
    return hashlib.sha1(canon.encode()).hexdigest()[:20]


def _fun_name(fun: Callable) -> str:
    while isinstance(fun, functools.partial):
        fun = fun.func
    return f"{getattr(fun, '__module__', '?')}.{getattr(fun, '__qualname__', type(fun).__name__)}"


def _fun_source_hash(fun: Callable) -> str | None:
    """A hash of the function's source code (None when it has none, e.g. a builtin)."""
    while isinstance(fun, functools.partial):
        fun = fun.func
    try:
        return hashlib.sha1(inspect.getsource(fun).encode()).hexdigest()[:12]
    except (OSError, TypeError):
        return None


def _key_value(value: Any) -> Any:
    """A value as canonical JSON data for a key (numbers as in :func:`point_key`; objects
    without a JSON form by type and repr, so an unknown object never matches another)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, (int, float)):
        return _canonical(value)
    if isinstance(value, (list, tuple)):
        return [_key_value(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _key_value(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    return f"{type(value).__module__}.{type(value).__qualname__}:{value!r}"


def _fun_identity(fun: Callable, cache_key: Any) -> dict:
    """What identifies the computation besides the point: function, source, bound
    arguments of partials, moreau version, the user's cache_key."""
    from moreau.core.version import __version__

    layers = []
    f = fun
    while isinstance(f, functools.partial):
        layers.append(f)
        f = f.func
    args: list = []
    keywords: dict = {}
    for p in reversed(layers):  # the innermost partial binds first
        args.extend(p.args)
        keywords.update(p.keywords)
    return {"function": _fun_name(fun), "source": _fun_source_hash(fun), "args": _key_value(args),
            "keywords": _key_value(keywords), "moreau": __version__, "cache_key": _key_value(cache_key)}


def _record_key(point: Mapping[str, Any], fun_id: str) -> str:
    canon = json.dumps({"point": {k: _canonical(v) for k, v in point.items()}, "fun": fun_id}, sort_keys=True)
    return hashlib.sha1(canon.encode()).hexdigest()[:24]


def source_digest(*modules: Any) -> str:
    """A hash of the source code of modules or packages (every ``.py`` file below a
    package), for ``sweep(..., cache_key=...)``: records computed before any of that code
    changed are then recomputed.

    Parameters
    ----------
    *modules : module or str
        Modules, packages, or their import names (``"moreau.problems.piston"``).
    """
    import importlib

    h = hashlib.sha1()
    for mod in modules:
        if isinstance(mod, str):
            mod = importlib.import_module(mod)
        paths: list[str] = []
        if hasattr(mod, "__path__"):
            for root in mod.__path__:
                for dirpath, dirnames, filenames in os.walk(root):
                    dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "__pycache__")))
                    paths.extend(os.path.join(dirpath, f) for f in sorted(filenames) if f.endswith(".py"))
            base = os.path.dirname(list(mod.__path__)[0])
        else:
            paths.append(mod.__file__)
            base = os.path.dirname(mod.__file__)
        for path in paths:
            h.update(os.path.relpath(path, base).replace(os.sep, "/").encode())
            with open(path, "rb") as fh:
                h.update(hashlib.sha1(fh.read()).digest())
    return h.hexdigest()[:16]


class SweepLockedError(ValueError):
    """Another sweep is writing to the same ``out``."""


# -- the record on disk -------------------------------------------------------------------
@dataclass
class _Record:
    """The ``<out>.parts/`` directory: one JSON file per finished point, a manifest, a lock."""

    directory: str
    fun_id: str = ""
    _locked: str | None = field(default=None, init=False, repr=False, compare=False)  # the lock this holds

    def lock(self) -> None:
        """Take the lock, or ``SweepLockedError`` naming the process that holds it."""
        os.makedirs(self.directory, exist_ok=True)
        path = os.path.join(self.directory, _LOCK)
        me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%dT%H:%M:%S")}
        for _ in range(2):
            try:
                fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = self._holder(path)
                if holder is not None and self._stale(holder):
                    log.warning("taking over the lock %s left by process %s, which no longer runs", path,
                                holder.get("pid"))
                    with contextlib.suppress(FileNotFoundError):
                        os.remove(path)
                    continue
                who = (f"process {holder.get('pid')} on {holder.get('host')}, started {holder.get('started')}"
                       if holder else "another process")
                raise SweepLockedError(f"another sweep ({who}) is writing to {self.directory!r}; wait for it "
                                       f"or give another out (if none runs, delete {path!r})") from None
            with os.fdopen(fd, "w") as fh:
                json.dump(me, fh)
            self._locked = path
            return
        raise SweepLockedError(f"could not take the lock {path!r}")

    def unlock(self) -> None:
        path = getattr(self, "_locked", None)
        if path is not None:
            with contextlib.suppress(FileNotFoundError):
                os.remove(path)
            self._locked = None

    @staticmethod
    def _holder(path: str) -> dict | None:
        try:
            with open(path) as fh:
                holder = json.load(fh)
            return holder if isinstance(holder, dict) else None
        except (OSError, ValueError):
            return None

    @staticmethod
    def _stale(holder: dict) -> bool:
        """A lock of a process of this machine that no longer exists (POSIX only)."""
        pid = holder.get("pid")
        if os.name != "posix" or holder.get("host") != socket.gethostname() or not isinstance(pid, int):
            return False
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        except OSError:
            return False
        return False

    def check_manifest(self, name: str, source: str | None) -> None:
        """Refuse an ``out`` of another function; note a changed source (its records are
        not reused: the source is part of their key)."""
        os.makedirs(self.directory, exist_ok=True)
        path = os.path.join(self.directory, _MANIFEST)
        manifest = None
        if os.path.exists(path):
            try:
                with open(path) as fh:
                    manifest = json.load(fh)
            except (OSError, ValueError) as exc:
                log.warning("ignoring the unreadable manifest %s (%s)", path, exc)
            if not isinstance(manifest, dict):
                manifest = None
        if manifest is not None:
            old = manifest.get("function")
            if old != name:
                raise ValueError(f"the finished points in {self.directory!r} were computed by {old}, not "
                                 f"{name}: give another out, or delete that directory to start afresh")
            if source is not None and manifest.get("source") not in (None, source):
                log.warning("the source of %s has changed since the points recorded in %s were computed; "
                            "they are recomputed", name, self.directory)
        if manifest is None or manifest.get("source") != source:
            self._write(path, {"function": name, "source": source, "written": time.strftime("%Y-%m-%dT%H:%M:%S")})

    def read(self, key: str, point: dict) -> dict | None:
        """The record of ``point``, checked; None (recompute) when absent or not valid."""
        path = os.path.join(self.directory, key + ".json")
        try:
            with open(path) as fh:
                part = json.load(fh)
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as exc:  # a damaged file: recompute the point
            log.warning("ignoring unreadable part %s (%s); the point is recomputed", path, exc)
            return None
        problem = self._check(part, point)
        if problem:
            log.warning("ignoring part %s: %s; the point is recomputed", path, problem)
            return None
        return part

    def _check(self, part: Any, point: dict) -> str | None:
        if not isinstance(part, dict):
            return f"not a record (a JSON {type(part).__name__})"
        if part.get("format") != _RECORD_FORMAT:
            return f"record format {part.get('format')!r}, expected {_RECORD_FORMAT}"
        params, result, error = part.get("params"), part.get("result"), part.get("error")
        if not isinstance(params, dict) or point_key(_untuple(params)) != point_key(point) or set(params) != set(point):
            return f"its parameters {params!r} are not the point {point!r}"
        if part.get("fun") != self.fun_id:
            return "it was computed by another function, arguments, version or cache_key"
        if not (result is None or isinstance(result, dict)) or not (error is None or isinstance(error, str)):
            return "result must be a dict or null and error a string or null"
        if result is None and error is None:
            return "neither a result nor an error"
        return None

    def write(self, key: str, point: dict, result: dict | None, error: str | None) -> None:
        self._write(os.path.join(self.directory, key + ".json"),
                    {"format": _RECORD_FORMAT, "params": point, "fun": self.fun_id, "result": result, "error": error})

    @staticmethod
    def _write(path: str, data: dict) -> None:
        tmp = f"{path}.{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp"
        try:
            with open(tmp, "x") as fh:
                json.dump(data, fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException as exc:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            if isinstance(exc, OSError) and not exc.filename:  # "[Errno 28] ...": name the file
                raise OSError(exc.errno, exc.strerror or str(exc), path) from exc
            raise


def _untuple(params: dict) -> dict:
    """Parameters read back from JSON: lists were tuples."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in params.items()}


