"""Events while the machine runs (hil_sim.events) and tappets on the rig (hil_sim.tappet_edges):
switches with the jumps they make, phase shifts, cam-out, and the tappet edges; checked on the
plan (no drive runs: cheap) against the cams' own definitions, ecam.cam_join and ruckig's limits."""

from __future__ import annotations

import copy
import tomllib
from dataclasses import replace

import numpy as np
import pytest

from ecam.cam_join import join_cams
from ecam.camfile import load_cam
from ecam.errors import CamFileError, InputError
from hil_sim import SCENES_DIR
from hil_sim.rig.cam import compile_cam
from hil_sim.rig.plan import count_cycles, plan_run
from hil_sim.rig.event_checks import event_checks
from hil_sim.scene import load_scene, parse_scene

CAMS = SCENES_DIR / "cams"
SPEED = 360.0  # deg/s: the change-over scenes' 60 rpm


def _plan(scene):
    cam = compile_cam(scene)
    cycles = count_cycles(scene, cam.profile.master_period, scene.master.units_per_second(360.0))
    return plan_run(scene, cam, np.zeros(cycles), cycles)


def _scene(name="changeover", **top):
    data = tomllib.loads((SCENES_DIR / f"{name}.toml").read_text())
    data.update(top)
    return parse_scene(data, base=SCENES_DIR, source=f"{name}.toml")


@pytest.fixture(scope="module")
def changeover():
    scene = load_scene(SCENES_DIR / "changeover.toml")
    return scene, _plan(scene)


def test_a_switch_that_changes_nothing_changes_no_bit():
    """The running cam switched to itself at its period end, absolute, unscaled: the same set
    points, velocity offsets and reference, bit for bit, and no jump reported."""
    plain = _scene("stiff_coupling")
    same = _scene("stiff_coupling", event=[{"action": "offset", "at_position": 100.0}])
    a, b = _plan(plain), _plan(same)
    assert b.events.switches[0].active_s == pytest.approx(1.0)  # the period end at 360 deg
    for name in ("targets", "velocities", "reference_units"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert b.events.switches[0].jumps == () and a.events is None


def test_the_changeover_switches_are_continuous_as_cam_join_says(changeover):
    scene, plan = changeover
    first, second = plan.events.switches
    assert (first.active_s, first.master) == (pytest.approx(1.0), pytest.approx(360.0))
    # the transition ends 90 deg later: product B from there, master relative
    assert (second.active_s, second.master) == (pytest.approx(1.25), pytest.approx(450.0))
    assert first.jumps == () and second.jumps == ()
    seed = load_cam(scene.cam.file)
    transition, product_b = load_cam(CAMS / "a_to_b.toml"), load_cam(CAMS / "product_b.toml")
    for switch, (a, b) in ((first, (seed, transition)), (second, (transition, product_b))):
        join = join_cams(a, b, master="relative", slave="absolute")
        assert not join.report.errors and not join.report.warnings
        assert switch.left == pytest.approx(join.left, abs=1e-12)
        assert switch.right == pytest.approx(join.right, abs=1e-12)
    # the set points never step more than the cams move in a cycle: no jump reached the drive
    assert np.max(np.abs(np.diff(plan.targets))) < 0.02 * 100000
    checks = {c.name: c for c in event_checks(replace_run(scene, plan))[0]}
    assert checks["switch_jumps"].passed and checks["switch_jumps"].value == 0


def replace_run(scene, plan):
    """What event_checks reads of a run: its scene, plan and cam."""
    class Run:
        pass
    run = Run()
    run.scene, run.plan, run.cam = scene, plan, compile_cam(scene)
    return run


def test_an_immediate_switch_mid_period_is_named_with_its_jump():
    """At 180 deg the seed cam stands at its full stroke, 1.75 in, at rest; product B at its
    dwell 0.25 in plus its stroke 1.25 in, at rest: the position jumps by -0.25 in, the velocity
    does not, and the check fails naming it."""
    scene = load_scene(SCENES_DIR / "changeover_immediate.toml")
    plan = _plan(scene)
    (switch,) = plan.events.switches
    assert switch.master == pytest.approx(180.0) and switch.active_s == pytest.approx(0.5)
    jumps = dict(switch.jumps)
    assert jumps[0] == pytest.approx(1.5 - 1.75, abs=1e-9)
    assert 1 not in jumps and 2 in jumps and switch.failed
    check = {c.name: c for c in event_checks(replace_run(scene, plan))[0]}["switch_jumps"]
    assert not check.passed and check.value == 1
    assert "to_product_b switch to product_b (immediate) at 0.5 s, master 180 deg: position -0.25 in" in check.detail
    allowed = _scene("changeover_immediate")
    allowed = replace(allowed, events=(replace(allowed.events[0], allow_jump=True),))
    check = {c.name: c for c in event_checks(replace_run(allowed, _plan(allowed)))[0]}["switch_jumps"]
    assert check.passed and "(allowed)" in check.detail


def test_the_phase_shift_and_the_cam_out_hold_their_limits(changeover):
    scene, plan = changeover
    phase, out = plan.events.motions
    assert phase.covered == pytest.approx(3.0, abs=1e-7)
    for motion in (phase, out):
        for peak, limit in zip(motion.peaks, motion.limits):
            assert peak <= limit * (1 + 1e-8)
    # after the shift the reference is product B at the master plus 3 deg (relative from 450)
    product_b = load_cam(CAMS / "product_b.toml")
    k = int(round(2.3 / plan.cycle_s)) - 1  # t = 2.3 s: the shift done, the cam-out to come
    master = plan.master_units[k]
    assert plan.reference_units[k] == pytest.approx(float(product_b(master - 450.0 + 3.0)), abs=1e-12)
    # the cam-out ends at rest: the last set points stand still
    assert np.all(plan.targets[-100:] == plan.targets[-1]) and np.all(plan.velocities[-100:] == 0.0)
    assert plan.events.phase[-1] == pytest.approx(3.0)


def test_the_tappet_edges_come_within_a_cycle_with_the_compensation(changeover):
    """At 360 deg/s the controller's 1 ms cycle is 0.36 deg: a compensated edge is found within
    one cycle's travel of its place; without the compensation the valve's 20 ms dead time puts
    it 7.2 deg late (plus that cycle)."""
    _, plan = changeover
    (glue,) = plan.tappets
    assert glue.edges == 6  # on and off in each of three periods
    assert glue.worst <= SPEED * 0.001
    assert SPEED * 0.02 <= glue.worst_uncompensated <= SPEED * 0.021
    for row in glue.rows:
        assert row["programmed"] in (200.0, 280.0)


@pytest.mark.parametrize("event, message", [
    ({"action": "switch", "cam": "x.toml"}, "should give exactly one of at_period, at_position, at_s"),
    ({"action": "phase", "at_s": 1.0, "shift": 1.0, "max_velocity": 1.0, "max_acceleration": 1.0},
     "event[0].max_jerk: missing"),
    ({"action": "cam_out", "at_s": 1.0, "shift": 1.0}, "event[0].shift: does not apply to action 'cam_out'"),
    ({"action": "switch", "at_s": 1.0, "cam": "nowhere.toml"}, "event[0].cam: 'nowhere.toml' does not exist"),
    ({"action": "offset", "at_s": 1.0, "activation": "master_position"},
     "event[0].activation_position: missing"),
    ({"action": "jump", "at_s": 1.0}, "event[0].action: 'jump' should be one of switch, offset, phase, cam_out"),
])
def test_bad_events_are_refused_naming_the_field(event, message):
    data = tomllib.loads((SCENES_DIR / "stiff_coupling.toml").read_text())
    data["event"] = [copy.deepcopy(event)]
    with pytest.raises(CamFileError) as caught:
        parse_scene(data, base=SCENES_DIR, source="s.toml")
    assert message in str(caught.value)


def test_events_after_a_cam_out_are_refused():
    late = _scene("changeover")
    late = replace(late, events=late.events + (replace(late.events[0], index=9, at_position=1000.0),))
    with pytest.raises(InputError, match="should come before the cam_out"):
        _plan(late)


# ------------------------------------------------------------------------ drive-side

def test_the_cam_slot_takes_a_queued_table_at_the_period_end():
    """0x2001:01 = 3 arms the pending table for the running table's period end; with 0x2001:05
    master and slave relative it starts there at its master 0, offset by where the running table
    ends (PLCopen MasterAbsolute = SlaveAbsolute = FALSE)."""
    from hil_sim.drive.cam_slot import (CAM_COMMAND_ACTIVATE, CAM_COMMAND_ACTIVATE_AT_PERIOD_END,
                                        CAM_STATUS_QUEUED, CamSlot)
    from hil_sim.drive.objects import CAM_MODE, CAM_STATUS, CAM_SWITCH_MODE, MASTER_POSITION

    seed = compile_cam(load_scene(SCENES_DIR / "stiff_coupling.toml"))
    b = compile_cam(replace(load_scene(SCENES_DIR / "stiff_coupling.toml"),
                            cam=replace(load_scene(SCENES_DIR / "stiff_coupling.toml").cam,
                                        file=CAMS / "product_b.toml")))
    period = seed.table.master_counts
    values = {CAM_STATUS: 0, CAM_MODE: 1, CAM_SWITCH_MODE: 3, MASTER_POSITION: 0}
    slot = CamSlot(values)
    slot.verify_download(seed.table.to_bytes())
    slot.write_command(CAM_COMMAND_ACTIVATE)
    slot.verify_download(b.table.to_bytes())
    targets = []
    for k, master in enumerate(range(period - 3 * 128, period + 3 * 128, 128)):
        values[MASTER_POSITION] = master
        targets.append(slot.target(0.001)[0])
        if k == 0:
            slot.write_command(CAM_COMMAND_ACTIVATE_AT_PERIOD_END)
            assert values[CAM_STATUS] & CAM_STATUS_QUEUED
    assert targets[:3] == [int(seed.table.lookup(m)) for m in range(period - 384, period, 128)]
    end = int(seed.table.lookup(period))  # the seed's position at its period end
    assert targets[3:] == [end + int(b.table.lookup(m)) for m in (0, 128, 256)]
    assert not values[CAM_STATUS] & CAM_STATUS_QUEUED and slot.pending_table is None


def test_drive_side_switches_run_the_same_on_the_bus_and_bus_free():
    """The changeover's switches and phase shift drive-side, at three times the speed (half a
    second): the drive's cam slot switches at the period ends (the load follows: the tracking
    error stays in its limit) and the bus-free path gives the same physics bit for bit; the bus
    budget names the switch whose table cannot arrive in time at this speed."""
    from hil_sim.rig import run_scene

    data = tomllib.loads((SCENES_DIR / "changeover.toml").read_text())
    data["cam_mode"] = "drive"
    data["master"]["speed_rpm"] = 180.0
    data["duration"] = {"cycles": 520}
    data["event"] = [dict(e) for e in data["event"] if e["action"] != "cam_out"]
    del data["tappet"]  # a cycle is 1.08 deg at this speed: more than the glue's tolerance
    for event, at in zip(data["event"], (100.0, 370.0, 455.0)):
        event["at_position"] = at
    scene = parse_scene(data, base=SCENES_DIR, source="drive.toml").with_fidelity("ideal")
    over_bus, bus_free = run_scene(scene), run_scene(scene, path="fast")
    # every check passes but the bus's: product B's table (702 SDO frames, 94 770 bits) needs
    # about 174 cycles of the bits the cyclic frames leave at 1 Mbit/s, and the transition it
    # is requested in lasts 83 cycles at this speed: on a real bus the switch would come late
    # (hil_sim/rig/event_bus.py); the lock-step drive has the table at once
    assert [c.name for c in over_bus.checks if not c.passed] == ["bus_load"], over_bus.to_text()
    assert "event[1] 702 SDO frames" in over_bus.check("bus_load").detail
    assert "past its activation" in over_bus.check("bus_load").detail
    for name in ("following_error", "tracking_error", "coupling_torque"):
        assert np.array_equal(over_bus.series[name], bus_free.series[name], equal_nan=True), name
    switches = over_bus.summary["events"]["switches"]
    assert [s["master"] for s in switches] == [pytest.approx(360.0), pytest.approx(450.0)]


def test_the_figure_shows_the_events_and_names_the_jump():
    """The report's figure gets an events panel: the jumping switch in red in its title."""
    from hil_sim.rig import run_scene
    from hil_sim.rig.plot import report_figure

    report = run_scene(load_scene(SCENES_DIR / "changeover_immediate.toml").with_fidelity("ideal"),
                       path="fast")
    assert not report.passed and not report.check("switch_jumps").passed
    titles = [ax.get_title(loc="left") for ax in report_figure(report).axes]
    assert "events: a switch jumps" in titles


def test_a_scene_tappet_outside_the_period_is_named():
    data = tomllib.loads((SCENES_DIR / "stiff_coupling.toml").read_text())
    data["tappet"] = [{"on": 10.0, "off": 400.0}]
    scene = parse_scene(data, base=SCENES_DIR, source="s.toml")
    with pytest.raises(InputError, match=r"tappet\[0\]\.off: 400 should be within the master period 0..360"):
        _plan(scene)


def test_each_axis_of_a_machine_takes_its_events():
    from hil_sim.machine import parse_machine

    scene = tomllib.loads((SCENES_DIR / "changeover_immediate.toml").read_text())
    axis = {key: scene[key] for key in ("cam", "drive", "mechanics", "limits", "event")}
    axis.update(name="b", node_id=2)
    axis["drive"] = {k: v for k, v in axis["drive"].items() if k != "node_id"}
    data = {"master": scene["master"], "duration": scene["duration"],
            "axis": [dict(axis, name="a", node_id=1, event=[]), axis]}
    machine = parse_machine(data, base=SCENES_DIR, source="m.toml")
    assert [len(a.events) for a in machine.axes] == [0, 1]
    assert machine.axes[1].events[0].name == "to_product_b"


def test_offsets_and_scaling_move_the_cam_as_mc_camin_places_it():
    """An offset event, immediate, in the middle of the seed's rise at 120 deg: SlaveScaling 2
    doubles the cam there (the position jumps by A(120), the velocity by A'(120)); SlaveOffset
    0.1 in adds to the position only; MasterOffset 360 (a whole period) changes nothing."""
    seed = load_cam(SCENES_DIR / "../../firmware_tables/cams/combination_drrd.toml")
    base = {"action": "offset", "at_position": 120.0, "activation": "immediate",
            "allow_jump": True}
    cases = ({"slave_scaling": 2.0}, {"slave_offset": 0.1}, {"master_offset": 360.0})
    plans = [_plan(_scene("stiff_coupling", event=[dict(base, **case)])) for case in cases]
    scaled, shifted, whole = (p.events.switches[0] for p in plans)
    a = [float(seed(120.0, order)) for order in range(3)]
    assert dict(scaled.jumps)[0] == pytest.approx(a[0], rel=1e-9)
    assert dict(scaled.jumps)[1] == pytest.approx(a[1], rel=1e-9)
    assert dict(scaled.jumps)[2] == pytest.approx(a[2], rel=1e-9)
    assert dict(shifted.jumps) == {0: pytest.approx(0.1, rel=1e-9)}
    assert whole.jumps == ()
