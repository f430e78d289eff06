"""moreau.load explains itself: versions, formats and fields named, checked at load time."""

import json

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import bouncing_ball


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    path = tmp_path_factory.mktemp("load") / "ball.npz"
    traj = oracle.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, backend="python", solver="exact")
    traj.save(path)
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def write(path, data, **meta_changes):
    data = dict(data)
    meta = json.loads(str(data["meta"]))
    meta.update(meta_changes)
    data["meta"] = np.array(json.dumps(meta))
    np.savez(path, **data)
    return path


def test_a_file_from_a_newer_version_loads_with_a_warning_naming_both(saved, tmp_path):
    path = write(tmp_path / "newer.npz", saved, version="99.0.0")
    with pytest.warns(UserWarning, match=rf"written by moreau 99\.0\.0, newer than this moreau {mo.__version__}"):
        traj = mo.load(path)
    assert len(traj) == saved["t"].shape[0]


def test_a_newer_file_format_is_refused_naming_it(saved, tmp_path):
    path = write(tmp_path / "format.npz", saved, format=99, version="99.0.0")
    with pytest.raises(ValueError, match=r"file format 99, written by moreau 99\.0\.0; this moreau reads format 1"):
        mo.load(path)


def test_missing_and_inconsistent_fields_are_named(saved, tmp_path):
    data = {k: v for k, v in saved.items() if k != "meta"}
    np.savez(tmp_path / "nometa.npz", **data)
    with pytest.raises(ValueError, match="has no 'meta' field"):
        mo.load(tmp_path / "nometa.npz")
    short = dict(saved, impacts_U_after=saved["impacts_U_after"][:-1])
    np.savez(tmp_path / "short.npz", **short)
    with pytest.raises(ValueError, match="short.npz' is inconsistent: impacts_U_after has"):
        mo.load(tmp_path / "short.npz")
    energy = dict(saved, kinetic_energy=saved["kinetic_energy"][:3])
    np.savez(tmp_path / "energy.npz", **energy)
    with pytest.raises(ValueError, match="inconsistent: kinetic_energy has 3 records"):
        mo.load(tmp_path / "energy.npz")


@pytest.fixture(scope="module")
def saved_friction(tmp_path_factory):
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    path = tmp_path_factory.mktemp("load") / "woodpecker.npz"
    q0, v0 = GLOCKER_STATE
    mo.simulate(woodpecker(), (0.0, 0.02), q0, v0, 1e-4, progress=False).save(path)
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("change, field", [
    ({"t": "nan"}, "t must be a non-empty, finite"),
    ({"meta": {"h": -1e-3}}, "h must be a positive number, got -0.001"),
    ({"meta": {"status": "splendid"}}, "status 'splendid' is not one of"),
    ({"meta": {"row_names": ["floor", "wall"]}}, "gaps has shape"),
    ({"meta": {"record_every": 0}}, "record_every must be a positive integer"),
])
def test_a_file_no_run_could_write_is_refused_naming_the_field(saved, tmp_path, change, field):
    data = dict(saved)
    if change.get("t") == "nan":
        data["t"] = saved["t"].copy()
        data["t"][5] = np.nan
    path = write(tmp_path / "bad.npz", data, **change.get("meta", {}))
    with pytest.raises(ValueError, match=field):
        mo.load(path)


def test_inconsistent_friction_fields_are_refused_naming_them(saved, saved_friction, tmp_path):
    assert mo.load(write(tmp_path / "good.npz", saved_friction)).tangential_impulses is not None
    two = dict(saved_friction, tangential_impulses=np.repeat(saved_friction["tangential_impulses"], 2, axis=1))
    with pytest.raises(ValueError, match="tangential_impulses has shape"):
        mo.load(write(tmp_path / "two.npz", two))
    missing = {k: v for k, v in saved_friction.items() if k != "sticking"}
    with pytest.raises(ValueError, match=r"friction fields .* without \['sticking'\]"):
        mo.load(write(tmp_path / "missing.npz", missing))
    floats = dict(saved_friction, sticking=saved_friction["sticking"].astype(float))
    with pytest.raises(ValueError, match="sticking must be boolean"):
        mo.load(write(tmp_path / "floats.npz", floats))
    meta = json.loads(str(saved["meta"]))
    ledger = write(tmp_path / "ledger.npz", saved, work=dict(meta["work"], friction=-1.0))
    with pytest.raises(ValueError, match=r"work\['friction'\] without the friction fields"):
        mo.load(ledger)
