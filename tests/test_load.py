"""moreau.load explains itself: versions, formats and fields named, checked at load time."""

import json

import numpy as np
import pytest

import moreau as mo
from moreau.problems.bouncing_ball import bouncing_ball


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    path = tmp_path_factory.mktemp("load") / "ball.npz"
    traj = mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3, backend="python", solver="exact")
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
