"""The API reference lists the public API: every name exported by moreau's public
modules has an autosummary entry in docs/api/*.rst (the build itself, with warnings as
errors, runs in .ci/run; a new export without an entry would be missing silently)."""

import importlib
import pathlib
import re

import pytest

API = pathlib.Path(__file__).resolve().parents[1] / "docs" / "api"
PUBLIC = ["moreau", "moreau.model.chain", "moreau.dynamics", "moreau.dynamics.benchmarks", "moreau.sweeps",
          "moreau.results.diagnostics", "moreau.results.plotting", "moreau.contact.testing"]
NOT_OBJECTS = {"__version__", "diagnostics"}  # a string and a module, not API objects


def autosummary_entries() -> set[str]:
    """Last dotted component of every entry of every autosummary table."""
    names = set()
    for rst in API.glob("*.rst"):
        for block in re.findall(r"\.\. autosummary::\n((?:   .*\n|\n)+)", rst.read_text()):
            for line in block.splitlines():
                line = line.strip()
                if line and not line.startswith(":"):
                    names.add(line.rsplit(".", 1)[-1])
    return names


@pytest.mark.parametrize("module", PUBLIC)
def test_every_public_name_is_in_the_api_reference(module):
    exported = set(importlib.import_module(module).__all__) - NOT_OBJECTS
    missing = sorted(exported - autosummary_entries())
    assert not missing, f"{module}: add {missing} to an autosummary table in docs/api/"
