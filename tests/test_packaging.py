"""What the distribution installs: every package listed, the problems inside moreau's
namespace, nothing top-level but ``moreau``; typed; licensed."""

import importlib
import pathlib
import subprocess
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_package_folder_is_listed():
    folders = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "moreau").rglob("__init__.py")}
    folders |= {".".join(("moreau",) + p.parent.relative_to(ROOT).parts)
                for p in (ROOT / "problems").rglob("__init__.py")}
    tool = PYPROJECT["tool"]["setuptools"]
    assert set(tool["packages"]) == folders
    assert tool["package-dir"] == {"moreau.problems": "problems"}


def test_metadata_names_the_distribution_license_and_entry_points():
    project = PYPROJECT["project"]
    assert project["name"] == "moreau-jean"
    assert project["license"] == "MIT" and (ROOT / "LICENSE").read_text().startswith("MIT License")
    assert (ROOT / "moreau" / "py.typed").exists()
    for name, target in project["entry-points"]["moreau.commands"].items():
        module, _, attr = target.partition(":")
        assert callable(getattr(importlib.import_module(module), attr)), name


def test_no_top_level_problems_package(tmp_path):
    """Run from a directory without a problems/ folder: only moreau.problems exists."""
    code = ("import importlib.util as u, moreau.problems.piston as p; "
            "print(u.find_spec('problems') is None, p.__name__)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", "moreau.problems.piston"]


def test_build_requirements_include_the_run_time_ones():
    """setup.py's build step imports the built package to compile the time loop into it:
    every run-time requirement is a build requirement too (the same bounds)."""
    build = set(PYPROJECT["build-system"]["requires"])
    assert set(PYPROJECT["project"]["dependencies"]) <= build
