import os

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def compiled_loop_in_cache():
    """Have the compiled loop in numba's cache before a test starts commands that are
    interrupted a second after they begin stepping: they then load it, not compile it."""
    import moreau as mo
    from moreau.problems.bouncing_ball import bouncing_ball

    mo.simulate(bouncing_ball(0.5), (0.0, 0.01), [1.0], [0.0], 1e-3, backend="compiled")


@pytest.fixture(scope="session")
def chaotic_pendulum():
    """The triple pendulum with a wall in its chaotic regime (torque 3 sin(6 t) N m,
    ``notebooks/triple_pendulum.py``), on its attractor after 100 forcing periods of
    transient at T/h = 400: ``(scene, q0, v0, t0, T)``."""
    import numpy as np

    import moreau as mo
    from moreau.dynamics.benchmarks import forced_triple_pendulum

    w = 6.0
    T = 2 * np.pi / w
    scene = forced_triple_pendulum(w, 3.0)
    tr = mo.simulate(scene, (0.0, 100 * T), [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], T / 400, solver="enum",
                     record_every=400, progress=False)
    return scene, tr.q[-1], tr.v[-1], tr.t[-1], T
