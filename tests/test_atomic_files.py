"""Output files are written atomically (issue 14, item 10)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ecam.atomic_files import write_files

ROOT = Path(__file__).resolve().parent.parent
CAM = ROOT / "firmware_tables" / "cams" / "modified_sine.toml"


def test_a_failure_midway_leaves_every_old_file_intact(tmp_path, monkeypatch):
    a, b = tmp_path / "t.h", tmp_path / "t.bin"
    a.write_text("old header")
    b.write_bytes(b"old blob")
    real_fsync = os.fsync
    calls = []

    def disk_full(fd):
        calls.append(fd)
        if len(calls) == 2:  # the second file of the group cannot be flushed
            raise OSError(28, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", disk_full)
    with pytest.raises(OSError):
        write_files({a: "new header", b: b"new blob"})
    assert a.read_text() == "old header" and b.read_bytes() == b"old blob"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.bin", "t.h"]  # no temporaries left


def test_a_symlinked_output_is_replaced_not_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "out.h"
    out.symlink_to(victim)
    write_files({out: "generated"})
    assert victim.read_text() == "precious"
    assert not out.is_symlink() and out.read_text() == "generated"


def test_compile_writes_its_files_through_the_atomic_path(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "tables"
    out.mkdir()
    (out / "modified_sine.h").symlink_to(victim)
    run = subprocess.run([sys.executable, "-m", "ecam.app", "compile", str(CAM), "--points", "65",
                          "-o", str(out), "--format", "c,bin"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert victim.read_text() == "precious"
    assert "modified_sine" in (out / "modified_sine.h").read_text()
    assert not (out / "modified_sine.h").is_symlink()
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.slow
def test_plot_replaces_a_symlinked_output_not_its_target(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "cam.png"
    out.symlink_to(victim)
    run = subprocess.run([sys.executable, "-m", "ecam.app", "plot", str(CAM), "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert victim.read_text() == "precious"
    assert not out.is_symlink() and out.read_bytes().startswith(b"\x89PNG")
