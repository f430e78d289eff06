"""Parameter sweeps: run a function of parameters over a grid, in parallel, resumably.

:func:`sweep` calls ``fun(**point)`` for every point of a grid and returns one row per
point — the point's parameters followed by what ``fun`` returned (a dict) and an ``error``
column — in grid order. The points run

* on a local process pool (default, one process per core),
* in this process (``executor="serial"``; for debugging),
* on any :class:`concurrent.futures.Executor` you pass (left open),
* or on a Dask cluster: a ``distributed.Client`` or a scheduler address such as
  ``"tcp://10.0.0.5:8786"`` (optional extra: ``pip install -e ".[dask]"``).

Record on disk and resuming
---------------------------
With ``out="results.parquet"`` (or ``.csv``) every finished point is written at once, as
one small JSON file in the directory ``results.parquet.parts/`` (written to a temporary
name and renamed, so a file is either complete or absent), and the whole table is
consolidated into ``out`` at the end (also after an interrupt: every point listed, those
not finished with the error ``"not computed"``). Run the same call again after an
interrupt, a crash or a reboot and the finished points are read back, not recomputed.

A record is reused only for the same computation. Its key is made of

* the point's parameters (names and values, floats to 12 significant digits: ``0.1``,
  ``np.float64(0.1)`` and ``0.1 + 1e-17`` are one point),
* the function: its qualified name, the hash of its source code, and the arguments bound
  by ``functools.partial`` (``partial(f, y=0)`` and ``partial(f, y=100)`` never share
  records),
* the moreau version (records of another version are recomputed),
* ``cache_key``: anything else the results depend on that the function's own source does
  not show, typically a digest of the code it calls (:func:`source_digest`; ``moreau
  sweep`` and the notebooks pass the digest of ``problems/piston`` and of ``moreau``).

Every record read back is checked against its point and its function; a malformed or
mismatched one is recomputed with a warning. A lock file (``<out>.parts/sweep.lock``)
refuses a second sweep on the same ``out`` while one runs (a lock left by a process that
no longer exists on this machine is taken over). The record also refuses an ``out`` whose
table was written by another function. Delete the parts directory to drop the record.
Failures
--------
A point whose function raises an ``Exception`` gets its message in ``error``
(``"ValueError: ..."``), NaN/None in the result columns, and the sweep goes on; it is a
finished point (set ``retry_errors=True`` to recompute such points on the next run).
``KeyboardInterrupt`` stops the sweep: the finished points stay recorded and the
interrupt is re-raised.

Determinism
-----------
Rows depend only on the grid and on what ``fun`` returns, never on which worker or in
which order points finished: with a pure ``fun`` the process pool and Dask give identical
tables. ``fun`` must be picklable (a module-level function, or a ``functools.partial`` of
one) and return a dict of JSON-like values (numbers, strings, bools, None, lists; numpy
scalars and arrays are converted to Python numbers and lists).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import functools
import hashlib
import inspect
import itertools
import json
import logging
import math
import os
import socket
import time
import uuid
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["sweep", "grid_points", "point_key", "read_table", "source_digest", "SweepLockedError"]

log = logging.getLogger(__name__)

_PARTS_SUFFIX = ".parts"
_MANIFEST = "sweep.json"
_LOCK = "sweep.lock"
_RECORD_FORMAT = 2
_ERROR = "error"


# -- grid ---------------------------------------------------------------------------------
def _scalar(value: Any, where: str, inner: bool = False) -> Any:
    """A grid value as plain Python data: a str, int, float, bool or None, or a tuple of
    those (one value, e.g. a set of angles)."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    if isinstance(value, tuple) and not inner:
        return tuple(_scalar(v, where, inner=True) for v in value)
    raise ValueError(f"{where}: grid values must be numbers, strings, bools, None or tuples of them, "
                     f"got {value!r}")


def grid_points(grid: Mapping[str, Any] | Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The points of a grid, in order.

    Parameters
    ----------
    grid : dict of lists, or list of dicts
        A dict maps each parameter name to a list (or array, range) of values, or to one
        value; the points are the cartesian product in key order, the last key varying
        fastest. A list gives the points themselves. A value is a number, string, bool,
        None, or a tuple of those (one value: ``{"angles": (60.0, 420.0)}``).

    Returns
    -------
    list of dict
        Points with plain Python values.

    Raises
    ------
    ValueError
        An empty grid, a parameter name that is not a string, a value that is not a
        scalar, or two points with the same parameters (see :func:`point_key`).
    """
    if isinstance(grid, Mapping):
        names = list(grid)
        axes = []
        for name in names:
            vals = grid[name]
            if isinstance(vals, np.ndarray):
                vals = vals.ravel().tolist()
            elif not isinstance(vals, (list, range)):
                vals = [vals]  # a scalar, or a tuple: one value
            axes.append([_scalar(v, f"parameter {name!r}") for v in vals])
        points = [dict(zip(names, combo)) for combo in itertools.product(*axes)]
    else:
        points = []
        for i, p in enumerate(grid):
            if not isinstance(p, Mapping):
                raise ValueError(f"grid point {i} must be a dict of parameters, got {p!r}")
            points.append({k: _scalar(v, f"grid point {i}, parameter {k!r}") for k, v in p.items()})
    if not points:
        raise ValueError("the grid has no points")
    seen: dict[str, int] = {}
    for i, p in enumerate(points):
        bad = [k for k in p if not isinstance(k, str) or not k]
        if bad:
            raise ValueError(f"grid point {i}: parameter names must be non-empty strings, got {bad!r}")
        k = point_key(p)
        if k in seen:
            raise ValueError(f"grid points {seen[k]} and {i} are the same point {p!r}")
        seen[k] = i
    return points


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


# -- running one point --------------------------------------------------------------------
def _plain(value: Any) -> Any:
    """A returned value as JSON-like Python data (numpy → Python numbers and lists)."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    raise TypeError(f"returned a value of type {type(value).__name__} ({value!r:.60}); "
                    "return numbers, strings, bools, None, lists or numpy arrays")


def _call(fun: Callable[..., Mapping], point: dict) -> tuple[dict | None, str | None]:
    """Run ``fun(**point)``: (result, None), or (None, message) if it raised an Exception.

    Runs on the worker. ``KeyboardInterrupt`` and other BaseExceptions pass through.
    """
    try:
        result = fun(**point)
        if not isinstance(result, Mapping):
            raise TypeError(f"the sweep function must return a dict, got {type(result).__name__}")
        result = {str(k): _plain(v) for k, v in result.items()}
        clash = sorted(set(result) & (set(point) | {_ERROR}))
        if clash:
            raise ValueError(f"the result's keys {clash} clash with the parameters or the error column")
        return result, None
    except Exception as exc:  # noqa: BLE001 - recorded in the row, the sweep goes on
        return None, f"{type(exc).__name__}: {exc}"


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
    from . import __version__

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
        Modules, packages, or their import names (``"problems.piston"``).
    """
    import importlib

    h = hashlib.sha1()
    for mod in modules:
        if isinstance(mod, str):
            mod = importlib.import_module(mod)
        paths = []
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
        except BaseException:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            raise


def _untuple(params: dict) -> dict:
    """Parameters read back from JSON: lists were tuples."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in params.items()}


# -- executors ----------------------------------------------------------------------------
def _dask_client(executor: Any, timeout: float = 10.0):
    """(client, owned) for a Dask Client or a scheduler address; (None, False) otherwise.

    An address that cannot be reached within ``timeout`` seconds is a ``ConnectionError``.
    """
    if isinstance(executor, str) and ":" in executor:
        try:
            from distributed import Client
        except ImportError:
            raise ImportError("running a sweep on a Dask scheduler needs dask.distributed: "
                              "pip install 'moreau[dask]' (or pip install 'dask[distributed]')") from None
        try:
            return Client(executor, timeout=timeout), True
        except (OSError, TimeoutError) as exc:
            raise ConnectionError(f"cannot reach the Dask scheduler at {executor!r} within {timeout:g} s "
                                  f"({type(exc).__name__}: {exc})") from None
    mod = type(executor).__module__ or ""
    if mod.split(".")[0] == "distributed" and hasattr(executor, "submit") and hasattr(executor, "gather"):
        return executor, False
    return None, False


def _run_serial(fun, todo, on_done):
    for i, point in todo:
        on_done(i, *_call(fun, point))


def _run_futures(pool: cf.Executor, fun, todo, on_done):
    futures = {pool.submit(_call, fun, point): i for i, point in todo}
    try:
        for fut in cf.as_completed(futures):
            on_done(futures[fut], *_outcome(fut))
    except BaseException:
        for fut in futures:
            fut.cancel()
        # keep what had finished anyway
        for fut, i in futures.items():
            if fut.done() and not fut.cancelled() and fut.exception() is None:
                on_done(i, *fut.result(), quiet=True)
        raise


def _outcome(fut) -> tuple[dict | None, str | None]:
    try:
        return fut.result()
    except cf.process.BrokenProcessPool as exc:
        raise RuntimeError(f"a worker process died ({exc}); the finished points are recorded, "
                           "run the sweep again to resume") from exc
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:  # noqa: BLE001 - e.g. the result could not be sent back
        return None, f"{type(exc).__name__}: {exc}"


def _run_processes(fun, todo, workers: int, on_done) -> None:
    """The local process pool: the scheduler shared with ``moreau piston``
    (:func:`moreau._pool.run_jobs`): a point starts only when a worker is free; on Ctrl-C
    or SIGTERM the running points are stopped, none starts, the workers end."""
    from ._pool import run_jobs

    index = [i for i, _ in todo]
    state = {"stopping": False}

    def done(j: int, outcome, exc: BaseException | None) -> None:
        if isinstance(exc, KeyboardInterrupt):  # the point was interrupted: the sweep is
            if not state["stopping"]:
                state["stopping"] = True
                raise exc
            return
        if exc is not None:
            if isinstance(exc, cf.process.BrokenProcessPool):
                raise RuntimeError(f"a worker process died ({exc}); the finished points are recorded, "
                                   "run the sweep again to resume") from exc
            outcome = (None, f"{type(exc).__name__}: {exc}")
        on_done(index[j], *outcome, quiet=state["stopping"])

    try:
        run_jobs(_call, [(fun, point) for _, point in todo], workers, done)
    except KeyboardInterrupt:
        state["stopping"] = True
        raise


def _run_dask(client, fun, todo, on_done):
    from distributed import as_completed

    futures = {}
    for i, point in todo:
        # a fresh key each run: never a stale result of an earlier run of the same point
        fut = client.submit(_call, fun, point, key=f"moreau-sweep-{point_key(point)}-{uuid.uuid4().hex[:8]}",
                            pure=False)
        futures[fut.key] = (fut, i)
    try:
        for fut in as_completed([f for f, _ in futures.values()]):
            i = futures[fut.key][1]
            try:
                res, err = fut.result()
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker
                res, err = None, f"{type(exc).__name__}: {exc}"
            on_done(i, res, err)
    except BaseException:
        pending = [f for f, _ in futures.values() if not f.done()]
        for fut, i in futures.values():
            if fut.status == "finished":
                on_done(i, *fut.result(), quiet=True)
        if pending:
            client.cancel(pending)
        raise


# -- the sweep ----------------------------------------------------------------------------
def sweep(
    fun: Callable[..., Mapping[str, Any]],
    grid: Mapping[str, Any] | Sequence[Mapping[str, Any]],
    *,
    executor: str | cf.Executor | Any = "processes",
    workers: int | None = None,
    out: str | os.PathLike | None = None,
    progress: bool = True,
    retry_errors: bool = False,
    cache_key: Any = None,
    dask_timeout: float = 10.0,
):
    """Run ``fun(**point)`` over a grid of points; one row per point, in grid order.

    Parameters
    ----------
    fun : callable
        A pure, picklable function of the parameters returning a dict of results.
    grid : dict of lists, or list of dicts
        The points (see :func:`grid_points`): ``{"e": np.linspace(0, 1, 21), "D_mm":
        80.04}`` is 21 points.
    executor : {"processes", "serial"}, concurrent.futures.Executor, distributed.Client or str
        Where the points run: a local process pool (default), this process, an executor
        you own (not shut down here), a Dask client, or a Dask scheduler address (a client
        is opened and closed here).
    workers : int, optional
        Processes of the local pool (default: the number of cores, at most one per point
        to compute). Ignored for the other executors.
    out : str or path, optional
        Table to write, ``.parquet`` (needs pyarrow) or ``.csv``; the finished points are
        recorded in ``<out>.parts/`` as they finish, and read back instead of recomputed
        when the sweep runs again (see the module docstring). None: nothing on disk.
    progress : bool
        A tqdm progress bar over the points.
    retry_errors : bool
        Recompute recorded points whose function raised.
    cache_key : JSON-like value, optional
        Part of every record's key, for what the results depend on beyond the function's
        own source and arguments (the code it calls, data files): e.g.
        ``source_digest("problems.piston")``. Records made with another ``cache_key`` are
        not reused.
    dask_timeout : float
        Seconds to wait for a Dask scheduler given by its address.

    Returns
    -------
    pandas.DataFrame
        The parameters (one column each), the returned keys (union over the points, in
        order of first appearance along the grid) and ``error`` (None, or the exception's
        type and message).

    Raises
    ------
    ValueError
        A bad grid, an ``out`` suffix other than .parquet/.csv, or an ``out`` whose
        recorded points came from another function; :class:`SweepLockedError` (a
        ValueError) when another sweep is writing to ``out``.
    ImportError
        pandas, pyarrow (for parquet) or dask.distributed missing.
    ConnectionError
        A Dask scheduler address that does not answer within ``dask_timeout``.
    KeyboardInterrupt
        Ctrl-C, or SIGTERM under ``moreau sweep``: re-raised after recording the
        finished points (``out`` lists every point, ``"not computed"`` for the others).
    """
    pd = _require("pandas", "sweeps return a pandas DataFrame: pip install 'moreau[sweeps]'")
    if isinstance(executor, str) and executor not in ("processes", "serial") and ":" not in executor:
        raise ValueError(f"executor must be 'processes', 'serial', a concurrent.futures.Executor, a "
                         f"dask.distributed Client or a scheduler address such as tcp://host:8786, got {executor!r}")
    points = grid_points(grid)
    keys = [point_key(p) for p in points]
    out_path = os.fspath(out) if out is not None else None
    if out_path is not None:
        fmt = _table_format(out_path)
        if fmt == "parquet":
            _require("pyarrow", "writing a .parquet table needs pyarrow: pip install pyarrow (or write .csv)")
    name = _fun_name(fun)

    results: list[tuple[dict | None, str | None] | None] = [None] * len(points)
    record = None
    if out_path is not None:
        if os.path.isdir(out_path):
            raise ValueError(f"out {out_path!r} is a directory; give the table's file name (.parquet or .csv)")
        parent = os.path.dirname(os.path.abspath(out_path))
        os.makedirs(parent, exist_ok=True)
        fun_id = json.dumps(_fun_identity(fun, cache_key), sort_keys=True)
        record = _Record(out_path + _PARTS_SUFFIX, fun_id)
        record.check_manifest(name, _fun_source_hash(fun))
        keys = [_record_key(p, fun_id) for p in points]
        for i, k in enumerate(keys):
            part = record.read(k, points[i])
            if part is not None and not (retry_errors and part.get("error")):
                results[i] = (part.get("result"), part.get("error"))
    todo = [(i, points[i]) for i in range(len(points)) if results[i] is None]
    n_done = len(points) - len(todo)
    if n_done:
        log.info("%s: %d of %d points read from %s, %d to compute", name, n_done, len(points),
                 record.directory, len(todo))

    from tqdm import tqdm  # plain text bar: the same in a terminal and a notebook (no widgets needed)

    bar = tqdm(total=len(points), initial=n_done, desc=f"sweep {name.rsplit('.', 1)[-1]}", unit="point",
               disable=not progress, smoothing=0.1)

    def on_done(i: int, result: dict | None, error: str | None, quiet: bool = False) -> None:
        if results[i] is not None and quiet:
            return
        results[i] = (result, error)
        if record is not None:
            record.write(keys[i], points[i], result, error)
        if error is not None:
            log.warning("point %s failed: %s", points[i], error)
        if not quiet:
            bar.update(1)

    client, owned = None, False
    if record is not None:
        try:
            record.lock()  # released in the finally below
        except BaseException:
            bar.close()
            raise
    try:
        client, owned = (None, False) if not todo else _dask_client(executor, dask_timeout)
        if not todo:
            pass
        elif client is not None:
            _run_dask(client, fun, todo, on_done)
        elif executor == "serial":
            _run_serial(fun, todo, on_done)
        elif executor == "processes":
            _run_processes(fun, todo, max(1, min(workers or os.cpu_count() or 1, len(todo))), on_done)
        elif isinstance(executor, cf.Executor):
            _run_futures(executor, fun, todo, on_done)
        else:
            raise ValueError(f"executor must be 'processes', 'serial', a concurrent.futures.Executor, "
                             f"a dask.distributed Client or a scheduler address, got {executor!r}")
    except KeyboardInterrupt:
        done = sum(r is not None for r in results)
        log.warning("sweep interrupted: %d of %d points finished%s", done, len(points),
                    f" and recorded in {record.directory}; run it again to resume" if record else "")
        if out_path is not None:  # every point, "not computed" for the unfinished ones
            _write_table(_table(pd, points, results), out_path)
        raise
    finally:
        bar.close()
        if owned:
            client.close()
        if record is not None:
            record.unlock()

    df = _table(pd, points, results)
    if out_path is not None:
        _write_table(df, out_path)
        log.info("sweep table written to %s", out_path)
    return df


def _table(pd, points: list[dict], results: list, finished_only: bool = False):
    """The rows in grid order: parameters, results (None where missing), error."""
    param_cols: list[str] = []
    result_cols: list[str] = []
    for p, r in zip(points, results):
        param_cols.extend(k for k in p if k not in param_cols)
        if r is not None and r[0]:
            result_cols.extend(k for k in r[0] if k not in result_cols)
    rows = []
    for p, r in zip(points, results):
        if r is None and finished_only:
            continue
        res, err = r if r is not None else (None, "not computed")
        row = {k: list(v) if isinstance(v := p.get(k), tuple) else v for k in param_cols}
        row.update({k: (res or {}).get(k) for k in result_cols})
        row[_ERROR] = err
        rows.append(row)
    cols = param_cols + result_cols + [_ERROR]
    df = pd.DataFrame.from_records(rows, columns=cols)
    return _error_as_object(pd, df)


def _error_as_object(pd, df):
    """The error column as Python objects (None or str) whatever the pandas version, so
    tables with and without failures, in memory and read back, compare equal."""
    df[_ERROR] = pd.Series([e if isinstance(e, str) else None for e in df[_ERROR]], index=df.index, dtype=object)
    return df


def _table_format(path: str) -> str:
    low = path.lower()
    if low.endswith(".parquet") or low.endswith(".pq"):
        return "parquet"
    if low.endswith(".csv"):
        return "csv"
    raise ValueError(f"out must end in .parquet or .csv, got {path!r}")


def _write_table(df, path: str) -> None:
    """Write the table atomically (temporary file, then rename)."""
    tmp = f"{path}.{os.getpid()}.tmp"
    if _table_format(path) == "parquet":
        try:
            df.to_parquet(tmp, index=False)
        except Exception as exc:  # noqa: BLE001 - pyarrow refuses mixed columns (lists and scalars, ...)
            log.warning("writing %s: %s; list columns are written as JSON text", path, exc)
            _json_columns(df).to_parquet(tmp, index=False)
    else:
        _json_columns(df).to_csv(tmp, index=False)
    os.replace(tmp, path)


def _json_columns(df):
    """A copy in which every object column holding lists or dicts is JSON text (None and
    NaN stay missing)."""
    enc = df.copy()
    for c in enc.columns:
        if enc[c].dtype == object and enc[c].map(lambda x: isinstance(x, (list, dict))).any():
            enc[c] = enc[c].map(lambda x: None if x is None or (isinstance(x, float) and math.isnan(x))
                                else json.dumps(x))
    return enc


def _decode_json_column(col):
    """A column of JSON text back to Python values, if it is one: every non-missing value
    a string that parses, and at least one a list or dict. Other columns are unchanged."""
    vals = [x for x in col if isinstance(x, str)]
    if not vals or len(vals) != int(col.notna().sum()) or not any(v[:1] in "[{" for v in vals):
        return col
    try:
        decoded = {v: json.loads(v) for v in set(vals)}
    except ValueError:
        return col
    return col.map(lambda x: decoded[x] if isinstance(x, str) else None).astype(object)


def read_table(path: str | os.PathLike):
    """Read a table written by :func:`sweep` (list columns of a CSV are JSON-decoded).

    Returns
    -------
    pandas.DataFrame
    """
    pd = _require("pandas", "reading a sweep table needs pandas: pip install 'moreau[sweeps]'")
    path = os.fspath(path)
    if _table_format(path) == "parquet":
        df = pd.read_parquet(path)
        for c in df.columns:
            if df[c].dtype == object:
                df[c] = df[c].map(lambda x: x.tolist() if isinstance(x, np.ndarray) else x)
    else:
        df = pd.read_csv(path)
    for c in df.columns:
        if df[c].dtype == object or str(df[c].dtype).startswith("str"):
            df[c] = _decode_json_column(df[c])
    return _error_as_object(pd, df) if _ERROR in df.columns else df


def _require(module: str, message: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(message) from None
