"""What the compiled loop costs before its first step: compile time and memory, per
feature set (the loop's variants, ``moreau.compiled.variants.VARIANTS``).

Runs a probe in new processes (absolute times on a shared 2-core machine are noisy; run
the script alone):

1. **plain**: an empty ``NUMBA_CACHE_DIR``; the variant without friction, bilateral rows
   and later passes (the frictionless piston's, the README's main job) is compiled;
2. **friction, after plain**: the same cache; the variant with friction (the piston with
   ``--mu``, the woodpecker) is compiled beside it;
3. **full, after them**: the same cache; the variant with friction, bilateral rows and
   later passes (joints, the predictor–corrector / energy-consistent step);
4. **full alone**: a new empty cache, the full variant only;
5. **warm**: the first cache again, every variant loaded (each runs fixed steps and
   step-size control alike);
6. **judge**: the first cache again, a short run of each variant with step-size control:
   its judge of an attempt (``moreau.compiled.adaptive.judge_attempt``, called through its
   address) is compiled apart from the loop, at the first such run.

Each row: the seconds of ``moreau.ensure_compiled`` for that variant, the process's wall
and CPU time and peak resident memory; then the compile time per kernel family of rows 1
to 3 (the module of the compiled function: its own share, callees excluded; and the
functions compiled a second time because a call passed a literal constant, and where the
loop function's own compile goes: numba's passes over it and LLVM's phases on its module),
and the seconds from ``simulate()`` to its end (0.1 s of stepping) of two scenes of user
``@numba.njit`` callables (their own compile) in rows 1 and 4.

    python benchmarks/compile_cost.py
    python benchmarks/compile_cost.py --against REV --rounds 4 [--variant friction]   # this build and REV

With ``--against``, one variant only (default plain), compiled by this build and by
``REV`` alternately (this shared machine's speed drifted by up to a half between runs of
one day: compare the rounds' pairs); a build of two variants (before 2026-12-02) compiles
its full one for ``friction``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time

_PROBE = textwrap.dedent('''
    import json, resource, sys, time
    from collections import defaultdict
    t0 = time.perf_counter()
    from numba.core import event
    import numpy as np
    import numba

    own = defaultdict(float)
    stack = []
    signatures = set()  # (function, argument types without literals) compiled so far
    again = [0, 0.0]  # compiles of a function again for a literal argument: count, own seconds

    class Exclusive(event.Listener):
        def on_start(self, ev):
            stack.append([time.perf_counter(), 0.0])

        def on_end(self, ev):
            start, children = stack.pop()
            d = time.perf_counter() - start
            f = getattr(ev.data.get("dispatcher"), "py_func", None)
            mod = getattr(f, "__module__", "") or ""
            fam = mod.rsplit(".", 1)[-1] if mod.startswith("moreau") else "numba / user"
            own[fam] += d - children
            args = ev.data.get("args")
            if f is not None and args is not None:
                key = (f, tuple(numba.types.unliteral(a) for a in args))
                if key in signatures:
                    again[0] += 1
                    again[1] += d - children
                signatures.add(key)
            if stack:
                stack[-1][1] += d

    event.register("numba:compile", Exclusive())

    from numba.core import codegen
    llvm = defaultdict(float)  # LLVM's seconds on the loop function's module, by phase

    def timed(name):
        orig = getattr(codegen.CPUCodeLibrary, name)

        def run(self, *a, **k):
            t = time.perf_counter()
            try:
                return orig(self, *a, **k)
            finally:
                if "_run_chunk" in self.name:
                    llvm[name] += time.perf_counter() - t
        setattr(codegen.CPUCodeLibrary, name, run)

    for name in ("_optimize_functions", "_optimize_final_module", "_finalize_final_module"):
        timed(name)
    import moreau as mo
    t_import = time.perf_counter() - t0
    t = time.perf_counter()
    from moreau.compiled.cache import ensure_compiled
    try:
        from moreau.compiled.variants import VARIANTS
    except ImportError:  # a build of two variants: ensure_compiled(full)
        VARIANTS = None
    names = json.loads(sys.argv[1])
    asked = names if VARIANTS else [v != "plain" for v in names]
    for v in asked:
        ensure_compiled(v)
    t_loop = time.perf_counter() - t
    from moreau.compiled.loop import _run_chunk
    passes = defaultdict(float)  # numba's passes over the loop function (compiled here)
    for cres in _run_chunk.overloads.values():
        for times in (cres.metadata or {}).get("pipeline_times", {}).values():  # None when loaded
            for key, tm in times.items():
                passes[key.split("_", 1)[1]] += tm.run

    def user_scene(k):
        @numba.njit
        def force(t, q, v):
            return np.array([-0.1 * k * v[0], -9.81])

        @numba.njit
        def gap(q):
            return np.array([q[1] - 0.1 * k * q[0]])

        @numba.njit
        def jac(q):
            return np.array([[-0.1 * k, 1.0]])

        return mo.Scene(mo.FunctionSystem(np.eye(2)), [mo.FunctionForce(force)],
                        [mo.Contact(mo.FunctionBarrier(gap, jac), 0.5)])

    judges = []  # step-size control's judge of an attempt (compiled apart): a short run of each variant
    for v in (asked if sys.argv[2:] == ["judge"] else ()):
        from moreau.compiled.layout import STEP_MIDPOINT
        from moreau.compiled.runner import one_row_scene, run_compiled
        t = time.perf_counter()
        run_compiled(one_row_scene(), None, 0.0, np.array([1e-3]), np.array([-1.0]), 1e-3, 2, step=STEP_MIDPOINT,
                     solver="exact", fallback=None, stride=1, bar=None, energy=True, tol=1e-8, drift_control=None,
                     flight_gap=np.zeros(1), gmax0=np.full(1, np.inf), variant=v,
                     control=(2e-3, np.full(2, 1e-3), 0.0, 1e-12))
        judges.append(time.perf_counter() - t)
    users = []
    for k in ((1, 2) if "plain" in names else ()):  # they run the plain variant
        scene = user_scene(k)
        t = time.perf_counter()
        traj = mo.simulate(scene, (0.0, 0.1), [0.0, 1.0], [1.0, 0.0], 1e-3)
        assert traj.completed
        users.append(time.perf_counter() - t)
    cpu = resource.getrusage(resource.RUSAGE_SELF)
    side = resource.getrusage(resource.RUSAGE_CHILDREN)  # the second process of the compile
    print(json.dumps({"import": t_import, "loop": t_loop, "user": users, "judges": judges,
                      "wall": time.perf_counter() - t0, "cpu_side": side.ru_utime + side.ru_stime,
                      "cpu": cpu.ru_utime + cpu.ru_stime, "rss_mb": cpu.ru_maxrss / 1024, "own": own,
                      "again": again, "passes": passes, "llvm": llvm}))
''')


def probe(cache: str, variants: list[str], tree: str | None = None, judge: bool = False) -> dict:
    """Run the probe in a new process with ``NUMBA_CACHE_DIR=cache``, loading (or compiling)
    the loop's ``variants`` (names); ``judge``: then a short run of each with step-size
    control (its judge compiled); ``tree``: moreau imported from that checkout."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, **({"PYTHONPATH": tree} if tree else {}))
    out = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(variants)] + (["judge"] if judge else []),
                         capture_output=True, text=True, env=env)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def against(rev: str, rounds: int, variant: str) -> None:
    """One variant compiled into empty caches by this build and by ``rev`` (a temporary git
    worktree), alternating, ``rounds`` times each: per round the loop's seconds, the CPU
    seconds of the process and of its second process, and its peak memory."""
    from interleaved import worktree  # (benchmarks/, this script's folder)

    with worktree(rev) as (here, tree):
        print(f"the {variant} variant into an empty cache, alternating "
              f"(MOREAU_SIDE_COMPILE={os.environ.get('MOREAU_SIDE_COMPILE', '1')})")
        print(f"{'round':>5s} {'build':>12s} {'loop (s)':>9s} {'CPU (s)':>9s} {'2nd CPU (s)':>12s} {'peak MB':>8s}"
              f" {'LLVM: own, linked, machine code (s)':>36s}")
        for k in range(rounds):
            for name, src in (("this", here), (rev, tree)):
                with tempfile.TemporaryDirectory() as cache:
                    r = probe(cache, [variant], tree=src)
                ll = r["llvm"]
                print(f"{k + 1:5d} {name[:12]:>12s} {r['loop']:9.2f} {r['cpu']:9.2f} {r['cpu_side']:12.2f} "
                      f"{r['rss_mb']:8.0f} {ll.get('_optimize_functions', 0):12.1f}"
                      f"{ll.get('_optimize_final_module', 0):8.1f}{ll.get('_finalize_final_module', 0):8.1f}",
                      flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--against", metavar="REV", help="compile one variant here and at REV, alternating")
    parser.add_argument("--rounds", type=int, default=3, help="with --against: rounds (default 3)")
    parser.add_argument("--variant", choices=("plain", "friction", "full"), default="plain",
                        help="with --against: the variant compiled (default plain)")
    args = parser.parse_args()
    if args.against:
        return against(args.against, args.rounds, args.variant)
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as alone:
        every = ["plain", "friction", "full"]
        runs = [("plain midpoint step, empty cache", probe(cache, ["plain"])),
                ("friction, beside it", probe(cache, ["friction"])),
                ("full (friction, joints, passes), beside them", probe(cache, ["full"])),
                ("full, empty cache", probe(alone, ["full"])),
                ("all three, warm cache", probe(cache, every))]
        judges = probe(cache, every, judge=True)["judges"]
    print("\nthe compiled loop before its first step, per variant (new processes; NUMBA_CACHE_DIR as said)")
    print(f"{'':44s} {'loop (s)':>9s} {'wall (s)':>9s} {'CPU (s)':>9s} {'peak MB':>9s}")
    for label, r in runs:
        print(f"{label:44s} {r['loop']:9.2f} {r['wall']:9.2f} {r['cpu']:9.2f} {r['rss_mb']:9.0f}")
    print(f"{'import moreau (s)':44s} {runs[0][1]['import']:9.2f}")
    print(f"{'step-size control judge, loops cached (s)':44s} plain {judges[0]:5.2f}   friction "
          f"{judges[1]:5.2f}   full {judges[2]:5.2f}")
    for i in range(2):
        label = f"user scene {i + 1}: simulate() to its end (s)"
        print(f"{label:44s} cold {runs[0][1]['user'][i]:6.2f}   warm {runs[4][1]['user'][i]:6.2f}")
    for label, r in runs[:3]:
        print(f"\ncompile per kernel family, {label} (s, each function's own share, callees excluded)")
        for fam, sec in sorted(r["own"].items(), key=lambda x: -x[1]):
            if sec >= 0.05:
                print(f"  {fam:32s} {sec:9.2f}")
        print(f"  {'compiled again for a literal argument':38s} {r['again'][0]:3d} functions, {r['again'][1]:.2f} s")
        p, ll = r["passes"], r["llvm"]
        print(f"  the loop function: type inference {p.get('nopython_type_inference', 0):.1f} s (its callees' "
              f"compiles included), inlining the parts {p.get('inline_inlinables', 0):.1f} s, lowering "
              f"{p.get('native_lowering', 0):.1f} s; of it LLVM on its module: its functions "
              f"{ll.get('_optimize_functions', 0):.1f} s, linked with its callees "
              f"{ll.get('_optimize_final_module', 0):.1f} s, machine code {ll.get('_finalize_final_module', 0):.1f} s")
    print(f"\n(benchmark wall time {time.perf_counter() - t_start:.0f} s)")


if __name__ == "__main__":
    main()
