"""Hostile files (issue 14): every bad path or file is one line on stderr and exit 2, at once."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ecam.camfile import MAX_FILE_BYTES

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "hil_sim" / "scenes"


def run_cli(*args):
    # A timeout turns a hang (a FIFO waited on, /dev/zero read forever) into a failure.
    return subprocess.run([sys.executable, "-m", "ecam.app", *map(str, args)],
                          capture_output=True, text=True, timeout=60)


def assert_one_line(run, message):
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], run.stderr


def nested(depth):
    return "x = " + "[" * depth + "]" * depth + "\n"


def symlink_loop(tmp_path, name):
    a, b = tmp_path / f"{name}_a.toml", tmp_path / f"{name}_b.toml"
    a.symlink_to(b)
    b.symlink_to(a)
    return a


@pytest.mark.parametrize("command", ["check", "compile", "sim"])
def test_device_is_refused_not_read(command):
    assert_one_line(run_cli(command, "/dev/zero"), "should be a regular file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this platform")
def test_fifo_is_refused_not_waited_on(tmp_path):
    fifo = tmp_path / "cam.toml"
    os.mkfifo(fifo)
    assert_one_line(run_cli("check", fifo), "should be a regular file")
    assert_one_line(run_cli("sim", fifo), "should be a regular file")


def test_oversized_file_is_refused(tmp_path):
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (MAX_FILE_BYTES + 1))
    assert_one_line(run_cli("check", big), f"should be at most {MAX_FILE_BYTES}")


@pytest.mark.parametrize("command", ["check", "compile", "sim"])
def test_deeply_nested_toml_is_one_line(tmp_path, command):
    path = tmp_path / "nested.toml"
    path.write_text(nested(500))
    assert_one_line(run_cli(command, path), "nest too deeply")


def test_scene_whose_cam_file_nests_too_deeply(tmp_path):
    cam = tmp_path / "nested.toml"
    cam.write_text(nested(500))
    text = (SCENES / "stiff_coupling.toml").read_text()
    lines = [f'file = "{cam}"' if line.strip().startswith("file =") else line
             for line in text.splitlines()]
    scene = tmp_path / "scene.toml"
    scene.write_text("\n".join(lines) + "\n")
    assert_one_line(run_cli("sim", scene), "arrays or tables nest too deeply to parse")


@pytest.mark.parametrize("command", ["check", "compile"])
def test_a_poly5_span_of_1e300_is_one_line(tmp_path, command):
    # Issue 14 item 4, as reported: OverflowError traceback.
    path = tmp_path / "span.toml"
    path.write_text('master_period = 360.0\nperiodic = false\n[[segment]]\nlaw = "poly5"\n'
                    'span = 1e300\nstroke = 1.0\n')
    assert_one_line(run_cli(command, path, *(["--points", "9", "-o", tmp_path] if command == "compile" else [])),
                    "segment[0].span: 1e+300 should be of magnitude <= 1e+150")


def test_symlink_loop_as_cam_and_as_scene(tmp_path):
    assert_one_line(run_cli("check", symlink_loop(tmp_path, "cam")), "cannot be read")
    assert_one_line(run_cli("sim", symlink_loop(tmp_path, "scene")), "cannot be read")


def test_scene_whose_cam_file_is_a_symlink_loop(tmp_path):
    loop = symlink_loop(tmp_path, "cam")
    text = (SCENES / "stiff_coupling.toml").read_text()
    lines = [f'file = "{loop}"' if line.strip().startswith("file =") else line
             for line in text.splitlines()]
    scene = tmp_path / "scene.toml"
    scene.write_text("\n".join(lines) + "\n")
    assert_one_line(run_cli("sim", scene), "cam.file")


def test_non_utf8_file_is_one_line(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'name = "caf\xe9"\n')
    assert_one_line(run_cli("check", path), "should be UTF-8 text")


def scene_with(tmp_path, old, new):
    text = (SCENES / "stiff_coupling.toml").read_text()
    text = text.replace("../../firmware_tables", str(ROOT / "firmware_tables"))
    assert old in text
    path = tmp_path / "scene.toml"
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize("old,new,message", [
    ("gear_ratio = 0.1 ", "gear_ratio = 1e300 ", "mechanics.gear_ratio: 1e+300 should be <= 10000"),
    ("motor_torque_limit = 6.0", "motor_torque_limit = 1e308",
     "mechanics.motor_torque_limit: 1e+308 should be <="),
    ("slave_counts_per_unit = 100000", "slave_counts_per_unit = 5e-324",
     "cam.slave_counts_per_unit: 4.94065645841e-324 should be >= 1e-06"),
    ("master_periods = 2.0", "seconds = 1e300", "duration.seconds: 1e+300 should be of magnitude <= 1e+150"),
    # The cycles that seconds make are bounded where the file is read, naming the field and the
    # limit at the scene's cycle time (issue 14 item 14; the rig's message named neither).
    ("master_periods = 2.0", "seconds = 1e9",
     "scene.toml: duration.seconds: 1000000000 should be <= 5000 (5000000 cycles at drive.cycle_s 0.001)"),
    ("master_periods = 2.0", "seconds = 5000.000001", "duration.seconds: 5000.000001 should be <= 5000"),
    ("master_periods = 2.0", "cycles = 100000000", "duration.cycles: 100000000 should be an integer in 1..5000000"),
])
def test_huge_and_tiny_scene_numbers_are_one_line(tmp_path, old, new, message):
    assert_one_line(run_cli("sim", scene_with(tmp_path, old, new)), message)


def test_the_longest_duration_in_seconds_is_accepted_and_makes_the_most_cycles(tmp_path):
    import hil_sim
    from hil_sim.rig.plan import count_cycles
    from hil_sim.scene import MAX_CYCLES

    for cycle_s, seconds in (("0.001", "5000.0"), ("1e-5", "50.0"), ("0.0025", "12500.0")):
        path = scene_with(tmp_path, "master_periods = 2.0", f"seconds = {seconds}")
        path.write_text(path.read_text().replace("cycle_s = 0.001", f"cycle_s = {cycle_s}"))
        assert count_cycles(hil_sim.load_scene(path), 1.0, 1.0) == MAX_CYCLES


def test_smallest_cycle_time_the_validator_allows_runs(tmp_path):
    # 0x60C2 = 10 x 10^-6 s was computed as 9.999...e-6 and refused by the drive's own check.
    import hil_sim
    from hil_sim.drive import interpolation_period_s

    assert interpolation_period_s(10, -6) == 1e-5
    scene = hil_sim.load_scene(scene_with(tmp_path, "cycle_s = 0.001", "cycle_s = 1e-5"))
    scene = scene.with_master_speed(36000.0)  # 100 periods/s: a short run
    report = hil_sim.run_scene(scene)
    assert report.cycles > 0


def test_poly5_boundary_that_overflows_when_normalized(tmp_path):
    # Every number is within validate.MAX_MAGNITUDE (1e150); normalized, 1e100 * 1e12**2 / 1e-100
    # is 1e224. (The span is the longest period: a segment longer than its period is refused
    # first, before any boundary condition is solved, issue 28 item 9.)
    path = tmp_path / "p5.toml"
    path.write_text('master_period = 1e12\nperiodic = false\n[[segment]]\nlaw = "poly5"\n'
                    'span = 1e12\nstroke = 1e-100\nstart_acceleration = 1e100\n')
    assert_one_line(run_cli("check", path), "segment[0].start_acceleration: 1e+100 should be finite and at most "
                    "1e+150 once normalized (value * span^2 / stroke; span 1e+12, stroke 1e-100)")


# --- found by the fuzz (tests/test_hostile_fuzz.py), in this process ---------------------------
def one_line(*args):
    """``ecam ARGS`` in this process: (exit status, the one stderr line); no exception escapes."""
    import contextlib
    import io

    from ecam.app.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main([str(a) for a in args])
    lines = err.getvalue().splitlines()
    assert status == 2 and len(lines) == 1, err.getvalue()
    return lines[0]


GOOD_CAM = 'master_period = 360.0\n[[segment]]\nlaw = "cycloidal"\nspan = 180.0\nstroke = 1.0\n' \
           '[[segment]]\nlaw = "cycloidal"\nspan = 180.0\nstroke = -1.0\n'


def test_a_directory_is_refused_not_opened(tmp_path):
    assert one_line("check", tmp_path).endswith("should be a regular file")


def test_a_path_with_a_nul_is_one_error():
    import ecam

    with pytest.raises(ecam.CamFileError, match="should be a path without NUL characters"):
        ecam.load_cam("cam\x00.toml")


def test_integers_past_float_and_past_4300_digits(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text(f"name = {10**400}\n" + GOOD_CAM)
    assert one_line("check", path).endswith("name: 1e+400 should be a string")
    path.write_text("x = " + "9" * 5000 + "\n")
    assert "Exceeds the limit (4300 digits)" in one_line("check", path)


def test_a_hostile_key_is_shown_quoted_and_cut(tmp_path):
    path = tmp_path / "keys.toml"
    path.write_text('"a\\nb" = 1\n' + GOOD_CAM)
    assert "'a\\nb': unknown field" in one_line("check", path)
    path.write_text(f'"{"x" * 300}" = 1\n' + GOOD_CAM)
    line = one_line("check", path)
    assert "...: unknown field" in line and len(line) < 300


@pytest.mark.parametrize("args,message", [
    (["--speed", "1e120"], "--speed: '1e120' should be at most 1e+30 deg/s"),
    (["--speed", "1e300 rpm"], "--speed: '1e300 rpm' should be at most 1e+30 deg/s"),
])
def test_check_speed_range(tmp_path, args, message):
    path = tmp_path / "cam.toml"
    path.write_text(GOOD_CAM)
    assert one_line("check", path, *args).endswith(message)


def test_tolerance_range_keeps_counts_finite(tmp_path):
    path = tmp_path / "cam.toml"
    path.write_text(GOOD_CAM)
    assert one_line("compile", path, "--tolerance", "1e308", "-o", tmp_path).endswith(
        "tolerance: '1e308' should be at most 1e+150")
    assert one_line("export", path, "--to", "csv", "--tolerance", "1e200 counts", "-o", tmp_path / "e.csv").endswith(
        "tolerance: '1e200 counts' should be at most 1e+150")


def test_a_long_format_list_is_cut(tmp_path):
    path = tmp_path / "cam.toml"
    path.write_text(GOOD_CAM)
    line = one_line("compile", path, "--points", "9", "--format", "x" * 1000, "-o", tmp_path)
    assert "--format 'xxx" in line and len(line) < 200


def test_more_segments_than_the_limit_in_a_file(tmp_path, monkeypatch):
    import ecam.profile

    monkeypatch.setattr(ecam.profile, "MAX_SEGMENTS", 3)
    path = tmp_path / "cam.toml"
    path.write_text("master_period = 4.0\n" + '[[segment]]\nlaw = "dwell"\nspan = 1.0\n' * 4)
    assert one_line("check", path).endswith("segment: 4 should be at most 3 segments")


def test_a_span_written_at_its_limit_is_accepted(tmp_path):
    """1e-9 of the period as written passes, though end - start rounds it a little below."""
    import ecam

    path = tmp_path / "cam.toml"
    path.write_text('master_period = 1.0\n[[segment]]\nlaw = "dwell"\nspan = 0.5\n'
                    '[[segment]]\nlaw = "cycloidal"\nspan = 1e-9\nstroke = 1.0\n'
                    '[[segment]]\nlaw = "cycloidal"\nspan = 1e-9\nstroke = -1.0\n'
                    '[[segment]]\nlaw = "dwell"\nend = 1.0\n')
    profile = ecam.load_cam(path)
    assert profile.segments[1].span < 1e-9 and profile.check().ok


def test_a_long_list_of_jumps_is_capped_with_errors_first(tmp_path):
    """Thousands of jerk steps print a screenful, not a line each, and an error among them (here a
    position gap at the seam) is still shown."""
    from ecam.app.cam_commands import LISTED

    count = 2 * LISTED + 40
    body = "".join('[[segment]]\nlaw = "cycloidal"\nspan = 1.0\nstroke = 1.0\n'
                   '[[segment]]\nlaw = "dwell"\nspan = 1.0\n' for _ in range(count // 2))
    path = tmp_path / "many.toml"
    path.write_text(f"master_period = {float(count)}\n" + body)
    run = subprocess.run([sys.executable, "-m", "ecam.app", "check", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1, run.stderr
    lines = run.stdout.splitlines()
    jumps = [line for line in lines if line.lstrip().startswith(("ERROR", "WARNING"))]
    assert len(jumps) == LISTED
    assert jumps[0].lstrip().startswith("ERROR") and "seam" in jumps[0]
    total = sum(1 for line in lines if "errors," in line)
    assert total == 1
    more = [line for line in lines if line.strip().startswith("... and")]
    assert len(more) == 1 and f"and {count + 1 - LISTED} more" in more[0], more
