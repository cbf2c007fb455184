"""The README's commands (run by tests/test_tutorial.py, the walkthrough being a part of the tutorial)
and the documentation's Python API example run as written."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
# The Python API example moved from the README to the documentation's Python API page.
PYTHON_API = ROOT / "docs" / "reference" / "python.md"


def python_api_example() -> str:
    section = PYTHON_API.read_text().split("## A complete example", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_the_python_api_example_runs(capsys):
    exec(compile(python_api_example(), "docs/reference/python.md: Python API", "exec"), {})
    out = capsys.readouterr().out.strip().splitlines()
    # The shipped stiff scene passes with the README's cam, and the search finds a speed.
    assert out[0].startswith("scene stiff_coupling: PASSED after ")
    assert "passed" in out
    speed = out[-1].split()
    assert speed[:2] == ["max", "speed"] and float(speed[2]) > 0 and speed[3] == "deg/s"


def test_every_name_the_example_uses_is_exported_and_documented():
    import ecam
    import ecam.export
    import hil_sim

    example = python_api_example()
    used = set(re.findall(r"\b(ecam|hil_sim)\.([A-Za-z_]+)\b", example))
    assert ("hil_sim", "SCENES_DIR") in used and ("ecam", "compile_table") in used
    for module, name in sorted(used):
        owner = {"ecam": ecam, "hil_sim": hil_sim}[module]
        if name == "export":  # `from ecam.export import ...`: a subpackage
            continue
        assert name in owner.__all__, f"{module}.{name} is not exported"
        if callable(getattr(owner, name)):
            assert getattr(owner, name).__doc__, f"{module}.{name} has no docstring"
    for name in ("CamProfile", "Segment", "TableSpec"):
        assert name in ecam.__all__ and getattr(ecam, name).__doc__
    assert ecam.export.to_c_header.__doc__


def test_the_methods_the_example_calls_have_docstrings():
    import ecam
    import hil_sim

    example = python_api_example()
    methods = [(ecam.CamProfile, "from_segments"), (ecam.CamProfile, "check"),
               (ecam.CamProfile, "to_toml"), (ecam.Segment, "from_span"),
               (ecam.CamTable, "lookup"), (ecam.Certificate, "max_error_counts"),
               (hil_sim.Report, "to_text"), (hil_sim.Report, "passed"),
               (hil_sim.Report, "failed"), (hil_sim.Check, "line"),
               (ecam.CheckReport, "ok"), (ecam.CheckReport, "errors"),
               (ecam.Discontinuity, "to_dict")]
    for owner, name in methods:
        assert f".{name}" in example, f"{name} is no longer in the example: update this list"
        assert getattr(owner, name).__doc__, f"{owner.__name__}.{name} has no docstring"


def test_ci_runs_the_readme_test_command():
    """.ci/run takes the second non-empty line of the README's first code block."""
    script = (ROOT / ".ci" / "run").read_text()
    awk = re.search(r"awk '([^']+)' README.md", script).group(1)
    line = subprocess.run(["awk", awk, str(README)], capture_output=True, text=True,
                          check=True).stdout.strip()
    assert line == "python3 -m pip install -e '.[test]' && python3 -m pytest -q -n auto --dist loadfile"
    first = README.read_text().split("```bash\n", 1)[1].splitlines()[0]
    assert first == "python3 -m pip install . && ecam demo"


def walkthrough_commands() -> list[str]:
    section = README.read_text().split("## Five minutes", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    lines = [line.split("  #", 1)[0].strip() for line in block.splitlines()]
    return [line for line in lines if line and not line.startswith("cd ")]


def test_the_readme_walkthrough_is_the_tutorials():
    """Every command of the five-minute walkthrough is one of the tutorial's, which
    tests/test_tutorial.py runs in a copy of examples/project (so it runs once, there), and every
    output line the README shows is one the tutorial shows for that command."""
    from test_tutorial import tutorial_commands

    commands = walkthrough_commands()
    assert [c.split()[:2] for c in commands][:4] == [["ecam", "check"], ["ecam", "compile"],
                                                      ["ecam", "export"], ["ecam", "sim"]]
    shown = dict(tutorial_commands())
    for command in commands:
        assert command in shown, f"{command!r} is not a command of docs/tutorial/index.md"
    readme = README.read_text().split("## Five minutes", 1)[1].split("\n## ", 1)[0]
    outputs = [body for language, body in re.findall(r"^```(\w*)\n(.*?)^```", readme, re.S | re.M)
               if not language]
    assert len(outputs) == 2
    for block, command in zip(outputs, ("ecam compile cams/lift.toml -o tables --format c,bin,json",
                                        "ecam sim scenes/lift.toml")):
        for line in block.splitlines():
            assert line == "..." or line in shown[command], f"README shows {line!r}; the tutorial does not"
