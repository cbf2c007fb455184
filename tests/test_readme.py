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
