"""Machines (issue 22): several axes from one virtual master on one bus. A machine file reads
each axis with the scene's own parsers; a two-axis machine gives each axis exactly the report it
gets alone (bus-free, and on the bus while the bus is no limit); one bus's arbitration makes the
higher COB-IDs late first; a scene file is a machine of one."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ecam.errors import CamFileError, InputError
from hil_sim.bus import frame_bits
from hil_sim.bus_sizing import size_bus
from hil_sim.machine import load_machine, parse_machine
from hil_sim.rig import run_scene
from hil_sim.rig.machine_run import run_machine
from hil_sim.scene import load_scene

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


def test_on_the_bus_each_axis_is_bit_identical_to_bus_free(pair_file):
    fast = run_machine(pair_file, path="fast")
    bus = run_machine(pair_file, path="canopen")
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


def test_cli_runs_a_machine(pair_file):
    out = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(pair_file), "--json"],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["machine"] == "pair" and [a["scene"] for a in data["axes"]] == ["screw", "lifter"]
    assert data["passed"] and {c["name"] for c in data["checks"]} == {"bus_load", "faults"}
    text = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(pair_file)],
                          capture_output=True, text=True, cwd=ROOT)
    assert text.returncode == 0 and text.stdout.startswith("machine pair: PASSED")
    assert "bus sizing" in text.stdout


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


@pytest.fixture(scope="module")
def line_reports():
    path = MACHINES / "packaging_line.toml"
    return run_machine(path, path="fast"), run_machine(path, path="canopen")


def test_the_shipped_line_passes_on_both_paths_alike(line_reports):
    fast, bus = line_reports
    assert fast.passed and bus.passed
    assert [a.scene for a in bus.axes] == ["knife", "pusher", "lifter", "transfer"]
    assert [a.summary["cam_mode"] for a in bus.axes] == ["controller", "controller", "drive",
                                                         "drive"]
    for a, b in zip(fast.axes, bus.axes):
        assert np.array_equal(a.series["tracking_error"], b.series["tracking_error"])


def test_the_shipped_line_is_sized_from_its_frames(line_reports):
    """Controller-side: RPDO 8 bytes + TPDOs 7 and 6 bytes = 135 + 125 + 115 = 375 bits;
    drive-side: RPDO 4 bytes = 95, + 240 = 335; two of each and the SYNC (55): 1475 bits per
    SYNC period; at 90 % of 1 Mbit/s at least 1475 / 900000 s = 1.639 ms: 2 ms fits."""
    sizing = line_reports[1].summary["bus"]["sizing"]
    assert sizing["axis_bits"] == {"knife": 375, "pusher": 375, "lifter": 335, "transfer": 335}
    assert sizing["bits_per_cycle"] == 1475 and sizing["fits"]
    assert sizing["min_cycle_s"] == pytest.approx(1475 / 900_000, rel=1e-12)
    assert sizing["more_axes"] == {"knife": 0, "pusher": 0, "lifter": 0, "transfer": 0}


def test_the_line_at_1_ms_does_not_fit_and_says_so():
    report = run_machine(MACHINES / "packaging_line_1ms.toml", path="canopen")
    assert not report.passed and not report.check("bus_load").passed
    late = report.summary["bus"]["late"]
    assert all(late[name]["late_set_points"] > 0 for name in late)
    assert not report.summary["bus"]["sizing"]["fits"]
    assert "DOES NOT FIT" in report.to_text()


def test_junit_has_a_testcase_per_machine_and_axis_check(pair_file, tmp_path):
    import xml.etree.ElementTree as ET
    junit = tmp_path / "machine.xml"
    out = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(pair_file), "--junit",
                          str(junit)], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    names = [case.get("name") for case in ET.parse(junit).getroot().iter("testcase")]
    assert names[:2] == ["bus_load", "faults"]
    assert "screw.tracking_error" in names and "lifter.loop_stability" in names
    assert len(names) == 2 + sum(len(a.checks) for a in run_machine(pair_file, path="fast").axes)


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
