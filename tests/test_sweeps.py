"""Parameter sweeps (issue 7): grid order, process pool = Dask, resume after an interrupt,
failing points recorded, the ``moreau sweep`` command, the piston study functions."""

from __future__ import annotations

import functools
import math
import os
import sys
import time
import uuid

import numpy as np
import pandas as pd
import pytest

from moreau.cli import main
from moreau.sweeps import grid_points, point_key, read_table, sweep


# -- cheap pure functions (module level: picklable by reference) ---------------------------
def cheap(a: float, b: int, tag: str = "x") -> dict:
    """A pure function with a float, an int, a string and a list among its results."""
    return {"s": a + b, "p": math.sin(a * b) * math.exp(-a), "label": f"{tag}{b}",
            "seq": [a, b, a * b], "big": np.float64(a) ** 2}


FLAKY = {"fail": True}  # module state, not an argument: a changed argument is another computation


def flaky(a: float, b: int, fail: bool = True) -> dict:
    """Raises for one point (when ``fail`` and ``FLAKY["fail"]``)."""
    if fail and FLAKY["fail"] and a == 0.5 and b == 2:
        raise ValueError(f"no result at a={a}, b={b}")
    return cheap(a, b)


def counted(a: float, b: int, calls_dir: str) -> dict:
    """``cheap`` that leaves one file per call in ``calls_dir/<a>_<b>/`` (counts calls across
    processes) and raises KeyboardInterrupt at the point named in ``calls_dir/interrupt_at``
    if that file exists (a file, not an argument: the interrupted and the resumed sweep
    must be the same computation)."""
    d = os.path.join(calls_dir, f"{a}_{b}")
    os.makedirs(d, exist_ok=True)
    open(os.path.join(d, uuid.uuid4().hex), "w").close()
    trigger = os.path.join(calls_dir, "interrupt_at")
    if os.path.exists(trigger) and open(trigger).read() == f"{a}_{b}":
        _stamp(os.path.join(calls_dir, "interrupted"))
        raise KeyboardInterrupt
    out = cheap(a, b)
    os.makedirs(os.path.join(calls_dir, "finished"), exist_ok=True)
    _stamp(os.path.join(calls_dir, "finished", f"{a}_{b}"))
    return out


def _stamp(path: str) -> None:
    """Write the time (a system-wide clock) to ``path`` through a unique name and a rename: a
    worker stopped mid-write by the interrupt leaves no empty stamp."""
    tmp = f"{path}.{uuid.uuid4().hex}.tmp"
    with open(tmp, "w") as f:
        f.write(repr(time.monotonic()))
    os.replace(tmp, path)


def _with_tuple(a: int, t: tuple) -> dict:
    return {"n": a * len(t)}


def calls(calls_dir) -> dict:
    """Calls made per point (``counted``'s files)."""
    if not calls_dir.exists():
        return {}
    return {p.name: len(list(p.iterdir())) for p in calls_dir.iterdir() if p.is_dir() and p.name != "finished"}


GRID = {"a": np.linspace(0.0, 1.0, 5), "b": [1, 2, 3]}


# -- grids --------------------------------------------------------------------------------
def test_grid_is_cartesian_in_key_order_and_points_are_identified_by_value():
    pts = grid_points({"a": [1.0, 2.0], "b": 7, "c": ["u", "v"]})
    assert pts == [{"a": 1.0, "b": 7, "c": "u"}, {"a": 1.0, "b": 7, "c": "v"},
                   {"a": 2.0, "b": 7, "c": "u"}, {"a": 2.0, "b": 7, "c": "v"}]
    assert type(grid_points({"a": np.linspace(0, 1, 3)})[1]["a"]) is float
    assert point_key({"a": 0.1, "b": 1}) == point_key({"b": 1.0, "a": np.float64(0.1) + 1e-17})
    assert point_key({"a": 0.1}) != point_key({"a": 0.1001})
    with pytest.raises(ValueError, match="same point"):
        grid_points([{"a": 1}, {"a": 1.0}])
    with pytest.raises(ValueError, match="no points"):
        grid_points({"a": []})
    with pytest.raises(ValueError, match="grid values"):
        grid_points([{"a": [1, 2]}])
    # a tuple is one value (e.g. a set of angles), part of the point's identity
    pts = grid_points({"a": [1, 2], "t": (60.0, np.float64(420.0))})
    assert pts == [{"a": 1, "t": (60.0, 420.0)}, {"a": 2, "t": (60.0, 420.0)}]
    assert point_key(pts[0]) != point_key({"a": 1, "t": (60.0, 421.0)})
    assert sweep(_with_tuple, pts, executor="serial", progress=False)["t"].tolist() == [[60.0, 420.0]] * 2


def test_rows_follow_the_grid_with_params_results_and_error_columns():
    df = sweep(cheap, GRID, executor="serial", progress=False)
    assert list(df.columns) == ["a", "b", "s", "p", "label", "seq", "big", "error"]
    assert len(df) == 15 and df["error"].isna().all()
    assert df[["a", "b"]].values.tolist() == [[a, b] for a in GRID["a"] for b in GRID["b"]]
    assert df["seq"].iloc[4] == [0.25, 2, 0.5]
    assert type(df["big"].iloc[0]) in (float, np.float64)


def test_failing_point_records_its_error_and_the_sweep_completes(tmp_path):
    out = tmp_path / "flaky.csv"
    df = sweep(flaky, GRID, workers=2, out=out, progress=False)
    bad = df[df["error"].notna()]
    assert len(df) == 15 and len(bad) == 1
    assert bad[["a", "b"]].values.tolist() == [[0.5, 2]]
    assert bad["error"].iloc[0] == "ValueError: no result at a=0.5, b=2"
    assert math.isnan(bad["s"].iloc[0])
    good = df[df["error"].isna()].reset_index(drop=True)
    ref = sweep(cheap, GRID, executor="serial", progress=False)
    ref = ref[~((ref.a == 0.5) & (ref.b == 2))].reset_index(drop=True)
    pd.testing.assert_frame_equal(good, ref)
    # the table on disk holds the same rows, the list column JSON-decoded
    back = read_table(out)
    assert back["error"].notna().sum() == 1 and back["seq"].iloc[0] == df["seq"].iloc[0]
    # a failed point is a finished one (not recomputed); retry_errors recomputes it
    FLAKY["fail"] = False
    try:
        assert sweep(flaky, GRID, executor="serial", out=out, progress=False)["error"].notna().sum() == 1
        df2 = sweep(flaky, GRID, executor="serial", out=out, progress=False, retry_errors=True)
    finally:
        FLAKY["fail"] = True
    pd.testing.assert_frame_equal(df2, sweep(cheap, GRID, executor="serial", progress=False))
    # another bound argument is another computation: nothing reused (issue 11 E)
    fixed = functools.partial(flaky, fail=False)
    assert sweep(fixed, GRID, executor="serial", out=out, progress=False)["error"].notna().sum() == 0


def test_process_pool_and_dask_give_identical_rows(tmp_path):
    distributed = pytest.importorskip("distributed")
    ref = sweep(flaky, GRID, executor="serial", progress=False)
    pool = sweep(flaky, GRID, executor="processes", workers=2, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        on_dask = sweep(flaky, GRID, executor=client, out=tmp_path / "dask.parquet", progress=False)
        by_address = sweep(flaky, GRID, executor=cluster.scheduler_address, progress=False)
        # the command, on the same cluster
        assert main(["sweep", "piston", "--param", "e=0,0.9", "--cycles", "1", "--transient", "0", "--h", "1e-3",
                     "--out", str(tmp_path / "cli.csv"), "--dask", cluster.scheduler_address, "--no-progress"]) == 0
    assert read_table(tmp_path / "cli.csv")["error"].isna().all()
    pd.testing.assert_frame_equal(pool, ref)
    pd.testing.assert_frame_equal(on_dask, ref)
    pd.testing.assert_frame_equal(by_address, ref)
    back = read_table(tmp_path / "dask.parquet")
    pd.testing.assert_frame_equal(back, ref)


@pytest.mark.parametrize("executor", ["serial", "processes"])
def test_interrupted_sweep_resumes_without_recomputing_finished_points(tmp_path, executor):
    calls_dir = tmp_path / "calls"
    out = tmp_path / "sweep.parquet"
    fun = functools.partial(counted, calls_dir=str(calls_dir))
    full = sweep(functools.partial(counted, calls_dir=str(tmp_path / "ref_calls")), GRID, executor="serial",
                 progress=False)
    calls_dir.mkdir()
    (calls_dir / "interrupt_at").write_text("0.5_2")
    with pytest.raises(KeyboardInterrupt):
        sweep(fun, GRID, executor=executor, workers=2, out=out, progress=False)
    (calls_dir / "interrupt_at").unlink()
    parts = [p for p in (tmp_path / "sweep.parquet.parts").iterdir() if p.name != "sweep.json"]
    before = calls(calls_dir)
    # every point that finished before the interrupt is kept (serially: the 7 before
    # (0.5, 2); with two workers, whatever the other had finished by then); not all
    t_stop = float((calls_dir / "interrupted").read_text())
    stamps = [p for p in (calls_dir / "finished").iterdir() if p.suffix != ".tmp"]
    kept_before = [p for p in stamps if float(p.read_text()) < t_stop]
    assert len(kept_before) <= len(parts) < 15
    if executor == "serial":
        assert len(parts) == 7
    # the table lists every point: the finished ones, and the others as not computed
    table = read_table(out)
    assert len(table) == 15 and (table["error"] == "not computed").sum() == 15 - len(parts)

    resumed = sweep(fun, GRID, executor=executor, workers=2, out=out, progress=False)
    after = calls(calls_dir)
    recomputed = {k for k in after if after[k] > before.get(k, 0)}
    assert len(recomputed) == 15 - len(parts)           # only the unfinished points ran again
    assert all(after[k] == before[k] for k in before if k not in recomputed)
    pd.testing.assert_frame_equal(resumed, full)
    pd.testing.assert_frame_equal(read_table(out), full)
    # a third run computes nothing
    sweep(fun, GRID, executor=executor, workers=2, out=out, progress=False)
    assert calls(calls_dir) == after


def test_missing_dask_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ImportError, match=r"pip install 'moreau\[dask\]'"):
        sweep(cheap, GRID, executor="tcp://127.0.0.1:1", progress=False)
    with pytest.raises(ValueError, match="executor must be"):
        sweep(cheap, GRID, executor="threads", progress=False)


def test_out_of_another_function_is_refused_a_changed_one_warned(tmp_path, caplog):
    out = tmp_path / "t.csv"
    sweep(cheap, {"a": [1.0], "b": [1]}, executor="serial", out=out, progress=False)
    with pytest.raises(ValueError, match="computed by .*cheap"):
        sweep(flaky, {"a": [1.0], "b": [1]}, executor="serial", out=out, progress=False)
    manifest = tmp_path / "t.csv.parts" / "sweep.json"
    manifest.write_text(manifest.read_text().replace('"source": "', '"source": "0'))
    sweep(cheap, {"a": [1.0], "b": [1]}, executor="serial", out=out, progress=False)
    assert "has changed" in caplog.text and "recomputed" in caplog.text
    with pytest.raises(ValueError, match=".parquet or .csv"):
        sweep(cheap, {"a": [1.0], "b": [1]}, executor="serial", out=tmp_path / "t.txt", progress=False)


def test_bad_return_values_are_errors_not_crashes():
    df = sweep(_returns_bad, {"k": [0, 1, 2, 3]}, executor="serial", progress=False)
    assert df["error"].tolist() == [
        None,
        "TypeError: the sweep function must return a dict, got list",
        "ValueError: the result's keys ['k'] clash with the parameters or the error column",
        "TypeError: returned a value of type object (<object object at" + df["error"][3].split("at", 1)[1],
    ]


def _ragged(k: int) -> dict:
    return {"v": [k, k + 1] if k % 2 else float(k), "w": k}


@pytest.mark.parametrize("suffix", ["parquet", "csv"])
def test_ragged_columns_round_trip_through_the_table(tmp_path, suffix):
    out = tmp_path / f"r.{suffix}"
    df = sweep(_ragged, {"k": [0, 1, 2, 3]}, executor="serial", out=out, progress=False)
    assert df["v"].tolist() == [0.0, [1, 2], 2.0, [3, 4]]
    back = read_table(out)
    assert back["v"].tolist() == [0.0, [1, 2], 2.0, [3, 4]] and back["w"].tolist() == [0, 1, 2, 3]


def _returns_bad(k: int):
    return [{"v": 1}, [1], {"k": 3}, {"v": object()}][k] if k else {"v": 1}


# -- the piston study functions ------------------------------------------------------------
def test_piston_point_and_bifurcation_samples_at_coarse_step():
    from moreau.problems.piston.study import bifurcation_samples, piston_point

    r = piston_point(0.0, 80.04, cycles=1, transient=1, h=1e-3, section_deg=(60.0, 420.0))
    assert r["clearance_um"] == pytest.approx(40.0)
    assert r["side_changes"] == [6]  # the paper's six stages, even at this coarse step
    assert r["impacts_mean"] >= r["slaps_mean"] >= r["side_changes_mean"] and r["energy_lost_J_mean"] > 0
    assert r["mean_speed_rpm"] == pytest.approx(2000, rel=0.02) and "rpm" not in r
    # settled speed at h = 1e-3: 1988.6 rpm by the long runs of benchmarks/steady_speed.py
    assert r["settled_speed_rpm"] == pytest.approx(1988.6, abs=0.4)
    assert 0 <= r["flight_deg_mean"] < 720 and r["max_penetration_ratio"] < 0.01  # drift control
    assert r["cycle"] == [1, 1] and r["angle_deg"] == [60.0, 420.0] and abs(r["x_O3"][0]) == pytest.approx(1, abs=0.05)
    b = bifurcation_samples(0.0, 80.04, cycles=1, transient=0, h=1e-3, angle_deg=[30.0, 400.0])
    assert b["cycle"] == [0, 0] and b["angle_deg"] == [30.0, 400.0]
    assert np.all(np.abs(b["x_O3"]) < 1.5) and len(b["side_changes"]) == 1
    with pytest.raises(ValueError, match="angle_deg"):
        bifurcation_samples(0.0, angle_deg=720.0, cycles=1, h=1e-3)


def test_piston_sweep_rows_are_deterministic_across_executors():
    from moreau.problems.piston.study import piston_point

    grid = {"e": [0.0, 0.9], "D_mm": 80.04, "cycles": 1, "transient": 0, "h": 1e-3}
    a = sweep(piston_point, grid, executor="serial", progress=False).drop(columns="wall_time_s")
    b = sweep(piston_point, grid, workers=2, progress=False).drop(columns="wall_time_s")
    pd.testing.assert_frame_equal(a, b)
    assert a["error"].isna().all()


# -- the command ---------------------------------------------------------------------------
def test_sweep_command_writes_the_table_and_resumes(tmp_path, capsys):
    out = tmp_path / "s.csv"
    argv = ["sweep", "piston", "--param", "e=0:0.9:2", "--param", "D=80.04", "--cycles", "1",
            "--transient", "0", "--h", "1e-3", "--out", str(out), "--no-progress", "--workers", "2"]
    assert main(argv) == 0
    df = read_table(out)
    assert df["e"].tolist() == [0.0, 0.9] and df["D_mm"].tolist() == [80.04, 80.04]
    assert df["error"].isna().all() and "table written" in capsys.readouterr().out
    mtimes = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "s.csv.parts").iterdir()}
    assert main(argv) == 0  # resumed: nothing recomputed
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "s.csv.parts").iterdir()} == mtimes


def test_sweep_command_sweeps_the_skirt_friction(tmp_path, capsys):
    # mu on the grid: the frictionless point loses nothing to friction, the rough one does
    out = tmp_path / "mu.csv"
    # (pytest's captured stderr is no terminal: a line per finished point, no bar)
    assert main(["sweep", "piston", "--param", "mu=0,0.05", "--cycles", "1", "--transient", "0", "--h", "1e-3",
                 "--out", str(out), "--workers", "1"]) == 0
    df = read_table(out)
    assert df["mu"].tolist() == [0.0, 0.05] and df["error"].isna().all()
    assert df["friction_loss_J_mean"].iloc[0] == 0.0 and df["friction_loss_J_mean"].iloc[1] > 0.0
    said = capsys.readouterr()
    assert "friction_loss_J_mean" in said.out and "\r" not in said.err and "point/s" not in said.err
    assert "point 1 of 2 done: mu=0\n" in said.out and "point 2 of 2 done: mu=0.05\n" in said.out
    records = sorted(p for p in (out.parent / "mu.csv.parts").iterdir() if p.name != "sweep.json")
    assert len(records) == 2
    records[0].unlink()  # one point to compute again
    assert main(["sweep", "piston", "--param", "mu=0,0.05", "--cycles", "1", "--transient", "0", "--h", "1e-3",
                 "--out", str(out), "--workers", "1"]) == 0
    assert capsys.readouterr().out.count("2 of 2 done") == 1  # one point read back, the other counted after it


@pytest.mark.parametrize("param, message", [
    ("mu=-0.1", "-0.1 is outside [0, 10]"),
    ("e=0:1", "e=0:1: give start:stop:num"),
    ("e=0:1:x", "give start:stop:num"),
    ("e=1.5", "1.5 is outside [0, 1]"),
    ("D=79", "79 is outside (80, 100]"),
    ("q=1", "unknown parameter 'q'; choose from e, D"),
    ("e", "expected NAME=VALUES"),
])
def test_sweep_bad_param_is_one_line_exit_2(tmp_path, param, message, cli_error):
    line = cli_error("sweep", "piston", "--param", param, "--out", str(tmp_path / "x.csv"))
    assert line.startswith("moreau sweep: error: argument --param: ") and message in line


def test_sweep_param_given_twice_or_bad_address_is_exit_2(tmp_path, capsys):
    assert main(["sweep", "piston", "--param", "e=0", "--param", "e=1", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--param e given twice" in capsys.readouterr().err
    assert main(["sweep", "piston", "--dask", "nowhere", "--out", str(tmp_path / "x.csv")]) == 2
    assert "not a scheduler address" in capsys.readouterr().err


def test_the_piston_study_reports_the_penetration_of_every_step():
    """The sweep summary's ``max_penetration_ratio`` is the largest penetration over every
    step (what ``moreau piston`` reports), not over the recorded states (every 7th step at
    h = 3e-4), which miss the impact steps: 1.0e-4 of the clearance recorded (a pressed
    corner, up to the drift control's tolerance of 1e-4) against 8.6e-4 per step (e = 0,
    the engine's drift control, one cycle; 1.5e-5 recorded with an exact projection). A
    summary of the recorded states would equal ``recorded``."""
    from moreau.problems.piston.analysis import cycle_figures, max_penetration_ratio
    from moreau.problems.piston.study import _run, piston_point

    r = piston_point(0.0, 80.04, cycles=1, transient=0, h=3e-4)
    traj, params = _run(0.0, 80.04, 1, 3e-4, "exact", True)  # the same run
    assert r["max_penetration_ratio"] == max_penetration_ratio(traj, params) > 0
    recorded = max(c.max_penetration for c in cycle_figures(traj, params))
    assert r["max_penetration_ratio"] > 2 * recorded
