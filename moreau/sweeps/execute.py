"""Running the points of a sweep: one point, and the executors (this process, a
concurrent.futures executor, the shared local process pool, Dask)."""

from __future__ import annotations

import concurrent.futures as cf
import logging
import uuid
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from moreau.sweeps.record import point_key

log = logging.getLogger("moreau.sweeps")

_ERROR = "error"


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
    (:func:`moreau.sweeps.pool.run_jobs`): a point starts only when a worker is free; on Ctrl-C
    or SIGTERM the running points are stopped, none starts, the workers end."""
    from moreau.sweeps.pool import run_jobs

    index = [i for i, _ in todo]
    state = {"stopping": False}

    def done(j: int, outcome, exc: BaseException | None) -> None:
        if isinstance(exc, KeyboardInterrupt):  # the point was interrupted: the sweep is
            if not state["stopping"]:
                state["stopping"] = True
                raise exc
            return
        if exc is not None:  # a worker that died is a WorkerDied here: the point's error
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


