"""How the velocity-dependent forces' treatment decides a long chain's energy (issue 26).

The 40-link chain of ``tests/hard_cases/test_long_chain.py`` (uniform rods of 0.05 kg and
2.5 cm hanging from the origin, released at rest horizontally under gravity, no contact,
2 s) has a fast-moving tail that whips. With the explicit midpoint step
(:class:`moreau.MoreauJeanMidpoint`: the centrifugal terms of the chain's configuration-
dependent M evaluated at v_k) the energy runs away at h = 1e-3. This study steps the
same chain, in numpy, with the midpoint step and three treatments of those terms, and
prints how far the mechanical energy rises above its start (gravity is the only force and
is conservative, so the exact flow keeps it constant) as a fraction of m g L:

* ``explicit``: bias N(q_m) (v_k ∘ v_k), moreau's midpoint step;
* ``linearly implicit``: bias N(q_m) (v_k ∘ v⁺), linear in v⁺ (Siconos' θ-method with
  θ = ½ on these terms, its Jacobian ∂f/∂v in the step's matrix; here the two coincide);
* ``implicit in v``: bias N(q_m) (v̄ ∘ v̄), v̄ = (v_k + v⁺)/2, solved by Newton's method
  to round-off (q_m = q_k + h/2 v_k as in the midpoint step);
* ``implicit midpoint``: the same with q_m = q_k + h/2 v̄ (M, N and gravity at the
  midpoint of q_k and q⁺).

Here the bias force is ``f_bias(q, v) = N(q) (v ∘ v)`` (absolute link angles: only
squared velocities appear), N's columns taken from
:meth:`moreau.model.chain.PendulumChain.bias_force` on unit vectors.

    python benchmarks/long_chain_schemes.py              # h = 1e-3, every scheme (~30 s)
    python benchmarks/long_chain_schemes.py --h 1e-4     # one tenth of that step (~3 min)

Measured (2026-11-26), largest rise / change at the end, in m g L:

========================  =================  =================
scheme                    h = 1e-3           h = 1e-4
========================  =================  =================
explicit                  20 (blew up at     0.037 / 0.029
                          step 1369)
linearly implicit         0.030 / -0.141     0.0002 / -0.0021
implicit in v             0.011 / -0.053     0.0001 / -0.0005
implicit midpoint         0.024 / +0.012     0.0002 / -0.0000
========================  =================  =================

Every treatment but the explicit one stays bounded at h = 1e-3, and none keeps the energy
within 1 % of m g L there (issue 26's bar); from 1e-3 to 1e-4 the linearly implicit
step's end error falls 67-fold (about second order), so it meets 1 % near h = 2.7e-4.

The last row is moreau's answer, :class:`moreau.MoreauJeanEnergyConsistent` (implicit in v
like the third scheme, with the bias force corrected along Δq so that the kinetic energy
changes by exactly the work of gravity): its energy error is only that of the midpoint
quadrature of gravity's work, 9.3e-5 / 9.3e-5 of m g L at h = 1e-3 (compiled, 2026-11-26).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core: the study is small dense algebra
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from moreau.model.chain import ChainGravity, Link, PendulumChain  # noqa: E402

N_LINKS, M_LINK, L_LINK = 40, 0.05, 0.025
SCHEMES = ("explicit", "linearly implicit", "implicit in v", "implicit midpoint")


def chain_model(n: int = N_LINKS):
    chain = PendulumChain([Link.rod(m=M_LINK, l=L_LINK) for _ in range(n)])
    return chain, ChainGravity(chain)


def bias_matrix(chain: PendulumChain, q: np.ndarray) -> np.ndarray:
    """N(q), shape (n, n): the bias force is N(q) (v ∘ v)."""
    eye = np.eye(q.size)
    return np.column_stack([chain.bias_force(q, eye[j]) for j in range(q.size)])


def run(scheme: str, h: float, T: float = 2.0, n: int = N_LINKS) -> dict:
    """Step the chain with ``scheme`` for T seconds at step h; returns the largest rise of
    the energy above its start and its change at the end (both / m g L), the steps taken
    and the Newton iterations per step."""
    chain, grav = chain_model(n)
    mgl = n * M_LINK * 9.81 * n * L_LINK

    def energy(q, v):
        return 0.5 * v @ chain.mass_matrix(q) @ v + grav.potential(q)

    q, v = np.full(n, np.pi / 2), np.zeros(n)
    e0 = energy(q, v)
    rise, iters, k, de = 0.0, 0, 0, 0.0
    t = time.perf_counter()
    while k < int(round(T / h)):
        k += 1
        if scheme in ("explicit", "linearly implicit"):
            qm = q + 0.5 * h * v
            M, Nm, g = chain.mass_matrix(qm), bias_matrix(chain, qm), grav.force(0.0, qm, v)
            if scheme == "explicit":
                v_new = v + np.linalg.solve(M, h * (g + Nm @ (v * v)))
            else:
                v_new = np.linalg.solve(M - h * Nm * v[None, :], M @ v + h * g)
        else:
            v_new = v.copy()
            for _ in range(50):
                vb = 0.5 * (v + v_new)
                qm = q + 0.5 * h * (v if scheme == "implicit in v" else vb)
                M, Nm, g = chain.mass_matrix(qm), bias_matrix(chain, qm), grav.force(0.0, qm, v)
                r = M @ (v_new - v) - h * (g + Nm @ (vb * vb))
                # Newton: exact with q_m held; the implicit midpoint leaves out q_m's dependence on v⁺
                d = np.linalg.solve(M - h * Nm * vb[None, :], -r)
                v_new = v_new + d
                iters += 1
                if np.abs(d).max() < 1e-12 * (1.0 + np.abs(v_new).max()):
                    break
        q, v = q + 0.5 * h * (v + v_new), v_new
        de = energy(q, v) - e0
        rise = max(rise, de)
        if not np.isfinite(de) or rise > 10 * mgl:
            break
    return dict(steps=k, rise=rise / mgl, end=de / mgl, iters=iters / k,
                us=(time.perf_counter() - t) / k * 1e6)


def run_moreau(h: float, T: float = 2.0, n: int = N_LINKS, backend: str = "compiled") -> dict:
    """The same chain with :class:`moreau.MoreauJeanEnergyConsistent` (the implicit,
    energy-consistent treatment of these terms, iterated to 1e-10); the same figures."""
    import moreau as mo

    chain, grav = chain_model(n)
    mgl = n * M_LINK * 9.81 * n * L_LINK
    traj = mo.simulate(mo.Scene(chain, [grav]), (0.0, T), np.full(n, np.pi / 2), np.zeros(n), h, backend=backend,
                       integrator=mo.MoreauJeanEnergyConsistent)
    de = traj.energy - traj.energy[0]
    return dict(steps=traj.stats.steps, rise=float(de.max()) / mgl, end=float(de[-1]) / mgl, iters=float("nan"),
                us=traj.stats.us_per_step)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--h", type=float, default=1e-3, help="step size (s), default 1e-3")
    ap.add_argument("--T", type=float, default=2.0, help="simulated time (s), default 2")
    args = ap.parse_args()
    steps = int(round(args.T / args.h))
    print(f"40-link chain, free, h = {args.h:g}, {args.T:g} s ({steps} steps); energy / m g L above its start")
    print(f"{'scheme':20s} {'steps':>7s} {'largest rise':>13s} {'at the end':>11s} {'Newton/step':>12s} "
          f"{'us/step (numpy)':>16s}")
    for s in SCHEMES:
        r = run(s, args.h, args.T)
        print(f"{s:20s} {r['steps']:7d} {r['rise']:13.4f} {r['end']:11.4f} {r['iters']:12.2f} {r['us']:16.0f}",
              flush=True)
    r = run_moreau(args.h, args.T)
    print(f"{'energy-consistent':20s} {r['steps']:7d} {r['rise']:13.2e} {r['end']:11.2e} {'':>12s} {r['us']:16.0f}"
          "  (moreau, compiled)")


if __name__ == "__main__":
    main()
