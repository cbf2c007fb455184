"""Cam files: the format, and one clear line for every kind of bad input."""
import subprocess
import sys
import textwrap

import pytest

import ecam

GOOD = """
name = "t"
master_period = 360.0
[[segment]]
law = "dwell"
span = 90.0
[[segment]]
law = "cycloidal"
span = 90.0
stroke = 10.0
[[segment]]
law = "cycloidal"
span = 180.0
to = 0.0
"""


def write(tmp_path, text, name="cam.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_errors_name_the_file(tmp_path):
    path = write(tmp_path, GOOD.replace("stroke = 10.0", "stroke = nan"))
    with pytest.raises(ecam.CamFileError) as info:
        ecam.load_cam(path)
    assert str(info.value) == f"cam {path}: segment[1].stroke: nan should be finite"


def test_good_file(tmp_path):
    profile = ecam.load_cam(write(tmp_path, GOOD))
    assert profile.master_period == 360.0 and len(profile.segments) == 3
    assert profile(180.0) == pytest.approx(10.0) and profile(360.0 - 1e-9) == pytest.approx(0.0, abs=1e-9)
    assert profile.check().ok


BAD = [
    ("master_period = 360.0\n", "segment: missing"),
    (GOOD.replace("master_period = 360.0", ""), "master_period: missing; expected a number"),
    (GOOD.replace('law = "cycloidal"\nspan = 90.0', 'law = "cycloid"\nspan = 90.0'), "segment[1].law: 'cycloid' should be one of constant_acceleration, "),
    (GOOD.replace("span = 90.0\nstroke", "span = -5.0\nstroke"), "segment[1].span: -5 should be > 0"),
    (GOOD.replace("span = 90.0\nstroke", "span = 0.0\nstroke"), "segment[1].span: 0 should be > 0"),
    (GOOD.replace("stroke = 10.0", "stroke = nan"), "segment[1].stroke: nan should be finite"),
    (GOOD.replace("stroke = 10.0", "stroke = inf"), "segment[1].stroke: inf should be finite"),
    (GOOD.replace("stroke = 10.0", 'stroke = "ten"'), "segment[1].stroke: 'ten' should be a number"),
    (GOOD.replace("stroke = 10.0", "stroke = true"), "segment[1].stroke: True should be a number"),
    (GOOD.replace("span = 180.0", "span = 170.0"), "segment[2].end: 350 should be 360, the master_period (it leaves a gap)"),
    (GOOD.replace("span = 180.0", "span = 190.0"), "segment[2].end: 370 should be 360, the master_period (it leaves an overlap)"),
    (GOOD.replace("span = 180.0", "start = 170.0\nspan = 180.0"), "segment[2].start: 170 should be 180, where segment[1] ends (it leaves an overlap)"),
    (GOOD.replace("span = 180.0", "start = 190.0\nspan = 170.0"), "segment[2].start: 190 should be 180, where segment[1] ends (it leaves a gap)"),
    (GOOD.replace("stroke = 10.0", ""), "segment[1].stroke: missing"),
    (GOOD + "bogus = 1\n", "unknown field"),
    (GOOD.replace("periodic", "x").replace('name = "t"', 'name = "t"\nperiodic = "yes"'), "periodic: 'yes' should be true or false"),
    ("master_period = 360.0\nsegment = 5\n", "should be an array of tables"),
    (GOOD.replace("[[segment]]\nlaw = \"dwell\"", "[[segment]]\nlaw = 7"), "segment[0].law: 7 should be one of "),
    ("master_period = 360.0\n[[segment\n", "is not valid TOML"),
    (GOOD.replace("stroke = 10.0", "stroke = 10.0\naccel_ratio = 2.0"),
     "segment[1].accel_ratio: 2 should be absent: only a combination takes one"),
    (GOOD.replace("stroke = 10.0", "stroke = 10.0\nstart_velocity = 1.0"),
     "segment[1].start_velocity: 1 should be absent: only poly5/poly7 segments take boundary conditions"),
    (GOOD.replace('law = "cycloidal"\nspan = 90.0', 'combination = ["cycloid", "half_harmonic_end"]\nspan = 90.0'),
     "segment[1].combination[0]: 'cycloid' should be one of constant_acceleration, "),
    (GOOD.replace('[[segment]]\nlaw = "dwell"\nspan = 90.0', '[[segment]]\nlaw = "dwell"\nspan = 90.0\nstroke = 1.0'),
     "segment[0].stroke: 1 should be 0 for a dwell"),
    (GOOD.replace('law = "cycloidal"\nspan = 90.0', 'law = "poly5"\nstart_jerk = 1.0\nspan = 90.0'),
     "segment[1].start_jerk: 1 should be absent for a 5th-order polynomial (poly5); use degree 7 (poly7)"),
    ("master_period = 360.0\nperiodic = false\n[[segment]]\nlaw = \"poly5\"\nspan = 360.0\nstroke = 1.0\n"
     "start_velocity = \"match\"\n",
     "segment[0].start_velocity: 'match' should have a neighbouring segment with a fixed law"),
]


@pytest.mark.parametrize("text,message", BAD)
def test_bad_files_name_field_value_and_expectation(tmp_path, text, message):
    with pytest.raises(ecam.CamFileError) as info:
        ecam.load_cam(write(tmp_path, text))
    assert message in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("text,message", BAD[:6])
def test_cli_prints_one_line_and_exits_2(tmp_path, text, message):
    path = write(tmp_path, text)
    run = subprocess.run([sys.executable, "-m", "ecam.app", "check", str(path)], capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stdout == ""
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in run.stderr


def test_missing_file_is_one_line(tmp_path):
    run = subprocess.run([sys.executable, "-m", "ecam.app", "check", str(tmp_path / "nope.toml")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "does not exist" in run.stderr and len(run.stderr.strip().splitlines()) == 1


def test_poly5_and_poly7_with_matched_neighbours(tmp_path):
    text = """
    master_period = 300.0
    periodic = false
    [[segment]]
    law = "constant_velocity"
    span = 100.0
    stroke = 100.0
    [[segment]]
    law = "poly5"
    span = 100.0
    stroke = 50.0
    start_velocity = "match"
    end_velocity = "match"
    [[segment]]
    law = "constant_velocity"
    span = 100.0
    stroke = 20.0
    """
    profile = ecam.load_cam(write(tmp_path, text))
    report = profile.check()
    assert report.continuous(1)  # velocity matched on both sides (VDI 2143 motion-to-motion)
    assert profile(150.0, 1) > 0
    text7 = text.replace('"poly5"', '"poly7"')
    assert ecam.load_cam(write(tmp_path, text7, "c7.toml")).check().continuous(2)


def test_combination_in_a_file_needs_a_ratio(tmp_path):
    text = """
    master_period = 120.0
    [[segment]]
    combination = ["half_cycloid_start", "half_harmonic_end"]
    span = 120.0
    stroke = 1.75
    """
    with pytest.raises(ecam.CamFileError, match="segment\\[0\\].accel_ratio: missing"):
        ecam.load_cam(write(tmp_path, text))


@pytest.mark.parametrize("target,message", [("plot.xyz", "has format 'xyz'"), ("missing/plot.png", "does not exist")])
def test_plot_to_a_bad_path_is_one_line(tmp_path, target, message):
    path = write(tmp_path, GOOD)
    run = subprocess.run([sys.executable, "-m", "ecam.app", "plot", str(path), "-o", str(tmp_path / target)],
                         capture_output=True, text=True)
    assert run.returncode == 2 and message in run.stderr and len(run.stderr.strip().splitlines()) == 1


EXTREME = [
    # the span as written, not as lost in rounding against its start (90)
    (GOOD.replace("span = 90.0\nstroke", "span = 1e-300\nstroke").replace("span = 180.0", "span = 270.0"),
     "segment[1].span: 1e-300 should be >= 1e-09 of master_period (3.6e-07)"),
    (GOOD.replace("master_period = 360.0", "master_period = 1e308"), "master_period: 1e+308 should be <= 1e+12"),
    (GOOD.replace('name = "t"', 'name = "t"\nstart = 1e308').replace("to = 0.0", "to = -1e308"),
     "start: 1e+308 should be of magnitude <= 1e+150"),
    (GOOD.replace('name = "t"', 'name = "t"\nstart = 1e20'), "start: 1e+20 should be <= 1e+15"),
    (GOOD.replace("to = 0.0", "to = -1e20"), "segment[2].to: -1e+20 should be >= -1e+15"),
    ("""master_period = 120.0
[[segment]]
combination = ["half_cycloid_start", "half_harmonic_end"]
accel_ratio = 1e300
span = 120.0
stroke = 1.0
""", "segment[0].accel_ratio: 1e+300 should be <= 1e+06"),
]


@pytest.mark.parametrize("text,message", EXTREME)
def test_extreme_numbers_are_bad_input_not_a_crash(tmp_path, text, message):
    path = write(tmp_path, text)
    run = subprocess.run([sys.executable, "-m", "ecam.app", "check", str(path)], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and message in run.stderr, run.stderr


INDEX = """
name = "index"
slave_unit = "deg"
master_period = 360.0
net_stroke = 45.0
[[segment]]
name = "index"
law = "modified_sine"
span = 240.0
stroke = 45.0
[[segment]]
law = "dwell"
span = 120.0
"""


def test_net_stroke_in_a_file(tmp_path):
    profile = ecam.load_cam(write(tmp_path, INDEX))
    assert profile.net_stroke == 45.0 and profile.check().ok and profile(720.0) == 90.0


@pytest.mark.parametrize("change, message", [
    (("net_stroke = 45.0", 'net_stroke = "45 deg"'), "net_stroke: '45 deg' should be a number"),
    (("net_stroke = 45.0", "net_stroke = 40.0"), "net_stroke: 40 should be +45, what the segments add up to (the "
                                                 "slave starts the period at 0 and ends it at 45)"),
    (("span = 240.0\nstroke = 45.0", "span = 240.0\nstroke = 4.5"), "net_stroke: 45 should be +4.5, what the "
                                                                    "segments add up to"),
    (("net_stroke = 45.0", "net_stroke = 45.0\nperiodic = false"), "net_stroke: 45 should be absent for a cam that "
                                                                  "is not periodic"),
    (("net_stroke = 45.0", "net_stroke = 45.0\nnet_strok = 1"), "net_strok: unknown field; expected one of"),
])
def test_bad_net_stroke_in_a_file(tmp_path, change, message):
    path = write(tmp_path, INDEX.replace(*change))
    with pytest.raises(ecam.CamFileError) as info:
        ecam.load_cam(path)
    assert str(info.value).startswith(f"cam {path}: {message}"), str(info.value)


def test_table_tolerance_in_counts(tmp_path):
    from ecam import compile_table

    text = GOOD + '[table]\ntolerance = "2 counts"\nmaster_counts = 65536\nslave_counts_per_unit = 1000\ninterp = "auto"\n'
    profile = ecam.load_cam(write(tmp_path, text))
    assert profile.table["tolerance"] == "2 counts"
    assert compile_table(profile).report["predicted_error_counts"] <= 2
    with pytest.raises(ecam.CamFileError, match="table.tolerance: '3 furlongs' should be in the cam's slave unit \\(mm\\) or in counts"):
        ecam.load_cam(write(tmp_path, text.replace('"2 counts"', '"3 furlongs"'), "bad.toml"))


@pytest.mark.parametrize("args,message", [
    (["compile", "{cam}", "-o", "{tmp}"], "points and tolerance are both missing"),
    (["compile", "{cam}", "--points", "9", "--format", "", "-o", "{tmp}"], "--format '' should name"),
    (["demo", "-o", "/proc/ecam-demo"], "cannot be created"),
])
def test_more_cli_bad_input(tmp_path, args, message):
    cam = write(tmp_path, GOOD)
    args = [a.format(cam=cam, tmp=tmp_path) for a in args]
    run = subprocess.run([sys.executable, "-m", "ecam.app", *args], capture_output=True, text=True)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and message in run.stderr, run.stderr


def test_a_long_path_in_an_error_is_cut_in_the_middle_and_keeps_the_files_name(tmp_path):
    from ecam.camfile import read_toml
    from ecam.errors import CamFileError

    deep = tmp_path.joinpath(*["a_rather_long_directory_name"] * 4)
    deep.mkdir(parents=True)
    broken = deep / "not_toml.toml"
    broken.write_text("[unclosed\n")
    with pytest.raises(CamFileError) as info:
        read_toml(broken, "scene file")
    message = str(info.value)
    assert "not_toml.toml'" in message and "..." in message
    shown = message.split("scene file ", 1)[1].split(" is not valid TOML")[0]
    assert len(shown) < 61 and shown.startswith("'/")
