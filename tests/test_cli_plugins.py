"""The ``moreau`` command finds its subcommands through the ``moreau.commands`` entry points:
a third-party package adds ``moreau hello``; a broken one does not break the others; the
core never imports the bundled problems."""

import importlib.util
import os
import pathlib
import re
import subprocess
import sys
import textwrap

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

HELLO = textwrap.dedent('''
    """A third-party package that adds ``moreau hello``."""
    from moreau.cli import EXIT_USAGE, CLIError


    def register(subparsers):
        p = subparsers.add_parser("hello", help="say hello")
        p.add_argument("--name", default="world", help="who to greet")
        p.set_defaults(func=run)


    def run(args):
        if not args.name:
            raise CLIError("--name is empty", EXIT_USAGE)
        print(f"hello, {args.name}")
        return 0


    def broken(subparsers):
        raise RuntimeError("this plug-in is broken")
''')

PYPROJECT = textwrap.dedent('''
    [build-system]
    requires = ["setuptools"]
    build-backend = "setuptools.build_meta"

    [project]
    name = "moreau-hello"
    version = "0.1"

    [project.entry-points."moreau.commands"]
    hello = "moreau_hello:register"
    broken = "moreau_hello:broken"
''')


def _can_build_offline() -> bool:
    """setuptools here, able to build a wheel without downloading (>= 70.1, or wheel)."""
    if importlib.util.find_spec("setuptools") is None:
        return False
    import setuptools

    major, minor = (int(x) for x in re.findall(r"\d+", setuptools.__version__)[:2])
    return (major, minor) >= (70, 1) or importlib.util.find_spec("wheel") is not None


@pytest.fixture(scope="module")
def hello_site(tmp_path_factory):
    """The package installed into a directory of its own (put on PYTHONPATH by the tests):
    with pip from its pyproject, offline, when setuptools can build it here; otherwise
    the files pip would write (module and ``.dist-info`` with ``entry_points.txt``)."""
    tmp = tmp_path_factory.mktemp("plugin")
    src, site = tmp / "src", tmp / "site"
    src.mkdir()
    (src / "moreau_hello.py").write_text(HELLO)
    (src / "pyproject.toml").write_text(PYPROJECT)
    if _can_build_offline():
        r = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
                            "--no-build-isolation", "--target", str(site), str(src)],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
    else:
        site.mkdir()
        (site / "moreau_hello.py").write_text(HELLO)
        info = site / "moreau_hello-0.1.dist-info"
        info.mkdir()
        (info / "METADATA").write_text("Metadata-Version: 2.1\nName: moreau-hello\nVersion: 0.1\n")
        (info / "entry_points.txt").write_text(
            "[moreau.commands]\nhello = moreau_hello:register\nbroken = moreau_hello:broken\n")
    assert list(site.glob("moreau_hello-0.1.dist-info/entry_points.txt"))
    return site


def moreau_cmd(args, site, tmp_path):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site)] + [p for p in [env.get("PYTHONPATH")] if p])
    return subprocess.run([sys.executable, "-m", "moreau", *args], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=120)


def test_a_third_party_package_adds_a_command(hello_site, tmp_path):
    r = moreau_cmd(["hello", "--name", "Jean"], hello_site, tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout == "hello, Jean\n"
    # the broken plug-in is skipped with a warning naming it; the others still work
    assert "moreau command 'broken'" in r.stderr and "this plug-in is broken" in r.stderr
    r = moreau_cmd(["--help"], hello_site, tmp_path)
    assert r.returncode == 0
    assert re.search(r"^\s+hello\s+say hello$", r.stdout, re.M)
    assert re.search(r"^\s+piston\s", r.stdout, re.M)  # the bundled ones, registered the same way
    assert "broken" not in r.stdout


def test_a_command_reports_its_errors_through_the_core(hello_site, tmp_path):
    r = moreau_cmd(["hello", "--name", ""], hello_site, tmp_path)
    assert r.returncode == 2
    assert r.stderr.splitlines()[-1] == "moreau hello: error: --name is empty"
    r = moreau_cmd(["hello", "--nome", "x"], hello_site, tmp_path)
    assert r.returncode == 2 and "unrecognized arguments: --nome x" in r.stderr.splitlines()[-1]


def test_the_bundled_commands_are_entry_points():
    from moreau.cli import command_entry_points

    eps = {ep.name: ep.value for ep in command_entry_points()}
    assert {"ball", "piston", "sweep"} <= set(eps)
    assert eps["piston"] == "moreau.problems.commands:register_piston"


def test_the_core_never_imports_the_problems():
    """Imports flow one way: problems, notebooks, benchmarks -> moreau, never back."""
    pattern = re.compile(r"^\s*(from|import)\s+(moreau\.problems|problems)\b|^\s*from\s+\.+problems\b", re.M)
    offenders = [str(p.relative_to(ROOT)) for p in sorted((ROOT / "moreau").rglob("*.py"))
                 if pattern.search(p.read_text())]
    assert offenders == []
    # and importing the command line loads no problem
    code = "import sys, moreau.cli; print(sorted(m for m in sys.modules if 'problems' in m))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stderr
