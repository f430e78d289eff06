"""Every notebook in notebooks/ (jupytext percent scripts) executes without a cell error at
reduced size (MOREAU_NOTEBOOK_SCALE=small) and saves its figures as PNG.

The full-size restitution notebook (21 values of e × (1 transient + 5) cycles at
h = 3e-4 with drift control) took 321 s on the 2 shared cores; it is measured, not
asserted, by the slow test below when MOREAU_FULL_NOTEBOOKS=1 (``MOREAU_FULL_NOTEBOOKS=1
python -m pytest -m slow tests/test_notebooks.py -s``), into a temporary folder.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
NOTEBOOKS = sorted(p for p in NOTEBOOK_DIR.glob("*.py") if "# %%" in p.read_text())


def execute(path: Path, env: dict[str, str], timeout: int = 600) -> tuple[float, object]:
    """Execute a jupytext script with nbclient in a fresh kernel; (wall time s, notebook)."""
    jupytext = pytest.importorskip("jupytext")
    nbclient = pytest.importorskip("nbclient")
    nb = jupytext.read(path)
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)  # the kernel inherits the environment
    try:
        client = nbclient.NotebookClient(nb, timeout=timeout, kernel_name="python3",
                                         resources={"metadata": {"path": str(path.parent)}})
        t0 = time.perf_counter()
        client.execute()  # CellExecutionError on the first failing cell
        return time.perf_counter() - t0, nb
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def test_there_are_notebooks():
    assert {p.stem for p in NOTEBOOKS} >= {"restitution", "clearance", "paper_figures", "triple_pendulum"}


#: the longest runs at reduced size (12-15 s each, 2026-11-26): in the slow suite, which CI
#: runs too (and CI's documentation build executes every notebook at reduced size again)
SLOW_NOTEBOOKS = {"clearance", "paper_figures", "restitution", "triple_pendulum"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.stem in SLOW_NOTEBOOKS else p
                                  for p in NOTEBOOKS], ids=lambda p: p.stem)
def test_notebook_runs_at_reduced_size(path, tmp_path):
    figures = tmp_path / "figures"
    wall, nb = execute(path, {
        "MOREAU_NOTEBOOK_SCALE": "small",
        "MOREAU_FIGURES_DIR": str(figures),
        "MOREAU_NOTEBOOK_DATA": str(tmp_path / "data"),
        "MPLBACKEND": "Agg",
    })
    print(f"{path.name}: {wall:.1f} s at reduced size")
    pngs = sorted(figures.glob("*.png"))
    assert pngs, "the notebook saved no figure"
    assert all(p.stat().st_size > 10_000 for p in pngs)
    md = [c for c in nb.cells if c.cell_type == "markdown"]
    assert len(md) >= 3, "each notebook explains what is studied, seen, and what it means"


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("MOREAU_FULL_NOTEBOOKS") != "1", reason="set MOREAU_FULL_NOTEBOOKS=1")
def test_restitution_notebook_full_size_is_measured(tmp_path, record_property):
    wall, _ = execute(NOTEBOOK_DIR / "restitution.py", {
        "MOREAU_NOTEBOOK_SCALE": "full",
        "MOREAU_FIGURES_DIR": str(tmp_path / "figures"),
        "MOREAU_NOTEBOOK_DATA": str(tmp_path / "data"),
        "MPLBACKEND": "Agg",
    }, timeout=7200)
    record_property("restitution_full_wall_s", round(wall, 1))
    print(f"restitution.py at full size: {wall:.0f} s")
