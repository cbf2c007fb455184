"""What a new user meets first: the version, a bare `ecam`, usage errors, the C runtime from an
installed package."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import ecam

ROOT = Path(__file__).resolve().parents[1]


def ecam_cli(*arguments, cwd=None):
    return subprocess.run([sys.executable, "-m", "ecam.app", *map(str, arguments)], capture_output=True,
                          text=True, timeout=120, cwd=cwd)


def test_version_has_one_source():
    import tomllib

    run = ecam_cli("--version")
    assert run.returncode == 0 and run.stdout.strip() == f"ecam {ecam.__version__}"
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "ecam.__version__"}


def test_a_license_file_as_pyproject_says():
    assert "MIT License" in (ROOT / "LICENSE").read_text()


def test_a_bare_ecam_prints_its_usage_and_the_commands():
    run = ecam_cli()
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert lines[0].startswith("usage: ecam ")
    assert lines[1].startswith("ecam: error: give a command, one of laws, check, ")
    assert "ecam: error: ecam" not in run.stderr  # the prefix once


def test_a_usage_error_names_the_command_once():
    run = ecam_cli("check")
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1
    assert run.stderr.startswith("ecam: error: check: the following arguments are required: cam")
    assert "`ecam check --help`" in run.stderr and "ecam: error: ecam" not in run.stderr


def test_firmware_emit_writes_the_runtime_as_the_package_holds_it(tmp_path):
    run = ecam_cli("firmware", "--emit", tmp_path / "fw")
    assert run.returncode == 0, run.stderr
    for name in ("ecam_table.c", "ecam_table.h", "FORMAT.md"):
        assert (tmp_path / "fw" / name).read_bytes() == (ROOT / "firmware_tables" / name).read_bytes()
        assert f"wrote {tmp_path / 'fw' / name}" in run.stdout


def test_firmware_emit_into_a_file_is_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    run = ecam_cli("firmware", "--emit", blocker)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1
    assert run.stderr.startswith("ecam: error: --emit: ")


def test_the_runtime_is_package_data():
    import tomllib

    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "c_runtime/*" in data["ecam"]
    for name in ("ecam_table.c", "ecam_table.h", "FORMAT.md"):
        assert (ROOT / "ecam" / "c_runtime" / name).is_file()
