"""A sweep never serves stale results (issue 11 E): a record is reused only for the same
point, function, bound arguments, source, moreau version and cache_key; every record read
back is checked; malformed ones are recomputed with a warning; one sweep at a time per out.
"""

from __future__ import annotations

import functools
import json
import os
import textwrap

import pytest

import moreau
import moreau.core.version
from moreau.cli import main
from moreau.sweeps import SweepLockedError, source_digest, sweep


def f(x: float, y: float = 0.0) -> dict:
    return {"v": x + y}


def g(x: float, y: float = 0.0) -> dict:
    return {"v": -x}


GRID = {"x": [1.0, 2.0]}


def run(fun, out, **kw):
    return sweep(fun, GRID, executor="serial", out=out, progress=False, **kw)["v"].tolist()


def parts(out) -> list:
    d = f"{out}.parts"
    return sorted(p for p in os.listdir(d) if p.endswith(".json") and p != "sweep.json")


def test_bound_arguments_of_partials_are_part_of_the_key(tmp_path):
    out = tmp_path / "t.csv"
    assert run(functools.partial(f, y=0), out) == [1.0, 2.0]
    assert run(functools.partial(f, y=100), out) == [101.0, 102.0]  # was: the y = 0 numbers
    assert run(functools.partial(functools.partial(f, y=0)), out) == [1.0, 2.0]  # same computation: reused
    assert len(parts(out)) == 4


def test_cache_key_and_version_are_part_of_the_key(tmp_path, monkeypatch):
    out = tmp_path / "t.csv"
    run(f, out, cache_key="model v1")
    n = len(parts(out))
    run(f, out, cache_key="model v1")
    assert len(parts(out)) == n  # reused
    run(f, out, cache_key="model v2")
    assert len(parts(out)) == 2 * n  # recomputed
    monkeypatch.setattr(moreau.core.version, "__version__", "0.0.0-other")
    run(f, out, cache_key="model v2")
    assert len(parts(out)) == 3 * n  # another version's records are not reused


def test_deleting_the_manifest_does_not_let_another_function_reuse_points(tmp_path):
    out = tmp_path / "t.csv"
    assert run(f, out) == [1.0, 2.0]
    os.remove(f"{out}.parts/sweep.json")
    assert run(g, out) == [-1.0, -2.0]


@pytest.mark.parametrize("content", [
    "[1, 2, 3]",                                   # valid JSON, not a record
    '{"result": {"v": 99}}',                       # no parameters, no format
    "{}",
    '"text"',
])
def test_malformed_parts_are_recomputed_with_a_warning(tmp_path, caplog, content):
    out = tmp_path / "t.csv"
    run(f, out)
    for name in parts(out):
        with open(f"{out}.parts/{name}", "w") as fh:
            fh.write(content)
    assert run(f, out) == [1.0, 2.0]  # was: AttributeError, or the stored numbers
    assert "the point is recomputed" in caplog.text


def test_a_part_is_checked_against_its_point(tmp_path, caplog):
    out = tmp_path / "t.csv"
    run(f, out)
    a, b = (f"{out}.parts/{n}" for n in parts(out))
    with open(a) as fh:
        rec_a = json.load(fh)
    with open(b) as fh:
        rec_b = json.load(fh)
    # swap the records: each file now holds the other point's parameters and result
    with open(a, "w") as fh:
        json.dump(rec_b, fh)
    with open(b, "w") as fh:
        json.dump(rec_a, fh)
    assert run(f, out) == [1.0, 2.0]
    assert "are not the point" in caplog.text
    # a record of this point with another function's identity is not reused either
    with open(a) as fh:
        rec = json.load(fh)
    rec["result"] = {"v": 1234.0}
    rec["fun"] = rec["fun"].replace('"cache_key": null', '"cache_key": "x"')
    with open(a, "w") as fh:
        json.dump(rec, fh)
    assert 1234.0 not in run(f, out)


def test_a_second_sweep_on_the_same_out_is_refused(tmp_path):
    out = tmp_path / "t.csv"
    run(f, out)
    lock = tmp_path / "t.csv.parts" / "sweep.lock"
    assert not lock.exists()  # released at the end
    lock.write_text(json.dumps({"pid": os.getpid(), "host": os.uname().nodename, "started": "now"}))
    with pytest.raises(SweepLockedError, match=rf"another sweep \(process {os.getpid()} on .*\) is writing to"):
        run(f, out)
    assert lock.exists()  # not ours to remove
    # a lock left by a process that no longer exists is taken over
    lock.write_text(json.dumps({"pid": 2**22 + 12345, "host": os.uname().nodename, "started": "then"}))
    assert run(f, out) == [1.0, 2.0]
    assert not lock.exists()


def test_a_locked_out_is_one_line_exit_2_in_the_command(tmp_path, capsys):
    out = tmp_path / "s.csv"
    (tmp_path / "s.csv.parts").mkdir()
    (tmp_path / "s.csv.parts" / "sweep.lock").write_text(json.dumps({"pid": os.getpid(), "host": os.uname().nodename}))
    assert main(["sweep", "piston", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("moreau sweep: error: another sweep (process")


def test_source_digest_follows_the_code(tmp_path, monkeypatch):
    pkg = tmp_path / "digestpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "params.py").write_text(textwrap.dedent("MASS = 1.0\n"))
    monkeypatch.syspath_prepend(str(tmp_path))
    before = source_digest("digestpkg")
    assert source_digest("digestpkg") == before
    (pkg / "params.py").write_text("MASS = 1.1\n")  # the piston's mass changed in the code
    assert source_digest("digestpkg") != before


def test_the_piston_command_keys_its_records_by_the_model_code(tmp_path, monkeypatch):
    import moreau.problems.piston.study as study

    out = tmp_path / "s.csv"
    argv = ["sweep", "piston", "--param", "e=0", "--cycles", "1", "--transient", "0", "--h", "1e-3",
            "--out", str(out), "--no-progress", "--workers", "1"]
    assert main(argv) == 0
    assert len(parts(out)) == 1
    assert main(argv) == 0
    assert len(parts(out)) == 1  # same code: reused
    monkeypatch.setattr(study, "piston_cache_key", lambda: "the model changed")
    assert main(argv) == 0
    assert len(parts(out)) == 2  # changed code: recomputed, not served from the old record
