"""The drive-side cam slot's master speed: the velocity offset the drive computes from the master
positions it receives in whole counts."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ecam
from hil_sim.drive.cam_slot import CAM_COMMAND_ACTIVATE, CAM_MODE_DRIVE_SIDE, CamSlot
from hil_sim.drive.objects import CAM_MODE, CAM_STATUS, MASTER_POSITION
from hil_sim.int32 import wrap_int32


def slot_on_a_straight_cam():
    """A cam whose slope is 1 everywhere (the slave is the master), so the velocity offset is the
    drive's estimate of the master speed itself."""
    profile = ecam.CamProfile.from_segments([ecam.Segment.from_span(1.0, 1.0, "constant_velocity")],
                                            net_stroke=1.0)
    table = ecam.compile_table(profile, ecam.TableSpec(interp="linear", points=2, master_counts=65536,
                                                       slave_counts_per_unit=65536))
    slot = CamSlot({CAM_STATUS: 0, CAM_MODE: 0})
    slot.verify_download(table.to_bytes())
    slot.write_command(CAM_COMMAND_ACTIVATE)
    slot.write_mode(CAM_MODE_DRIVE_SIDE)
    return slot


def speeds(slot, positions, cycle_s):
    out = []
    for p in positions:
        slot.values[MASTER_POSITION] = wrap_int32(int(p))
        out.append(slot.target(cycle_s)[1])
    return np.array(out)


@pytest.mark.parametrize("cycle_s", [0.001, 0.00025])
def test_a_constant_master_speed_in_whole_counts_is_seen_without_the_counts_ripple(cycle_s):
    """131.072 counts per ms arrive as 131, 131, ..., 132: one cycle's increment is off the speed
    by most of a count per cycle (0.7 % at 1 kHz, 2.3 % at 4 kHz); the observer's speed stays within
    0.2 % at either rate, a quarter of the increment's error or less."""
    speed = 131072.0  # counts/s
    t = np.arange(4000) * cycle_s
    positions = np.floor(speed * t)
    got = speeds(slot_on_a_straight_cam(), positions, cycle_s)
    increment_error = np.max(np.abs(np.diff(positions) / cycle_s - speed))
    assert 0.5 / cycle_s < increment_error < 1.0 / cycle_s
    settled = np.max(np.abs(got[t > 0.5] - speed))
    assert settled < 2e-3 * speed and settled < 0.25 * increment_error


def test_a_ramping_master_is_followed_without_a_steady_speed_error():
    """A master accelerating at a constant rate, through the INTEGER32 roll-over of its position:
    after the observer has settled, its speed is the true speed within one cycle's change of speed
    and the counts' ripple (1.5 a T), where a mean over the last 4 ms would lag by a x 2 ms (2.7x
    that) and the observer's speed state alone by a x 2/omega (21x)."""
    cycle_s, acceleration = 0.001, 2.0e5  # counts/s^2
    t = np.arange(3000) * cycle_s
    start = 2**31 - 400_000
    positions = np.floor(start + 0.5 * acceleration * t**2)
    assert positions[-1] > 2**31  # rolls over on the wire
    got = speeds(slot_on_a_straight_cam(), positions, cycle_s)
    late = t > 1.0
    assert np.max(np.abs(got[late] - acceleration * t[late])) < 1.5 * acceleration * cycle_s


def test_the_observer_restarts_when_the_master_is_forgotten():
    slot = slot_on_a_straight_cam()
    speeds(slot, np.arange(100) * 50, 0.001)
    slot.forget_master()
    again = speeds(slot, [10**6, 10**6 + 80], 0.001)
    assert again[0] == 0.0 and again[1] == pytest.approx(80_000.0)
    assert math.isfinite(again[1])
