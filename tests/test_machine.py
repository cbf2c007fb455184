"""Machines (issue 22): several axes from one virtual master on one bus. A machine file reads
each axis with the scene's own parsers; a two-axis machine gives each axis exactly the report it
gets alone (bus-free, and on the bus while the bus is no limit); one bus's arbitration makes the
higher COB-IDs late first; a scene file is a machine of one."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from ecam.errors import CamFileError, InputError
from ecam.app.junit import junit_xml
from hil_sim.bus import frame_bits
from hil_sim.bus_sizing import size_bus
from hil_sim.machine import load_machine, parse_machine
from hil_sim.rig import run_scene
from hil_sim.rig.cam import compile_cam
from hil_sim.rig.machine_run import run_machine
from hil_sim.scene import DurationSpec, load_scene

ROOT = Path(__file__).resolve().parents[1]
CAM = str(ROOT / "firmware_tables" / "cams" / "modified_sine.toml")

# the drive_side scene's ballscrew axis, as an [[axis]] table
AXIS = """
[[axis]]
name = "{name}"
node_id = {node}
cam_mode = "{mode}"
phase = {phase}
[axis.cam]
file = "{cam}"
interp = "cubic"
points = 257
master_counts = 65536
slave_counts_per_unit = 1000
[axis.drive]
cycle_s = 0.001
following_error_window = 5000
[axis.mechanics]
motor_inertia = 1.2e-4
gear_ratio = 1.0
motor_damping = 1.0e-4
load_damping = 1.0e-3
load_inertia = 2.0e-4
motor_torque_limit = 6.0
slave_units_per_load_radian = 1.5915494309189535
[axis.limits]
tracking_error = 0.05
"""


def machine_text(axes, bitrate=1_000_000, periods=1.0) -> str:
    head = f"""name = "pair"
[master]
speed_rpm = 60.0
profile = "start_stop"
max_acceleration = 2000.0
max_jerk = 40000.0
[bus]
bitrate = {bitrate}
[limits]
bus_load_percent = 90.0
[duration]
master_periods = {periods}
"""
    return head + "".join(AXIS.format(cam=CAM, **a) for a in axes)


PAIR = [dict(name="screw", node=3, mode="drive", phase=0.0),
        dict(name="lifter", node=5, mode="controller", phase=90.0)]


@pytest.fixture(scope="module")
def pair_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("machine") / "pair.toml"
    path.write_text(machine_text(PAIR))
    return path


def _axis_dict(report) -> dict:
    out = report.to_dict()
    out.pop("node_id", None)
    out.pop("phase", None)
    return out


def test_axes_read_with_the_scene_parsers(pair_file):
    machine = load_machine(pair_file)
    assert not machine.single and [a.name for a in machine.axes] == ["screw", "lifter"]
    screw, lifter = machine.axes
    assert (screw.drive.node_id, lifter.drive.node_id) == (3, 5)
    assert (screw.cam_mode, lifter.cam_mode) == ("drive", "controller")
    assert (screw.phase, lifter.phase) == (0.0, 90.0)
    assert screw.master == lifter.master and screw.master.profile == "start_stop"
    assert machine.bus.bitrate == 1_000_000 and machine.bus_load_percent == 90.0


def test_a_scene_file_is_a_machine_of_one():
    path = ROOT / "hil_sim" / "scenes" / "drive_side.toml"
    machine = load_machine(path)
    assert machine.single and machine.axes == (load_scene(path),)


@pytest.mark.parametrize("change, field", [
    (lambda t: t.replace("node_id = 5", "node_id = 3"), "axis[1].node_id: 3 should be distinct"),
    (lambda t: t.replace('name = "lifter"', 'name = "screw"'), "axis[1].name: 'screw' should be"),
    (lambda t: t[::-1].replace("100.0 = s_elcyc", "200.0 = s_elcyc", 1)[::-1],
     "axis[1].drive.cycle_s: 0.002 should be 0.001"),
    (lambda t: t.replace("[axis.drive]\n", "[axis.drive]\nnode_id = 9\n", 1),
     "axis[0].drive.node_id: give the node id as axis[0].node_id"),
    (lambda t: t.replace('phase = 90.0', 'phase = 90.0\nspeed = 1.0'), "axis[1].speed: unknown"),
    (lambda t: t.replace("interp = \"cubic\"", "interp = \"cubic\"\nzz = 1", 1),
     "axis[0] (screw): cam.zz: unknown field"),
])
def test_bad_machines_name_the_field(change, field):
    import tomllib
    data = tomllib.loads(change(machine_text(PAIR)))
    with pytest.raises(CamFileError) as raised:
        parse_machine(data, source="m.toml")
    message = str(raised.value)
    assert field in message and "\n" not in message


def test_a_cam_in_master_is_refused():
    import tomllib
    text = machine_text(PAIR).replace('profile = "start_stop"', 'profile = "cam_in"')
    with pytest.raises(CamFileError, match="master.profile: 'cam_in' should be"):
        parse_machine(tomllib.loads(text), source="m.toml")


def test_bus_free_machine_equals_its_axes_alone(pair_file):
    machine = load_machine(pair_file)
    report = run_machine(machine, path="fast")
    for axis, alone in zip(report.axes, machine.axes):
        single = run_scene(alone, path="fast")
        assert _axis_dict(axis) == single.to_dict()
        assert np.array_equal(axis.series["tracking_error"], single.series["tracking_error"])
    assert report.axis("lifter").summary["phase"] == 90.0
    assert report.check("bus_load").value is None  # no bus bus-free


@pytest.fixture(scope="module")
def pair_reports(pair_file):
    return run_machine(pair_file, path="fast"), run_machine(pair_file, path="canopen")


def test_on_the_bus_each_axis_is_bit_identical_to_bus_free(pair_reports):
    fast, bus = pair_reports
    assert bus.passed and bus.check("bus_load").passed
    for a, b in zip(fast.axes, bus.axes):
        for name in ("tracking_error", "coupling_torque", "following_error"):
            assert np.array_equal(a.series[name], b.series[name], equal_nan=True), name
        assert b.summary["bus"]["late_set_points"] == b.summary["bus"]["late_tpdos"] == 0
    # one bus for both: the same load in every axis's report and the machine's
    assert bus.axes[0].summary["bus"]["peak_bits"] == bus.summary["bus"]["peak_bits"]


def test_over_the_budget_the_higher_cob_ids_are_late_first(tmp_path):
    """Two controller-side axes, nodes 3 and 5: per cycle the SYNC (55 bits), TPDO1 7 bytes
    (0x183, 0x185: 125 bits each), TPDO2 6 bytes (0x283, 0x285: 115), RPDO2 8 bytes (0x303,
    0x305: 135), frame_bits = 47 + 8 n + floor((34 + 8 n - 1) / 4). At 750 kbit/s a 1 ms cycle
    has 750 bits: in cycle 0 the frames end at 180, 305, 420, 535, 670, 805: node 5's set point
    (0x305) is late. Cycle 1 starts with it (55 + 135 = 190), and its frames end at 315, 440,
    555, 670, 805: node 3's set point is late too, from cycle 1."""
    axes = [dict(name="a", node=3, mode="controller", phase=0.0),
            dict(name="b", node=5, mode="controller", phase=0.0)]
    assert [frame_bits(n) for n in (0, 4, 6, 7, 8)] == [55, 95, 115, 125, 135]
    path = tmp_path / "slow.toml"
    path.write_text(machine_text(axes, bitrate=750_000, periods=0.1))
    report = run_machine(path, path="canopen")
    late = report.summary["bus"]["late"]
    assert late["b"]["first_late_cycle"] == 0 and late["a"]["first_late_cycle"] == 1
    assert late["b"]["late_set_points"] > 0 and late["a"]["late_set_points"] > 0
    bus = report.check("bus_load")
    assert not bus.passed and "b " in bus.detail and "first at cycle 0" in bus.detail
    assert not report.passed
    sizing = report.summary["bus"]["sizing"]
    assert sizing["bits_per_cycle"] == 805 and not sizing["fits"]


def test_sizing_reproduces_the_issues_figures():
    """One 6-byte RPDO and one 6-byte TPDO per axis, SYNC, 80 % of 1 Mbit/s: 3 axes at 1 ms,
    6 at 2 ms, 13 at 4 ms; with 8-byte PDOs 2 / 5 / 11 (issue 22, from the same frame
    lengths): a machine of one axis fits that many minus one more."""
    for lengths, expected in (([6, 6], (3, 6, 13)), ([8, 8], (2, 5, 11))):
        for cycle_s, axes in zip((0.001, 0.002, 0.004), expected):
            sizing = size_bus({"x": lengths}, 1_000_000, cycle_s, 80.0)
            assert sizing["more_axes"]["x"] == axes - 1
    sizing = size_bus({"x": [6, 6]}, 1_000_000, 0.001, 80.0)
    assert sizing["bits_per_cycle"] == 55 + 230
    assert sizing["min_standard_bitrate"] == 500_000  # 285 bits / 0.8 ms = 356 kbit/s


def test_machine_durations_must_agree(tmp_path):
    """duration.master_periods with a master speed in master units/s and cams of different
    master periods gives the axes different cycle counts: refused, naming both (speed_rpm is
    machine cycles per minute: every axis one period per machine cycle)."""
    cam = tmp_path / "half.toml"
    cam.write_text('master_period = 180.0\n[[segment]]\nlaw = "cycloidal"\nspan = 90.0\n'
                   'stroke = 10.0\n[[segment]]\nlaw = "cycloidal"\nspan = 90.0\nstroke = -10.0\n')
    path = tmp_path / "m.toml"
    text = machine_text(PAIR).replace(f'file = "{CAM}"', f'file = "{cam}"', 1)
    path.write_text(text.replace("speed_rpm = 60.0", "speed = 360.0"))  # master units/s
    with pytest.raises(InputError, match="duration: 500 cycles for axis screw, 1000 cycles for "
                                         "axis lifter should be one count"):
        run_machine(path, path="fast")


MACHINES = ROOT / "hil_sim" / "machines"


def short(path, cycles=40):
    """A machine file run for a few cycles with every effect on (no measurement of the effects):
    enough for its frames and its bus, cheap enough for the quick suite."""
    machine = load_machine(path).with_fidelity("full")
    return replace(machine, axes=tuple(replace(a, duration=DurationSpec(cycles=cycles))
                                       for a in machine.axes))


def test_the_machine_api_is_on_hil_sim():
    import hil_sim
    assert hil_sim.MACHINES_DIR == MACHINES
    assert hil_sim.load_machine is load_machine and hil_sim.run_machine is run_machine
    assert {"find_machine_max_speed", "Machine", "MachineReport"} <= set(dir(hil_sim))


def test_the_shipped_line_has_the_issues_stations():
    """Six stations mixing controller- and drive-side cams: a feed roll whose net stroke is a
    fraction of a count (200 mm of film at 10000 counts per revolution of an 80 mm roll:
    200 x 10000 / (80 pi) = 7957.747 counts), the knife (360000 counts per cut), an
    eight-station turret (360 / 8 = 45 deg = 45000 counts per index) and the
    dwell-rise-return-dwell pusher."""
    machine = load_machine(MACHINES / "packaging_line.toml")
    modes = {a.name: a.cam_mode for a in machine.axes}
    assert modes == {"knife": "controller", "pusher": "controller", "lifter": "drive",
                     "transfer": "drive", "feed": "drive", "turret": "drive"}
    axes = {a.name: a for a in machine.axes}
    feed = compile_cam(axes["feed"]).table.net_stroke
    assert feed.denominator > 1  # a fraction of a count, stored exactly as a fraction
    assert float(feed) == pytest.approx(200.0 * 10000 / (80.0 * math.pi), abs=1e-6)
    assert compile_cam(axes["turret"]).table.net_stroke == Fraction(360 // 8 * 1000)
    assert compile_cam(axes["knife"]).table.net_stroke == Fraction(360 * 1000)
    pusher = compile_cam(axes["pusher"]).profile
    laws = [segment.law.name for segment in pusher.segments]
    assert pusher.net_stroke is None and laws[0] == laws[-1] == "dwell"  # dwell-rise-return-dwell
    assert pusher.slave_range == pytest.approx((0.0, 1.75))
    assert {a.drive.cycle_s for a in machine.axes} == {0.004}


def test_the_shipped_line_is_sized_from_its_frames():
    """Controller-side: RPDO 8 bytes + TPDOs 7 and 6 bytes = 135 + 125 + 115 = 375 bits;
    drive-side: RPDO 4 bytes = 95, + 240 = 335; two controller-side, four drive-side and the
    SYNC (55): 2145 bits per SYNC period; at 80 % of 1 Mbit/s at least 2145 / 800000 s =
    2.68 ms: 4 ms fits (3200 bits), with 1055 bits left: 2 more controller-side axes (750),
    3 more drive-side ones (1005)."""
    report = run_machine(short(MACHINES / "packaging_line.toml"), path="canopen")
    sizing = report.summary["bus"]["sizing"]
    assert sizing["axis_bits"] == {"knife": 375, "pusher": 375, "lifter": 335, "transfer": 335,
                                   "feed": 335, "turret": 335}
    assert sizing["bits_per_cycle"] == 2145 and sizing["fits"]
    assert sizing["min_cycle_s"] == pytest.approx(2145 / 800_000, rel=1e-12)
    assert sizing["more_axes"] == {"knife": 2, "pusher": 2, "lifter": 3, "transfer": 3,
                                   "feed": 3, "turret": 3}
    assert report.check("bus_load").passed and all(
        not v["late_set_points"] for v in report.summary["bus"]["late"].values())


def test_the_line_at_1_ms_does_not_fit_and_says_so():
    report = run_machine(short(MACHINES / "packaging_line_1ms.toml"), path="canopen")
    assert not report.passed and not report.check("bus_load").passed
    late = report.summary["bus"]["late"]
    assert set(late) == {a.scene for a in report.axes}
    assert all(late[name]["late_set_points"] > 0 for name in late)
    sizing = report.summary["bus"]["sizing"]
    assert not sizing["fits"] and sizing["min_cycle_s"] == pytest.approx(2145 / 800_000)
    text = report.to_text()
    assert "DOES NOT FIT" in text and "at least 2.68 ms" in text and "no more axes" in text


@pytest.mark.slow
def test_the_shipped_line_passes_on_both_paths_alike():
    path = MACHINES / "packaging_line.toml"
    fast, bus = run_machine(path, path="fast"), run_machine(path, path="canopen")
    assert fast.passed and bus.passed, bus.to_text()
    assert [a.scene for a in bus.axes] == ["knife", "pusher", "lifter", "transfer", "feed",
                                           "turret"]
    for a, b in zip(fast.axes, bus.axes):
        assert np.array_equal(a.series["tracking_error"], b.series["tracking_error"])


def test_junit_has_a_testcase_per_machine_and_axis_check(pair_reports):
    import xml.etree.ElementTree as ET
    bus = pair_reports[1]
    cases = list(ET.fromstring(junit_xml([("pair.toml", bus, 1.0)])).iter("testcase"))
    names = [case.get("name") for case in cases]
    assert names[:2] == ["bus_load", "faults"]
    assert "screw.tracking_error" in names and "lifter.loop_stability" in names
    assert len(names) == 2 + sum(len(a.checks) for a in bus.axes)


def test_the_machine_plot_draws_what_each_tracking_check_reads(pair_reports, tmp_path):
    """The machine's figure draws each axis's tracking error where its check looks, as a share
    of its limit: the highest point drawn is the check's value over its limit."""
    from hil_sim.rig.machine_plot import checked_tracking, machine_figure_bytes, plot_machine
    bus = pair_reports[1]
    for axis in bus.axes:
        x, share = checked_tracking(axis, 360.0)
        check = axis.check("tracking_error")
        assert np.nanmax(share) == pytest.approx(100.0 * check.value / check.limit, rel=1e-12)
        assert np.nanmin(x) >= 0.0 and np.nanmax(x) < 360.0
    written = plot_machine(bus, tmp_path / "pair.png")
    assert [p.name for p in written] == ["pair.png", "pair_screw.png", "pair_lifter.png"]
    assert all(p.read_bytes().startswith(b"\x89PNG") for p in written)
    assert machine_figure_bytes(bus, dpi=110) == written[0].read_bytes()  # the same bytes again


def test_the_machine_page_has_the_machine_first_then_each_axis(pair_reports, pair_file):
    import copy
    from dataclasses import replace as change
    from ecam.app.machine_html import sim_page
    bus = pair_reports[1]
    page = sim_page([(pair_file, bus, 1.0)])
    assert "<h1>PASSED: machine pair, 2 of 2 axes passed</h1>" in page
    machine, screw, lifter = (page.index(f'id="{anchor}"') for anchor in
                              ("machine", "scene-screw", "scene-lifter"))
    assert machine < screw < lifter
    assert "bus sizing (worst-case bit stuffing)" in page[machine:screw]
    assert page.count('<img class="plot"') >= 3  # the machine's, and each axis's
    # the bus fails, every axis passes: the page says FAILED, and why
    failing = copy.copy(bus)
    failing.machine_checks = [change(c, passed=False) if c.name == "bus_load" else c
                              for c in bus.machine_checks]
    failing.axes = [change(a, series={}, summary={k: v for k, v in a.summary.items()
                                                  if k != "tuning"}) for a in bus.axes]
    page = sim_page([(pair_file, failing, 1.0)])
    assert "<h1>FAILED: machine pair, 2 of 2 axes passed; the machine&#x27;s own checks failed" \
        in page and "the machine's own checks failed (below)" in page


def test_a_directory_run_takes_machine_files(pair_file, tmp_path):
    from ecam.app.multi import run_scenes, summary_table
    directory = tmp_path / "line"
    directory.mkdir()
    (directory / "pair.toml").write_text(machine_text(PAIR, periods=0.25))
    (directory / "cam.toml").write_text(Path(CAM).read_text())  # a cam file: not a scene
    results = run_scenes([directory], fidelity="full")
    assert len(results) == 1
    _, report, _ = results[0]
    assert report.machine == "pair" and [a.scene for a in report.axes] == ["screw", "lifter"]
    assert "pair  " in summary_table(results) and "1 of 1 scenes passed" in summary_table(results)


pytest_plugins = ["pytester"]


def test_the_pytest_plugin_has_a_test_per_axis(pytester):
    machines = pytester.path / "machines"
    machines.mkdir()
    text = machine_text(PAIR, periods=0.25)
    head, lifter = text.rsplit("[[axis]]", 1)
    (machines / "pair.toml").write_text(head + "[[axis]]" + lifter.replace(
        "tracking_error = 0.05", "tracking_error = 1e-9"))  # the lifter cannot pass
    from importlib.metadata import entry_points
    installed = any(e.value == "ecam.app.pytest_plugin" for e in entry_points(group="pytest11"))
    result = pytester.runpytest(*([] if installed else ["-p", "ecam.app.pytest_plugin"]),
                                "--ecam-scenes", "machines", "-ra", "-v")
    result.assert_outcomes(passed=2, failed=1)
    result.stdout.fnmatch_lines(["*machines/pair.toml::machine PASSED*",
                                 "*machines/pair.toml::screw PASSED*",
                                 "*machines/pair.toml::lifter FAILED*",
                                 "FAILED machines/pair.toml::lifter - FAIL  tracking_error: *"])


def test_find_max_speed_names_the_limiting_station(tmp_path):
    """Two like axes, the lifter's motor clamped at half the screw's torque: the lifter's
    torque limits the machine, the search says so (station and check), and the speed found
    passes over CANopen while the failing one fails on that station's check."""
    from hil_sim.rig.machine_search import find_machine_max_speed
    text = machine_text(PAIR)
    head, lifter = text.rsplit("[[axis]]", 1)
    path = tmp_path / "weak.toml"
    path.write_text(head + "[[axis]]" + lifter.replace("motor_torque_limit = 6.0",
                                                       "motor_torque_limit = 3.0"))
    result = find_machine_max_speed(path, tolerance=0.1)  # a coarse search: a short test
    assert result["limiting_station"] == "lifter"
    assert result["confirmed"] and result["speed"] < result["failing_speed"]
    assert all(name.startswith("lifter.") for name in result["failed_checks"])
    assert result["limiting_check"].startswith("FAIL  lifter.")
    assert result["periods_per_minute"] == pytest.approx(60.0 * result["speed"] / 360.0)
    last = result["runs"][-1]
    assert last["path"] == "canopen" and last["passed"] and last["speed"] == result["speed"]


@pytest.mark.slow
def test_cli_writes_every_output_of_a_machine(pair_file, tmp_path):
    """One `ecam sim MACHINE --json --junit --html --plot`: the JSON's axes list carries each
    axis's report with a single scene's fields, and every file is written."""
    files = {k: tmp_path / f"pair.{k}" for k in ("xml", "html", "png")}
    out = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(pair_file), "--json",
                          "--junit", str(files["xml"]), "--html", str(files["html"]), "--plot",
                          str(files["png"])], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["machine"] == "pair" and [a["scene"] for a in data["axes"]] == ["screw", "lifter"]
    assert data["passed"] and {c["name"] for c in data["checks"]} == {"bus_load", "faults"}
    alone = run_scene(load_machine(pair_file).axes[0], path="fast").to_dict()
    assert set(data["axes"][0]) == set(alone) | {"node_id", "phase"}
    assert all(f.stat().st_size > 0 for f in files.values())
    assert (tmp_path / "pair_screw.png").is_file() and (tmp_path / "pair_lifter.png").is_file()
    assert "wrote" in out.stderr and "plots:" in out.stderr
