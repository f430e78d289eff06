"""The README tells the truth: its Python examples run."""

import pathlib
import re

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"


def python_blocks():
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_python_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    blocks = python_blocks()
    assert blocks, "README has no python example"
    for code in blocks:
        exec(compile(code, str(README), "exec"), {"__name__": "readme"})


def test_readme_has_exactly_two_setup_commands():
    first = README.read_text().split("```bash\n", 1)[1].split("```", 1)[0]
    cmds = [line for line in first.splitlines() if line.strip()]
    assert len(cmds) == 2
    assert cmds[0].startswith("pip install -e") and cmds[1] == "python -m pytest"
    ci = (README.parent / ".ci" / "run").read_text()
    assert "\npython -m pytest\n" in ci
