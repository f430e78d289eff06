"""Machine code built with the package (issue 23): a wheel carries the compiled time loop in
``moreau/_prebuilt`` (setup.py's build step); on first use it is copied into an empty numba
cache and loaded, not compiled. An editable checkout has no ``_prebuilt``, so these tests
export the suite's own compiled code and seed a new cache from it, as an installed wheel does."""

import os
import subprocess
import sys

import pytest

from moreau.compiled.cache import ensure_compiled
from moreau.core import jitcache

SEEDED_RUN = """
import glob, os, sys
import moreau.core.jitcache as j
j.PREBUILT = sys.argv[1]
print("seeded", j.seed())
from moreau.compiled.cache import ensure_compiled
from moreau.compiled.loop import _run_chunk as run_chunk
ensure_compiled("plain")
print("hits", sum(run_chunk.stats.cache_hits.values()), "misses", sum(run_chunk.stats.cache_misses.values()))
"""


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """The suite's compiled loop, exported as the build step exports it."""
    ensure_compiled()
    out = tmp_path_factory.mktemp("prebuilt")
    n = jitcache.export(str(out))
    assert n >= 2 and (out / "moreau-jit.digest").read_text() == jitcache.source_digest()
    assert list((out / "compiled").glob("loop._run_chunk-*.nbi"))
    return out


def _run(prebuilt, cache) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-c", SEEDED_RUN, str(prebuilt)], capture_output=True, text=True,
                          env=env, cwd=cache, timeout=600)


def test_prebuilt_code_seeds_an_empty_cache_and_loads_without_compiling(exported, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    r = _run(exported, cache)
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.splitlines())
    assert int(lines["seeded"]) >= 2
    assert lines["hits"].split() == ["1", "misses", "0"]  # loaded from the seeded cache, not compiled
    assert "compiling the time loop" not in r.stderr


def test_prebuilt_code_of_another_source_is_not_used(exported, tmp_path, monkeypatch):
    """A digest that is not this source's (another version of moreau or numba): nothing is
    copied, and the run compiles, saying so."""
    stale = tmp_path / "stale"
    stale.mkdir()
    for p in exported.rglob("*"):
        if p.is_file():
            target = stale / p.relative_to(exported)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(p.read_bytes())
    (stale / "moreau-jit.digest").write_text("0" * 64)
    monkeypatch.setattr(jitcache, "PREBUILT", str(stale))
    assert jitcache.seed() == 0
    monkeypatch.setattr(jitcache, "PREBUILT", str(tmp_path / "absent"))
    assert jitcache.seed() == 0
