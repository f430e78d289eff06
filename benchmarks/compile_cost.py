"""What the compiled loop costs before its first step: compile time and memory.

Runs a probe in new processes (absolute times on a shared 2-core machine are noisy; run
the script alone):

1. **cold**: an empty ``NUMBA_CACHE_DIR`` — the first run on a new machine compiles the
   time loop (``moreau.ensure_compiled``); wall time, CPU time and peak resident memory
   of the process, and the compile time per kernel family (the module of the compiled
   function: its own share, callees excluded);
2. **warm**: the same cache again — the loop is loaded, not compiled;
3. in both, two scenes of user ``@numba.njit`` callables (a ``FunctionForce``, a
   ``FunctionBarrier``; the second scene with other functions): the seconds from
   ``simulate()`` to its end (0.1 s of stepping), which is their own compile.

    python benchmarks/compile_cost.py
"""

from __future__ import annotations

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
            if stack:
                stack[-1][1] += d

    event.register("numba:compile", Exclusive())
    import moreau as mo
    t_import = time.perf_counter() - t0
    t = time.perf_counter()
    mo.ensure_compiled()
    t_loop = time.perf_counter() - t

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

    users = []
    for k in (1, 2):
        scene = user_scene(k)
        t = time.perf_counter()
        traj = mo.simulate(scene, (0.0, 0.1), [0.0, 1.0], [1.0, 0.0], 1e-3, backend="compiled")
        assert traj.completed
        users.append(time.perf_counter() - t)
    cpu = resource.getrusage(resource.RUSAGE_SELF)
    print(json.dumps({"import": t_import, "loop": t_loop, "user": users, "wall": time.perf_counter() - t0,
                      "cpu": cpu.ru_utime + cpu.ru_stime, "rss_mb": cpu.ru_maxrss / 1024, "own": own}))
''')


def probe(cache: str) -> dict:
    """Run the probe in a new process with ``NUMBA_CACHE_DIR=cache``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache:
        cold = probe(cache)
        warm = probe(cache)
    print("\nthe compiled loop before its first step (new processes; cold: empty NUMBA_CACHE_DIR)")
    print(f"{'':44s} {'cold':>9s} {'warm':>9s}")
    rows = [("import moreau (s)", "import"), ("load or compile the loop (s)", "loop"),
            ("process wall time (s)", "wall"), ("process CPU time (s)", "cpu"), ("peak resident memory (MB)", "rss_mb")]
    for label, key in rows:
        print(f"{label:44s} {cold[key]:9.2f} {warm[key]:9.2f}")
    for i in range(2):
        label = f"user scene {i + 1}: simulate() to its end (s)"
        print(f"{label:44s} {cold['user'][i]:9.2f} {warm['user'][i]:9.2f}")
    print("\ncold compile per kernel family (s, each function's own share, callees excluded)")
    for fam, s in sorted(cold["own"].items(), key=lambda x: -x[1]):
        print(f"  {fam:32s} {s:9.2f}")
    print(f"\n(benchmark wall time {time.perf_counter() - t_start:.0f} s)")


if __name__ == "__main__":
    main()
