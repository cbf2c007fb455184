"""The tutorial (docs/tutorial/index.md) runs as written: every command of its console blocks, in
order, in a copy of examples/project, with the exit status and the output lines it shows. So the
page cannot drift from what ecam prints. The README's five-minute walkthrough is a subset of these
commands (tests/test_readme.py checks that), so it runs here too, once."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial" / "index.md"
PROJECT = ROOT / "examples" / "project"


def console_blocks(text: str) -> list[list[tuple[str, list[str]]]]:
    """Each ```console block as (command, the output lines shown after it)."""
    blocks = []
    for block in re.findall(r"```console\n(.*?)```", text, re.S):
        steps: list[tuple[str, list[str]]] = []
        for line in block.splitlines():
            if line.startswith("$ "):
                steps.append((line[2:].strip(), []))
            else:
                assert steps, f"output before any command: {line!r}"
                steps[-1][1].append(line.rstrip())
        blocks.append(steps)
    return blocks


def tutorial_commands() -> list[tuple[str, list[str]]]:
    return [step for block in console_blocks(TUTORIAL.read_text()) for step in block]


def shell_lines(text: str) -> list[str]:
    """The commands of the ```bash blocks (comments cut)."""
    lines = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        lines += [line.split("  #", 1)[0].strip() for line in block.splitlines() if line.strip()]
    return lines


def test_the_tutorial_names_every_new_capability_in_a_newcomers_order():
    text = TUTORIAL.read_text()
    steps = re.findall(r"^## (\d+)\. (.+)$", text, re.M)
    assert [int(n) for n, _ in steps] == list(range(len(steps)))
    # design (and fit), compile, export, rig (commissioned), size, speed, sweep, cam change,
    # machine, CI: each step's page is linked where the step is
    order = [text.index(page) for page in ("../fit.md", "../tuning.md", "../sizing.md", "../sweep.md",
                                           "../cam_changes.md", "../machine.md", "../howto/ci.md")]
    assert order == sorted(order)
    commands = [command for command, _ in tutorial_commands()]
    for start in ("ecam fit ", "ecam sweep ", "ecam check cams/lift.toml --then ", "ecam sim machines/",
                  "ecam sim scenes/lift_sized.toml"):
        assert any(c.startswith(start) for c in commands), start


def test_the_shell_blocks_are_install_and_cd_only():
    """Commands outside console blocks are not run here; they are the install (its `ecam --version`
    and `ecam demo` run in tests/test_first_contact.py and tests/test_demo.py) and the `cd`."""
    assert shell_lines(TUTORIAL.read_text()) == [
        "python3 -m pip install .", "ecam --version", "ecam demo", "cd examples/project"]


def _shown_in(expected: list[str], output: list[str]) -> str | None:
    """The first shown line the output lacks, in order ('...' skips lines; a line ending in '...'
    matches a line it starts)."""
    at = 0
    for line in expected:
        if line.strip() in ("", "..."):
            continue
        prefix = line[:-3] if line.endswith("...") else None
        for index in range(at, len(output)):
            if output[index] == line or (prefix is not None and output[index].startswith(prefix)):
                at = index + 1
                break
        else:
            return line
    return None


def _argv(command: str) -> list[str]:
    words = shlex.split(command)
    if words[0] == "ecam":
        return [sys.executable, "-m", "ecam.app", *words[1:]]
    if words[:3] == ["python3", "-m", "pytest"]:
        return [sys.executable, *words[1:], "-q", "-p", "no:cacheprovider"]
    raise AssertionError(f"the tutorial runs {command!r}: teach this test how")


# The project's own tests: tests/test_examples.py runs them (and checks that they pass); not twice.
RUN_ELSEWHERE = "python3 -m pytest tests"


def test_the_command_run_elsewhere_is_run_there():
    assert RUN_ELSEWHERE in [command for command, _ in tutorial_commands()]
    assert '"pytest", "-q", "-p", "no:cacheprovider", str(EXAMPLES / "project" / "tests")' in \
        (ROOT / "tests" / "test_examples.py").read_text()


@pytest.mark.slow
def test_every_tutorial_command_runs_and_prints_what_the_page_shows(tmp_path):
    project = tmp_path / "project"
    shutil.copytree(PROJECT, project)
    environment = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200"}
    for command, shown in tutorial_commands():
        if command == RUN_ELSEWHERE:
            continue
        done = subprocess.run(_argv(command), cwd=project, env=environment, capture_output=True,
                              text=True, timeout=300)
        output = (done.stdout + done.stderr).splitlines()
        # a page that shows a FAILED verdict says so; every other command succeeds
        expected_status = 1 if any("FAILED" in line for line in shown[:1]) else 0
        assert done.returncode == expected_status, f"{command}: {done.stdout[-2000:]}{done.stderr[-2000:]}"
        # progress lines (stderr) come before the summary (stdout): compare each stream alone
        missing = _shown_in(shown, done.stdout.splitlines())
        if missing is not None:
            missing = _shown_in(shown, done.stderr.splitlines() + done.stdout.splitlines())
        assert missing is None, f"{command}: the page shows {missing!r}, ecam printed:\n" + "\n".join(output)
    assert (project / "lift.st").is_file() and (project / "tables" / "lift.h").is_file()
    assert (project / "lift_from_points.toml").is_file() and (project / "lift.png").is_file()
