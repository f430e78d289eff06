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


@pytest.fixture(scope="session", autouse=True)
def loop_variants_side_by_side(request):
    """Under pytest-xdist, the first two workers load what the suite compiles before their
    first test: on an empty cache gw0 compiles the plain and the friction variants of the
    compiled loop (:data:`moreau.compiled.variants.VARIANTS`) with step-size control's judge
    of each, while gw1 compiles OSQP's exact refinement and the tangent map's smooth steps,
    then the full variant and its judge (each under its own lock), so that no test compiles
    one of them or waits for another worker's compile."""
    worker = getattr(request.config, "workerinput", {}).get("workerid")
    if worker in ("gw0", "gw1"):
        from moreau.compiled.cache import ensure_judged

        if worker == "gw1":
            from moreau.contact.refine import ensure_loaded

            ensure_loaded()
            _tangent_steps_loaded()
            ensure_judged("full")
        else:
            ensure_judged("plain")
            ensure_judged("friction")


def _tangent_steps_loaded():
    """Load (or compile) ``moreau.compiled.tangent.smooth_steps`` with the argument types
    ``lyapunov_spectrum_tangent`` passes: one smooth step of the free ball."""
    import numpy as np

    from moreau.dynamics.tangent import _compiled_smooth_steps
    from moreau.problems.bouncing_ball import bouncing_ball

    X = np.hstack([np.ones((2, 1)), np.zeros((2, 1))])
    _compiled_smooth_steps(bouncing_ball(0.5), 1e-7)(0.0, 1e-3, X, 0, 1, np.ascontiguousarray(np.eye(2)))


# modules with tests that run the loop's full variant (friction, bilateral rows, the later
# passes), in their own process or in a command's: on an empty cache they wait for its compile
_FULL_VARIANT = ("constraints/", "friction/", "hard_cases/test_fault_injection.py",
                 "hard_cases/test_long_chain_stable.py", "test_compiled.py", "test_docs.py", "test_drift_theta.py",
                 "test_event_driven.py", "test_load.py", "test_notebooks.py", "test_prebuilt.py", "test_user_scenes.py",
                 "test_work_precision.py")


def pytest_collection_modifyitems(config, items):
    """The modules that need the full variant last (a stable sort: each module's order
    kept): on an empty cache the worker that compiled the plain variant runs the others
    while the full one still compiles (loop_variants_side_by_side), instead of waiting."""
    items.sort(key=lambda item: item.nodeid.split("::")[0].removeprefix("tests/").startswith(_FULL_VARIANT))


@pytest.fixture
def cli_error(capsys):
    """Run the command line in this process, ``cli_error(*args, code=2)``: it must exit with
    ``code`` having written nothing to stdout and one line, no traceback, to stderr; returns
    that line, without the cost of a new process (tests/test_cli.py and
    tests/test_bad_inputs.py run the command as its own process)."""
    from moreau.cli import main

    def run(*args: str, code: int = 2) -> str:
        try:
            rc = main(list(args))
        except SystemExit as exc:  # argparse's errors
            rc = exc.code
        said = capsys.readouterr()
        assert rc == code, said.err
        assert said.out == "" and "Traceback" not in said.err, said
        lines = said.err.strip().splitlines()
        assert len(lines) == 1, said.err
        return lines[0]

    return run
