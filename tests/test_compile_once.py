"""The compiled loop is compiled once per machine and version, and a user's scene
compiles only its own functions."""

import os
import subprocess
import sys
import textwrap
import time

import numba
import numpy as np
import pytest

import moreau as mo
from moreau.compiled import loop
from moreau.compiled.lowering import lower
from moreau.compiled.variants import VARIANTS

_PROBE = textwrap.dedent("""
    from moreau.compiled import loop
    from moreau.compiled.cache import ensure_compiled
    ensure_compiled("plain")
    st = loop._run_chunk.stats
    print(sum(st.cache_misses.values()), sum(st.cache_hits.values()))
""")


@pytest.mark.slow  # a full compile of the loop into its own cache (90-120 s on 2 cores, 2026-11-26)
def test_two_processes_started_together_on_an_empty_cache_compile_once(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=os.getcwd())
    procs = [subprocess.Popen([sys.executable, "-c", _PROBE], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-2000:]
    counts = sorted(tuple(int(x) for x in out.split()) for out, _ in outs)
    assert counts == [(0, 1), (1, 0)]  # one compiled (and said so), the other waited and loaded
    said = [err for _, err in outs if "compiling the time loop for the plain midpoint step once" in err]
    assert len(said) == 1


def test_scenes_with_other_user_callables_reuse_the_loop_of_a_built_in_scene():
    from moreau.problems.bouncing_ball import bouncing_ball
    from tests.test_compiled import user_scene

    ball = bouncing_ball(0.5)
    mo.simulate(ball, (0.0, 0.01), [1.0], [0.0], 1e-3)
    before = len(loop._run_chunk.overloads)

    @numba.njit
    def force(t, q, v):
        return np.array([-0.1 * v[0], -9.0])

    @numba.njit
    def gap(q):
        return np.array([q[1] - 0.2 * q[0]])

    @numba.njit
    def jac(q):
        return np.array([[-0.2, 1.0]])

    other = mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.FunctionForce(force)],
                     [mo.Contact(mo.FunctionBarrier(gap, jac), 0.5)])
    for scene in (user_scene(), other):
        traj = mo.simulate(scene, (0.0, 0.5), [0.0, 1.0], [1.0, 0.0], 1e-3, backend="compiled")
        assert traj.completed and traj.stats.backend == "compiled"
    assert len(loop._run_chunk.overloads) == before  # no specialization per scene: the ball's variant
    assert lower(other).user.addresses.tolist()[:2] == [0, 0]  # no user mass, no bias: empty slots


def _cache_holding_the_loop(tmp_path) -> dict:
    """An environment whose empty ``NUMBA_CACHE_DIR`` holds this session's compiled loop
    (``jitcache.export`` here, ``jitcache.seed`` in a new process): a test that needs a
    filled cache of its own does not compile the loop for it."""
    from moreau.core import jitcache

    mo.ensure_compiled()
    staged = tmp_path / "staged"
    assert jitcache.export(str(staged)) > 0
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=os.getcwd())
    fill = f"from moreau.core import jitcache as j; j.ensure_fresh(); assert j.seed(prebuilt={str(staged)!r}) > 0"
    subprocess.run([sys.executable, "-c", fill], env=env, check=True, timeout=120)
    return env


@pytest.mark.slow  # one compile into its own cache (about 100 s, 2026-11-26)
def test_a_corrupt_cache_warns_and_the_run_works(tmp_path):
    env = _cache_holding_the_loop(tmp_path)
    run = [sys.executable, "-c", _PROBE]
    out = subprocess.run(run, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["0", "1"]  # the filled cache is loaded
    files = list((tmp_path / "cache").glob("*/loop._run_chunk-*.nbc"))
    assert files
    for f in files:  # damaged in place: random bytes, the same size
        f.write_bytes(os.urandom(f.stat().st_size))
    out = subprocess.run(run, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "could not be read" in out.stderr and "loop._run_chunk" in out.stderr
    assert out.stdout.split() == ["1", "0"]  # compiled afresh


_DAMAGED = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    import tiny
    from moreau.core.jitcache import call_recovering
    print(call_recovering(tiny.twice, 21.0) if sys.argv[2] == "recover" else tiny.twice(21.0))
""")


def test_a_cache_file_overwritten_with_random_bytes_is_removed_and_compiled_again(tmp_path):
    (tmp_path / "tiny.py").write_text("from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}  # its cache beside it

    def run(mode):
        return subprocess.run([sys.executable, "-c", _DAMAGED, str(tmp_path), mode], env=env, capture_output=True,
                              text=True, timeout=300)

    assert run("plain").stdout.split() == ["42.0"]  # compiled and cached
    data = list((tmp_path / "__pycache__").glob("tiny.twice-*.nbc"))
    assert len(data) == 1
    data[0].write_bytes(os.urandom(data[0].stat().st_size))
    assert run("plain").returncode != 0  # numba itself fails on the damaged file, on every run
    out = run("recover")
    assert out.returncode == 0 and out.stdout.split() == ["42.0"], out.stderr[-2000:]
    assert "could not be read" in out.stderr and "tiny.twice" in out.stderr
    again = run("plain")  # the file was replaced by a good one
    assert again.returncode == 0 and again.stdout.split() == ["42.0"]


_NOWHERE = textwrap.dedent("""
    import os, sys, warnings
    import numpy as np
    from numba.core import caching

    class Nowhere(caching._CacheLocator):  # no directory numba knows of is writable
        def get_cache_path(self):
            return ""

        def get_source_stamp(self):
            return None

        def get_disambiguator(self):
            return ""

        @classmethod
        def from_function(cls, py_func, py_file):
            return None

    (getattr(caching, "CacheImpl", None) or caching._CacheImpl)._locator_classes[:] = [Nowhere]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import moreau
        from moreau.core import jitcache
        from moreau.core.kernels import cholesky
        M, L = np.array([[4.0, 2.0], [2.0, 3.0]]), np.zeros((2, 2))
        print(cholesky(M, L, 2), np.allclose(L @ L.T, M))
    said = [str(w.message) for w in caught if "cache" in str(w.message)]
    print(len(said), jitcache.cache_dir())
    print(said[0] if said else "")
""")


def test_no_writable_cache_directory_runs_with_one_warning_in_a_temporary_one():
    """numba's locators all refusing (a read-only package, home and NUMBA_CACHE_DIR): moreau
    imports and compiles with one RuntimeWarning naming the way out, into a temporary
    directory of the process that is gone after it exits (numba alone raises "no locator
    available" at import)."""
    out = subprocess.run([sys.executable, "-c", _NOWHERE], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = out.stdout.splitlines()
    assert lines[0] == "-1 True"
    count, where = lines[1].split(" ", 1)
    assert count == "1" and "moreau-numba-" in where
    assert "no writable numba cache directory" in lines[2] and "NUMBA_CACHE_DIR" in lines[2]
    assert not os.path.exists(where)  # removed when the process ended
    assert "Traceback" not in out.stderr


def test_a_scene_runs_the_loop_compiled_for_its_features():
    from moreau.compiled.layout import STEP_ENERGY, STEP_MIDPOINT, STEP_THETA
    from moreau.compiled.variants import variant
    from moreau.problems.bouncing_ball import bouncing_ball
    from moreau.problems.four_bar import four_bar
    from moreau.problems.piston import piston_model

    piston, rough = lower(piston_model(e=0.9).scene), lower(piston_model(e=0.9, mu=0.05).scene)
    ball = lower(bouncing_ball(0.5))
    assert variant(piston.ints, STEP_MIDPOINT) == variant(ball.ints, STEP_MIDPOINT) == "plain"
    assert variant(rough.ints, STEP_MIDPOINT) == "friction"  # tangent rows
    assert variant(rough.ints, STEP_ENERGY, 8) == "full"  # and later passes
    assert variant(lower(four_bar().scene).ints, STEP_MIDPOINT) == "full"  # bilateral rows
    assert variant(piston.ints, STEP_ENERGY, 8) == "full"  # M(q): the energy-consistent step iterates
    assert variant(ball.ints, STEP_ENERGY, 8) == "plain"  # constant M, no damping: one pass, as the midpoint step
    assert variant(ball.ints, STEP_THETA) == "plain"  # no velocity-dependent force: one pass


_PLAIN_ONLY = textwrap.dedent("""
    import moreau as mo
    from moreau.compiled.cache import cached_variants
    from moreau.problems.piston import piston_model
    traj = piston_model(e=0.0).simulate(0.02, 1e-3)
    assert traj.completed
    print(sorted(cached_variants()))
""")


@pytest.mark.slow  # one compile of the plain variant into its own cache (about 55 s, 2026-11-27)
def test_a_scene_without_friction_or_bilateral_rows_compiles_none_of_their_code(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=os.getcwd())
    out = subprocess.run([sys.executable, "-c", _PLAIN_ONLY], env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["['plain']"]  # the plain variant only
    names = {p.name.split("-")[0] for p in tmp_path.glob("*/*.nbi")}
    assert "loop._run_chunk" in names and "one_step.solve_one_step" in names
    assert not {n for n in names if n.startswith(("friction.", "lemke.", "friction_states.", "equality.",
                                                  "implicit.", "bilateral."))}


def test_step_size_control_runs_on_the_variant_already_loaded():
    """A run with step-size control compiles nothing more than its variant of the loop: the
    same compiled function takes both (a new process; the cache holds the plain variant from
    the suite's first worker, or this compiles it once)."""
    probe = textwrap.dedent("""
        import moreau as mo
        from moreau.compiled.loop import _run_chunk
        from moreau.problems.bouncing_ball import bouncing_ball
        scene = bouncing_ball(0.8)
        mo.ensure_compiled(scene)
        known = len(_run_chunk.overloads)
        traj = mo.simulate(scene, (0.0, 1.0), [1.0], [0.0], 1e-2, step_control=mo.StepControl(1e-6))
        print(known, len(_run_chunk.overloads), traj.completed and traj.stats.rejected > 0)
    """)
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=600,
                         env=dict(os.environ, PYTHONPATH=os.getcwd()))
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split("\n")[-2] == "1 1 True"  # one overload of the loop, before and after


@pytest.mark.slow  # compiles the full variant's judge (about 5 s), which no default test runs
def test_ensure_compiled_without_scenes_loads_the_judges_runs_use():
    """``mo.ensure_compiled()`` (``moreau compile``) loads step-size control's judge for every
    variant with the argument types runs give it: a controlled run on the plain variant and
    one on the friction variant afterwards compile no judge of their own."""
    from moreau.compiled import adaptive
    from moreau.problems.bouncing_ball import bouncing_ball
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    mo.ensure_compiled()
    assert adaptive._judged >= set(VARIANTS)
    known = len(adaptive.judge_attempt.overloads)
    assert known >= len(VARIANTS)
    ball = mo.simulate(bouncing_ball(0.8), (0.0, 1.0), [1.0], [0.0], 1e-2, step_control=mo.StepControl(1e-5))
    bird = mo.simulate(woodpecker(), (0.0, 0.02), *GLOCKER_STATE, 1e-3, step_control=mo.StepControl(1e-4))
    assert ball.completed and bird.completed and ball.stats.rejected > 0
    assert len(adaptive.judge_attempt.overloads) == known


def test_no_cached_function_is_compiled_again_for_a_literal_argument():
    """A constant argument (``0``, ``True``) at one call site types as a literal, and numba
    compiles the callee (and all it calls) once more for it: in the loop's variants that
    was 5 s of each cold compile. Every cached signature of moreau's functions is distinct
    once its literals are replaced by their types."""
    import pickle

    from numba.core import types

    from moreau.core import jitcache

    mo.ensure_compiled()  # every variant: loaded (the suite's first workers compiled them) or compiled
    twice = []
    index = [p for p in jitcache._cached_files() if p.endswith(".nbi")]
    assert any(os.path.basename(p).startswith("one_step.solve_one_step") for p in index)
    for path in index:
        with open(path, "rb") as f:
            pickle.load(f)  # numba's version
            _, overloads = pickle.loads(f.read())
        seen = {}
        for key in overloads:
            sig = key[0]
            plain = tuple(types.unliteral(t) for t in sig)
            if plain in seen and seen[plain] != sig:
                twice.append(f"{os.path.basename(path)}: {[str(t) for t in sig if isinstance(t, types.Literal)]}")
            seen.setdefault(plain, sig)
    assert not twice


@pytest.mark.parametrize("solve", ["one_step.solve_one_step", "friction.solve_friction_step"])
def test_the_loops_contact_solves_are_the_ones_their_python_entries_compile(solve):
    """The loop and the Python entries of its contact solves (ExactSolver.solve,
    :func:`moreau.contact.friction.friction_one_step`) call them with the same argument
    types, so the cache holds one compiled copy of each: a second copy of the friction
    solve was 5 s of the test suite's cold compile, and the second process of a cold
    compile (:mod:`moreau.compiled.side_compile`) saves the loop's copies through them."""
    import pickle

    from moreau.compiled.side_compile import _compile
    from moreau.core import jitcache

    mo.ensure_compiled()  # the loop's copies: compiled (or loaded) with each variant
    _compile("full")  # the entries, as the second process calls them
    index = [p for p in jitcache._cached_files() if os.path.basename(p).startswith(solve) and p.endswith(".nbi")]
    assert len(index) == 1
    with open(index[0], "rb") as f:
        pickle.load(f)  # numba's version
        _, overloads = pickle.loads(f.read())
    assert len(overloads) == 1, [str(key[0]) for key in overloads]


def _cached_signatures(stem: str) -> list[str]:
    """The signatures numba's cache holds for the function whose index file starts with ``stem``."""
    import pickle

    from moreau.core import jitcache

    index = [p for p in jitcache._cached_files() if os.path.basename(p).startswith(stem) and p.endswith(".nbi")]
    assert len(index) == 1, index
    with open(index[0], "rb") as f:
        pickle.load(f)  # numba's version
        _, overloads = pickle.loads(f.read())
    return sorted(str(key[0]) for key in overloads)


def test_the_side_compile_uses_the_loops_argument_types():
    """The second process compiles each variant's drift projection (through
    ``drift.projection_address``, as a run does) and types the loop's other calls, the
    contact check among them (``side_compile._calls_of_the_loop``): after the loop of each variant, it adds no
    compiled copy of them (a new one would be a compile the loop waits for, or a run
    compiles)."""
    from moreau.compiled.drift import projection_address
    from moreau.compiled.runner import chunk_example
    from moreau.compiled.side_compile import type_calls_of_the_loop

    mo.ensure_compiled()
    stems = ("drift.project_rows", "energy._energy_check", "kkt.kkt_residuals_kernel")
    before = {s: _cached_signatures(s) for s in stems}
    assert len(before["drift.project_rows"]) == 2  # eqw None in the plain and friction variants
    for v in VARIANTS:
        projection_address(*chunk_example(v)[:7])  # each variant's, through its address
        type_calls_of_the_loop(v)
    assert {s: _cached_signatures(s) for s in stems} == before


def test_a_projection_address_for_other_types_is_never_called(monkeypatch):
    """The loop calls the drift projection through its address only when the key of the
    address's argument types is its own call's; else the run fails, naming the bug."""
    from moreau.compiled import runner
    from tests.test_drift_theta import bead_in_circle

    monkeypatch.setattr(runner, "projection_address", lambda *arrays: (0, 12345))  # address 0: a crash if called
    with pytest.raises(mo.SimulationError, match="internal error") as caught:
        mo.simulate(bead_in_circle(), (0.0, 2.0), [0.0, -1.0], [3.0, 0.0], 1e-2, solver="enum",
                    drift_control=mo.PositionProjection())
    assert caught.value.trajectory.status == "failed"


def test_a_friction_solve_address_for_other_types_is_never_called(monkeypatch):
    """The same for the friction solve: a block sliding on a rough floor, its solve's
    address given a wrong key, fails at its first contact step, naming the bug."""
    from moreau.compiled import runner

    scene = mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.ConstantForce([0.0, -9.81])],
                     [mo.Contact(mo.LinearBarrier([[0.0, 1.0]], [0.0], tangent=[[1.0, 0.0]]),
                                 mo.NewtonImpactFriction(0.0, 0.5))])
    monkeypatch.setattr(runner, "friction_address", lambda *arrays: (0, 12345))  # address 0: a crash if called
    with pytest.raises(mo.SimulationError, match="internal error") as caught:
        mo.simulate(scene, (0.0, 0.1), [0.0, 0.0], [1.0, 0.0], 1e-3)
    assert caught.value.trajectory.status == "failed"
    assert caught.value.step == 0


def test_the_loops_compile_waits_for_what_the_second_process_is_compiling(monkeypatch):
    """A function the second process said it is compiling gets a compile of its own that
    waits for its save (then loads it), except for a signature this process has; once
    saved, or once the process ends, the dispatcher's own compile is back."""
    import threading

    from numba import types

    from moreau.compiled import side_compile

    @numba.njit
    def twice(x):
        return 2 * x

    name = "moreau.somewhere:twice"
    monkeypatch.setattr(side_compile, "_dispatcher", lambda n: twice if n == name else None)
    twice.compile((types.int64,))
    fake = (f"import sys; print('start {name}', flush=True); sys.stdin.readline(); "
            f"print('saved {name}', flush=True); sys.stdin.readline()")
    proc = subprocess.Popen([sys.executable, "-c", fake], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    helper = side_compile.Helper(proc)
    try:
        deadline = time.monotonic() + 60
        while "compile" not in vars(twice) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert "compile" in vars(twice)
        twice.compile((types.int64,))  # a copy this process has: no wait
        done = threading.Event()
        waiter = threading.Thread(target=lambda: (twice.compile((types.float64,)), done.set()))
        waiter.start()
        assert not done.wait(0.3)  # waiting for the save
        proc.stdin.write("\n")
        proc.stdin.flush()
        waiter.join(60)
        assert done.is_set() and "compile" not in vars(twice)
        assert (types.float64,) in twice.overloads
    finally:
        side_compile.stop(helper)
    assert "compile" not in vars(twice)


def test_the_side_compile_needs_two_cores_and_can_be_turned_off(monkeypatch):
    from moreau.compiled import side_compile

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    assert side_compile.start("plain") is None
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    monkeypatch.setenv("MOREAU_SIDE_COMPILE", "0")
    assert side_compile.start("plain") is None


def test_the_side_compile_ends_with_the_process_that_started_it(tmp_path):
    """Its parent killed, the second process ends too, before its compiles are done (in
    an empty cache they take seconds: the friction solve is not saved)."""
    from test_trust_stops import alive  # a zombie counts as ended

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=os.getcwd())
    parent = ("import os, sys; from moreau.compiled import side_compile; p = side_compile.start('full'); "
              "print(p.proc.pid, flush=True); sys.stdin.read()")
    proc = subprocess.Popen([sys.executable, "-c", parent], env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)
    child = int(proc.stdout.readline())
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and alive(child):
        time.sleep(0.1)
    assert not alive(child)
    assert not list(tmp_path.rglob("friction.solve_friction_step*.nbi"))  # ended, not done


def test_a_second_process_started_ahead_is_taken_over_by_the_compile_or_ended(monkeypatch):
    """``cache.compiling_ahead`` (around a run's checks) starts the second process of a cold
    compile; ``ensure_compiled`` inside the block takes that one over (starting none of its
    own), and one that no compile took over ends with the block. A variant this process has,
    or one in the cache, starts nothing."""
    from moreau.compiled import cache, side_compile

    started, stopped = [], []
    monkeypatch.setattr(side_compile, "start", lambda v: started.append(v) or f"helper {len(started)}")
    monkeypatch.setattr(side_compile, "stop", stopped.append)
    monkeypatch.setattr(cache, "cached_variants", lambda: set())
    monkeypatch.setattr(cache, "_load_or_compile", lambda v, cold, d: None)
    monkeypatch.setitem(cache._ready, "plain", type(cache._ready["plain"])())  # not yet in this process
    with cache.compiling_ahead("plain"):
        assert started == ["plain"] and cache._ahead == {"plain": "helper 1"}
    assert stopped == ["helper 1"] and cache._ahead == {}  # not taken over: ended
    with cache.compiling_ahead("plain"):
        cache.ensure_compiled("plain")
        assert started == ["plain", "plain"] and stopped == ["helper 1", "helper 2"]  # the compile's own
    assert stopped == ["helper 1", "helper 2"] and cache._ahead == {}  # and not again at the block's end
    with cache.compiling_ahead("plain"):  # compiled in this process now
        pass
    monkeypatch.setitem(cache._ready, "plain", type(cache._ready["plain"])())
    monkeypatch.setattr(cache, "cached_variants", lambda: {"plain"})
    with cache.compiling_ahead("plain"):  # in the cache
        pass
    assert len(started) == 2
