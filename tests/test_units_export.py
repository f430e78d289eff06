"""Units metadata (scene → trajectory → file), the short repr, the xarray and pandas exports,
and the units every command-line option names."""

import argparse
import json
import math
import re
import sys
import zipfile

import numpy as np
import pytest

import moreau as mo
from moreau.cli import build_parser
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.problems.piston import PistonParameters, piston_model


@pytest.fixture(scope="module")
def ball():
    return mo.simulate(bouncing_ball(0.5), (0.0, 1.0), [1.0], [0.0], 1e-3)


@pytest.fixture(scope="module")
def piston():
    return piston_model().simulate(0.02, 1e-3)


def test_a_scene_declares_its_units_and_its_trajectories_carry_them(ball, tmp_path):
    u = ball.units
    assert (u["t"], u["q"], u["v"], u["gaps"], u["impulses"], u["energy"]) == ("s", ["m"], ["m/s"], ["m"], ["N s"], "J")
    assert ball.impacts.units is u and ball.impacts.row_names == ["floor"]
    back = mo.load(ball.save(tmp_path / "b.npz"))
    assert back.units == u and back.impacts.units["impulses"] == ["N s"]


def test_undeclared_units_are_empty_and_v_follows_q_and_t():
    scene = mo.Scene(mo.FunctionSystem(np.eye(2)), units={"t": "s", "q": ["m", "rad"]})
    assert scene.units["v"] == ["m/s", "rad/s"] and scene.units["gaps"] == [] and scene.units["energy"] == ""
    plain = mo.Scene(mo.FunctionSystem(np.eye(1)))
    assert plain.units["t"] == "" and plain.units["q"] == [""]


@pytest.mark.parametrize("units, message", [
    ({"time": "s"}, r"unknown key\(s\) \['time'\]"),
    ({"q": ["m"]}, r"units\['q'\] has 1 entries for 2 coordinates"),
    ({"t": 1.0}, r"units\['t'\] must be a string, got 1.0"),
    ({"scales": {"t": "fast"}}, r"units\['scales'\]\['t'\] must be a number, got 'fast'"),
])
def test_bad_units_are_refused_naming_the_key(units, message):
    with pytest.raises(ValueError, match=message):
        mo.Scene(mo.FunctionSystem(np.eye(2)), units=units)


def test_piston_trajectories_say_they_are_non_dimensional_and_give_the_scales(piston):
    p = PistonParameters()
    u = piston.units
    assert u["t"] == "1" and u["q"] == ["rad"] * 3 and u["impulses"] == ["1"] * 4
    assert "non-dimensional" in u["description"] and "tau = omega t" in u["description"]
    assert u["scales"]["t"] == pytest.approx(1.0 / p.omega) and u["si"]["t"] == "s"
    assert u["scales"]["gaps"] == pytest.approx(p.l1) and u["si"]["impulses"] == "N s"
    # energy scale: M11 ω² (the mass unit is M11 / l1²)
    assert u["scales"]["energy"] == pytest.approx(p.M11 * p.omega**2)


def test_files_written_before_units_existed_still_load(ball, tmp_path):
    path = ball.save(tmp_path / "new.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("meta")))
    del meta["units"], meta["scene"]["units"]
    old = tmp_path / "old.npz"
    np.savez_compressed(old, meta=np.array(json.dumps(meta)), **arrays)
    back = mo.load(old)
    assert back.units["t"] == "" and back.units["q"] == [""] and len(back.impacts) == len(ball.impacts)
    assert zipfile.is_zipfile(old)


def test_files_written_before_crossing_times_load_them_as_nan(ball, tmp_path):
    path = ball.save(tmp_path / "new.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files if k != "impacts_t_cross"}
    assert mo.load(path).impacts.t_cross.tolist() == ball.impacts.t_cross.tolist()
    old = tmp_path / "old.npz"
    np.savez_compressed(old, **arrays)
    back = mo.load(old)
    assert len(back.impacts) == len(ball.impacts) > 0 and np.isnan(back.impacts.t_cross).all()


def test_repr_is_short(ball, piston):
    text = repr(ball)
    assert text == "Trajectory('bouncing_ball': 1001 records, t = 0 to 1 s, 1 dof, 1 row, completed, 2 impacts)"
    assert "\n" not in repr(piston) and len(repr(piston)) < 160
    assert "(non-dimensional)" in repr(piston)
    assert re.fullmatch(r"ImpactLog\(2 impacts, t = 0\.452 to 0\.904 s, largest impulse [\d.]+ N s\)",
                        repr(ball.impacts))


def test_to_xarray_labels_dims_units_and_run(piston):
    xr = pytest.importorskip("xarray")
    ds = piston.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert dict(ds.sizes) == {"time": len(piston), "dof": 3, "row": 4}
    assert list(ds["row"].values) == piston.row_names
    np.testing.assert_array_equal(ds["q"].values, piston.q)
    np.testing.assert_array_equal(ds["impulses"].sel(row="cylinder[top-left]").values,
                                  piston.impulses[:, piston.row_index("cylinder[top-left]")])
    assert ds["q"].attrs["units"] == "rad" and ds["time"].attrs["units"] == "1"
    assert ds.attrs["scene"] == "piston" and ds.attrs["solver"] == piston.stats.solver
    assert ds.attrs["version"] == mo.__version__ and ds.attrs["n_impacts"] == len(piston.impacts)
    assert json.loads(ds.attrs["units"]) == piston.units
    assert json.loads(ds.attrs["scene_json"])["name"] == "piston"


def test_impacts_to_dataframe(ball):
    pd = pytest.importorskip("pandas")
    df = ball.impacts.to_dataframe()
    assert isinstance(df, pd.DataFrame) and len(df) == len(ball.impacts) == 2
    assert list(df.columns) == ["t", "t_cross", "step", "row", "row_name", "U_before", "U_after", "impulse",
                                "energy_lost"]
    assert (df["row_name"] == "floor").all()
    np.testing.assert_array_equal(df["impulse"].to_numpy(), ball.impacts.impulse)
    assert df.attrs["units"]["impulse"] == "N s" and df.attrs["units"]["U_before"] == "m/s"
    assert df.attrs["units"]["t_cross"] == df.attrs["units"]["t"] == "s"
    np.testing.assert_array_equal(df["t_cross"].to_numpy(), ball.impacts.t_cross)
    assert len(mo.ImpactLog().to_dataframe()) == 0


@pytest.mark.parametrize("module, call", [("xarray", "to_xarray"), ("pandas", "to_dataframe")])
def test_a_missing_export_dependency_names_the_extra(ball, monkeypatch, module, call):
    monkeypatch.setitem(sys.modules, module, None)
    target = ball if call == "to_xarray" else ball.impacts
    with pytest.raises(ImportError, match=re.escape(f'needs {module}, which is not installed: '
                                                    f'pip install "moreau-jean[export]"')):
        getattr(target, call)()


# the options that are quantities, and the units their help must name
UNIT = re.compile(r"\((dimensionless|m|mm|s|τ|steps|cycles of 720° crank angle)[;),:]")
QUANTITIES = {"e", "h0", "h", "t_end", "D", "cycles", "transient", "record_every"}


def test_every_command_option_that_is_a_quantity_names_its_unit():
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    checked = 0
    for name in ("ball", "piston", "sweep"):
        for action in sub.choices[name]._actions:
            if action.dest in QUANTITIES:
                assert UNIT.search(action.help or ""), f"moreau {name} {action.option_strings}: {action.help!r}"
                checked += 1
    assert checked == 5 + 6 + 3
    step = {name: next(a for a in sub.choices[name]._actions if a.dest == "h") for name in ("ball", "piston", "sweep")}
    assert step["ball"].metavar == "SECONDS" and "(s;" in step["ball"].help
    for name in ("piston", "sweep"):  # the piston's step is τ in both commands, described alike
        assert step[name].metavar == "TAU" and "non-dimensional crank-angle time τ = ω t" in step[name].help
    assert step["piston"].help.split("default")[0] == step["sweep"].help.split("default")[0]
    param = next(a for a in sub.choices["sweep"]._actions if a.dest == "param")
    assert "D (cylinder diameter, mm)" in param.help
    assert math.isclose(PistonParameters().omega, 2 * math.pi * 2000 / 60)
