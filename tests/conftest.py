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
    """The triple pendulum with a wall in its chaotic regime on its attractor:
    :func:`moreau.dynamics.benchmarks.chaotic_pendulum`, ``(scene, q0, v0, t0, T)``."""
    from moreau.dynamics.benchmarks import chaotic_pendulum

    return chaotic_pendulum()


#: Tests that run without the compiled loop (the numpy reference of tests/oracle, the solvers
#: on their own; no subprocess), found with a plugin recording which tests call
#: ``ensure_compiled``. Under pytest-xdist they open the second worker's first batch: on an
#: empty cache one worker compiles the time loop (about 90 s) and the other used to wait on
#: the compile lock in its first compiled test meanwhile; now it runs these. A name missing
#: here costs only that wait.
NO_LOOP_FIRST = (
    "test_painleve_rod_tangential_impact",
    "test_block_pressed_on_two_corners_leaves_without_spin",
    "test_exact_solver_agrees_with_enumeration_and_osqp_on_2000_random_problems",
    "test_located_impacts_leave_the_block_rocking_at_coarse_h",
    "test_friction_routes_agree_with_lemke",
)


@pytest.hookimpl(trylast=True)  # after the -m selection: the chunk is of the tests that run
def pytest_collection_modifyitems(session, config, items):
    """Under xdist, put the tests without the loop at the start of the second worker's first batch
    (xdist's load scheduling sends each worker a consecutive chunk of a quarter of its
    share first); the order is the same in every worker, as xdist requires."""
    workers = getattr(config, "workerinput", {}).get("workercount", 0)
    if workers < 2:
        return
    first = [it for it in items if it.originalname in NO_LOOP_FIRST]
    rest = [it for it in items if it.originalname not in NO_LOOP_FIRST]
    chunk = max(2, len(items) // workers // 4)
    items[:] = rest[:chunk] + first + rest[chunk:]
