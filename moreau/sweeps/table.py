"""The table of a sweep: rows in grid order, written atomically, read back."""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import uuid

import numpy as np

log = logging.getLogger("moreau.sweeps")

_ERROR = "error"


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
    tmp = f"{path}.{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp"
    try:
        if _table_format(path) == "parquet":
            try:
                df.to_parquet(tmp, index=False)
            except Exception as exc:  # noqa: BLE001 - pyarrow refuses mixed columns (lists and scalars, ...)
                log.warning("writing %s: %s; list columns are written as JSON text", path, exc)
                _json_columns(df).to_parquet(tmp, index=False)
        else:
            _json_columns(df).to_csv(tmp, index=False)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        if isinstance(exc, OSError) and (not exc.filename or exc.filename == tmp):  # name the table, not tmp
            raise OSError(exc.errno, exc.strerror or str(exc), path) from exc
        raise


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

