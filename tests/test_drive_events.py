"""Drive-side events (issue 23): the virtual drive's cam slot (hil_sim/drive/cam_slot.py) with
MC_CamIn's offsets and scaling (0x2001:07..0C, hil_sim/drive/cam_coupling.py) and a switch at a
master position (0x2001:01 = 4, 0x2001:06), against ecam.table_pair.SwitchPair (the firmware's
switch) and against the same scene controller-side (hil_sim/events.py): the set points cycle by
cycle, without running a drive (cheap), and one short run over the bus against the bus-free path."""

from __future__ import annotations

import tomllib
from dataclasses import replace

import numpy as np
import pytest

from ecam.errors import InputError
from ecam.table_pair import SwitchPair
from hil_sim import SCENES_DIR
from hil_sim.drive.cam_coupling import Coupling, round_ratio, scaling_ratio
from hil_sim.drive.cam_slot import (
    CAM_COMMAND_ACTIVATE, CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION, CAM_COMMAND_ACTIVATE_AT_PERIOD_END,
    CAM_MODE_DRIVE_SIDE, CAM_STATUS_QUEUED, CamSlot,
)
from hil_sim.drive.objects import (
    CAM_ACTIVATION_POSITION, CAM_MASTER_OFFSET, CAM_MODE, CAM_SLAVE_OFFSET, CAM_STATUS, CAM_SWITCH_MODE,
    MASTER_POSITION,
)
from hil_sim.int32 import wrap_int32
from hil_sim.rig.cam import compile_cam
from hil_sim.rig.fast import _cam_commands, _write
from hil_sim.rig.plan import plan_run, wire_set_points
from hil_sim.scene import parse_scene

CYCLES = 1500  # 1.5 s at 60 rpm: the switch at 360 deg and half a period of the new cam
SWITCH_B = {"action": "switch", "cam": "cams/product_b.toml", "at_position": 100.0, "allow_jump": True}
# the changeover's first switch: into the transition cam designed from the seed's end
TO_TRANSITION = {"action": "switch", "cam": "cams/a_to_b.toml", "master": "relative"}
# the changeover's stop (in/s, in/s^2, in/s^3)
CAM_OUT = {"action": "cam_out", "at_position": 120.0, "max_velocity": 10.0, "max_acceleration": 200.0,
           "max_jerk": 20000.0}


def _scene(mode: str, events: list, speed_rpm: float = 60.0):
    data = tomllib.loads((SCENES_DIR / "stiff_coupling.toml").read_text())
    data.update(cam_mode=mode, event=events, duration={"cycles": CYCLES})
    data["master"]["speed_rpm"] = speed_rpm
    return parse_scene(data, base=SCENES_DIR, source="events.toml").with_fidelity("ideal")


def _tables():
    """The seed cam's table and product B's, at the scene's counts."""
    seed = _scene("drive", [])
    b = replace(seed, cam=replace(seed.cam, file=SCENES_DIR / "cams" / "product_b.toml"))
    return compile_cam(seed).table, compile_cam(b).table


def _slot(table, values=None):
    slot = CamSlot({CAM_STATUS: 0, CAM_MODE: 0, CAM_SWITCH_MODE: 0, **(values or {})})
    slot.verify_download(table.to_bytes())
    slot.write_command(CAM_COMMAND_ACTIVATE)
    slot.write_mode(CAM_MODE_DRIVE_SIDE)
    return slot


def _drive_targets(scene, velocities: bool = False):
    """What the drive's cam slot commands each cycle for a drive-side scene's plan: the master
    it is streamed and the events' SDO writes after each cycle's SYNC, as the rig applies them
    (the targets; with ``velocities`` also the velocity offsets)."""
    cam = compile_cam(scene)
    plan = plan_run(scene, cam, np.zeros(CYCLES), CYCLES)
    masters = wire_set_points(plan, drive_side=True)[0].tolist()
    slot = _slot(cam.table)
    commands = _cam_commands(plan)
    out = []
    for k, master in enumerate(masters):
        slot.values[MASTER_POSITION] = master
        out.append(slot.target(0.001))
        for command in commands.get(k, ()):
            _write(slot, slot.values, command)
    out = np.array(out)
    targets = out[:, 0].astype(np.int64)
    return (plan, targets, out[:, 1]) if velocities else (plan, targets)


def _controller_targets(events):
    scene = _scene("controller", events)
    return plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES)


# ------------------------------------------------------------------------------ the cam slot
@pytest.mark.parametrize("mode", range(4))
def test_offsets_on_the_drive_are_the_firmware_switch_both_ways(mode):
    """MC_CamIn's MasterOffset and SlaveOffset (0x2001:07/08) with each queued switch: the slot's
    targets are SwitchPair's (ecam_table_pair.c's) cycle by cycle, for a master that crosses one
    switch forwards and another backwards, with jumps of up to a seventh of a period."""
    seed, b = _tables()
    rng = np.random.default_rng(230 + mode)
    steps = np.concatenate([rng.integers(0, seed.master_counts // 7, 60), -rng.integers(0, b.master_counts // 7, 60)])
    masters = np.cumsum(steps).tolist()
    slot, pair = _slot(seed, {CAM_SWITCH_MODE: mode}), SwitchPair()
    pair.engage(seed)
    switched = []
    for k, master in enumerate(masters):
        for at, table in ((20, b), (70, seed)):
            if k == at:
                offsets = int(rng.integers(-50_000, 50_000)), int(rng.integers(-30_000, 30_000))
                slot.values[CAM_MASTER_OFFSET], slot.values[CAM_SLAVE_OFFSET] = offsets
                slot.verify_download(table.to_bytes())
                slot.write_command(CAM_COMMAND_ACTIVATE_AT_PERIOD_END)
                pair.arm_mode(table, mode, *offsets)
        slot.values[MASTER_POSITION] = wrap_int32(master)
        sample = pair.step(master)
        assert wrap_int32(slot.target(0.001)[0]) == sample.position, (k, master)
        switched += [k] if sample.switched else []
    assert len(switched) == 2 and masters[switched[1]] < masters[switched[1] - 1]


def test_a_master_position_activation_switches_where_the_master_crosses_it_either_way():
    """0x2001:01 = 4 (TwinCAT MC_CAMACTIVATION_ATMASTERAXISPOS: "when master axis position
    crosses the activation position"): forwards at the position itself, backwards at the first
    master below it, placed at the position (here master and slave relative: the new cam's 0
    there, the running cam's position there added); not before, however close."""
    seed, b = _tables()
    where = 5000
    slot = _slot(seed, {CAM_SWITCH_MODE: 3, CAM_ACTIVATION_POSITION: where})
    slot.values[MASTER_POSITION] = 4000
    slot.target(0.001)
    slot.verify_download(b.to_bytes())
    slot.write_command(CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION)
    at = int(seed.lookup(where))
    got = []
    for master in (4999, 5000, 5001):
        slot.values[MASTER_POSITION] = master
        got.append(slot.target(0.001)[0])
        if master == 4999:
            assert slot.values[CAM_STATUS] & CAM_STATUS_QUEUED
    assert got == [int(seed.lookup(4999)), at + int(b.lookup(0)), at + int(b.lookup(1))]
    # backwards across it: armed again (the seed, absolute), the switch at the count below
    slot.verify_download(seed.to_bytes())
    slot.values[CAM_SWITCH_MODE] = 0
    slot.write_command(CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION)
    got = []
    for master in (5003, 5000, 4999):
        slot.values[MASTER_POSITION] = master
        got.append(slot.target(0.001)[0])
    assert got == [at + int(b.lookup(3)), at + int(b.lookup(0)), int(seed.lookup(4999))]
    assert not slot.values[CAM_STATUS] & CAM_STATUS_QUEUED


def test_scaling_rounds_half_up_at_the_int64_edge():
    """round_ratio at the documented extremes (|master - zero| up to 2^31 - 1, terms up to
    2^32 - 1) against exact rational half-up rounding, floor(a N / D + 1/2)."""
    import math
    from fractions import Fraction

    rng = np.random.default_rng(2301)
    big = 2**32 - 1
    for _ in range(300):
        a = int(rng.integers(-(2**31) + 1, 2**31))
        n, d = int(rng.integers(1, big + 1)), int(rng.integers(1, big + 1))
        assert round_ratio(a, n, d) == math.floor(Fraction(a * n, d) + Fraction(1, 2)), (a, n, d)
    # +-(2^31 - 1) x (1 + 1 / (2^32 - 2)) = +-(2^31 - 1 + 1/2) exactly: half up both ways
    assert [round_ratio(a, big, big - 1) for a in (2**31 - 1, -(2**31) + 1)] == [2**31, -(2**31) + 1]
    assert round_ratio(5, 1, 2) == 3 and round_ratio(-5, 1, 2) == -2


def test_scaling_is_a_ratio_of_integers_rounded_half_up():
    """MasterScaling and SlaveScaling as numerator/denominator (0x2001:09..0C): X = round(N (m -
    zero) / D) + MasterOffset, slave = base + SlaveOffset + round(N CAM(X) / D), half up."""
    assert scaling_ratio(0.5) == (1, 2) and scaling_ratio(1.25) == (5, 4) and scaling_ratio(1e6) == (10**6, 1)
    assert scaling_ratio(1 / 3) == (1, 3)
    assert [round_ratio(v, 1, 2) for v in (-3, -2, -1, 0, 1, 2, 3)] == [-1, -1, 0, 0, 1, 1, 2]
    c = Coupling(zero=100, master_offset=7, master_ratio=(1, 2), base=1000, slave_offset=-5, slave_ratio=(5, 4))
    assert c.x(100) == 7 and c.x(103) == 9 and c.x(97) == 6  # 1.5 -> 2, -1.5 -> -1: half up
    assert c.master_at(9) == 104 and c.y(8) == 1005  # round(8 x 5/4) = 10, + 1000 - 5
    assert not Coupling(master_ratio=(3, 3)).scaled and Coupling(slave_ratio=(2, 1)).scaled


# ------------------------------------------------------------------- against controller-side
@pytest.mark.parametrize("name,event", [
    ("master_position", dict(SWITCH_B, activation="master_position", activation_position=200.0, master="relative",
                             slave="relative")),
    ("offsets", {"action": "offset", "at_position": 100.0, "master_offset": 10.0, "slave_offset": 0.05,
                 "allow_jump": True}),
    ("switch_offsets", dict(SWITCH_B, master="relative", master_offset=30.0, slave_offset=-0.02)),
])
def test_drive_side_set_points_are_the_controller_side_ones(name, event):
    """A switch at a master position and MC_CamIn offsets: the drive's cam slot commands the
    controller-side plan's targets bit for bit, every cycle (both see the master in whole counts;
    the activation falls in the same cycle)."""
    drive_plan, drive = _drive_targets(_scene("drive", [event]))
    controller = _controller_targets([event])
    assert drive_plan.events.switches[0].active_s is not None
    assert np.array_equal(drive, controller.targets)
    assert not np.array_equal(controller.targets, _controller_targets([]).targets)  # the event did something


@pytest.mark.parametrize("master,slave", [("relative", "absolute"), ("absolute", "relative"), ("relative", "relative")])
def test_an_immediate_drive_side_switch_is_placed_where_the_drive_takes_it(master, slave):
    """0x2001:01 = 1 is written after the SYNC of the request's cycle and the drive places the
    table at the master it received last (10322 counts, 279 x 36.864 rounded): the scene's
    ideal path switches there too, so the drive's set points are the plan's after the switch,
    bit for bit (only the activation cycle's own set point differs, the drive's still the old
    cam's). Before, the plan placed it at the exact master of the request (100.3 deg), up to a
    cycle's travel earlier: relative placements stayed 0.02 in off, ten times the tracking limit."""
    event = dict(SWITCH_B, at_position=100.3, activation="immediate", master=master, slave=slave)
    plan, drive = _drive_targets(_scene("drive", [event]))
    switch, = plan.events.switches
    assert switch.master == 10322 / 102.4 and switch.active_s == pytest.approx(0.280)
    assert np.flatnonzero(drive != plan.targets).tolist() == [279]


def test_an_immediate_drive_side_switch_keeps_the_velocity_offset():
    """A switch is no engagement: the master runs on, so the drive keeps its master speed
    observer. Switched (master absolute, slave relative) into product B where it moves at about
    634 000 counts/s, the drive's velocity offset follows the plan's within the observer's
    whole-count quantization (1 %) from the first cycle after the activation on; before, the
    observer restarted: that cycle's offset was 0 (the whole feed-forward missing for a cycle)."""
    event = dict(SWITCH_B, at_position=100.3, activation="immediate", slave="relative")
    plan, _, velocity = _drive_targets(_scene("drive", [event]), velocities=True)
    after = slice(280, 300)  # the drive's first cycles on B (the write follows cycle 279's SYNC)
    assert np.min(np.abs(plan.velocities[after])) > 6e5
    assert np.max(np.abs(velocity[after] / plan.velocities[after] - 1.0)) < 0.01


@pytest.mark.parametrize("activation", ["master_position", "period_end"])
def test_a_phase_shift_before_a_queued_switch_moves_where_it_activates(activation):
    """A switch requested at 100 deg for master 200 deg (or the period end, 360 deg), and a
    registration phase of +20 deg requested at 150 deg, before the activation: the master the
    slave sees (and the drive is streamed) gets there 20 deg of axis travel early, at
    (200 - 20) / 360 s or (360 - 20) / 360 s, and the drive's set points are the plan's bit for
    bit. Before, the switch's activation was found on the master without the phase planned after
    its request (at 200 / 360 s), the drive switched where its shifted master crossed, and its
    set points left the plan's by up to 46 702 counts."""
    event = dict(SWITCH_B, activation=activation, master="relative", slave="relative")
    where = 360.0
    if activation == "master_position":
        event["activation_position"] = where = 200.0
    phase = {"action": "phase", "at_position": 150.0, "shift": 20.0, "max_velocity": 1000.0,
             "max_acceleration": 1e5, "max_jerk": 1e7}  # done within 0.04 s, by 165 deg
    plan, drive = _drive_targets(_scene("drive", [event, phase]))
    switch, = plan.events.switches
    assert switch.master == where and switch.active_s == pytest.approx((where - 20.0) / 360.0, abs=1e-9)
    assert np.array_equal(drive, plan.targets)
    assert plan.events.motions[0].event.action == "phase"


def test_a_master_position_activation_is_at_the_first_crossing_when_a_phase_turns_the_master_back():
    """A switch for master 200 deg, then at 201 deg a -30 deg phase shift faster than the axis
    (1000 deg/s against 360): the master the slave sees crosses 200 at 200/360 s, goes back below
    it and crosses again at 230/360 s. The drive switches at the first crossing, and so does the
    plan, bit for bit; before, the bisection over the run found the second (28 072 counts off)."""
    event = dict(SWITCH_B, activation="master_position", activation_position=200.0, master="relative",
                 slave="relative")
    phase = {"action": "phase", "at_position": 201.0, "shift": -30.0, "max_velocity": 1000.0,
             "max_acceleration": 1e5, "max_jerk": 1e7}
    plan, drive = _drive_targets(_scene("drive", [event, phase]))
    switch, = plan.events.switches
    assert switch.active_s == pytest.approx(200.0 / 360.0, abs=1e-9)
    assert np.array_equal(drive, plan.targets)


def test_drive_side_scaling_is_within_a_master_count_of_controller_side():
    """MasterScaling 0.5 and SlaveScaling 1.25 at the period end: the drive scales the master it
    receives in whole counts, the controller the exact one, so the table's master coordinate
    differs by at most one count (two half-count roundings and a quarter count) and the slave by
    at most SlaveScaling x the table's steepest slope per count, plus the rounding's count."""
    event = {"action": "offset", "at_position": 100.0, "master_scaling": 0.5, "slave_scaling": 1.25,
             "allow_jump": True}
    _, drive = _drive_targets(_scene("drive", [event]))
    controller = _controller_targets([event])
    table = compile_cam(_scene("drive", [])).table
    slope = np.max(np.abs(table.lookup(np.arange(table.master_counts), with_slope=True)[1])) / 65536.0
    difference = np.abs(drive - controller.targets)
    assert difference.max() <= 1 + 1.25 * slope
    assert np.count_nonzero(difference > 1) < 0.1 * CYCLES  # only where the master count's rounding flips X
    assert not np.array_equal(controller.targets, _controller_targets([]).targets)


def test_a_master_position_the_drive_has_passed_is_refused():
    """The drive activates where the master crosses the position: one it has passed at the
    request would never come (controller-side it activates at once), so the scene is refused."""
    event = dict(SWITCH_B, at_position=250.0, activation="master_position", activation_position=200.0)
    scene = _scene("drive", [event])
    with pytest.raises(InputError, match=r"event\[0\]\.activation_position: 200 should be ahead of the master"):
        plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES)


def test_a_master_position_the_drive_stands_on_at_the_request_is_refused():
    """The master the drive has seen at the request is 279 x 36.864 = 10321.92 counts, streamed
    as 10322; an activation position of 10322 counts is ahead of the exact master but the drive
    stands on it, so going forwards it never crosses it (the switch would silently never happen
    while the plan reports it): refused, as a position behind the master is."""
    event = dict(SWITCH_B, at_position=100.3, activation="master_position", activation_position=10322 / 102.4)
    scene = _scene("drive", [event])
    with pytest.raises(InputError, match=r"activation_position: 100\.801 should be ahead .* 10322 counts, the "
                       r"position 10322\)"):
        plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES)


def test_a_slave_offset_past_integer32_counts_is_refused_in_one_line():
    """0x2001:08 SlaveOffset is INTEGER32: 30000 in at 100000 counts/in is 3e9 counts, past
    2^31 - 1 = 2147483647 (21474.8 in); before, the SDO write raised a traceback over the bus."""
    scene = _scene("drive", [dict(SWITCH_B, activation="immediate", slave_offset=30000.0)])
    with pytest.raises(InputError, match=r"event\[0\]\.slave_offset: 30000 should be within -21474\.8\.\.21474\.8 "
                       r"slave units with cam_mode 'drive' \(INTEGER32 counts"):
        plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES)


def test_drive_side_offsets_master_position_and_cam_out_over_the_bus_are_the_bus_free_run():
    """The SDO writes (0x2001:06 and :07 are INTEGER64: segmented; the cam-out's 0x6083, 0x6084,
    0x60A4:01) reach the drive over the bus and give the bus-free path's physics bit for bit: the
    change-over's transition switched in where the master crosses 360 deg, with a SlaveOffset of
    0.001 in, and a cam-out mid-transition at 400 deg; the bus_load check names both transfers."""
    from hil_sim.rig import run_scene

    events = [dict(TO_TRANSITION, at_position=100.0, activation="master_position", activation_position=360.0,
                   slave_offset=0.001, allow_jump=True), dict(CAM_OUT, at_position=400.0)]
    data = tomllib.loads((SCENES_DIR / "stiff_coupling.toml").read_text())
    data.update(cam_mode="drive", event=events, duration={"cycles": 1200})
    scene = parse_scene(data, base=SCENES_DIR, source="bus.toml").with_fidelity("ideal")
    over_bus, bus_free = run_scene(scene), run_scene(scene, path="fast")
    assert over_bus.cycles == 1200 and over_bus.check("faults").passed  # ran to its end
    for name in ("following_error", "tracking_error"):
        assert np.array_equal(over_bus.series[name], bus_free.series[name], equal_nan=True), name
    assert over_bus.summary["events"]["switches"][0]["master"] == pytest.approx(360.0)
    assert over_bus.summary["events"]["motions"][0]["duration_s"] > 0.02  # a stop mid-transition
    detail = over_bus.check("bus_load").detail
    assert "before its activation in cycle 999" in detail and "event[1] 8 SDO frames" in detail


# ------------------------------------------------------------------------------------ cam-out
def test_a_drive_side_cam_out_stops_where_the_controller_side_plan_stops():
    """0x2001:01 = 5 (MC_CamOut) mid-rise at 120 deg: the drive plans its jerk-limited stop in
    the cycle after the write from the cam's state there, within 0x6083/0x6084/0x60A4:01, and the
    scene's ideal path stops from the exact cam's state at that cycle's time. The drive's set
    points follow it within what the drive cannot know: the master in whole counts (half a count
    x the steepest slope), the table's rounding (a count) and its observed master speed; they end
    at rest, and their second differences stay within the deceleration (plus the rounding's
    two counts per cycle^2)."""
    plan, drive = _drive_targets(_scene("drive", [CAM_OUT]))
    motion = plan.events.motions[0]
    scale = 100000.0  # counts/in
    table = compile_cam(_scene("drive", [])).table
    slope = np.max(np.abs(table.lookup(np.arange(table.master_counts), with_slope=True)[1])) / 65536.0
    assert np.max(np.abs(drive - plan.targets)) <= 2 + 0.5 * slope
    start = int(round(motion.start_s / 0.001)) - 1  # t_set = (k + 1 lead cycle) x 1 ms
    end = start + int(np.ceil(motion.duration_s / 0.001)) + 1
    assert np.all(drive[end:] == drive[end]) and drive[end] != drive[start]
    second = np.diff(drive[start:end + 1], 2) / 0.001**2
    assert np.max(np.abs(second)) <= 200.0 * scale + 2 / 0.001**2
    assert not np.array_equal(plan.targets, _controller_targets([]).targets)


def test_the_cam_out_command_needs_a_table_and_shows_in_the_status():
    from canopen.sdo import SdoAbortedError

    from hil_sim.drive.cam_slot import CAM_COMMAND_CAM_OUT, CAM_STATUS_CAM_OUT

    empty = CamSlot({CAM_STATUS: 0, CAM_MODE: 0, CAM_SWITCH_MODE: 0})
    with pytest.raises(SdoAbortedError):
        empty.write_command(CAM_COMMAND_CAM_OUT)
    from hil_sim.drive.objects import PROFILE_ACCELERATION, PROFILE_DECELERATION, PROFILE_JERK

    seed, _ = _tables()
    slot = _slot(seed, {PROFILE_ACCELERATION: 20_000_000, PROFILE_DECELERATION: 20_000_000,
                        PROFILE_JERK: 2_000_000_000})  # the changeover's stop in counts
    for master in (12_000, 12_037):  # mid-rise, 37 counts a cycle
        slot.values[MASTER_POSITION] = master
        slot.target(0.001)
    slot.write_command(CAM_COMMAND_CAM_OUT)
    assert slot.values[CAM_STATUS] & CAM_STATUS_CAM_OUT
    stopped = []
    for master in range(12_074, 12_074 + 37 * 100, 37):  # 0.1 s: the stop takes about 0.05 s
        slot.values[MASTER_POSITION] = master
        stopped.append(slot.target(0.001)[0])
    assert stopped[-1] == stopped[-2] != stopped[0] and stopped[-1] != int(seed.lookup(master))  # at rest, off the cam
    slot.verify_download(seed.to_bytes())
    with pytest.raises(SdoAbortedError):  # off the cam, nothing to queue a switch on
        slot.write_command(CAM_COMMAND_ACTIVATE_AT_PERIOD_END)
    slot.values[CAM_SWITCH_MODE] = 3
    slot.write_command(CAM_COMMAND_ACTIVATE)  # a new engagement ends it, from where it stopped
    assert not slot.values[CAM_STATUS] & CAM_STATUS_CAM_OUT and slot.out is None
    slot.values[MASTER_POSITION] = master
    assert slot.target(0.001)[0] == stopped[-1] + int(seed.lookup(0))


def test_a_cam_out_limit_past_unsigned32_counts_is_refused():
    scene = _scene("drive", [dict(CAM_OUT, max_jerk=1e5)])  # 1e10 counts/s^3
    with pytest.raises(InputError, match=r"event\[0\]\.max_jerk: 100000 should be within 1e-05\.\.42949\.7 slave "
                       r"units/s\^3 with cam_mode 'drive' \(0x60A4 is UNSIGNED32"):
        plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES)


# ------------------------------------------------------------------------------ bus budget
def _bus_run(at_position: float, cycles: int = 1020):
    from hil_sim.rig import run_scene

    data = tomllib.loads((SCENES_DIR / "stiff_coupling.toml").read_text())
    data.update(cam_mode="drive", event=[dict(TO_TRANSITION, at_position=at_position)], duration={"cycles": cycles})
    return run_scene(parse_scene(data, base=SCENES_DIR, source="bus.toml").with_fidelity("ideal"))


def _sdo_bytes(command) -> int:
    """A command's data: the blob, a 64-bit object (0x2001:06/07), or at most 4 bytes."""
    if isinstance(command.value, bytes):
        return len(command.value)
    return 8 if (command.index, command.subindex) in ((0x2001, 6), (0x2001, 7)) else 4


def test_a_switch_s_sdo_frames_go_in_the_cycles_spare_bits_before_it_activates():
    """The change-over's transition switched in at the seed's period end (cycle 999), requested
    at 100 deg: its
    SDO download and writes are the frames CiA 301's segmented download counts (initiate, then
    a request and a response per 7 bytes; expedited writes a request and a response), they go
    at the lowest priority into the bits the cyclic frames leave, over many cycles, all before
    the activation, and the cyclic load the limit judges is what it is without them."""
    from hil_sim.bus_sizing import sdo_download_frames
    from hil_sim.bus import frame_bits

    report = _bus_run(100.0)
    transfer, = report.summary["bus"]["event_sdo"]["transfers"]
    commands = [c for c in _drive_commands_of(100.0)]
    frames = sum(sdo_download_frames(_sdo_bytes(c)) for c in commands)
    assert transfer["frames"] == frames and transfer["bits"] == frames * frame_bits(8)
    spare = report.summary["bus"]["budget_bits"] - report.summary["bus"]["peak_bits"]
    assert transfer["sent_cycle"] - transfer["queued_cycle"] + 1 >= transfer["bits"] / spare
    bus_load = report.check("bus_load")
    assert bus_load.passed and "before its activation in cycle 999" in bus_load.detail
    assert bus_load.value == report.summary["bus"]["peak_percent"] < 50.0


def test_a_switch_whose_sdo_frames_cannot_arrive_before_it_activates_fails_the_bus_load():
    """The same switch requested at 355 deg, 12 cycles before the period end: its 28 080 bits
    would need 2 340 bits a cycle there on top of the cyclic 455, past the 1000 bits of a 1 ms
    cycle at 1 Mbit/s (they are not all sent by the end of the run): the bus_load check fails
    with the load it would need and names the switch."""
    report = _bus_run(355.0)
    bus_load = report.check("bus_load")
    transfer, = report.summary["bus"]["event_sdo"]["transfers"]
    act = 999
    expected = 100.0 * (report.summary["bus"]["peak_bits"]
                        + -(-transfer["bits"] // (act - transfer["queued_cycle"]))) / 1000
    assert not bus_load.passed and bus_load.value == pytest.approx(expected)
    assert "past its activation in cycle 999" in bus_load.detail


def _drive_commands_of(at_position: float) -> list:
    scene = _scene("drive", [dict(TO_TRANSITION, at_position=at_position)])
    return list(plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES).events.drive_commands)


def test_sdo_download_frames_follow_cia_301():
    from hil_sim.bus_sizing import sdo_download_frames

    assert [sdo_download_frames(n) for n in (1, 4, 5, 7, 8, 14, 15)] == [2, 2, 4, 4, 6, 6, 8]
    # block: initiate, 7 bytes a frame, an acknowledgement per 127 segments, end
    assert sdo_download_frames(7 * 127, block=True) == 2 + 127 + 1 + 2
    assert sdo_download_frames(7 * 128, block=True) == 2 + 128 + 2 + 2


# ----------------------------------------------------------------- a later request supersedes
QUEUED_B = dict(SWITCH_B, activation="period_end")  # requested at 100 deg, due at 360 deg


@pytest.mark.parametrize("mode", ["controller", "drive"])
def test_a_cam_out_before_a_queued_switch_activates_supersedes_it(mode):
    """A switch queued for the period end (360 deg) and a cam-out at 120 deg: the drive's cam-out
    clears the queued switch (0x2001:01 = 5), so the switch never happens on either path; it is
    reported superseded, not as a switch at 360 deg with the jump it never made."""
    scene = _scene(mode, [QUEUED_B, CAM_OUT])
    plan = plan_run(scene, compile_cam(scene), np.zeros(CYCLES), CYCLES)
    switch, = plan.events.switches
    assert switch.active_s is None and switch.superseded_by == "event[1]" and not switch.jumps
    assert switch.to_dict()["superseded_by"] == "event[1]"
    assert [m.event.action for m in plan.events.motions] == ["cam_out"]


def test_an_immediate_offset_supersedes_a_queued_switch_on_both_paths_alike():
    """A switch to product B queued for the period end (360 deg), then at 200 deg an immediate
    offset: the drive's pending slot takes the offset's table (a new download replaces B) and
    activates it at once, so B never comes; the controller-side plan does the same, and the
    drive's set points are its targets bit for bit (before, the plan kept B's piece after the
    offset's and looked its pieces up out of order). The drive takes an immediate activation
    with the SDO write after the request's SYNC: its set points follow a few cycles later there."""
    offset = {"action": "offset", "at_position": 200.0, "activation": "immediate", "slave_offset": 0.05,
              "allow_jump": True}
    _, drive = _drive_targets(_scene("drive", [QUEUED_B, offset]))
    controller = _controller_targets([QUEUED_B, offset])
    offset_cycle = int(controller.events.switches[1].active_s / 0.001)
    assert controller.events.switches[0].active_s is None  # B never comes
    assert [s.superseded_by for s in controller.events.switches] == ["event[1]", ""]
    assert np.array_equal(drive[:offset_cycle], controller.targets[:offset_cycle])
    assert np.array_equal(drive[offset_cycle + 3:], controller.targets[offset_cycle + 3:])


def test_a_superseded_queued_switch_s_sdo_frames_are_counted_and_never_activate():
    """Over the bus: the transition queued at 100 deg, a cam-out at 200 deg. CiA 301 by hand: the
    blob of L bytes segmented (initiate request and response, then ceil(L / 7) segments, each
    answered), 0x2001:07 (INTEGER64) segmented in two segments (6 frames), 0x2001:05, :08, :09..0C
    and :01 expedited (2 frames each); the cam-out's 0x6083, 0x6084, 0x60A4:01 and 0x2001:01 (8).
    The detail says the switch never activated, not that it acted."""
    from hil_sim.rig import run_scene

    events = [dict(TO_TRANSITION, at_position=100.0), dict(CAM_OUT, at_position=200.0)]
    data = tomllib.loads((SCENES_DIR / "stiff_coupling.toml").read_text())
    data.update(cam_mode="drive", event=events, duration={"cycles": 1010})  # past 360 deg
    report = run_scene(parse_scene(data, base=SCENES_DIR, source="bus.toml").with_fidelity("ideal"))
    blob, = [c.value for c in _drive_commands_of(100.0) if isinstance(c.value, bytes)]
    frames = 2 + 2 * -(-len(blob) // 7) + 6 + 2 * (1 + 1 + 4 + 1)
    detail = report.check("bus_load").detail
    assert f"event[0] {frames} SDO frames" in detail and "event[1] 8 SDO frames" in detail
    assert "event[0]" in detail and "never activated" in detail
    assert report.check("switch_jumps").passed
