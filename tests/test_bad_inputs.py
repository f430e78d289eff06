"""Bad-input catalogue: every public constructor and the front door refuse bad values with
a clear exception that names the bad value; a property-based test throws generated
garbage at them and checks that only the documented exceptions come out.

Already covered elsewhere, not repeated here:

* ``tests/test_api.py``: NaN/inf q0 and v0, wrongly shaped q0, h <= 0 and NaN, a
  reversed or infinite t_span, an initial penetration (ball), an unknown solver name,
  record_every = 0, e outside [0, 1] (NewtonImpact, bouncing_ball), a mass matrix not
  SPD or not symmetric (constant and callable), a negative ball mass, a force and a
  Jacobian of the wrong shape, a gap that is NaN at the start, a missing / not-a-zip /
  foreign .npz file;
* ``tests/test_chain.py``: zero links, a link with NaN inertia, negative mass or length,
  zero inertia, a bad orientation, a point or a PointLineRow on a link out of range, a
  zero wall normal, JointStop bounds;
* ``tests/test_piston.py``: D <= d, a negative piston mass, e out of range, an unknown
  effect; ``tests/test_cli.py``: ``moreau ball --e 1.5`` and ``--h -1``, ``piston --D 79``;
* ``tests/hard_cases/test_initial_state.py``: a penetrating piston (rows and gaps named);
  ``tests/hard_cases/test_fault_injection.py``: FaultInjectingSolver's own arguments.

Bugs this catalogue found (now fixed) have their own tests at the end of part 1.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from numbers import Real

import numpy as np
import oracle
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import moreau as mo
from moreau.cli import main
from moreau.model.chain import ChainGravity, JointDamping, Link, PendulumChain, PointForce
from moreau.problems.bouncing_ball import bouncing_ball
from moreau.problems.piston import PistonParameters, piston_model

DOCUMENTED = (ValueError, mo.SolverError, mo.SimulationError)


def ball():
    return bouncing_ball(0.5)


def sim(scene=None, t_span=(0.0, 0.01), q0=(1.0,), v0=(0.0,), h=1e-3, **kw):
    return mo.simulate(ball() if scene is None else scene, t_span, q0, v0, h, **kw)


def point1(effects=(), contacts=(), mass=None, ndof=None):
    system = mo.FunctionSystem(np.eye(1) if mass is None else mass, ndof=ndof)
    return mo.Scene(system, effects, contacts)


def floor_contact(gap=None, jac=None, nrows=1, name="floor"):
    barrier = mo.FunctionBarrier(gap or (lambda q: np.array([q[0]])), jac or (lambda q: np.array([[1.0]])), nrows=nrows)
    return mo.Contact(barrier, 0.5, name=name)


def chain3():
    return PendulumChain([Link.rod(1.0, 1.0)] * 3)


def saved(tmp_path, mutate):
    """A valid saved trajectory, with its arrays/metadata changed by ``mutate(dict)``."""
    path = sim().save(tmp_path / "good.npz")
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    mutate(data)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **data)
    return bad


def set_meta(data, **changes):
    meta = json.loads(str(data["meta"]))
    meta.update(changes)
    data["meta"] = np.array(json.dumps(meta))


def truncated(tmp_path):
    path = sim().save(tmp_path / "good.npz")
    raw = open(path, "rb").read()
    bad = tmp_path / "truncated.npz"
    bad.write_bytes(raw[: len(raw) // 2])
    return bad


# -- part 1: the catalogue -------------------------------------------------------------------
# (kind, call, exception, message that names the bad value)
CATALOGUE = [
    # the front door: time span, step, states, options
    ("t_span with NaN", lambda: sim(t_span=(np.nan, 1.0)), ValueError, r"t_span must be finite, got \(nan, 1\.0\)"),
    ("t_span of one number", lambda: sim(t_span=(0.0,)), ValueError, r"t_span must be two numbers \(t0, t1\), got \(0\.0,\)"),
    ("t_span empty interval", lambda: sim(t_span=(1.0, 1.0)), ValueError, r"t1 > t0, got t_span = \(1\.0, 1\.0\)"),
    ("h longer than t_span", lambda: sim(t_span=(0.0, 0.001), h=0.01), ValueError,
     r"step size h = 0\.01 is longer than t_span = \(0\.0, 0\.001\): the run would end at t = 0\.01; give h <= 0\.001"),
    ("h infinite", lambda: sim(h=np.inf), ValueError, "step size h must be finite and positive, got inf"),
    ("h not a number", lambda: sim(h="fast"), ValueError, "step size h must be a number, got 'fast'"),
    ("q0 of strings", lambda: sim(q0=["up"]), ValueError, r"q0 must be an array of numbers, got \['up'\]"),
    ("v0 two-dimensional", lambda: sim(v0=[[0.0]]), ValueError, r"v0 must be one-dimensional, got shape \(1, 1\)"),
    ("t0 NaN via integrator", lambda: oracle.MoreauJeanMidpoint(ball(), 1e-3).init(np.nan, [1.0], [0.0]), ValueError,
     "t0 must be finite, got nan"),
    ("tol zero", lambda: sim(tol=0.0), ValueError, "tol must be finite and positive, got 0.0"),
    ("record_every fractional", lambda: sim(record_every=2.5), ValueError, "record_every must be a positive integer, got 2.5"),
    ("record_every boolean", lambda: sim(record_every=True), ValueError, "record_every must be a positive integer, got True"),
    ("integrator not a class", lambda: sim(integrator="midpoint"), ValueError,
     "integrator must be a OneStepIntegrator subclass, got 'midpoint'"),
    ("scene not a Scene", lambda: mo.simulate("ball", (0, 1), [1.0], [0.0], 1e-3), ValueError, "scene must be a Scene, got 'ball'"),
    ("solver not a name", lambda: sim(solver=42), ValueError, "solver must be a name or a ContactSolver, got 42"),
    ("fallback unknown", lambda: sim(fallback="cplex"), ValueError, "unknown solver 'cplex'"),
    ("fallback is the solver", lambda: (lambda s: sim(solver=s, fallback=s))(mo.EnumerationSolver()), ValueError,
     "fallback must be another solver than the main one, got .enum. twice"),
    # issue 11 F: undocumented input is refused, not converted
    ("h boolean", lambda: sim(h=True), ValueError, "step size h must be a number, got True"),
    ("h a numeric string", lambda: sim(h="0.001"), ValueError, "step size h must be a number, got '0.001'"),
    ("tol boolean", lambda: sim(tol=True), ValueError, "tol must be a number, got True"),
    ("t_span a dict", lambda: sim(t_span={0: 0.0, 1: 0.01}), ValueError,
     r"t_span must be two numbers \(t0, t1\), got \{0: 0\.0, 1: 0\.01\}"),
    ("t_span of numeric strings", lambda: sim(t_span=("0", "0.01")), ValueError,
     r"t_span must be two numbers \(t0, t1\), got \('0', '0\.01'\)"),
    ("t_span a set", lambda: sim(t_span={0.0, 0.01}), ValueError, "t_span must be two numbers"),
    ("t_span of booleans", lambda: sim(t_span=(False, True)), ValueError, "t_span must be two numbers"),
    ("q0 None", lambda: sim(q0=None), ValueError, "q0 must be an array of numbers, got None"),
    ("q0 boolean", lambda: sim(q0=[True]), ValueError, r"q0 must be an array of numbers, got \[True\]"),
    ("v0 numeric string", lambda: sim(v0=["0"]), ValueError, r"v0 must be an array of numbers, got \['0'\]"),
    ("q0 complex", lambda: sim(q0=[1.0 + 0j]), ValueError, "q0 must be an array of numbers"),
    ("NewtonImpact boolean", lambda: mo.NewtonImpact(True), ValueError, "restitution e must be a number in \\[0, 1\\], got True"),
    ("NewtonImpact numeric string", lambda: mo.NewtonImpact("0.5"), ValueError, "restitution e must be a number in \\[0, 1\\], got '0.5'"),
    ("Contact law boolean", lambda: mo.Contact(mo.LinearBarrier([[1.0]]), True), ValueError, "got True"),
    ("FunctionSystem empty mass", lambda: mo.FunctionSystem(np.zeros((0, 0))), ValueError,
     r"mass must not be empty, got shape \(0, 0\)"),
    ("FunctionSystem ndof boolean", lambda: mo.FunctionSystem(np.eye(1), ndof=True), ValueError,
     "ndof must be a positive integer, got True"),
    ("mass of booleans", lambda: mo.FunctionSystem([[True]]), ValueError, r"mass must be an array of numbers, got \[\[True\]\]"),
    ("gap raising at t0", lambda: sim(point1(contacts=[floor_contact(gap=lambda q: np.array([1.0 / int(q[0] - q[0])]))])), ValueError,
     r"gap of contact 'floor' raised ZeroDivisionError at the initial state \(t0 = 0\.0, q0 = \[1\.0\]\)"),
    ("force raising at t0", lambda: sim(point1([mo.FunctionForce(lambda t, q, v: {}["x"], name="thrust")])), ValueError,
     "force of effect 'thrust' raised KeyError at the initial state"),
    # systems: mass matrices
    ("negative inertia (FunctionSystem)", lambda: mo.FunctionSystem(np.diag([2.0, 2.0, -0.1])), ValueError,
     r"mass is not positive definite \(smallest eigenvalue -0\.1\)"),
    ("mass with NaN", lambda: mo.FunctionSystem([[1.0, np.nan], [np.nan, 1.0]]), ValueError, "mass has non-finite entries"),
    ("mass not square", lambda: mo.FunctionSystem(np.ones((2, 3))), ValueError, r"mass must be square, got shape \(2, 3\)"),
    ("ndof missing for callable mass", lambda: mo.FunctionSystem(lambda q: np.eye(1)), ValueError,
     "ndof is required when mass is a callable"),
    ("ndof zero", lambda: mo.FunctionSystem(lambda q: np.eye(1), ndof=0), ValueError, "ndof must be a positive integer, got 0"),
    ("ndof mismatch", lambda: mo.FunctionSystem(np.eye(2), ndof=3), ValueError, r"ndof=3 does not match mass of shape \(2, 2\)"),
    ("callable mass of wrong shape", lambda: sim(point1(mass=lambda q: np.eye(2), ndof=1)), ValueError,
     r"mass matrix at the initial state has shape \(2, 2\), expected \(1, 1\)"),
    ("callable mass with inf", lambda: sim(point1(mass=lambda q: np.array([[np.inf]]), ndof=1)), ValueError,
     r"mass matrix at the initial state has non-finite entries: \[\[inf\]\]"),
    # effects
    ("non-finite force", lambda: sim(point1([mo.FunctionForce(lambda t, q, v: np.array([np.inf]), name="thrust")])),
     ValueError, r"force of effect 'thrust' at the initial state is not finite: \[inf\]"),
    ("ConstantForce with NaN", lambda: mo.ConstantForce([np.nan]), ValueError, r"ConstantForce\.f has non-finite entries: \[nan\]"),
    ("damping not PSD", lambda: mo.LinearDamping([[1.0, 0.0], [0.0, -1.0]]), ValueError,
     r"LinearDamping\.C must be positive semi-definite, got \[\[1\.0, 0\.0\], \[0\.0, -1\.0\]\]"),
    ("scalar damping without ndof", lambda: mo.LinearDamping(0.3), ValueError, "ndof is required for a scalar C"),
    ("spring not symmetric", lambda: mo.LinearSpring([[1.0, 2.0], [0.0, 1.0]]), ValueError,
     r"LinearSpring\.K must be square and symmetric, got \[\[1\.0, 2\.0\], \[0\.0, 1\.0\]\]"),
    ("force not callable", lambda: mo.FunctionForce(9.81), ValueError, "fun must be callable, got 9.81"),
    # barriers and contacts
    ("gap of wrong shape", lambda: sim(point1(contacts=[floor_contact(gap=lambda q: np.zeros(2))])), ValueError,
     r"gap of contact 'floor' at the initial state has shape \(2,\), expected \(1,\)"),
    ("Jacobian with NaN", lambda: sim(point1(contacts=[floor_contact(jac=lambda q: np.array([[np.nan]]))])), ValueError,
     r"Jacobian of contact 'floor' at the initial state is not finite: \[\[nan\]\]"),
    ("barrier all-zero row", lambda: mo.LinearBarrier([[0.0, 0.0]]), ValueError, r"LinearBarrier\.A has an all-zero row: \[\[0\.0, 0\.0\]\]"),
    ("barrier offsets of wrong size", lambda: mo.LinearBarrier([[1.0]], [0.0, 1.0]), ValueError,
     r"LinearBarrier\.b must have shape \(1,\), got shape \(2,\)"),
    ("barrier gap not callable", lambda: mo.FunctionBarrier("y", lambda q: q), ValueError, "gap and jacobian must be callables"),
    ("barrier with zero rows", lambda: mo.FunctionBarrier(lambda q: q, lambda q: q, nrows=0), ValueError,
     "nrows must be a positive integer, got 0"),
    ("check_jacobian of wrong shape", lambda: mo.check_jacobian(mo.FunctionBarrier(lambda q: q[:1], lambda q: np.ones((1, 3))), [0.0, 1.0]),
     ValueError, r"jacobian returned shape \(1, 3\), expected \(1, 2\)"),
    ("contact without a barrier", lambda: mo.Contact("floor", 0.5), ValueError, "barrier must be a Barrier, got 'floor'"),
    ("restitution per row, wrong count", lambda: mo.Contact(mo.LinearBarrier([[1.0]]), [0.5, 0.5], name="floor"), ValueError,
     "Contact 'floor': 2 restitution coefficients for 1 rows"),
    ("restitution per row, out of range", lambda: mo.Contact(mo.LinearBarrier([[1.0], [2.0]]), [0.5, 1.5]), ValueError,
     r"restitution e must be in \[0, 1\], got 1\.5"),
    # scenes
    ("system not a system", lambda: mo.Scene(np.eye(1)), ValueError, "Scene: system must be a MechanicalSystem"),
    ("effect not an Effect", lambda: point1(["gravity"]), ValueError, "Scene: effects must be Effect objects, got 'gravity'"),
    ("duplicate contact names", lambda: point1(contacts=[floor_contact(), floor_contact()]), ValueError,
     r"contact names must be unique, got \['floor', 'floor'\]"),
    ("barrier for another system", lambda: point1(contacts=[mo.Contact(mo.LinearBarrier([[0.0, 1.0]]), 0.5, "floor")]),
     ValueError, "contact 'floor' expects 2 coordinates, the system has 1"),
    # chains
    ("negative inertia (Link)", lambda: Link(m=1.0, J=-0.2, l=1.0, com=0.5), ValueError,
     r"Link\.J \(central moment of inertia, kg m\^2\) must be > 0, got -0\.2"),
    ("chain pivot with NaN", lambda: PendulumChain([Link.rod(1.0, 1.0)], pivot=(0.0, np.nan)), ValueError,
     r"PendulumChain\.pivot has non-finite entries: \[0\.0, nan\]"),
    ("point force on a missing link", lambda: PointForce(chain3(), 3, (0.0, 0.0), (1.0, 0.0)), ValueError,
     r"index 3 is out of range for a chain of 3 links \(0\.\.2\)"),
    ("negative joint damping", lambda: JointDamping(chain3(), [1.0, -1.0, 0.0]), ValueError, r"JointDamping\.c\[1\] must be >= 0, got (np\.float64\()?-1\.0"),
    ("gravity not finite", lambda: ChainGravity(chain3(), g=np.inf), ValueError, "ChainGravity: g must be finite, got inf"),
    # the piston
    ("negative inertia (PistonParameters)", lambda: PistonParameters(J1=-1.0), ValueError,
     "piston parameter J1 must be positive, got -1.0"),
    ("piston parameter not a number", lambda: PistonParameters(m1="heavy"), ValueError,
     "piston parameter m1 must be a finite number, got 'heavy'"),
    ("piston parameter NaN", lambda: PistonParameters(D=np.nan), ValueError, "piston parameter D must be a finite number, got nan"),
    ("pin below the piston", lambda: PistonParameters(h=0.09), ValueError, "pin depth h = 0.09 m must not exceed the piston height s = 0.08 m"),
    ("rod shorter than crank", lambda: PistonParameters(l2=0.03), ValueError, "rod length l2 = 0.03 m must exceed the crank radius l1 = 0.04 m"),
    ("piston restitution count", lambda: piston_model(e=[0.5, 0.5, 0.5]), ValueError, "3 restitution coefficients for 4 rows"),
]


@pytest.mark.parametrize("kind, call, exc, match", CATALOGUE, ids=[c[0] for c in CATALOGUE])
def test_catalogue(kind, call, exc, match):
    with pytest.raises(exc, match=match):
        call()


@pytest.mark.parametrize("mutate, match", [
    (lambda d: set_meta(d, format=99), r"is a moreau trajectory of file format 99, .* this moreau reads format 1"),
    (lambda d: set_meta(d, format="other"), r"is not a moreau trajectory \(format 'other'\)"),
    (lambda d: d.pop("q"), r"is incomplete: missing 'q'"),
    (lambda d: d.__setitem__("meta", np.array("{not json")), "'meta' field is not valid JSON .*Expecting property name"),
], ids=["newer format", "not a format", "array missing", "metadata not JSON"])
def test_corrupt_saved_trajectory(tmp_path, mutate, match):
    with pytest.raises(ValueError, match=match):
        mo.load(saved(tmp_path, mutate))


def test_unreadable_saved_trajectory(tmp_path):
    with pytest.raises(ValueError, match=r"cannot read trajectory file .*truncated\.npz"):
        mo.load(truncated(tmp_path))
    with pytest.raises(ValueError, match=r"cannot read trajectory file .*Is a directory"):
        mo.load(tmp_path)  # exists, but cannot be read as a file (root reads any file)


@pytest.mark.parametrize("argv, message", [
    (["piston", "--cycles", "0"], "argument --cycles: must be >= 1, got 0"),
    (["piston", "--e", "2"], r"argument --e: 2 is outside \[0, 1\]"),
    (["piston", "--h", "0.1"], r"argument --h: 0.1 is outside \(0, 0.05\]"),
    (["piston", "--transient", "-1"], "argument --transient: must be >= 0, got -1"),
    (["piston", "--solver", "gurobi"], "argument --solver: invalid choice: 'gurobi'"),
    (["ball", "--t-end", "nan"], r"argument --t-end: nan is outside \(0, inf\]"),
])
def test_cli_options_out_of_range(argv, message, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert len([line for line in err.splitlines() if "error:" in line]) == 1
    assert re.search(message, err.splitlines()[-1])


def test_cli_solver_whose_backend_is_not_installed_is_one_line_exit_2(tmp_path, monkeypatch, capsys):
    """``--solver`` offers every name make_solver knows (the parser does not import
    qpsolvers); a qpsolvers back-end that is not installed is refused by the run, by name."""
    import qpsolvers

    monkeypatch.setattr(qpsolvers, "available_solvers", [s for s in qpsolvers.available_solvers if s != "daqp"])
    assert main(["ball", "--solver", "daqp", "--t-end", "0.01", "--no-progress", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("moreau ball: error: ") and "'daqp'" in err[0], err
    assert not list(tmp_path.iterdir())  # nothing written


def test_cli_piston_negative_step_exits_2_with_one_error_line(cli_error):
    assert cli_error("piston", "--h", "-1") == "moreau piston: error: argument --h: -1 is outside (0, 0.05]"


# -- bugs this catalogue found, fixed; the tests keep them fixed ----------------------------
def test_cli_bad_option_is_exactly_one_line():
    r = subprocess.run([sys.executable, "-m", "moreau", "piston", "--h", "-1"], capture_output=True, text=True)
    assert r.stderr.strip().count("\n") == 0


def test_gap_becoming_nan_mid_run_is_an_error():
    def gap(q):
        return np.array([q[0]]) if q[0] > 0.5 else np.array([np.nan])

    scene = point1([mo.ConstantForce([-9.81])], [floor_contact(gap=gap)])
    with pytest.raises(mo.SimulationError, match="gap"):
        mo.simulate(scene, (0.0, 1.0), [1.0], [0.0], 1e-3)


@pytest.mark.parametrize("h", [5e-324, 1e-300])
def test_step_count_overflow_is_a_value_error_naming_h(h):
    with pytest.raises(ValueError, match="step size h"):
        sim(t_span=(0.0, 1.0), h=h)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_position_overflowing_mid_run_is_an_error():
    with pytest.raises(mo.SimulationError, match="non-finite"):
        sim(t_span=(0.0, 3.0), q0=[1.79e308], v0=[1e308], h=1.0)


@pytest.mark.parametrize("kw", [dict(contacts=[5]), dict(contacts="ab"), dict(effects=5), dict(contacts=None)],
                         ids=["int in contacts", "string contacts", "int effects", "None contacts"])
def test_scene_with_non_contacts_raises_value_error(kw):
    with pytest.raises(ValueError, match="Scene: "):
        mo.Scene(mo.FunctionSystem(np.eye(1)), **kw)


@pytest.mark.parametrize("links", [5, None], ids=["int", "None"])
def test_chain_of_non_links_raises_value_error(links):
    with pytest.raises(ValueError, match="link"):
        PendulumChain(links)


def test_saved_trajectory_with_non_object_metadata(tmp_path):
    with pytest.raises(ValueError, match="not a moreau trajectory"):
        mo.load(saved(tmp_path, lambda d: d.__setitem__("meta", np.array("[1, 2]"))))


def test_saved_trajectory_with_inconsistent_arrays(tmp_path):
    with pytest.raises(ValueError, match="q"):
        mo.load(saved(tmp_path, lambda d: d.__setitem__("q", d["q"][:5])))


# -- part 2: property-based -------------------------------------------------------------------
# Generated garbage for the public constructors and simulate: numbers of every kind (NaN,
# ±inf, huge, tiny, negative, booleans), strings, None, and nested lists of them of every
# shape. Only the documented exceptions may come out. The bug classes above are kept out
# of the generated inputs (non-iterable effects/contacts/links, non-Contact contacts, steps
# below 1e-6 of the span, which besides overflowing would take ~1e6+ steps) so that each
# property checks everything else; the tests above hold them.
# Budget: 1550 examples in all, ~15–30 s.
numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-10, max_value=10),
    st.integers(min_value=-3, max_value=3),
    st.booleans(),
)
atoms = st.one_of(numbers, st.none(), st.text(max_size=2))
values = st.recursive(atoms, lambda inner: st.lists(inner, max_size=3), max_leaves=9)
matrices = st.one_of(
    values,
    st.integers(1, 3).flatmap(lambda n: st.lists(st.lists(numbers, min_size=n, max_size=n), min_size=1, max_size=3)),
)

SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


def only_documented(call, *args, documented=None, **kw):
    """Call; a documented exception is fine, anything else fails the test. When the call
    is accepted, ``documented()`` (if given) must hold: what is accepted is what the
    docstrings promise, not whatever numpy can convert. Outcomes are counted as
    hypothesis events (``--hypothesis-show-statistics``)."""
    try:
        call(*args, **kw)
    except DOCUMENTED as exc:
        event(f"refused: {type(exc).__name__}")
    else:
        event("accepted")
        if documented is not None:
            assert documented(), f"accepted an undocumented input: {args!r} {kw!r}"


def is_number(x):
    """A real number that is not a bool (what the docs call a number)."""
    return isinstance(x, Real) and not isinstance(x, (bool, np.bool_))


def numeric(x):
    """A number, or a (nested) list of numbers."""
    if isinstance(x, (list, tuple)):
        return all(numeric(el) for el in x)
    return is_number(x)


@settings(max_examples=300, **SETTINGS)
@given(mass=matrices, ndof=st.one_of(st.none(), st.integers(-1, 4), numbers))
def test_function_system_properties(mass, ndof):
    only_documented(mo.FunctionSystem, mass, ndof=ndof,
                    documented=lambda: numeric(mass) and np.size(mass) > 0
                    and (ndof is None or (isinstance(ndof, int) and not isinstance(ndof, bool))))


@settings(max_examples=250, **SETTINGS)
@given(A=matrices, b=values, law=values)
def test_barrier_law_contact_properties(A, b, law):
    only_documented(mo.NewtonImpact, law, documented=lambda: is_number(law) and 0 <= law <= 1)
    only_documented(mo.LinearBarrier, A, b, documented=lambda: numeric(A) and (b is None or numeric(b)))
    try:
        barrier = mo.LinearBarrier(A, b)
    except ValueError:
        barrier = mo.LinearBarrier([[1.0]])
    only_documented(mo.Contact, barrier, law)


@settings(max_examples=200, **SETTINGS)
@given(n_effects=st.integers(0, 2), n_contacts=st.integers(0, 2), f=values, A=matrices,
       names=st.lists(st.sampled_from(["a", "b"]), min_size=2, max_size=2))
def test_scene_properties(n_effects, n_contacts, f, A, names):
    def build():
        system = mo.FunctionSystem(np.eye(2))
        effects = [mo.ConstantForce(f) for _ in range(n_effects)]
        contacts = [mo.Contact(mo.LinearBarrier(A), 0.5, name=names[i]) for i in range(n_contacts)]
        mo.Scene(system, effects, contacts)
    only_documented(build)


@settings(max_examples=250, **SETTINGS)
@given(fields=st.lists(numbers | atoms, min_size=4, max_size=5), n=st.integers(0, 3),
       pivot=values, orientation=st.one_of(st.sampled_from(["hanging", "inverted", "sideways"]), values))
def test_chain_properties(fields, n, pivot, orientation):
    only_documented(Link, *fields)
    only_documented(lambda: PendulumChain([dict(zip(("m", "J", "l", "com", "com_lateral"), fields))] * n,
                                          pivot=pivot, orientation=orientation))


PISTON_FIELDS = ["m1", "J1", "l1", "l2", "d", "s", "h", "D", "c1", "M0", "p_max", "rpm", "e"]


@settings(max_examples=250, **SETTINGS)
@given(changes=st.dictionaries(st.sampled_from(PISTON_FIELDS), atoms, max_size=3))
def test_piston_parameters_properties(changes):
    only_documented(PistonParameters, **changes)


states = st.one_of(values, st.lists(st.floats(-1.0, 2.0), min_size=1, max_size=1))


@settings(max_examples=300, **SETTINGS)
@given(t0=numbers, span=st.one_of(numbers, st.floats(1e-4, 1e-2)), q0=states, v0=states,
       h_fraction=st.one_of(numbers, st.floats(1e-3, 2.0)), e=st.sampled_from([0.0, 0.5, 1.0]),
       solver=st.sampled_from(["enum", "osqp", "daqp", "nope", 3]))
def test_simulate_properties(t0, span, q0, v0, h_fraction, e, solver):
    try:
        t0, span, frac = float(t0), float(span), float(h_fraction)
    except (TypeError, ValueError):
        return
    span = float(np.clip(span, -1e-2, 1e-2))  # tiny spans (NaN stays NaN: refused)
    if np.isfinite(frac) and abs(frac) >= 1e-3:
        h = frac * span  # a valid step when frac and span are positive: 1 to 1000 steps
    elif not np.isfinite(frac) or frac <= 0:
        h = frac  # an invalid step, refused
    else:
        return  # 0 < h < 1e-3 span: the overflow bug class above (and too many steps)
    t1 = t0 + span
    if np.isfinite(t0) and np.isfinite(h) and h > 0 and (t1 - t0) / h > 2000:
        return  # a large t0 rounds t1 − t0 up to its ulp: too many steps for this budget
    try:
        big = max(abs(float(np.ravel(q0)[0])), abs(float(np.ravel(v0)[0])))
    except (TypeError, ValueError, IndexError):
        big = 0.0
    if big > 1e300:
        return  # the overflow-to-inf bug class above (test_position_overflowing_mid_run...)
    try:
        traj = sim(bouncing_ball(e), (t0, t1), q0, v0, h, solver=solver)
    except DOCUMENTED as exc:
        event(f"refused: {type(exc).__name__}")
    else:
        event("accepted")
        # accepted input gives a finite result, whatever it was
        assert traj.completed and np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.v))
        # ... and only documented input is accepted: numbers, not bools, strings or None
        assert numeric(q0) and numeric(v0) and np.size(q0) == 1 and np.size(v0) == 1, (q0, v0)
