"""The module paths of moreau 0.1 before its subpackages (``moreau.chain``, ``moreau.lcp``,
...), kept importable for one release: importing one warns (``DeprecationWarning``) with
its new path and returns the moved module itself.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings

__all__ = ["MOVED", "install"]

#: old module path -> new module path
MOVED: dict[str, str] = {
    f"moreau.{old}": f"moreau.{new}" for old, new in {
        "errors": "core.errors", "_validation": "core.validation", "jitcache": "core.jitcache",
        "kernels": "core.kernels",
        "units": "model.units", "system": "model.system", "forces": "model.forces", "barriers": "model.barriers",
        "laws": "model.laws", "scene": "model.scene", "chain": "model.chain",
        "onestep": "contact.problem", "lcp": "contact.lcp", "solvers": "contact.solvers", "testing": "contact.testing",
        "integrator": "step.integrator", "drift": "step.drift",
        "lowering": "compiled.lowering", "evaluate": "compiled.evaluate", "usercalls": "compiled.usercalls",
        "loop": "compiled.loop",
        "result": "results.trajectory", "export": "results.export", "diagnostics": "results.diagnostics",
        "plotting": "results.plotting",
        "simulate": "run.simulation", "trust": "run.trust", "flights": "run.flights",
        "_sweep_exec": "sweeps.execute", "_sweep_record": "sweeps.record", "_sweep_table": "sweeps.table",
        "_pool": "sweeps.pool", "_cli_common": "cli.common",
    }.items()
}


def moved(old: str) -> types.ModuleType:
    """The module that ``old`` (a former path) became, with a ``DeprecationWarning``."""
    new = MOVED[old]
    warnings.warn(f"{old} moved to {new}; import it from there (the old path goes in the next release)",
                  DeprecationWarning, stacklevel=3)
    return importlib.import_module(new)


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves a former module path to the module it became."""

    def find_spec(self, fullname: str, path: object, target: object = None) -> importlib.machinery.ModuleSpec | None:
        if fullname in MOVED:
            return importlib.machinery.ModuleSpec(fullname, self)
        return None

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        return moved(spec.name)

    def exec_module(self, module: types.ModuleType) -> None:
        pass


class _Package(types.ModuleType):
    """The ``moreau`` package: importing a former module path does not replace the public
    name it shares (``import moreau.simulate`` leaves the function ``moreau.simulate``)."""

    def __setattr__(self, name: str, value: object) -> None:
        old = self.__dict__.get(name)
        if (isinstance(value, types.ModuleType) and f"{self.__name__}.{name}" in MOVED
                and old is not None and not isinstance(old, types.ModuleType)):
            return
        super().__setattr__(name, value)


def install(package: types.ModuleType) -> None:
    """Put the finder of former paths on ``sys.meta_path`` (once) and keep ``package``'s
    public names from being replaced by the former modules of the same name."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())
    package.__class__ = _Package
