"""Cost of one time step (µs) of the compiled loop, for the bundled scenes and a user's own.

Prints, in one run (absolute times on a shared 2-core machine are noisy; the ratios are
measured side by side):

1. the piston at h = 1e-4 over one engine cycle:
   e = 0 with the engine's drift control (``PistonModel.drift_control()``, a
   ``CombinedProjection`` accepting 1e-4 of the clearance) and with an exact one
   (``tol=0``: a projection on 80 % of the steps), e = 0.9 without and with the engine's,
   e = 0 with ``PositionProjection``;
   and the piston with skirt friction (mu = 0.05, Lemke's method);
2. pendulum chains of N = 3, 6, 12, 24, 40 links with a floor row per link, swinging free
   and lying on the floor (N rows in contact every step), and N = 3, 24 lying on a rough
   floor (mu = 0.5: N normal and N tangential rows every step); N = 3, 24 on the floor and
   issue 26's 40-link chain falling onto a floor with the energy-consistent step; the four-bar linkage
   (``moreau.problems.four_bar``: two bilateral rows every step), free and with a stop;
   the README's first example as written (plain numpy lambdas), with ``@njit`` callables and
   with a gap numba cannot compile (a Python callback), and built anew in a user's loop
   (its callables compiled for a new value, reused for one run before); the woodpecker's whole
   ``simulate()`` call recording every step against every 100th; a short run's whole call
   against its loop (what checks, set-up and result cost per call);
3. the compile time of the loop (a fresh numba cache, in a new process) and the time a
   new process takes to load it from the cache;
4. the contact solvers on the piston sliding on a wall (e = 0): the loop's own (exact,
   enum) and those it calls back in Python (OSQP updated, OSQP rebuilt every step through
   qpsolvers, daqp, quadprog).

    python benchmarks/step_cost.py            # everything (the compile alone takes ~1.5 min)
    python benchmarks/step_cost.py --quick    # < 30 s: shorter runs, no fresh compile
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import moreau as mo
from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow
from moreau.problems.piston import PistonParameters, piston_model

H = 1e-4
CYCLE = 4 * np.pi  # one engine cycle in non-dimensional time


def us_per_step(scene, q0, v0, steps, h=H, repeat=1, **kw) -> float:
    """µs per step of a run of ``steps`` steps; the best of ``repeat`` runs (the others
    were slowed by whatever else ran on the machine)."""
    best = np.inf
    for _ in range(repeat):
        traj = mo.simulate(scene, (0.0, steps * h), q0, v0, h, energy=False,
                           record_every=max(1, steps // 1000), **kw)
        if not traj.completed:
            raise RuntimeError(traj.message)
        best = min(best, traj.stats.us_per_step)
    return best


def piston_table(quick: bool) -> list[tuple]:
    rows = []
    cycle_steps = int(round(CYCLE / H))
    cases = (
        (0.0, "engine drift control", lambda m: m.drift_control(), 0.0),
        (0.0, "CombinedProjection(tol=0)", lambda m: mo.CombinedProjection(), 0.0),
        (0.9, "", lambda m: None, 0.0),
        (0.9, "engine drift control", lambda m: m.drift_control(), 0.0),
        (0.0, "PositionProjection", lambda m: mo.PositionProjection(), 0.0),
        (0.0, "engine drift control, mu = 0.05", lambda m: m.drift_control(), 0.05),
    )
    for e, label, make, mu in cases:
        model = piston_model(PistonParameters(e=e, mu=mu))
        q0, v0 = model.initial_state()
        dc = make(model)
        lim = model.params.clearance / model.params.l1  # as PistonModel.simulate: the clearance
        comp = us_per_step(model.scene, q0, v0, cycle_steps, repeat=3, backend="compiled", drift_control=dc,
                           penetration_limit=lim)
        rows.append((f"piston e = {e:g}" + (f" + {label}" if label else ""), cycle_steps, comp))
    return rows


def chain_scene(N: int, on_floor: bool, mu: float = 0.0):
    """N equal rods hanging from the origin; a floor row under each link's tip, at y = 0
    (the chain laid on it, horizontal) or far below (free swinging); ``mu`` > 0: a rough
    floor (Coulomb friction)."""
    chain = PendulumChain([Link.rod(m=1.0 / N, l=1.0 / N) for _ in range(N)])
    y_floor = 0.0 if on_floor else -10.0
    rows = [PointLineRow(i, (1.0 / N, 0.0), line_point=(0.0, y_floor), normal=(0.0, 1.0)) for i in range(N)]
    law = mo.NewtonImpactFriction(0.0, mu) if mu > 0 else 0.0
    scene = mo.Scene(chain, [ChainGravity(chain)], [mo.Contact(PointLineBarrier(chain, rows), law, name="floor")],
                     name=f"chain{N}")
    q0 = np.full(N, np.pi / 2) if on_floor else np.linspace(0.3, 1.2, N)
    return scene, q0, np.zeros(N)


def falling_chain(N: int = 40):
    """Issue 26's hard case: N rods of 0.05 kg and 2.5 cm (N = 40: 1 m, 2 kg) released
    horizontally above a floor 0.3 m below the pivot, a row per link tip (e = 0.5)."""
    chain = PendulumChain([Link.rod(m=0.05, l=0.025) for _ in range(N)])
    rows = [PointLineRow(i, (0.025, 0.0), line_point=(0.0, -0.3), normal=(0.0, 1.0)) for i in range(N)]
    scene = mo.Scene(chain, [ChainGravity(chain)], [mo.Contact(PointLineBarrier(chain, rows), 0.5, name="floor")],
                     name=f"falling chain{N}")
    return scene, np.full(N, np.pi / 2), np.zeros(N)


def stable_chain_table(quick: bool) -> list[tuple]:
    """The chains with :class:`moreau.MoreauJeanEnergyConsistent` (fixed-point iterates,
    each a contact solve): lying on the floor, and the 40-link chain falling onto one (its
    fast tail whips; the midpoint step runs away there at h = 1e-3)."""
    ec = {"integrator": mo.MoreauJeanEnergyConsistent, "solver": "exact"}
    rows = []
    for N in (3, 24):
        scene, q0, v0 = chain_scene(N, True)
        steps = (20_000 if quick else 100_000) // N
        comp = us_per_step(scene, q0, v0, steps, h=1e-3, backend="compiled", **ec)
        rows.append((f"chain N = {N:2d}, on the floor, energy-cons.", steps, comp))
    scene, q0, v0 = falling_chain(40)
    steps = 1_000 if quick else 2_000  # 1 s (the landing and the first whips) or the whole 2 s
    comp = us_per_step(scene, q0, v0, steps, h=1e-3, backend="compiled", **ec)
    rows.append(("chain N = 40 falling on a floor, energy-c.", steps, comp))
    return rows


def four_bar_table(quick: bool) -> list[tuple]:
    """The four-bar linkage (two bilateral rows closing the loop), free and hitting a stop."""
    from moreau.problems.four_bar import four_bar

    rows = []
    for label, kw in (("four-bar (closed loop)", {}), ("four-bar with a stop (e = 0.5)", {"stop": 0.75})):
        fb = four_bar(**kw)
        q0, v0 = fb.initial_state()
        steps = 20_000 if quick else 100_000
        comp = us_per_step(fb.scene, q0, v0, steps, backend="compiled", repeat=3)
        rows.append((label, steps, comp))
    return rows


def chain_table(quick: bool) -> list[tuple]:
    rows = []
    for N in (3, 6, 12, 24, 40):
        for on_floor in (False, True):
            scene, q0, v0 = chain_scene(N, on_floor)
            steps = (20_000 if quick else 100_000) // (N if on_floor else 1)
            comp = us_per_step(scene, q0, v0, steps, h=1e-3, backend="compiled")
            rows.append((f"chain N = {N:2d}, {'on the floor' if on_floor else 'free'}", steps, comp))
    for N in (3, 24):  # on a rough floor: N normal and N tangential rows every step (Lemke)
        scene, q0, v0 = chain_scene(N, True, mu=0.5)
        steps = (20_000 if quick else 100_000) // N
        comp = us_per_step(scene, q0, v0, steps, h=1e-3, backend="compiled")
        rows.append((f"chain N = {N:2d}, on a rough floor (mu 0.5)", steps, comp))
    return rows


def _inclined(gap, jac):
    """The README's first example: a point mass bouncing on an inclined floor (e = 0.7)."""
    system = mo.FunctionSystem(2.0 * np.eye(2))
    floor = mo.FunctionBarrier(gap=gap, jacobian=jac)
    return mo.Scene(system, [mo.ConstantForce([0.0, -9.81 * 2.0], name="gravity")],
                    [mo.Contact(floor, mo.NewtonImpact(0.7), name="floor")])


def user_scene_table(quick: bool) -> list[tuple]:
    """The README's first example as a user writes it (plain numpy lambdas, compiled by numba
    as they are), with ``@njit`` callables, and with a gap numba cannot compile (a dict
    lookup: a Python callback from the loop); h = 1e-3."""
    import numba

    offsets = {"floor": 0.0}

    def dict_gap(q):
        return np.array([q[1] - 0.2 * q[0] + offsets["floor"]])

    scenes = {
        "README example, plain lambdas": _inclined(lambda q: np.array([q[1] - 0.2 * q[0]]),
                                                   lambda q: np.array([[-0.2, 1.0]])),
        "README example, @njit callables": _inclined(numba.njit(lambda q: np.array([q[1] - 0.2 * q[0]])),
                                                     numba.njit(lambda q: np.array([[-0.2, 1.0]]))),
        "README example, gap a Python callback": _inclined(dict_gap, lambda q: np.array([[-0.2, 1.0]])),
    }
    steps = 20_000 if quick else 200_000
    return [(name, steps, us_per_step(scene, [0.0, 1.0], [1.0, 0.0], steps, h=1e-3, repeat=2))
            for name, scene in scenes.items()]


def rebuilt_scene_calls() -> tuple[float, float]:
    """Seconds of ``simulate()`` (0.2 s at h = 1e-3) on the README example as a user's loop
    builds it anew each pass (new lambdas over the slope): for a slope not run before (its
    callables compiled) and for one run before (reused; best of 3)."""
    def make(slope):
        return _inclined(lambda q: np.array([q[1] - slope * q[0]]), lambda q: np.array([[-slope, 1.0]]))

    def call(slope):
        t0 = time.perf_counter()
        mo.simulate(make(slope), (0.0, 0.2), [0.0, 1.0], [1.0, 0.0], 1e-3, progress=False)
        return time.perf_counter() - t0

    new = call(0.21)  # a value this process has not compiled
    return new, min(call(0.2) for _ in range(3))


def woodpecker_call(quick: bool) -> tuple[float, float, int]:
    """Seconds of the whole ``simulate()`` call of the woodpecker (h = 2e-5, 1.5 s; 0.3 s in
    quick mode), recording every step and every 100th: the result's cost beside the loop's."""
    from moreau.problems.woodpecker import GLOCKER_STATE, woodpecker

    scene = woodpecker()
    (q0, v0), t_end, h = GLOCKER_STATE, (0.3 if quick else 1.5), 2e-5
    mo.simulate(scene, (0.0, 100 * h), q0, v0, h, progress=False)  # its kernels loaded first
    secs = [np.inf, np.inf]
    for _ in range(2):  # best of 2
        for i, every in enumerate((1, 100)):
            t0 = time.perf_counter()
            mo.simulate(scene, (0.0, t_end), q0, v0, h, record_every=every, progress=False)
            secs[i] = min(secs[i], time.perf_counter() - t0)
    return secs[0], secs[1], int(round(t_end / h))


def short_run_call() -> tuple[float, float, int]:
    """(whole call, the loop's part, steps) in seconds of one short ``simulate()``: the forced
    triple pendulum over half a forcing period at T/1600 (800 steps), as a Lyapunov exponent
    or a time map (``moreau.dynamics``) runs it again and again; best of 50."""
    from moreau.dynamics.benchmarks import forced_triple_pendulum

    scene, T = forced_triple_pendulum(6.0, 3.0), 2 * np.pi / 6.0
    run = lambda: mo.simulate(scene, (0.0, T / 2), np.zeros(3), np.zeros(3), T / 1600,  # noqa: E731
                              solver="enum", progress=False)
    run()
    best, loop = np.inf, np.inf
    for _ in range(50):
        t0 = time.perf_counter()
        traj = run()
        best, loop = min(best, time.perf_counter() - t0), min(loop, traj.stats.wall_time)
    return best, loop, traj.stats.steps


_PROBE = """
import time
t0 = time.perf_counter()
import moreau as mo
from moreau.problems.piston import piston_model
t1 = time.perf_counter()
m = piston_model(e=0.9)
t2 = time.perf_counter()
m.simulate(0.001, 1e-4, drift_control=m.drift_control(), backend="compiled")
t3 = time.perf_counter()
print(t1 - t0, t3 - t2)
"""


def startup_times(fresh: bool) -> tuple[float, float]:
    """(import seconds, first-run seconds) of a new process; ``fresh``: empty numba cache."""
    env = dict(os.environ, PYTHONPATH=os.getcwd() + os.pathsep + os.environ.get("PYTHONPATH", ""))
    with tempfile.TemporaryDirectory() as d:
        if fresh:
            env["NUMBA_CACHE_DIR"] = d
        out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, check=True)
    imp, first = (float(x) for x in out.stdout.split())
    return imp, first


def solver_table(steps: int) -> list[tuple]:
    """µs per step of the piston sliding on a wall (e = 0, h = 1e-4) with each contact solver:
    the loop's own by name, the others called back (each warmed up by the same run first: the
    first use of OSQP imports and sets it up, and its first refined answer compiles the exact
    refinement, ``moreau.contact.refine``, 9-10 s on an empty cache)."""
    model = piston_model(PistonParameters(e=0.0))
    q0, v0 = model.initial_state(phi1=np.radians(60.0))  # adjoining the left wall, sliding
    lim = model.params.clearance / model.params.l1
    solvers = {
        "exact (the loop's own)": lambda: "exact",
        "enum (the loop's own)": lambda: "enum",
        "osqp (set up once, update; called back)": mo.OSQPSolver,
        "qpsolvers:osqp (rebuilt every step)": lambda: mo.QpsolversSolver("osqp", eps_abs=1e-9, eps_rel=1e-9,
                                                                          polish=True),
        "daqp (called back)": lambda: mo.make_solver("daqp"),
        "quadprog (called back)": lambda: mo.make_solver("quadprog"),
    }
    rows = []
    for name, make in solvers.items():
        fallback = "exact" if name.startswith("enum") else "enum"
        us_per_step(model.scene, q0, v0, steps, solver=make(), fallback=fallback, penetration_limit=lim)
        rows.append((name, us_per_step(model.scene, q0, v0, steps, solver=make(), fallback=fallback,
                                       penetration_limit=lim)))
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short runs, no fresh compile (< 30 s)")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    us_per_step(*chain_scene(3, True), 10, h=1e-3, backend="compiled")  # load (or compile) first
    print("\nµs per step of the compiled loop (piston: best of 3)")
    print(f"{'case':40s} {'steps':>8s} {'µs/step':>9s}")
    table = piston_table(args.quick) + chain_table(args.quick) + stable_chain_table(args.quick) + \
        four_bar_table(args.quick) + user_scene_table(args.quick)
    for name, cs, comp in table:
        print(f"{name:40s} {cs:8d} {comp:9.3f}")
    cost = {name: comp for name, _, comp in table}
    piston = cost["piston e = 0 + engine drift control, mu = 0.05"] / cost["piston e = 0 + engine drift control"]
    chain = cost["chain N = 24, on a rough floor (mu 0.5)"] / cost["chain N = 24, on the floor"]
    print(f"\nfriction: the piston at mu = 0.05 costs {piston:.2f}x its frictionless step; "
          f"the 24-link chain on a rough floor {chain:.1f}x on a smooth one")
    falling = cost["chain N = 40 falling on a floor, energy-c."] / cost["chain N =  3, on the floor"]
    ec3 = cost["chain N =  3, on the floor, energy-cons."] / cost["chain N =  3, on the floor"]
    print(f"energy-consistent step: the 40-link chain falling on a floor costs {falling:.0f}x the 3-link chain's "
          f"midpoint step on the floor (issue 26 asks <= 10x), {falling / ec3:.1f}x its energy-consistent step; "
          f"the 3-link chain {ec3:.1f}x its midpoint step")
    lying = cost["chain N = 40, on the floor"] / cost["chain N =  3, on the floor"]
    print(f"the 40-link chain lying on the floor (40 rows in contact) costs {lying:.0f}x the 3-link chain's step "
          "(midpoint step both)")
    readme = cost["README example, plain lambdas"] / cost["README example, @njit callables"]
    callback = cost["README example, gap a Python callback"] / cost["README example, @njit callables"]
    print(f"a user's scene: the README example as written costs {readme:.2f}x the same with @njit callables "
          f"(issue 41 asks <= 2x); with its gap a Python callback {callback:.0f}x (<= 50x)")
    new, again = rebuilt_scene_calls()
    print(f"the README example built anew in a user's loop: simulate() {new:.2f} s for a slope not run before "
          f"(its callables compiled), {again * 1e3:.1f} ms for one run before (reused)")
    every, sparse, wsteps = woodpecker_call(args.quick)
    print(f"the woodpecker's whole simulate() call, {wsteps} steps: every step recorded {every:.3f} s, every 100th "
          f"{sparse:.3f} s ({every / sparse:.2f}x; issue 41 asks <= 1.5x)")
    call, loop, steps = short_run_call()
    print(f"a short run (the forced triple pendulum, {steps} steps): the whole simulate() call {call * 1e3:.2f} ms, "
          f"its loop {loop * 1e3:.2f} ms (checks, set-up and result {(call - loop) * 1e3:.2f} ms)")
    from moreau.problems.piston.pressure import calibrated_pressure

    fp = calibrated_pressure()
    fp(0.0)  # a first call outside the timing
    calls = 20_000
    t0 = time.perf_counter()
    for i in range(calls):
        fp(0.001 * i)
    print(f"the piston's gas pressure, one scalar evaluation in Python: "
          f"{(time.perf_counter() - t0) / calls * 1e6:.2f} µs")
    imp, load = startup_times(fresh=False)
    print(f"\nnew process: import moreau {imp:.2f} s; first piston run, loop loaded from the cache {load:.2f} s")
    if not args.quick:
        imp, comp = startup_times(fresh=True)
        print(f"new process, empty numba cache: first piston run (compiling the loop) {comp:.1f} s")
    print("\ncontact solvers, piston sliding on a wall (e = 0), µs per contact-heavy step")
    for name, us in solver_table(2_000 if args.quick else 20_000):
        print(f"{name:40s} {us:9.1f}")
    print(f"\n(benchmark wall time {time.perf_counter() - t_start:.0f} s)")


if __name__ == "__main__":
    main()
