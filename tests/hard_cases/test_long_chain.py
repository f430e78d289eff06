"""A 40-link chain (issue 26): uniform rods of 0.05 kg and 2.5 cm hanging from the origin,
released at rest horizontally under gravity. With the explicit midpoint step at h = 1e-3
its fast tail makes the step unstable (the energy used to reach 1e238 J before the state
became non-finite); the energy check (moreau.model.stability) must say so early: a
warning before the energy has risen by 5 % of m g L, then a SimulationError that names the
step size and a smaller one, with the trajectory kept and finite."""

import re
import warnings

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow

N, M_LINK, L_LINK = 40, 0.05, 0.025
MGL = N * M_LINK * 9.81 * N * L_LINK  # the chain's m g L (19.6 J)
Q0, V0 = np.full(N, np.pi / 2), np.zeros(N)


def chain_scene(floor: bool, e: float = 0.0) -> mo.Scene:
    chain = PendulumChain([Link.rod(m=M_LINK, l=L_LINK) for _ in range(N)])
    contacts = []
    if floor:
        rows = [PointLineRow(i, (L_LINK, 0.0), line_point=(0.0, -0.3), normal=(0.0, 1.0)) for i in range(N)]
        contacts = [mo.Contact(PointLineBarrier(chain, rows), e, name="floor")]
    return mo.Scene(chain, [ChainGravity(chain)], contacts)


def _time_in(message: str) -> float:
    return float(re.search(r"by t = ([0-9.eE+-]+)", message).group(1))


@pytest.mark.parametrize("backend", ["compiled", "python"])
@pytest.mark.parametrize(("floor", "e"), [(False, 0.0), (True, 0.0), (True, 0.5)])
def test_the_explicit_step_at_h_1e3_warns_then_stops_before_the_energy_runs_away(backend, floor, e):
    scene = chain_scene(floor, e)
    with pytest.warns(RuntimeWarning, match="energy grew") as caught, pytest.raises(mo.SimulationError) as info:
        oracle.simulate(scene, (0.0, 2.0), Q0, V0, 1e-3, backend=backend, solver="exact")
    warned = [str(w.message) for w in caught if "energy grew" in str(w.message)]
    assert len(warned) == 1  # warns once
    msg = str(info.value)
    assert "energy grew" in msg and "h = 0.001" in msg
    advice = float(re.search(r"about h = ([0-9.eE+-]+)", msg).group(1))
    assert 0.0 < advice < 1e-3  # names a smaller step
    traj = info.value.trajectory
    assert traj.status == "failed" and traj.t[-1] < 2.0
    assert np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.v)) and np.all(np.isfinite(traj.energy))
    # kept up to the last check that passed: the runaway after it is not in the trajectory
    assert f"kept up to t = {traj.t[-1]:.9g}" in msg and traj.t[-1] < _time_in(msg)
    assert (traj.energy - traj.energy[0]).max() <= 0.1 * MGL
    # the warning came no later than the first record with the mechanical energy 5 % of
    # m g L above its start
    t_warn = _time_in(warned[0])
    risen = np.flatnonzero(traj.energy - traj.energy[0] > 0.05 * MGL)
    assert risen.size == 0 or t_warn <= traj.t[risen[0]] + 1e-12
    assert t_warn < _time_in(msg)


def test_both_paths_stop_at_the_same_step():
    scene = chain_scene(False)
    stops, said = [], []
    for backend in ("compiled", "python"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            with pytest.raises(mo.SimulationError) as info:
                oracle.simulate(scene, (0.0, 2.0), Q0, V0, 1e-3, backend=backend, solver="exact")
        stops.append(info.value.step)
        said.append((info.value.trajectory.warnings, str(info.value), info.value.trajectory.t[-1]))
    assert stops[0] == stops[1]
    assert said[0] == said[1]  # the same figures in the warning and the error, the same kept end


def test_without_the_check_the_same_run_only_stops_at_non_finite_numbers():
    with pytest.raises(mo.SimulationError, match="non-finite") as info:
        mo.simulate(chain_scene(False), (0.0, 2.0), Q0, V0, 1e-3, energy_growth=None)
    assert info.value.step > 1000  # hundreds of steps after the check would have stopped it


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_resolved_run_is_not_flagged(backend):
    """Three rods of 0.3 kg and 0.3 m at h = 1e-3 (free, then on a floor with e = 0.5, whose
    impacts only remove energy): resolved, so no warning on either path."""
    chain = PendulumChain([Link.rod(m=0.3, l=0.3) for _ in range(3)])
    rows = [PointLineRow(i, (0.3, 0.0), line_point=(0.0, -0.5), normal=(0.0, 1.0)) for i in range(3)]
    for contacts in ([], [mo.Contact(PointLineBarrier(chain, rows), 0.5, name="floor")]):
        scene = mo.Scene(chain, [ChainGravity(chain)], contacts)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            traj = oracle.simulate(scene, (0.0, 2.0), np.full(3, np.pi / 2), np.zeros(3), 1e-3, backend=backend,
                               solver="exact")
        assert traj.status == "completed" and not traj.warnings


@pytest.mark.parametrize("bad", [(0.1,), (0.0, 0.1), (0.2, 0.1), ("a", "b"), (0.1, float("inf")), 0.1])
def test_a_bad_energy_growth_is_refused_naming_it(bad):
    with pytest.raises(ValueError, match="energy_growth"):
        mo.simulate(chain_scene(False), (0.0, 0.01), Q0, V0, 1e-3, energy_growth=bad)
