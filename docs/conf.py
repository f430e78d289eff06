"""Sphinx configuration of moreau's documentation site.

Build (from the repository root; warnings and unresolved references are errors, as in CI)::

    python -m sphinx -W --keep-going -n -b html docs docs/_build/html

The notebooks of ``notebooks/`` (jupytext percent scripts) are copied into
``docs/notebooks/`` (not versioned) and executed by myst-nb at reduced size
(``MOREAU_NOTEBOOK_SCALE=small``, the size the test suite runs); a cell error fails the
build. Set ``MOREAU_NOTEBOOK_SCALE=full`` in the environment to render them at full size
(about 15 minutes for the triple pendulum alone; add ``-D nb_execution_timeout=-1``, as
a cell may then run longer than the 900 s allowed here). ``MOREAU_DOCS_EXECUTE=0`` renders
every page without executing anything, for a quick preview of the text.
"""

from __future__ import annotations

import importlib
import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

# Document the source tree this file belongs to, also in the notebooks' kernels.
sys.path.insert(0, str(ROOT))
os.environ["PYTHONPATH"] = os.pathsep.join(
    [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])

import moreau  # noqa: E402

project = "moreau"
author = "the moreau developers"
copyright = "the moreau developers"
release = moreau.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_nb",
]

exclude_patterns = ["_build", "conf.py", "_templates", "piston", "**/.ipynb_checkpoints",
                    "notebooks/figures", "notebooks/data"]
templates_path = ["_templates"]
root_doc = "index"

# Every cross-reference must resolve (sphinx-build -n). The documentation is built
# offline, so objects of other projects cannot be linked (no intersphinx): these are the
# third-party names the docstrings mention.
nitpicky = True
nitpick_ignore = [
    ("py:class", "abc.ABC"),
    ("py:class", "concurrent.futures.Executor"),
    ("py:func", "numpy.linalg.lstsq"),
    ("py:func", "scipy.optimize.brentq"),
]

# ---- autodoc / autosummary / numpydoc -----------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"           # the numpydoc sections state the types
numpydoc_show_class_members = False  # members are listed by the class template
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# ---- MyST and notebooks --------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
nb_custom_formats = {".py": ["jupytext.reads", {"fmt": "py:percent"}]}
# The scripts have no outputs: each is executed when read. MOREAU_DOCS_EXECUTE=0 renders
# them unexecuted (for quick previews of the other pages; not what CI builds).
nb_execution_mode = "off" if os.environ.get("MOREAU_DOCS_EXECUTE") == "0" else "auto"
nb_execution_raise_on_error = True   # a cell error fails the build
nb_execution_timeout = 900           # s per cell
nb_merge_streams = True

# ---- HTML ---------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"moreau {release}"
html_static_path = ["_static"]
html_css_files = ["custom.css"]
html_theme_options = {
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "secondary_sidebar_items": ["page-toc"],
}
html_show_sourcelink = False
html_sidebars = {"index": [], "theory": [], "piston_accuracy": [], "performance": []}  # pages without sub-pages


# ---- the notebooks: copied from notebooks/, executed at reduced size -------------------
def _sync_notebooks() -> None:
    """Copy the jupytext notebooks into docs/notebooks/ (only when changed, so that an
    incremental build does not execute them again) and drop copies of removed ones."""
    src_dir, dst_dir = ROOT / "notebooks", DOCS / "notebooks"
    dst_dir.mkdir(exist_ok=True)
    wanted = {p.name: p for p in sorted(src_dir.glob("*.py")) if "# %%" in p.read_text()}
    for old in dst_dir.glob("*.py"):
        if old.name not in wanted:
            old.unlink()
    for name, src in wanted.items():
        dst = dst_dir / name
        if not dst.exists() or dst.read_bytes() != src.read_bytes():
            shutil.copyfile(src, dst)


_sync_notebooks()


def _notebook_environment(app) -> None:
    """The environment the notebook kernels inherit: reduced size, figures and sweep
    records under the build directory, the inline matplotlib backend."""
    build = Path(app.doctreedir).parent
    os.environ.setdefault("MOREAU_NOTEBOOK_SCALE", "small")
    os.environ["MOREAU_FIGURES_DIR"] = str(build / "notebook-figures")
    os.environ["MOREAU_NOTEBOOK_DATA"] = str(build / "notebook-data")
    os.environ.pop("MPLBACKEND", None)  # CI sets Agg, which would hide the figures


# ---- references to re-exported names -----------------------------------------------
# Objects are documented where users import them (``moreau.Scene``,
# ``moreau.dynamics.TimeMap``); docstrings also name them by their defining module
# (``moreau.model.scene.Scene``). Such a reference is resolved to the documented name of the
# same object.
def _documented_alias(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    obj = _import_object(target) or _import_object(f"{node.get('py:module') or ''}.{target}")
    if obj is None:
        return None
    domain = env.get_domain("py")
    short = target.rsplit(".", 1)[-1]
    for name, entry in list(domain.objects.items()):
        if name.rsplit(".", 1)[-1] == short and name != target and _import_object(name) is obj:
            return domain.resolve_xref(env, node.get("refdoc"), app.builder, entry.objtype,
                                       name, node, contnode)
    return None


_IMPORTED: dict[str, object] = {}


def _import_object(dotted: str):
    if dotted in _IMPORTED:
        return _IMPORTED[dotted]
    obj = None
    parts = dotted.strip(".").split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except Exception:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            obj = None
        break
    _IMPORTED[dotted] = obj
    return obj


def _public_bases(app, name, obj, options, bases):
    """Show a private base class (``_CompiledLCPSolver``) as its own public bases."""
    i = 0
    while i < len(bases):
        if bases[i].__name__.startswith("_"):
            bases[i:i + 1] = [b for b in bases[i].__bases__ if b is not object]
        else:
            i += 1


def setup(app):
    app.connect("builder-inited", _notebook_environment)
    app.connect("autodoc-process-bases", _public_bases)
    app.connect("missing-reference", _documented_alias)
