"""The house's rules (issue 24): layers that only point down, no import circle, small
modules and functions, a short top level, and every former public name still there."""

from __future__ import annotations

import ast
import importlib
import pathlib
import warnings

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PKG = ROOT / "moreau"

#: a module may import from its own subpackage and from subpackages of a lower rank;
#: subpackages of one rank are siblings and must not import each other
RANK = {
    "core": 0,
    "model": 1, "contact": 1,
    "results": 2,
    "step": 3, "compiled": 3,
    "run": 4,
    "": 5,  # the public API, moreau/__init__.py
    "sweeps": 6,
    "dynamics": 7,
    "cli": 8,
    "__main__": 9,
}

#: every name ``import moreau as mo`` offered before the redesign (its __all__ and the
#: former module paths)
FORMER_NAMES = [
    "__version__", "Barrier", "FunctionBarrier", "LinearBarrier", "check_jacobian", "SimulationError",
    "SolverError", "ConstantForce", "Effect", "FourierLoad", "FunctionForce", "HarmonicForce", "LinearDamping",
    "LinearSpring", "MoreauJeanMidpoint", "MoreauJeanPredictorCorrector", "OneStepIntegrator",
    "PositionProjection", "CombinedProjection", "NewtonImpact", "OneStepProblem", "Residuals", "ImpactLog",
    "SolverStats", "Trajectory", "load", "Contact", "Scene", "simulate", "ensure_compiled", "ContactSolver",
    "EnumerationSolver", "ExactSolver", "OSQPSolver", "QpsolversSolver", "make_solver", "FunctionSystem",
    "MechanicalSystem", "diagnostics", "MoreauJeanTheta", "DISTRIBUTION",
]
FORMER_MODULES = [
    "barriers", "chain", "cli", "compiled", "diagnostics", "drift", "errors", "evaluate", "export", "flights",
    "forces", "integrator", "jitcache", "kernels", "laws", "lcp", "loop", "lowering", "onestep", "plotting",
    "result", "scene", "simulate", "solvers", "sweeps", "system", "testing", "trust", "units", "usercalls",
    "_validation", "_pool", "_cli_common", "_sweep_exec", "_sweep_record", "_sweep_table", "dynamics",
]


def modules() -> list[pathlib.Path]:
    return sorted(PKG.rglob("*.py"))


def module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def subpackage(name: str) -> str:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else ""


def runtime_imports(path: pathlib.Path) -> set[str]:
    """The moreau modules ``path`` imports when it runs (module level or in a function;
    not under ``if TYPE_CHECKING:``)."""
    tree = ast.parse(path.read_text())
    me = module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip |= {id(n) for b in node.body for n in ast.walk(b)}
    found: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "moreau"}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            if base.split(".")[0] != "moreau":
                continue
            for a in node.names:
                sub = f"{base}.{a.name}"
                found.add(sub if (ROOT / sub.replace(".", "/")).with_suffix(".py").exists()
                          or (ROOT / sub.replace(".", "/") / "__init__.py").exists() else base)
    found.discard(me)
    return {f for f in found if not f.startswith("moreau.problems")}


def test_layers_only_point_down():
    wrong = []
    for path in modules():
        me = module_name(path)
        if me.startswith("moreau.problems"):
            continue
        mine = subpackage(me)
        for target in runtime_imports(path):
            theirs = subpackage(target)
            if theirs == mine:
                continue
            if RANK[theirs] >= RANK[mine]:
                wrong.append(f"{me} imports {target} ({theirs or 'the public API'} is not below {mine or 'it'})")
    assert not wrong, "\n".join(wrong)


def test_no_import_circle():
    graph = {module_name(p): runtime_imports(p) for p in modules()}
    state: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                circles.append(stack[stack.index(t):] + [t])
            elif t in graph and not state.get(t):
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if not state.get(m):
            visit(m)
    assert not circles, "\n".join(" -> ".join(c) for c in circles)


@pytest.mark.parametrize("folder", ["moreau", "problems"])
def test_no_module_over_400_lines(folder):
    long = {str(p.relative_to(ROOT)): n for p in sorted((ROOT / folder).rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > 400}
    assert not long


@pytest.mark.parametrize("folder", ["moreau", "problems"])
def test_no_function_over_120_lines(folder):
    long = []
    for p in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > 120:
                    long.append(f"{p.relative_to(ROOT)}::{node.name} {n} lines")
    assert not long, "\n".join(long)


def test_at_most_12_entries_at_the_top_of_the_package():
    top = [p.name for p in PKG.iterdir() if (p.suffix == ".py") or (p.is_dir() and (p / "__init__.py").exists())]
    assert len(top) <= 12, sorted(top)


def test_every_subpackage_says_what_lives_there_and_what_it_may_import():
    for init in sorted(PKG.glob("*/__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        if init.parent.name == "dynamics":
            continue  # an application of the public API, documented by its modules
        assert "May import" in doc, init


def test_every_former_public_name_is_still_there():
    import moreau as mo

    missing = [n for n in FORMER_NAMES if not hasattr(mo, n)]
    assert not missing


@pytest.mark.parametrize("old", FORMER_MODULES)
def test_every_former_module_path_still_imports(old):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(f"moreau.{old}")
    assert module.__name__.startswith("moreau.")
    moved = [w for w in caught
             if issubclass(w.category, DeprecationWarning) and f"moreau.{old} moved" in str(w.message)]
    if module.__name__ != f"moreau.{old}":  # moved: the warning names the new path
        assert moved and module.__name__ in str(moved[0].message)
    import moreau as mo

    # a former module of the same name as a public function leaves the function in place
    assert callable(mo.simulate) and mo.simulate.__name__ == "simulate"
