"""The voltage limit in the drive's torque clamp (issue 21, item 4): ecam.sizing.VoltageLimit
(the curve's constants computed once) against voltage_limited_torque, and the controller's clamp
(hil_sim.control, DriveEffects.voltage_limit) against a hand calculation of the top speed.

Oracle: the 1FT7044-AK7 of the Siemens 1FT7 configuration manual 01/2009, table 4-8, p. 90
(kT 0.88 N m/A, kE 57 V/1000 rpm, Rph 0.61 ohm, LD 4.2 mH, 2p = 6).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ecam import sizing
from ecam.errors import InputError
from ecam.mechanics import Mechanics
from hil_sim.control import DriveEffects, ServoAxis
from hil_sim.scene import load_scene
from hil_sim.rig.run import axis_setup, prepare

KT, RPH, LD, POLE_PAIRS = 0.88, 0.61, 4.2e-3, 3
KE = 57.0 / (1000.0 * 2.0 * math.pi / 60.0)  # V s/rad


def test_the_precomputed_curve_is_the_formula():
    limit = sizing.VoltageLimit(KT, KE, RPH, 600.0, LD, POLE_PAIRS)
    speeds = np.linspace(0.0, 1200.0, 97)  # past the no-load speed, 1094 rad/s on 600 V
    formula = sizing.voltage_limited_torque(speeds, torque_constant=KT, voltage_constant=KE,
                                            resistance=RPH, dc_bus_voltage=600.0,
                                            inductance=LD, pole_pairs=POLE_PAIRS)
    precomputed = np.array([limit.torque(w) for w in speeds])
    assert np.allclose(precomputed, formula, rtol=1e-12, atol=0.0)
    assert limit.torque(-500.0) == limit.torque(500.0)
    assert limit.torque(1200.0) == 0.0
    # a winding without resistance and inductance has no limit at standstill
    assert sizing.VoltageLimit(KT, KE, 0.0, 600.0).torque(0.0) == math.inf
    with pytest.raises(InputError, match="dc_bus_voltage"):
        sizing.VoltageLimit(KT, KE, RPH, 0.0)


def _spin(drive_effects: DriveEffects, damping: float, cycles: int = 150) -> ServoAxis:
    """The motor alone (a rigid axis, its rotor and nothing else worth counting), asked for far
    more speed than the voltage allows: the clamp holds it, the speed settles where it can."""
    mechanics = Mechanics(motor_inertia=5.43e-4, load_inertia=1e-9, motor_damping=damping,
                          motor_torque_limit=15.0)
    axis = ServoAxis(mechanics, cycle_s=1e-3, substeps=8, drive_effects=drive_effects)
    cpr = axis.counts_per_motor_rad
    for k in range(1, cycles + 1):
        axis.cycle(int(round(400.0 * k * 1e-3 * cpr)))  # 400 rad/s asked
    return axis


def test_the_clamp_settles_the_motor_at_the_hand_calculated_top_speed():
    # on 120 V without inductance the voltage allows T = kT (U - a w) / R, U = U_dc / sqrt 6,
    # a = kE / sqrt 3; the speed settles where that equals the damping's b w:
    # w = kT U / (R b + kT a)
    u_dc, b = 120.0, 0.01
    u, a = u_dc / math.sqrt(6.0), KE / math.sqrt(3.0)
    hand = KT * u / (RPH * b + KT * a)  # 152.5 rad/s, below the no-load 155.9 (U / a)
    voltage = sizing.VoltageLimit(KT, KE, RPH, u_dc)
    axis = _spin(DriveEffects(voltage_limit=voltage), b)
    state = axis.state
    assert state["saturated"] == 1.0
    assert state["motor_speed"] == pytest.approx(hand, rel=1e-6)
    assert state["motor_torque"] == pytest.approx(b * hand, rel=1e-4)
    # without the voltage limit the same command runs away to what the 15 N m clamp allows
    free = _spin(DriveEffects(), b)
    assert free.state["motor_speed"] > 1.5 * hand


def test_a_scene_without_its_own_clamp_gets_the_voltage_limit_and_one_with_it_does_not():
    scenes = "hil_sim/scenes/"
    knife = load_scene(scenes + "rotary_knife.toml")  # 1FT7044 on 600 V, no motor_torque_limit
    run, _ = prepare(knife)
    limit = axis_setup(run, set()).drive_effects.voltage_limit
    assert (limit.torque_constant, limit.resistance, limit.dc_bus_voltage, limit.inductance,
            limit.pole_pairs) == (KT, RPH, 600.0, LD, POLE_PAIRS)
    assert limit.voltage_constant == pytest.approx(KE, rel=1e-9)
    stiff = load_scene(scenes + "stiff_coupling.toml")  # gives motor_torque_limit = 6.0
    assert stiff.sizing.scene_clamp and stiff.sizing.voltage_limit() is None


def test_the_knee_where_the_voltage_starts_to_bind_is_the_hand_solved_speed():
    limit = sizing.VoltageLimit(KT, KE, RPH, 600.0, LD, POLE_PAIRS)
    # no-load: U_LL / kE = (600 / sqrt 2) V / 57 V per 1000 rpm
    assert limit.no_load_speed() / sizing.RPM == pytest.approx(600.0 / math.sqrt(2.0) / 57.0
                                                               * 1000.0, rel=1e-12)
    # where the 15 N m of the 18 A module run out: (kE w / sqrt3 + R I)^2 + (p w L I)^2 = U^2
    # with I = 15 / kT, a quadratic in w
    u, current = 600.0 / math.sqrt(6.0), 15.0 / KT
    a = KE**2 / 3.0 + (POLE_PAIRS * LD * current) ** 2
    b = 2.0 * KE / math.sqrt(3.0) * RPH * current
    c = (RPH * current) ** 2 - u**2
    hand = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
    knee = limit.speed_at(15.0)
    assert knee == pytest.approx(hand, rel=1e-12) and limit.torque(knee) >= 15.0
    assert limit.speed_at(1e6) == 0.0
