"""Sizing formulas (ecam.sizing) against hand calculations, and the rig's sizing checks
(hil_sim.rig.sizing_checks) failing when they should.

The oracles are the catalogue data of the rotary knife's drive train (Siemens 1FT7 configuration
manual 01/2009, table 4-8: 1FT7044-AK7; Beckhoff AG2300 SP075 MF data sheet) worked by hand
here, in the test, from the formulas the docstrings name.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ecam import sizing
from ecam.errors import CamFileError, InputError
from hil_sim.rig.run import prepare
from hil_sim.rig.sizing_checks import NAMES, duty_cycle, sizing_checks
from hil_sim.scene import load_scene, parse_scene
from hil_sim.sizing_spec import catalogue

SCENES = Path(__file__).resolve().parents[1] / "hil_sim" / "scenes"
KNIFE = SCENES / "rotary_knife.toml"

# 1FT7044-AK7, table 4-8 of the 1FT7 configuration manual 01/2009 (p. 90)
M0, MN, NN = 5.0, 2.0, 6000.0
KT, KE_PER_KRPM, RPH, LD, POLE_PAIRS = 0.88, 57.0, 0.61, 4.2e-3, 3
KE = KE_PER_KRPM / (1000.0 * 2.0 * math.pi / 60.0)  # V s/rad


# ----------------------------------------------------------------------------------- formulas

def test_rms_torque_of_a_trapezoidal_move():
    # A trapezoidal speed profile: accelerate 0.1 s, cruise 0.2 s, decelerate 0.1 s, dwell 0.1 s
    # on J = 0.01 kg m^2 at alpha = 500 rad/s^2: torque J alpha, 0, -J alpha, 0.
    j, alpha = 0.01, 500.0
    hand = j * alpha * math.sqrt((0.1 + 0.1) / 0.5)
    slices = sizing.rms_torque([j * alpha, 0.0, -j * alpha, 0.0], [0.1, 0.2, 0.1, 0.1])
    assert slices == pytest.approx(hand, rel=1e-12)
    # the same move sampled evenly (the way the rig samples a cam period)
    t = (np.arange(5000) + 0.5) * (0.5 / 5000)
    torque = j * np.select([t < 0.1, t < 0.3, t < 0.4], [alpha, 0.0, -alpha], 0.0)
    assert sizing.rms_torque(torque) == pytest.approx(hand, rel=1e-12)
    with pytest.raises(InputError, match="durations"):
        sizing.rms_torque([1.0, 2.0], [1.0])


def test_s1_curve_between_and_beyond_the_catalogue_points():
    points = [(0.0, M0), (NN, MN)]
    # linear from M0 at standstill to M_N at n_N: 5 - 3 n / 6000
    for n in (0.0, 1000.0, 2350.0, 6000.0):
        assert sizing.s1_torque(n, points) == pytest.approx(M0 - (M0 - MN) * n / NN, rel=1e-12)
    # past n_N the slope goes on (0.5 N m at the 9000 rpm maximum), never below 0
    assert sizing.s1_torque(9000.0, points) == pytest.approx(0.5, rel=1e-12)
    assert sizing.s1_torque(20000.0, points) == 0.0
    assert np.allclose(sizing.s1_torque([-2350.0, 2350.0], points), 3.825)
    with pytest.raises(InputError, match="points"):
        sizing.s1_torque(100.0, [(100.0, 5.0), (0.0, 2.0)])


def _voltage(speed, **extra):
    kwargs = dict(torque_constant=KT, voltage_constant=KE, resistance=RPH, dc_bus_voltage=600.0,
                  inductance=LD, pole_pairs=POLE_PAIRS)
    kwargs.update(extra)
    return sizing.voltage_limited_torque(speed, **kwargs)


def test_voltage_limit_curve_of_the_1ft7044_on_600_v():
    u_phase = 600.0 / math.sqrt(6.0)  # largest phase voltage (rms) of an SVPWM inverter
    # where the 15 N m of the 18 A module run out: (kE w / sqrt3 + R I)^2 + (p w L I)^2 = U^2
    current = 15.0 / KT
    a = KE**2 / 3.0 + (POLE_PAIRS * LD * current) ** 2
    b = 2.0 * KE / math.sqrt(3.0) * RPH * current
    c = (RPH * current) ** 2 - u_phase**2
    w15 = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
    assert 5800.0 < w15 / sizing.RPM < 6000.0  # the "about 5800 rpm"
    assert _voltage(w15) == pytest.approx(15.0, rel=1e-9)
    # no current is left where the back-EMF alone reaches the voltage: n0 = U_LL / kE
    n0 = (600.0 / math.sqrt(2.0)) / KE_PER_KRPM * 1000.0
    assert _voltage(n0 * 1.0001 * sizing.RPM) == 0.0
    assert _voltage(n0 * 0.99 * sizing.RPM) > 0.0
    # without inductance: I = (U - E) / R
    w = 3000.0 * sizing.RPM
    hand = KT * (u_phase - KE * w / math.sqrt(3.0)) / RPH
    assert _voltage(w, inductance=0.0) == pytest.approx(hand, rel=1e-12)
    # the curve falls with the speed
    curve = _voltage(np.linspace(0.0, n0 * sizing.RPM, 50))
    assert np.all(np.diff(curve) <= 0.0)


def test_torque_current_points_of_a_saturating_motor():
    points = [(0.0, 0.0), (5.7, 5.0), (18.0, 15.0), (30.0, 23.0)]
    assert sizing.torque_for_current(18.0, points) == pytest.approx(15.0)
    assert sizing.current_for_torque(15.0, points) == pytest.approx(18.0)
    assert sizing.current_for_torque(10.0, points) == pytest.approx(5.7 + 5.0 * 12.3 / 10.0)
    assert sizing.current_for_torque(-5.0, points) == pytest.approx(5.7)
    with pytest.raises(InputError, match="torque_current_points"):
        sizing.current_for_torque(1.0, [(0.0, 0.0), (1.0, 2.0), (0.5, 3.0)])


def test_dc_link_energy_and_a_braking_pulse():
    # C (U_chop^2 - U_dc^2) / 2
    assert sizing.dc_link_energy(705e-6, 600.0, 774.0) == pytest.approx(
        0.5 * 705e-6 * (774.0**2 - 600.0**2), rel=1e-12)
    with pytest.raises(InputError, match="limit_voltage"):
        sizing.dc_link_energy(1e-3, 600.0, 600.0)
    # 100 W returned for 0.5 s, then 0.5 s motoring at 200 W: 50 J stored at once
    power = np.r_[np.full(500, -100.0), np.full(500, 200.0)]
    assert sizing.regenerated_energy(power, 1e-3) == pytest.approx(50.0, rel=1e-9)
    # a link of 30 J with a 40 W resistor: 30 J after 0.3 s, then 60 W net for 0.2 s
    assert sizing.regenerated_energy(power, 1e-3, 30.0, 40.0) == pytest.approx(42.0, rel=1e-9)
    # motoring only: nothing stored
    assert sizing.regenerated_energy(np.full(10, 5.0), 1e-3) == 0.0


def test_thermal_model_of_a_pulse_and_of_a_short_cycle():
    # a torque T for d from a cold motor: T sqrt(1 - exp(-d / tau))
    tau, d = 600.0, 300.0
    torque = np.r_[np.full(3000, 4.0), np.zeros(3000)]
    assert sizing.thermal_torque(torque, d / 3000, tau, periodic=False) == pytest.approx(
        4.0 * math.sqrt(1.0 - math.exp(-d / tau)), rel=1e-9)
    # a cycle far shorter than the time constant: the RMS torque, plus the ripple of the
    # periodic steady state, at most one period's heat over the time constant
    cycle = np.sin(np.linspace(0.0, 2.0 * math.pi, 1000, endpoint=False)) * 3.0
    period, tau = 0.1, 2100.0
    rms = sizing.rms_torque(cycle)
    value = sizing.thermal_torque(cycle, period / cycle.size, tau)
    assert rms <= value <= math.sqrt(rms**2 + period / tau * 9.0)


def test_series_stiffness_and_the_two_mass_frequency_with_the_gearhead_in():
    # the knife: bellows 1.5e5, SP075 C_t21 10 N m/arcmin, the 1FT7044's shaft 9500 N m/rad
    # behind an i = 5 gear, rotor 5.43e-4 + gearhead input 0.68e-4 kg m^2, drum 0.0674 kg m^2
    gearhead = 10.0 * 60.0 * 180.0 / math.pi
    assert sizing.arcmin_stiffness(10.0) == pytest.approx(gearhead, rel=1e-12)
    r = 0.2
    k = 1.0 / (r * r / 9500.0 + 1.0 / gearhead + 1.0 / 1.5e5)
    assert sizing.series_stiffness(sizing.stiffness_at_output(9500.0, r), gearhead, 1.5e5) == \
        pytest.approx(k, rel=1e-12)
    assert sizing.series_stiffness(None, None) == math.inf
    j1 = 0.97 * (5.43e-4 + 0.68e-4) / (r * r)
    j2 = 0.0674
    hand = math.sqrt(k * (j1 + j2) / (j1 * j2)) / (2.0 * math.pi)
    f = sizing.two_mass_frequency_with_gearhead(
        motor_inertia=5.43e-4, load_inertia=j2, ratio=r, efficiency=0.97,
        coupling_stiffness=1.5e5, gearhead_stiffness=gearhead, shaft_stiffness=9500.0,
        gearhead_input_inertia=0.68e-4)
    assert f == pytest.approx(hand, rel=1e-12)
    # the bellows alone: 587 Hz; with gearhead and shaft: less than half
    alone = sizing.two_mass_frequency_with_gearhead(
        motor_inertia=5.43e-4, load_inertia=j2, ratio=r, efficiency=0.97,
        coupling_stiffness=1.5e5)
    assert f < 0.45 * alone
    # the scene's machine is what the plant and the tuner see: the same spring, the same mode
    machine = load_scene(KNIFE).mechanics.build()
    assert machine.coupling_stiffness == pytest.approx(k, rel=1e-9)
    assert machine.motor_inertia == pytest.approx(5.43e-4 + 0.68e-4, rel=1e-12)
    assert machine.torsional_frequency_hz() == pytest.approx(hand, rel=1e-9)


def test_gearhead_cyclic_torque():
    assert sizing.gearhead_cyclic_torque(132.0, 900.0)[0] == 132.0
    limit, how = sizing.gearhead_cyclic_torque(132.0, 7200.0, 1.2)
    assert limit == pytest.approx(110.0) and "f_s 1.2" in how
    limit, how = sizing.gearhead_cyclic_torque(132.0, 7200.0)
    assert limit == 132.0 and "not applied" in how


def test_the_catalogue_carries_a_source_for_every_entry():
    data = catalogue()
    for kind in ("motor", "module", "gearhead"):
        for name, entry in data[kind].items():
            assert entry["source"], f"{kind} {name} has no source"
    # every value has its source on its line (a comment) in the file
    text = Path(__file__).resolve().parents[1].joinpath("hil_sim", "catalogue.toml").read_text()
    for line in text.splitlines():
        if "=" in line and not line.startswith(("#", "source", "[")):
            assert "#" in line, f"no source beside: {line}"
    assert tomllib.loads(text) == data


# ------------------------------------------------------------------------- the scene's checks

def _knife(speed: float | None = None, **tables):
    """The knife's scene with some fields changed (``motor={...}``, ``drive={...}``, ...; a
    field set to None is taken out)."""
    data = tomllib.loads(KNIFE.read_text())
    for table, values in tables.items():
        data.setdefault(table, {}).update(values)
        data[table] = {k: v for k, v in data[table].items() if v is not None}
    scene = parse_scene(data, base=KNIFE.parent, source="rotary_knife.toml")
    return scene if speed is None else scene.with_master_speed(speed)


def _checks(scene) -> dict:
    run, _ = prepare(scene)
    checks, summary, _ = sizing_checks(run)
    assert [c.name for c in checks] == list(NAMES)
    return {c.name: c for c in checks} | {"summary": summary}


def test_the_knife_is_sized_at_its_own_speed():
    checks = _checks(_knife())
    for name in NAMES:
        if name not in ("regeneration", "inertia_ratio"):
            assert checks[name].limit is not None and checks[name].passed, checks[name].line()
    # the thermal check reads the S1 curve at the mean motor speed: 600 rpm at 120 cuts/min
    # (one drum turn per cut through i = 5), 5 - 3 x 600 / 6000 = 4.7 N m
    assert checks["motor_thermal"].limit == pytest.approx(4.7, rel=1e-3)
    parts = checks["summary"]["components"]
    assert parts["motor"]["model"] == "1FT7044-AK7" and parts["gearhead"]["model"] == "SP075-MF1-5"
    assert 0.0 < parts["motor"]["utilisation_percent"] < 100.0


def test_motor_thermal_fails_faster_and_its_value_grows_with_the_square_of_the_speed():
    slow, fast = _checks(_knife(1800.0)), _checks(_knife(2200.0))
    assert slow["motor_thermal"].passed and not fast["motor_thermal"].passed
    assert "at master" not in fast["motor_thermal"].detail  # a cycle's RMS has no one place
    assert "mean speed" in fast["motor_thermal"].detail


def test_motor_speed_torque_fails_on_a_low_dc_link():
    checks = _checks(_knife(1800.0, drive={"dc_bus_voltage": 120.0}))
    line = checks["motor_speed_torque"]
    assert not line.passed and "at master" in line.detail
    assert _checks(_knife(1800.0))["motor_speed_torque"].passed


def test_motor_speed_fails_above_the_motors_maximum():
    line = _checks(_knife(motor={"max_speed_rpm": 500.0}))["motor_speed"]
    assert not line.passed and line.limit == 500.0 and "the motor's maximum" in line.detail


def test_drive_currents_fail_on_a_small_module():
    checks = _checks(_knife(drive={"rated_current": 1.0, "peak_current": 2.0}))
    assert not checks["drive_current"].passed and not checks["drive_peak_current"].passed
    # the clamp follows the module: 2 A through the motor's points, 5 N m / 5.7 A
    scene = _knife(drive={"rated_current": 1.0, "peak_current": 2.0})
    assert scene.mechanics.build().motor_torque_limit == pytest.approx(2.0 * 5.0 / 5.7)


def test_regeneration_fails_on_a_small_dc_link_and_a_resistor_or_the_infeed_takes_it():
    # a rectifier infeed returns nothing: the DC link alone takes the braking energy
    small = {"dc_link_capacitance": 2e-6, "brake_chopper_voltage": 774.0, "infeed": "rectifier"}
    line = _checks(_knife(2000.0, drive=small))["regeneration"]
    assert line.limit == pytest.approx(0.5 * 2e-6 * (774.0**2 - 600.0**2))
    assert not line.passed, line.line()
    resistor = _checks(_knife(2000.0, drive={**small, "brake_resistor_power": 1e4}))
    assert resistor["regeneration"].passed
    # the knife's Active Line Module returns it all: the braking peaks below its 16 kW
    regenerative = _checks(_knife(2000.0, drive={**small, "infeed": "regenerative"}))
    line = regenerative["regeneration"]
    assert line.passed and line.value == 0.0 and "returns up to 16000 W" in line.detail


def test_a_cycle_without_braking_names_no_place_in_the_dc_link():
    # the knife at its own 720 deg/s brakes nowhere (its losses outweigh the inertia's return)
    line = _checks(_knife())["regeneration"]
    assert line.value == 0.0 and "nothing stored; no braking in the cycle" in line.detail
    assert "at master" not in line.detail
    # at 1912.5 deg/s it brakes, and the Active Line Module returns all of it
    line = _checks(_knife(1912.5))["regeneration"]
    assert line.value == 0.0 and line.detail.startswith("nothing stored (the infeed returns all of the braking); "
                                                        "braking peaks at ")


def test_the_stand_in_dc_link_alone_would_limit_the_knife_below_its_motor():
    """The DC link without the infeed (as the knife was rated before the Active Line Module):
    the regeneration check fails at 1900 deg/s, where the motor's heat still passes; with the
    infeed it passes there."""
    rectifier = _checks(_knife(1900.0, drive={"infeed": "rectifier"}))
    assert not rectifier["regeneration"].passed and rectifier["motor_thermal"].passed
    assert _checks(_knife(1900.0))["regeneration"].passed


def test_dc_link_energy_with_a_regenerative_infeed():
    # 100 W braking for 0.5 s, then 200 W motoring for 0.5 s; the infeed returns 60 W: the
    # link stores the other 40 W for 0.5 s = 20 J, then motoring and the infeed drain it
    power = np.r_[np.full(500, -100.0), np.full(500, 200.0)]
    stored = sizing.dc_link_stored_energy(power, 1e-3, line_power=60.0)
    assert stored.max() == pytest.approx(20.0, rel=1e-9)
    assert stored[-1] == 0.0
    assert sizing.regenerated_energy(power, 1e-3, line_power=60.0) == pytest.approx(20.0)
    # an infeed that returns 100 W or more leaves nothing in the link
    assert sizing.regenerated_energy(power, 1e-3, line_power=100.0) == 0.0
    # a 20 J link with a 40 W resistor and a 30 W infeed: 70 W charge it to 20 J in 2/7 s,
    # then 100 - 30 - 40 = 30 W for the remaining 0.5 - 2/7 s
    hand = 20.0 + 30.0 * (0.5 - 20.0 / 70.0)
    assert sizing.regenerated_energy(power, 1e-3, 20.0, 40.0, line_power=30.0) == pytest.approx(
        hand, rel=2e-3)
    with pytest.raises(InputError, match="line_power"):
        sizing.dc_link_stored_energy(power, 1e-3, line_power=-1.0)


def test_a_periodic_duty_that_returns_more_than_it_draws_charges_the_link_for_ever():
    # 100 W braking for 0.5 s and 20 W motoring for 0.5 s: 40 J more in the link every cycle
    # (an overhauling load); two cycles showed 90 J, a link of any size trips in the end
    power = np.r_[np.full(500, -100.0), np.full(500, 20.0)]
    assert sizing.regenerated_energy(power, 1e-3) == math.inf
    assert sizing.regenerated_energy(power, 1e-3, periodic=False) == pytest.approx(50.0)
    # a 100 W resistor above 20 J takes all of the braking: the link holds 20 J
    assert sizing.regenerated_energy(power, 1e-3, 20.0, 100.0) == pytest.approx(20.0)
    # a 50 W infeed leaves 50 W x 0.5 s = 25 J, drained at 20 + 50 W before the cycle ends
    assert sizing.regenerated_energy(power, 1e-3, line_power=50.0) == pytest.approx(25.0)


def test_energy_to_the_line_includes_what_the_link_stored():
    # 100 W braking for 0.5 s, then 200 W motoring for 0.5 s, a 60 W infeed: 60 W x 0.5 s = 30 J
    # while braking, then the 20 J stored drain at 200 W (motor) + 60 W (infeed) for 20/260 s, of
    # which the infeed takes 60 x 20 / 260 = 4.615 J: 34.615 J per cycle
    power = np.r_[np.full(500, -100.0), np.full(500, 200.0)]
    assert sizing.energy_to_line(power, 1e-3, line_power=60.0) == pytest.approx(30.0 + 60.0 * 20.0 / 260.0,
                                                                                abs=0.06)
    # a block of braking across the seam of a periodic duty counts once, all of it
    seam = np.r_[np.full(250, -100.0), np.full(500, 200.0), np.full(250, -100.0)]
    assert sizing.energy_to_line(seam, 1e-3, line_power=60.0) == pytest.approx(
        sizing.energy_to_line(power, 1e-3, line_power=60.0), abs=1e-9)
    # a rectifier returns nothing; an infeed above the braking peak returns all the braking
    assert sizing.energy_to_line(power, 1e-3) == 0.0
    assert sizing.energy_to_line(power, 1e-3, line_power=150.0) == pytest.approx(50.0)
    # what the brake resistor burns does not reach the line: a 20 J link, 40 W resistor and 30 W
    # infeed (the hand case above: 20 + 30 (0.5 - 2/7) J stored when the braking ends) returns
    # 30 W x 0.5 s while braking, then 30 W while the link drains, at 200 + 30 + 40 W down to
    # 20 J (the resistor still on) and at 200 + 30 W below
    above = 30.0 * (0.5 - 20.0 / 70.0)
    hand = 15.0 + 30.0 * (above / 270.0 + 20.0 / 230.0)
    assert sizing.energy_to_line(power, 1e-3, 20.0, 40.0, 30.0) == pytest.approx(hand, abs=0.05)
    # the knife on a 300 W infeed: its summary counts what the link stored and gave back too
    checks = _checks(_knife(2000.0, drive={"infeed_power": 300.0}))
    duty = duty_cycle(prepare(_knife(2000.0))[0])
    braking_only = float(np.sum(np.minimum(np.maximum(-duty.power, 0.0), 300.0)) * duty.dt)
    to_line = checks["summary"]["components"]["infeed"]["required"]["energy_to_line_per_cycle"]
    assert to_line == pytest.approx(sizing.energy_to_line(duty.power, duty.dt, 30.2913, 0.0, 300.0), rel=1e-3)
    assert to_line > braking_only + 1.0


def test_power_through_the_infeed():
    # motoring drawn in full; braking returned up to the infeed's power; none by a rectifier
    assert sizing.infeed_power(500.0, 300.0) == 500.0
    assert sizing.infeed_power(-200.0, 300.0) == -200.0
    assert sizing.infeed_power(-500.0, 300.0) == -300.0
    assert np.array_equal(sizing.infeed_power([-500.0, 100.0], 0.0), [0.0, 100.0])
    with pytest.raises(InputError, match="regenerative_power"):
        sizing.infeed_power(1.0, -1.0)
    # the line supplies the losses too (P_line = P_mech + P_losses): 100 W of them are drawn on
    # top of motoring; braking returns the shaft power, its losses left out (the safe side),
    # unless they exceed it and the line supplies the difference
    assert sizing.infeed_power(500.0, 300.0, 100.0) == 600.0
    assert sizing.infeed_power(-200.0, 300.0, 100.0) == -200.0
    assert sizing.infeed_power(-50.0, 300.0, 100.0) == 50.0
    assert np.array_equal(sizing.infeed_power([-500.0, 100.0], 300.0, [100.0, 50.0]), [-300.0, 150.0])
    with pytest.raises(InputError, match=r"losses: -1 should be >= 0"):
        sizing.infeed_power(1.0, 0.0, -1.0)


def test_copper_losses_of_a_hot_winding():
    # 1FT7044-AK7: R_ph 0.61 ohm at 20 degC; copper at 120 degC (the 100 K data):
    # 0.61 x (1 + 0.00393 x 100) = 0.849730 ohm; at I0 = 5.7 A, 3 x 5.7^2 x 0.84973 = 82.826 W
    hot = sizing.hot_winding_resistance(0.61)
    assert hot == pytest.approx(0.84973, rel=1e-12)
    assert sizing.copper_loss(5.7, hot) == pytest.approx(3 * 5.7**2 * 0.84973, rel=1e-12)
    assert np.allclose(sizing.copper_loss([0.0, -2.0], 1.0), [0.0, 12.0])
    with pytest.raises(InputError, match="resistance"):
        sizing.copper_loss(1.0, -0.1)


def test_the_active_line_modules_rating_is_the_manuals():
    """S120 Booksize Power Units manual (GH2) 04/2014, section 3.11, p. 144: S_K line >=
    0.73 x 70 x P_n, "for 16 kW Active Line Module: S_K line = 0.82 MVA"."""
    entry = catalogue()["line_module"]["6SL3130-7TE21-6AA4"]
    assert entry["infeed"] == "regenerative"
    assert 0.73 * 70.0 * entry["infeed_power"] == pytest.approx(0.82e6, abs=0.005e6)
    # the 07/2016 edition's transformer row: S_n >= 1.27 P_n, 21 kVA
    assert 1.27 * entry["infeed_power"] <= 21e3
    assert "infeed_peak_power" not in entry  # not found: the rated power stands in
    spec = _knife().sizing.infeed
    assert spec.rated_power == spec.peak_power == spec.regenerative_power == 16e3


def test_infeed_power_fails_on_a_small_infeed():
    checks = _checks(_knife(2000.0, drive={"infeed_power": 500.0}))
    line = checks["infeed_power"]
    assert not line.passed and line.limit == 500.0 and "at master" in line.detail
    # the value is the larger share: the cycle's peak power through the infeed (the shaft's
    # motoring peak and the hot winding's copper losses, 3 I^2 R_ph (1 + 0.00393 x 100) with
    # R_ph = 0.61 ohm; braking is returned only up to 500 W) against the peak, here the rated
    run, _ = prepare(_knife(2000.0))
    duty = duty_cycle(run)
    current = sizing.current_for_torque(duty.motor_torque, [[0.0, 0.0], [5.7, 5.0], [18.0, 15.0], [30.0, 23.0]])
    drawn = duty.power + 3.0 * current**2 * 0.61 * 1.393
    assert line.value == pytest.approx(float(np.max(np.abs(np.where(drawn > 0.0, drawn,
                                                                      np.maximum(duty.power, -500.0))))))
    assert line.value > float(np.max(duty.power)) + 100.0  # the losses are not small
    assert checks["summary"]["components"]["infeed"]["utilisation_percent"] > 100.0
    # the RMS counts where it is the larger share: a peak rating far above the rated power
    rms = _checks(_knife(2000.0, drive={"infeed_power": 500.0, "infeed_peak_power": 1e6}))
    assert rms["infeed_power"].limit == 500.0
    assert rms["infeed_power"].value == pytest.approx(sizing.rms_torque(np.where(drawn > 0.0, drawn, duty.power)))


def test_infeed_fields_are_checked_where_they_enter():
    with pytest.raises(CamFileError, match=r"drive\.infeed_power: missing should be given"):
        _knife(drive={"line_module": None, "infeed": "regenerative"})
    with pytest.raises(CamFileError, match=r"drive\.infeed_peak_power: 100 should be >= "
                                           r"infeed_power 16000"):
        _knife(drive={"infeed_peak_power": 100.0})
    with pytest.raises(CamFileError, match=r"drive\.infeed: .*regenerative"):
        _knife(drive={"infeed": "solar"})
    with pytest.raises(CamFileError, match=r"drive\.line_module: .*not in the catalogue"):
        _knife(drive={"line_module": "6SL3130-0000"})


def test_inertia_ratio_fails_above_the_scenes_limit():
    line = _checks(_knife(limits={"inertia_ratio": 3.0}))["inertia_ratio"]
    assert not line.passed and line.limit == 3.0 and line.value > 3.0


def test_gearhead_torque_fails_above_t2b():
    line = _checks(_knife(mechanics={"gearhead_acceleration_torque": 3.0}))["gearhead_torque"]
    assert not line.passed and "at master" in line.detail


def _without_motor(name: str = "stiff_coupling"):
    """A shipped scene with its drive train taken out."""
    path = SCENES / f"{name}.toml"
    data = tomllib.loads(path.read_text())
    del data["motor"]
    data["drive"].pop("dc_bus_voltage", None)
    return parse_scene(data, base=path.parent, source=path.name)


def test_a_scene_without_a_motor_reports_the_sizing_checks_without_limits():
    checks = _checks(_without_motor())
    assert all(checks[name].limit is None and checks[name].passed for name in NAMES)
    assert checks["summary"]["applicable"] is False


def test_catalogue_names_and_ratios_are_checked_where_they_enter():
    with pytest.raises(CamFileError, match=r"motor\.model: .*not in the catalogue"):
        _knife(motor={"model": "1FT7999"})
    with pytest.raises(CamFileError, match=r"mechanics\.gear_ratio: 0\.1 should be 0\.2"):
        _knife(mechanics={"gear_ratio": 0.1})
    with pytest.raises(CamFileError, match=r"drive\.peak_current: 1 should be >= rated_current"):
        _knife(drive={"peak_current": 1.0})
    with pytest.raises(CamFileError, match=r"motor\.stall_torque: -1 should be > 0"):
        _knife(motor={"stall_torque": -1.0})


def test_the_duty_is_the_cams_motion_through_the_gear():
    scene = _knife()
    run, _ = prepare(scene)
    duty = duty_cycle(run)
    # one drum turn per cut at 120 cuts/min through i = 5: a mean motor speed of 600 rpm
    assert float(np.mean(duty.motor_speed)) / sizing.RPM == pytest.approx(600.0, rel=1e-3)
    assert duty.dt * duty.master.size == pytest.approx(0.5)
    assert replace(scene, sizing=scene.sizing).sizing.motor.model == "1FT7044-AK7"


@pytest.mark.slow
def test_the_knifes_maximum_speed_is_limited_by_its_drive_train():
    """Issue 21, item 5: the search stops at the first limit of any kind and names it; the
    sized knife, its braking energy returned to the line by its Active Line Module, runs out of
    S1 torque before its DC link, its tracking or its clamp give up."""
    from hil_sim.rig import find_max_speed

    result = find_max_speed(load_scene(KNIFE))
    assert result["confirmed"] and result["failed_checks"] == ["motor_thermal"]
    assert result["limiting_check"].startswith("FAIL  motor_thermal:")
    below = _checks(_knife(result["speed"]))
    above = _checks(_knife(result["failing_speed"]))
    assert below["motor_thermal"].passed and not above["motor_thermal"].passed
    assert above["regeneration"].passed and above["infeed_power"].passed


def test_the_summary_in_the_text_the_json_the_html_and_the_figure():
    from ecam.app.sizing_html import sizing_section
    from hil_sim.rig import run_scene
    from hil_sim.rig.sizing_plot import has_torque_speed
    from hil_sim.scene import DurationSpec

    knife = run_scene(replace(_knife(), duration=DurationSpec(cycles=200)), path="fast")
    text = knife.to_text()
    assert "sizing (one cam period at the cruise speed" in text
    assert "  motor 1FT7044-AK7: " in text and "  gearhead SP075-MF1-5: " in text
    data = knife.to_dict()
    parts = data["sizing"]["components"]
    assert set(parts) == {"motor", "module", "gearhead", "coupling", "infeed", "brake_resistor"}
    assert "  infeed 6SL3130-7TE21-6AA4: " in text
    thermal = knife.check("motor_thermal")
    assert parts["motor"]["utilisation_percent"] >= 100.0 * thermal.ratio
    page = sizing_section(data)
    assert page.startswith("<h3>Sizing</h3>") and "1FT7044-AK7" in page and "table 4-8" in page
    assert has_torque_speed(knife)
    stiff = run_scene(replace(_without_motor(), duration=DurationSpec(cycles=50)), path="fast")
    assert "sizing (" not in stiff.to_text() and sizing_section(stiff.to_dict()) == ""
    assert not has_torque_speed(stiff)
