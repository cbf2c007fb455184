"""Hostile files, names and paths, second round (issue 28, items 2, 4, 5, 8, 9 and 10): each
is one line on stderr and exit 2, or a correct output, never a traceback, a hang, an unbounded
read, a destroyed file or an injected line."""

from __future__ import annotations

import contextlib
import io
import os
import re
import stat
import subprocess
import sys
import warnings
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

import ecam
from ecam.app.cli import main
from ecam.camfile import MAX_FILE_BYTES

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "hil_sim" / "scenes"
COMBINATION = ROOT / "firmware_tables" / "cams" / "combination_drrd.toml"
LONG = "x" * 300  # a path component past NAME_MAX (255 bytes on Linux)
# The name of the issue, as a cam file writes it.
INJECTED = "*)\nVAR_GLOBAL injected : INT := 1; END_VAR\n(* x\n1,2\n3,4"


def cam_text(name="cam", slave_unit="mm", master_unit="deg") -> str:
    return (f"name = {toml(name)}\nslave_unit = {toml(slave_unit)}\nmaster_unit = {toml(master_unit)}\n"
            'master_period = 360.0\n[table]\ninterp = "cubic"\npoints = 37\nmaster_counts = 3600\ntolerance = 0.001\n'
            '[[segment]]\nlaw = "cycloidal"\nspan = 180.0\nstroke = 1.0\n'
            '[[segment]]\nlaw = "cycloidal"\nspan = 180.0\nstroke = -1.0\n')


def toml(text: str) -> str:
    return '"' + "".join(c if c.isprintable() and c not in '"\\' else f"\\u{ord(c):04X}" for c in text) + '"'


def run(*args):
    """``ecam ARGS`` in this process: (status, stdout, stderr, warnings)."""
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        status = main([str(a) for a in args])
    return status, out.getvalue(), err.getvalue(), caught


def one_line(*args) -> str:
    status, _, err, caught = run(*args)
    lines = err.splitlines()
    assert status == 2 and len(lines) == 1 and lines[0].startswith("ecam: error: "), err
    assert not caught, caught[0]
    return lines[0]


def scene_with_cam(tmp_path, cam: Path, name: str | None = None) -> Path:
    text = (SCENES / "stiff_coupling.toml").read_text()
    text = re.sub(r'^file = .*$', lambda _: f'file = "{cam}"', text, flags=re.M)
    text = text.replace("master_periods = 2.0", "cycles = 50")
    if name is not None:
        text = re.sub(r'^name = .*$', lambda _: f"name = {toml(name)}", text, flags=re.M)
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return path


# --- item 2: bounded reads ------------------------------------------------------------------------
def test_a_scenes_cam_file_is_not_read_whole_before_its_size_is_checked(tmp_path, monkeypatch):
    """A sparse file 4 times the limit as the scene's cam: the rig keyed its cache on the whole
    file's bytes (2.1 GB for a 2 GB file) before the loader refused it. Every byte read from
    it is counted here: at most the limit and one."""
    import hil_sim
    from hil_sim.rig import cam as rig_cam

    big = tmp_path / "big.toml"
    with open(big, "wb") as handle:
        handle.truncate(4 * MAX_FILE_BYTES)
    read = []
    real_read, real_read_bytes = os.read, Path.read_bytes
    monkeypatch.setattr(os, "read", lambda fd, n: read.append(len(b := real_read(fd, n))) or b)
    monkeypatch.setattr(Path, "read_bytes", lambda self: read.append(len(b := real_read_bytes(self))) or b)
    scene = hil_sim.load_scene(scene_with_cam(tmp_path, big))
    with pytest.raises(ecam.CamFileError, match=f"bytes should be at most {MAX_FILE_BYTES}"):
        rig_cam.compile_cam(scene)
    assert sum(read) <= MAX_FILE_BYTES + 1


def test_a_regular_file_with_nothing_to_read_now_is_refused_not_waited_on(tmp_path, monkeypatch):
    """/proc/kmsg is a regular file whose read waits for the kernel's next message (a non-blocking
    read returned None: a TypeError in `ecam check`, a hang in `ecam sim`). Here a cam file whose
    read would block, as the kernel says it with O_NONBLOCK (EAGAIN)."""
    cam = tmp_path / "kmsg.toml"
    cam.write_text(cam_text())

    def would_block(fd, n):
        raise BlockingIOError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(os, "read", would_block)
    assert "cannot be read without waiting" in one_line("check", cam)


@pytest.mark.skipif(not os.access("/proc/kmsg", os.R_OK), reason="/proc/kmsg is not readable here")
@pytest.mark.parametrize("command", ["check", "fit"])
def test_check_proc_kmsg_is_one_line(command):
    """Both readers of a user's file (a cam file, a point table) read it the one bounded way."""
    run_ = subprocess.run([sys.executable, "-m", "ecam.app", command, "/proc/kmsg"], capture_output=True,
                          text=True, timeout=60)
    assert run_.returncode == 2 and len(run_.stderr.splitlines()) == 1, run_.stderr
    assert "Traceback" not in run_.stderr


# --- item 4: outputs never destroy ------------------------------------------------------------
def test_an_output_that_is_the_input_is_refused(tmp_path):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text())
    before = cam.read_bytes()
    assert "is the input file" in one_line("export", cam, "--to", "csv", "-o", cam)
    os.link(cam, tmp_path / "hard.toml")  # the same file by another name
    assert "is the input file" in one_line("export", cam, "--to", "csv", "-o", tmp_path / "hard.toml")
    # a cam named victim, in victim.json, compiled to JSON into its own directory
    victim = tmp_path / "victim.json"
    victim.write_text(cam_text(name="victim"))
    assert "is the input file" in one_line("compile", victim, "--format", "json", "-o", tmp_path)
    assert cam.read_bytes() == before and victim.read_text() == cam_text(name="victim")


def test_a_report_over_its_own_scene_or_cam_is_refused(tmp_path):
    cam = tmp_path / "cam.png"  # a cam file (TOML) whatever its name
    cam.write_text(cam_text())
    scene = scene_with_cam(tmp_path, cam)
    before = scene.read_bytes()
    assert "is the input file" in one_line("sim", scene, "--html", scene)
    assert "is the input file" in one_line("sim", scene, "--junit", cam)
    assert "is the input file" in one_line("sim", scene, "--plot", cam)
    assert scene.read_bytes() == before and cam.read_text() == cam_text()


def test_device_nodes_fifos_and_links_to_streams_are_refused(tmp_path):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text())
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert "is a FIFO" in one_line("export", cam, "--to", "csv", "-o", fifo)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    link = tmp_path / "link.csv"
    link.symlink_to(fifo)
    assert "is a symbolic link to a FIFO" in one_line("export", cam, "--to", "csv", "-o", link)
    stream = tmp_path / "stdout.csv"  # as /dev/stdout -> /proc/self/fd/1
    stream.symlink_to("/proc/self/fd/1")
    assert "process's open file" in one_line("export", cam, "--to", "csv", "-o", stream)
    assert os.readlink(stream) == "/proc/self/fd/1"
    try:
        os.mknod(tmp_path / "null", stat.S_IFCHR | 0o666, os.makedev(1, 3))  # /dev/null's numbers
    except (PermissionError, OSError):
        return  # no CAP_MKNOD here
    assert "is a character device" in one_line("export", cam, "--to", "csv", "-o", tmp_path / "null")
    assert stat.S_ISCHR(os.lstat(tmp_path / "null").st_mode)


# --- item 5: names and units never escape their place in an export -----------------------------
def iec_code(text: str) -> str:
    """IEC 61131-3 source without its comments ((* *), /* */ nested, // to the line's end)."""
    out, depth, i = [], [], 0
    while i < len(text):
        pair = text[i:i + 2]
        if pair in ("(*", "/*"):
            depth.append(pair)
            i += 2
        elif depth and pair == {"(*": "*)", "/*": "*/"}[depth[-1]]:
            depth.pop()
            i += 2
        elif not depth and pair == "//":
            i = text.find("\n", i) % (len(text) + 1)
        else:
            if not depth:
                out.append(text[i])
            i += 1
    assert not depth, "a comment is left open"
    return "".join(out)


def test_a_name_with_control_characters_is_refused_where_the_cam_is_read(tmp_path):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text(name=INJECTED))
    line = one_line("check", cam)
    assert "name: '*)\\nVAR_GLOBAL" in line and "should be a text without control characters" in line
    for unit in ("a\u0000b", "m\u2028m", "\u202emm"):
        cam.write_text(cam_text(slave_unit=unit))
        assert "slave_unit" in one_line("check", cam)
    cam.write_text(cam_text(slave_unit="u" * 100_000))
    line = one_line("check", cam)
    assert "slave_unit" in line and "at most 32 characters" in line and len(line) < 300
    with pytest.raises(ecam.InputError, match="should be a text without control characters"):
        ecam.CamProfile(ecam.load_cam(COMBINATION).segments, 360.0, name="a\nb")


def test_comment_terminators_in_names_and_units_stay_inside_the_comments(tmp_path):
    """Without line breaks the same attack closes the CODESYS comment with *) (or opens a
    nested one with (*), adds CSV columns with a comma, or a TwinCAT header word with '#'."""
    name = "*) VAR_GLOBAL injected : INT := 1; END_VAR (* x /* y"
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text(name=name, slave_unit="mm*)(*,q\"", master_unit="deg"))
    st = tmp_path / "cam.st"
    status, *_ = run("export", cam, "--to", "codesys", "-o", st)
    assert status == 0
    written = st.read_text()
    assert "\\n" not in written and written.splitlines()[2].startswith("   Between two points")  # lines kept
    code = iec_code(written)
    assert "injected : INT" not in code and code.count("VAR_GLOBAL") == 1 and code.count("END_VAR") == 1
    csv = tmp_path / "cam.csv"
    status, *_ = run("export", cam, "--to", "csv", "--interp", "cubic", "-o", csv)
    assert status == 0
    import csv as csv_module

    rows = [row for row in csv_module.reader(line for line in csv.read_text().splitlines()
                                             if not line.startswith("#"))]
    assert len(rows[0]) == 3 and {len(row) for row in rows} == {3}
    assert rows[0][1] == 'slave_mm*)(*,q"'
    cam.write_text(cam_text(name=name + " # Lines = 1"))
    txt = tmp_path / "cam.txt"
    status, *_ = run("export", cam, "--to", "twincat-cnc", "-o", txt)
    assert status == 0
    keys = [line.split("#")[0].split("=")[0].strip() for line in txt.read_text().splitlines()
            if "=" in line.split("#")[0]]
    assert keys == ["Tablename", "Table-ID", "Tabletype", "Functiontype", "Lines"]


# --- item 8: text from files is never markup --------------------------------------------------
def test_dollars_in_names_and_units_plot_as_written(tmp_path):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text(name="$x^$", slave_unit="$$", master_unit="\\alpha$"))
    status, _, err, caught = run("plot", cam, "-o", tmp_path / "cam.svg")
    assert status == 0 and err == "" and not caught, err
    assert (tmp_path / "cam.svg").stat().st_size > 0


@pytest.mark.slow
def test_dollars_in_names_and_units_in_the_rig_plot_and_html(tmp_path):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text(name="$x^$", slave_unit="$$"))
    scene = scene_with_cam(tmp_path, cam, name="$s$")
    status, _, err, caught = run("sim", scene, "--plot", tmp_path / "rig.png")
    assert status in (0, 1) and err == "" and not caught, err
    status, _, err, caught = run("sim", scene, "--html", tmp_path / "rig.html")
    assert status in (0, 1) and "error" not in err and not caught, err


# --- item 9: overflow before validation -------------------------------------------------------
P7_MATCH = ('master_period = 360.0\nperiodic = false\n[[segment]]\nlaw = "poly7"\nspan = 180\nstroke = 1.0\n'
            'end_jerk = "match"\n[[segment]]\nlaw = "cycloidal"\nend = 1e103\nstroke = 1.0\n')


@pytest.mark.parametrize("command", [["check"], ["compile", "-o", "OUT"], ["export", "--to", "csv", "-o", "OUT/x.csv"],
                                     ["plot", "-o", "OUT/x.png"]], ids=lambda c: c[0])
def test_match_next_to_a_segment_past_the_period_is_one_line(tmp_path, command):
    cam = tmp_path / "p7.toml"
    cam.write_text(P7_MATCH)
    args = [a.replace("OUT", str(tmp_path)) for a in command]
    line = one_line(args[0], cam, *args[1:])
    assert "segment[1].end: 1e+103 should be 360, the master_period (it leaves an overlap)" in line


# --- item 10: small ones ------------------------------------------------------------------------
def test_a_notch_that_cannot_be_designed_is_refused_at_the_scene(tmp_path):
    text = (SCENES / "stiff_coupling.toml").read_text().replace("../../firmware_tables", str(ROOT / "firmware_tables"))
    text = re.sub(r"^\[drive\]$", "[drive.gains]\nnotch_hz = 5e-324\n\n[drive]", text, count=1, flags=re.M)
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    assert "drive.gains.notch_hz: 4.94065645841e-324 should be 0 (no notch) or >= 0.1 Hz" in one_line("sim", scene)
    from hil_sim.filters import Notch

    with pytest.raises(ecam.InputError, match="notch_hz"):
        Notch(5e-324, 0.5, 30.0, 1e-4)


def test_path_components_past_name_max_are_one_line(tmp_path):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text())
    scene = scene_with_cam(tmp_path, cam)
    long = tmp_path / LONG
    assert "File name too long" in one_line("export", cam, "--to", "csv", "-o", long / "x.csv")
    assert "File name too long" in one_line("compile", cam, "-o", long)
    assert "File name too long" in one_line("plot", cam, "-o", f"{long}.png")
    assert "File name too long" in one_line("sim", scene, "--plot", f"{long}.png")
    assert "File name too long" in one_line("sim", scene, "--junit", f"{long}.xml")
    assert "File name too long" in one_line("sim", f"{long}.toml")
    assert "does not exist" in one_line("sim", f"{long}.toml", scene)


def test_a_symlink_loop_as_junit_and_an_empty_scene_path(tmp_path, monkeypatch):
    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text())
    scene = scene_with_cam(tmp_path, cam)
    a, b = tmp_path / "a.xml", tmp_path / "b.xml"
    a.symlink_to(b)
    b.symlink_to(a)
    assert "symbolic link" in one_line("sim", scene, "--junit", a)
    assert "its directory does not exist" in one_line("sim", scene, "--junit", a / "x.xml")
    monkeypatch.chdir(tmp_path)  # before, "" ran every scene under here
    assert "scene '': should be a path" in one_line("sim", "")
    assert "scene '': should be a path" in one_line("sim", "", scene)


def test_a_control_character_in_a_scene_name_is_refused_and_junit_stays_well_formed(tmp_path):
    from ecam.app.junit import junit_xml

    cam = tmp_path / "cam.toml"
    cam.write_text(cam_text())
    scene = scene_with_cam(tmp_path, cam, name="knife\x1b[31m")
    assert "name: 'knife\\x1b[31m' should be a text without control characters" in one_line("sim", scene)
    # A file name may hold any character but / and NUL: its label still makes well-formed XML.
    xml = junit_xml([(tmp_path / "bad\x01\x1bname.toml", ecam.CamFileError("bad\x02 file"), 0.1)])
    root = ET.fromstring(xml.encode("utf-8"))
    assert root.find("testsuite").get("name") == "bad\\x01\\x1bname"


# --- item 3: a point count near its limit -------------------------------------------------------
def test_more_points_than_the_master_grid_holds_are_refused_before_the_placement(tmp_path, monkeypatch):
    """1 000 001 points on a cam of 36 864 master counts: before, 40 spreads of a million knots
    (261 s, 6.3 GB) came before the refusal. Now no placement runs."""
    import ecam.export.certify as certify

    def placement(*args, **kwargs):
        raise AssertionError("the placement ran")

    monkeypatch.setattr(certify, "equidistributed", placement)
    line = one_line("export", COMBINATION, "--to", "csv", "--points", "1000001", "-o", tmp_path / "x.csv")
    assert "points: 1000001 should be at most 36865" in line


@pytest.mark.slow
def test_an_export_takes_memory_linear_in_its_points_with_a_small_constant():
    """tracemalloc's peak for 4 097 and 16 385 points of a csv export: the 12 288 points between
    them cost under 2 kB each (the file itself holds about 40 bytes a point). Before, the
    predicted bounds and the dense measurement held every interval's 257 and 65 samples at once:
    about 10 kB a point, MemoryError at the documented 2^20 + 1."""
    import tracemalloc

    from ecam.export import export_cam

    profile = ecam.load_cam(COMBINATION)
    peaks = []
    for points in (4097, 16385):
        tracemalloc.start()
        try:
            export_cam(profile, "csv", points=points, master_counts=2**21, name="x")
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    assert (peaks[1] - peaks[0]) / (16385 - 4097) < 2048, peaks


# --- item 6: an output group switches in one step for a reader that checks its manifest ----------
KILLED_WRITER = """
import os, signal, sys
from pathlib import Path
from ecam.atomic_files import write_group
out = Path(sys.argv[1])
real, calls = os.replace, []

def replace(src, dst):
    calls.append(dst)
    if len(calls) == 2:  # killed between the renames of the group
        os.kill(os.getpid(), signal.SIGKILL)
    real(src, dst)

os.replace = replace
write_group({out / "t.h": "new header", out / "t.bin": b"new blob", out / "t.json": "{}"}, out / "t.group.json")
"""


def test_a_group_killed_between_its_renames_is_refused_by_its_manifest_and_its_temporaries_go(tmp_path):
    from ecam.atomic_files import STALE_TEMPORARY_S, check_group, write_group

    old = {tmp_path / "t.h": "old header", tmp_path / "t.bin": b"old blob", tmp_path / "t.json": "[]"}
    write_group(old, tmp_path / "t.group.json")
    assert check_group(tmp_path / "t.group.json") == sorted(old, key=lambda p: p.name)
    killed = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(tmp_path)], capture_output=True, timeout=60)
    assert killed.returncode == -9, killed.stderr
    # a new header beside the old blob: the manifest that named the old group is gone
    assert (tmp_path / "t.bin").read_text() == "new blob" or (tmp_path / "t.h").read_text() == "new header"
    with pytest.raises(ecam.InputError, match="no manifest"):
        check_group(tmp_path / "t.group.json")
    leftovers = [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    assert leftovers
    for leftover in leftovers:  # as old as a killed writer's after a while
        os.utime(leftover, (0, 0))
    write_group(old, tmp_path / "t.group.json")
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    assert check_group(tmp_path / "t.group.json")
    (tmp_path / "t.bin").write_bytes(b"edited")
    with pytest.raises(ecam.InputError, match="'t.bin' is not the file the manifest names"):
        check_group(tmp_path / "t.group.json")
    assert STALE_TEMPORARY_S > 0


def test_compile_writes_its_group_with_a_manifest_last(tmp_path):
    from ecam.atomic_files import check_group

    status, out, err, _ = run("compile", COMBINATION, "--points", "65", "--format", "c,bin,csv,json", "-o", tmp_path,
                              "--json")
    assert status == 0, err
    import json

    summary = json.loads(out)
    members = check_group(summary["manifest"])
    assert sorted(map(str, members)) == sorted(summary["files"])
