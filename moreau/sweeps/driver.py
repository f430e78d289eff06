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
import itertools
import json
import logging
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from moreau.sweeps.execute import _dask_client, _run_dask, _run_futures, _run_processes, _run_serial
from moreau.sweeps.record import (
    SweepLockedError,
    _fun_identity,
    _fun_name,
    _fun_source_hash,
    _Record,
    _record_key,
    point_key,
    source_digest,
)
from moreau.sweeps.table import _require, _table, _table_format, _write_table, read_table

__all__ = ["sweep", "grid_points", "point_key", "read_table", "source_digest", "SweepLockedError"]

log = logging.getLogger(__name__)

_PARTS_SUFFIX = ".parts"


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
    report: Callable[[str], None] | None = None,
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
        ``source_digest("moreau.problems.piston")``. Records made with another ``cache_key`` are
        not reused.
    dask_timeout : float
        Seconds to wait for a Dask scheduler given by its address.
    report : callable, optional
        Called with one line as each point finishes (``"point 3 of 21 done: e=0.1,
        D_mm=80.04"``, or ``failed``): progress where no terminal shows the bar.

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
    _check_executor(executor)
    points = grid_points(grid)
    keys = [point_key(p) for p in points]
    out_path = _out_path(out)
    name = _fun_name(fun)

    results: list[tuple[dict | None, str | None] | None] = [None] * len(points)
    record = None
    if out_path is not None:
        record, keys = _open_record(out_path, fun, cache_key, name, points, results, retry_errors)
    todo = [(i, points[i]) for i in range(len(points)) if results[i] is None]
    n_done = len(points) - len(todo)
    if n_done:
        assert record is not None  # points are only ever read back from a record
        log.info("%s: %d of %d points read from %s, %d to compute", name, n_done, len(points),
                 record.directory, len(todo))

    from tqdm import tqdm  # plain text bar: the same in a terminal and a notebook (no widgets needed)

    bar = tqdm(total=len(points), initial=n_done, desc=f"sweep {name.rsplit('.', 1)[-1]}", unit="point",
               disable=not progress, smoothing=0.1)
    on_done = _recorder(results, record, keys, points, bar, report)
    client, owned = None, False
    if record is not None:
        try:
            record.lock()  # released in the finally below
        except BaseException:
            bar.close()
            raise
    try:
        client, owned = (None, False) if not todo else _dask_client(executor, dask_timeout)
        _dispatch(executor, client, workers, fun, todo, on_done)
    except KeyboardInterrupt:
        _interrupted(pd, points, results, record, out_path)
        raise
    finally:
        bar.close()
        if owned and client is not None:
            client.close()
        if record is not None:
            record.unlock()

    df = _table(pd, points, results)
    if out_path is not None:
        _write_table(df, out_path)
        log.info("sweep table written to %s", out_path)
    return df


# -- the sweep's steps --------------------------------------------------------------------
def _check_executor(executor: Any) -> None:
    """Refuse an executor name that is neither a local one nor a scheduler address."""
    if isinstance(executor, str) and executor not in ("processes", "serial") and ":" not in executor:
        raise ValueError(f"executor must be 'processes', 'serial', a concurrent.futures.Executor, a "
                         f"dask.distributed Client or a scheduler address such as tcp://host:8786, got {executor!r}")


def _out_path(out: str | os.PathLike | None) -> str | None:
    """``out`` as a path (None: nothing on disk), its format checked and its writer present."""
    out_path = os.fspath(out) if out is not None else None
    if out_path is not None:
        fmt = _table_format(out_path)
        if fmt == "parquet":
            _require("pyarrow", "writing a .parquet table needs pyarrow: pip install pyarrow (or write .csv)")
    return out_path


def _open_record(out_path: str, fun: Callable[..., Mapping[str, Any]], cache_key: Any, name: str,
                 points: list[dict[str, Any]], results: list, retry_errors: bool) -> tuple[_Record, list[str]]:
    """The record of ``out_path`` and the points' keys in it; the finished points it holds
    are put into ``results`` (those that raised only without ``retry_errors``)."""
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
    return record, keys


def _recorder(results: list, record: _Record | None, keys: list[str], points: list[dict[str, Any]],
              bar: Any, report: Callable[[str], None] | None = None) -> Callable[..., None]:
    """The callback of a finished point: into ``results``, the record, the bar and ``report``
    (the point by the parameters that vary over the grid)."""
    varying = ([k for k in (points[0] if points else {}) if len({repr(p.get(k)) for p in points}) > 1]
               if report is not None else [])
    done = [sum(r is not None for r in results)]  # the points finished, those read back included

    def on_done(i: int, result: dict | None, error: str | None, quiet: bool = False) -> None:
        if results[i] is not None and quiet:
            return
        done[0] += results[i] is None
        results[i] = (result, error)
        if record is not None:
            record.write(keys[i], points[i], result, error)
        if error is not None:
            log.warning("point %s failed: %s", points[i], error)
        if not quiet:
            bar.update(1)
            if report is not None:
                what = ", ".join(f"{k}={_short(points[i][k])}" for k in varying)
                report(f"point {done[0]} of {len(points)} {'failed' if error is not None else 'done'}"
                       + (f": {what}" if what else ""))

    return on_done


def _short(value: Any) -> str:
    """A point's value in a line of progress: floats as %g."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def _dispatch(executor: Any, client: Any, workers: int | None, fun: Callable[..., Mapping[str, Any]],
              todo: list[tuple[int, dict[str, Any]]], on_done: Callable[..., None]) -> None:
    """Run the points ``todo`` where ``executor`` says (``client``: its Dask client, if any)."""
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


def _interrupted(pd: Any, points: list[dict[str, Any]], results: list, record: _Record | None,
                 out_path: str | None) -> None:
    """After an interrupt: say how far the sweep got and write the table of every point,
    ``"not computed"`` for the unfinished ones."""
    done = sum(r is not None for r in results)
    log.warning("sweep interrupted: %d of %d points finished%s", done, len(points),
                f" and recorded in {record.directory}; run it again to resume" if record else "")
    if out_path is not None:
        _write_table(_table(pd, points, results), out_path)
