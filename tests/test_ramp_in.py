"""A switch's start mode ramp_in (hil_sim.ramp_in): the slave brought onto the new cam by a
jerk-limited correction instead of a jump. Checked on the plan (no drive runs: cheap) against the
cams' own definitions and the event's limits, and once on the bus-free rig for the shipped scene."""

from __future__ import annotations

import tomllib
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ecam.camfile import load_cam
from ecam.errors import CamFileError, InputError
from hil_sim import SCENES_DIR
from hil_sim.event_spec import Event
from hil_sim.ramp_in import plan_ramp_in
from hil_sim.rig.cam import compile_cam
from hil_sim.rig.event_checks import event_checks
from hil_sim.rig.plan import count_cycles, plan_run
from hil_sim.scene import DurationSpec, load_scene, parse_scene

CAMS = SCENES_DIR / "cams"
SEED = SCENES_DIR / "../../firmware_tables/cams/combination_drrd.toml"
LIMITS = (5.0, 200.0, 20000.0)  # the shipped scene's: in/s, in/s^2, in/s^3


def _plan(scene):
    cam = compile_cam(scene)
    cycles = count_cycles(scene, cam.profile.master_period, scene.master.units_per_second(360.0))
    return plan_run(scene, cam, np.zeros(cycles), cycles)


def _scene(name, **top):
    data = tomllib.loads((SCENES_DIR / f"{name}.toml").read_text())
    data.update(top)
    return parse_scene(data, base=SCENES_DIR, source=f"{name}.toml")


def _checks(scene, plan):
    class Run:
        pass
    run = Run()
    run.scene, run.plan, run.cam = scene, plan, compile_cam(scene)
    checks, summary, _ = event_checks(run)
    return {c.name: c for c in checks}, summary


@pytest.fixture(scope="module")
def ramped():
    scene = load_scene(SCENES_DIR / "changeover_ramp_in.toml")
    return scene, _plan(scene)


def test_the_immediate_switch_ramps_in_where_the_absolute_one_jumps(ramped):
    """changeover_immediate's switch (the seed at 1.75 in, product B at 1.5 in at 180 deg) fails
    with the jump named; with start_mode ramp_in the same switch reports no jump, the ramp's
    duration and its peak correction, and passes."""
    absolute = load_scene(SCENES_DIR / "changeover_immediate.toml")
    checks, _ = _checks(absolute, _plan(absolute))
    assert not checks["switch_jumps"].passed and "position -0.25 in" in checks["switch_jumps"].detail
    scene, plan = ramped
    (switch,) = plan.events.switches
    seed, product_b = load_cam(SEED), load_cam(CAMS / "product_b.toml")
    jump = float(product_b(180.0)) - float(seed(180.0))
    assert jump == pytest.approx(-0.25, abs=1e-12)
    assert switch.jumps == () and not switch.failed
    ramp = switch.ramp
    assert dict(ramp.compensated)[0] == pytest.approx(jump, abs=1e-12)
    # the correction starts at the slave's state minus the cam's, per second at 360 deg/s
    acceleration = (float(seed(180.0, 2)) - float(product_b(180.0, 2))) * 360.0**2
    assert ramp.start == pytest.approx((-jump, 0.0, acceleration), abs=1e-9)
    assert ramp.peak == pytest.approx(0.25, abs=1e-8)
    checks, summary = _checks(scene, plan)
    assert checks["switch_jumps"].passed and checks["switch_jumps"].value == 0
    assert (f"no jump, ramp_in over {ramp.duration_s:.4g} s, peak correction 0.25 in (compensates "
            "position -0.25 in") in checks["switch_jumps"].detail
    assert checks["event_motion"].passed  # the correction within its limits
    entry = summary["events"]["switches"][0]
    assert entry["start_mode"] == "ramp_in"
    assert entry["ramp_in"]["duration_s"] == ramp.duration_s and entry["ramp_in"]["peak_correction"] == ramp.peak


def test_the_slave_joins_the_new_cam_without_a_step_and_stays_on_it(ramped):
    """Set points: no step bigger than the cams move in a cycle; after the ramp the reference is
    product B itself at the master (absolute), exactly."""
    scene, plan = ramped
    ramp = plan.events.switches[0].ramp
    assert np.max(np.abs(np.diff(plan.targets))) < 0.01 * 100000  # the absolute one steps 0.25 in
    product_b = load_cam(CAMS / "product_b.toml")
    time_end = (np.arange(plan.cycles) + 1) * plan.cycle_s
    after = time_end >= ramp.end_s
    assert after.any()
    np.testing.assert_allclose(plan.reference_units[after], product_b(plan.master_units[after]), atol=1e-12)


def test_the_correction_holds_its_limits_sampled_on_the_plan(ramped):
    """The correction is the reference minus the new cam. Its central difference over a cycle is
    the mean of its velocity over two cycles, its second difference a weighted mean of its
    acceleration: neither can exceed the event's limits (ruckig's 1e-8 contract aside)."""
    scene, plan = ramped
    product_b = load_cam(CAMS / "product_b.toml")
    dt = plan.cycle_s
    seed = load_cam(SEED)
    reference = np.asarray(plan.reference_units, dtype=float)
    correction = reference - np.asarray(product_b(plan.master_units), dtype=float)
    ramp = plan.events.switches[0].ramp
    time_end = (np.arange(plan.cycles) + 1) * dt
    before = time_end < ramp.start_s
    # before the switch the slave runs the seed: the difference to product B there is not a correction
    correction[before] = np.asarray(seed(plan.master_units[before])) - np.asarray(product_b(plan.master_units[before]))
    inside = np.flatnonzero((time_end >= ramp.start_s) & (time_end < ramp.end_s + 3 * dt))
    window = correction[inside[0] - 1:inside[-1] + 2]
    velocity = (window[2:] - window[:-2]) / (2 * dt)
    acceleration = (window[2:] - 2 * window[1:-1] + window[:-2]) / dt**2
    assert np.max(np.abs(velocity[1:])) <= LIMITS[0] * (1 + 1e-7)
    assert np.max(np.abs(acceleration[1:])) <= LIMITS[1] * (1 + 1e-7)
    assert np.max(np.abs(velocity)) > 0.9 * LIMITS[0]  # a 0.25 in correction reaches its limit
    assert correction[inside[-1]] == 0.0 and np.all(correction[time_end >= ramp.end_s] == 0.0)


@settings(max_examples=40, deadline=None)
@given(position=st.floats(-2.0, 2.0), velocity=st.floats(-4.0, 4.0), acceleration=st.floats(-150.0, 150.0),
       limits=st.tuples(st.floats(4.5, 50.0), st.floats(160.0, 2000.0), st.floats(1e3, 1e5)))
def test_any_jump_within_the_limits_is_corrected_within_them(position, velocity, acceleration, limits):
    """The correction starts at the jump (position, velocity, acceleration), ends at rest at 0,
    and on a fine grid its velocity and acceleration stay within the limits, for every start the
    limits can hold (the acceleration brought to 0 at max_jerk adds a^2 / 2j to the velocity)."""
    assume(abs(velocity) + acceleration**2 / (2 * limits[2]) <= limits[0])
    event = Event(0, "switch", at_s=0.0, start_mode="ramp_in", max_velocity=limits[0],
                  max_acceleration=limits[1], max_jerk=limits[2])
    # per master unit at 1 master unit/s and no master acceleration: the states are per second
    ramp = plan_ramp_in(event, 0.25, (position, velocity, acceleration, 0.0), (0.0, 0.0, 0.0, 0.0),
                        ((0, -position),), 1.0, 0.0)
    assert ramp.state(0.25) == pytest.approx((position, velocity, acceleration), abs=1e-9)
    assert ramp.state(ramp.end_s) == (0.0, 0.0, 0.0) and ramp.state(0.2) == (0.0, 0.0, 0.0)
    times = 0.25 + np.linspace(0.0, ramp.duration_s, 2001)
    states = ramp.sample(times[:-1])
    assert np.max(np.abs(states[:, 1])) <= limits[0] * (1 + 1e-8)
    assert np.max(np.abs(states[:, 2])) <= limits[1] * (1 + 1e-8)
    # ruckig ends within 1e-8 of the start's size (its contract, in the units it solved in)
    end = ramp.profile.state(ramp.duration_s)
    # the start's size: the distance the jerk limit covers in the time it needs to undo it
    tau = max(abs(acceleration) / limits[2], (abs(velocity) / limits[2]) ** 0.5,
              (abs(position) / limits[2]) ** (1 / 3))
    size = limits[2] * tau**3
    assert abs(end[0]) <= 1e-7 * size


def test_a_jump_the_limits_cannot_hold_fails_event_motion():
    """At 180 deg the accelerations differ by 17.94 in/s^2: at 20000 in/s^3 the correction's
    velocity passes 17.94^2 / 40000 = 0.008 in/s before its acceleration is back at 0. With
    max_velocity 0.005 in/s ruckig brakes from outside the limit and event_motion fails, naming it."""
    data = tomllib.loads((SCENES_DIR / "changeover_ramp_in.toml").read_text())
    data["event"][0]["max_velocity"] = 0.005
    scene = parse_scene(data, base=SCENES_DIR, source="s.toml")
    plan = _plan(scene)
    (motion,) = plan.events.motions
    assert motion.peaks[0] > 0.005 and motion.ratio > 1.0
    checks, _ = _checks(scene, plan)
    assert checks["switch_jumps"].passed and not checks["event_motion"].passed
    assert "event[0] to_product_b switch at 0.5 s" in checks["event_motion"].detail


def test_a_cam_out_during_the_ramp_leaves_from_the_corrected_slave(ramped):
    """A cam-out 10 deg into the ramp starts where the slave is (cam plus correction): the set
    points stay continuous."""
    scene, _ = ramped
    data = tomllib.loads((SCENES_DIR / "changeover_ramp_in.toml").read_text())
    data["event"].append({"name": "stop", "action": "cam_out", "at_position": 190.0,
                          "max_velocity": 10.0, "max_acceleration": 400.0, "max_jerk": 40000.0})
    plan = _plan(parse_scene(data, base=SCENES_DIR, source="s.toml"))
    ramp = plan.events.switches[0].ramp
    out = plan.events.motions[-1]
    assert ramp.start_s < out.start_s < ramp.end_s
    assert np.max(np.abs(np.diff(plan.targets))) < 0.01 * 100000


def test_a_switch_during_the_ramp_starts_from_the_corrected_slave(ramped):
    """An offset that changes nothing, immediate at 190 deg (10 deg into the ramp), takes the slave
    from where it is, the cam plus the correction, back onto product B: without ramp_in it jumps
    by minus the correction there (per master unit at 360 deg/s); with ramp_in it starts a new
    correction from that state and the set points never step."""
    data = tomllib.loads((SCENES_DIR / "changeover_ramp_in.toml").read_text())
    data["event"].append({"name": "again", "action": "offset", "at_position": 190.0, "activation": "immediate",
                          "allow_jump": True})
    plan = _plan(parse_scene(data, base=SCENES_DIR, source="s.toml"))
    first, second = plan.events.switches
    assert first.ramp.start_s < second.active_s < first.ramp.end_s and second.ramp is None
    p, v, a = first.ramp.state(second.active_s)
    assert dict(second.jumps) == pytest.approx({0: -p, 1: -v / 360.0, 2: -a / 360.0**2}, rel=1e-9)
    data["event"][-1].update(start_mode="ramp_in", max_velocity=5.0, max_acceleration=200.0, max_jerk=20000.0)
    plan = _plan(parse_scene(data, base=SCENES_DIR, source="s.toml"))
    second = plan.events.switches[1]
    assert second.jumps == () and second.ramp.start == pytest.approx((p, v, a), rel=1e-9)
    assert np.max(np.abs(np.diff(plan.targets))) < 0.01 * 100000


def test_ramp_in_fields_are_checked_and_drive_side_refused():
    data = tomllib.loads((SCENES_DIR / "changeover_ramp_in.toml").read_text())
    del data["event"][0]["max_jerk"]
    with pytest.raises(CamFileError, match=r"event\[0\]\.max_jerk: missing"):
        parse_scene(data, base=SCENES_DIR, source="s.toml")
    data = tomllib.loads((SCENES_DIR / "changeover_immediate.toml").read_text())
    data["event"][0]["max_velocity"] = 1.0
    with pytest.raises(CamFileError, match=r"event\[0\]\.max_velocity: applies to start_mode 'ramp_in' only"):
        parse_scene(data, base=SCENES_DIR, source="s.toml")
    drive = replace(load_scene(SCENES_DIR / "changeover_ramp_in.toml"), cam_mode="drive",
                    duration=DurationSpec(cycles=10))
    with pytest.raises(InputError, match=r"^event\[0\] to_product_b\.start_mode: 'ramp_in' should be 'direct' "
                                         r"with cam_mode 'drive'"):
        _plan(drive)


def test_the_shipped_scene_passes_and_its_figure_shades_the_ramp():
    from hil_sim.rig import run_scene
    from hil_sim.rig.plot import report_figure

    report = run_scene(load_scene(SCENES_DIR / "changeover_ramp_in.toml").with_fidelity("ideal"), path="fast")
    assert report.passed, report.to_text()
    (panel,) = [ax for ax in report_figure(report).axes if ax.get_title(loc="left").startswith("events")]
    assert panel.get_title(loc="left") == "events: every switch continuous"
    labels = panel.get_legend_handles_labels()[1]
    assert "ramp_in, peak correction 0.25 in" in labels
