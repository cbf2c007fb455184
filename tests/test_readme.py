"""The README's Python example runs as written."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def python_api_example() -> str:
    section = README.read_text().split("## Python API", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_the_python_api_example_runs(capsys):
    exec(compile(python_api_example(), "README.md: Python API", "exec"), {})
    out = capsys.readouterr().out
    assert out.strip().splitlines()[-1].startswith("max speed ")


def test_every_name_the_example_uses_is_exported_and_documented():
    import ecam
    import ecam.export
    import hil_sim

    example = python_api_example()
    for module, name in re.findall(r"\b(ecam|hil_sim)\.([A-Za-z_]+)\(", example):
        owner = {"ecam": ecam, "hil_sim": hil_sim}[module]
        assert name in owner.__all__, f"{module}.{name} is not exported"
        assert getattr(owner, name).__doc__, f"{module}.{name} has no docstring"
    for name in ("CamProfile", "Segment", "TableSpec"):
        assert name in ecam.__all__ and getattr(ecam, name).__doc__
    assert ecam.export.to_c_header.__doc__
