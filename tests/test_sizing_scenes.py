"""The drive trains of the shipped 6 N m scenes (stiff_coupling, soft_coupling, drive_side,
cam_in and the packaging line's pusher, lifter and transfer): the catalogue's WITTENSTEIN premo
320 V stator 2D, held to its own data sheet by hand calculation.

Oracle: WITTENSTEIN premo operating manual rev. 02 (4022-D045530), Tbl-16 "Motor
specifications, premo 320 V", stator 2D, p. en-28: U_D 320 V DC, Kt 0.52 Nm/A, Ke 31.6 V/krpm,
T0 2.11 Nm at I0 4.04 A, Tmax 5.53 Nm at Imax 12.0 A, no-load speed n0 7023 rpm, Rtt 3.72 ohm,
Ltt 7.43 mH, tau_e 2.00 ms, p 4, J 0.83 kg cm^2, tau_th 17.4 min.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest

from ecam import sizing
from ecam.errors import CamFileError
from hil_sim.rig.run import prepare
from hil_sim.rig.sizing_checks import sizing_checks
from hil_sim.scene import load_scene, parse_scene
from hil_sim.sizing_spec import catalogue

SCENES = Path(__file__).resolve().parents[1] / "hil_sim" / "scenes"
PREMO = "premo-320V-2D"


def test_the_premo_entry_is_its_data_sheet():
    entry = catalogue()["motor"][PREMO]
    assert entry["voltage_constant"] == pytest.approx(31.6 / (1000.0 * 2.0 * math.pi / 60.0))
    # phase values from the terminal-to-terminal ones of a star winding, and the sheet's own
    # electrical time constant as their check: tau_e = Ltt / Rtt = 2.16 ms
    assert entry["winding_resistance"] == pytest.approx(3.72 / 2.0)
    assert entry["inductance"] / entry["winding_resistance"] == pytest.approx(2.00e-3, rel=5e-3)
    # T0 = Kt I0 within the sheet's rounding
    assert entry["torque_constant"] * 4.04 == pytest.approx(entry["stall_torque"], rel=5e-3)
    assert entry["thermal_time_constant_s"] == 17.4 * 60.0
    # not in the sheet, so not in the entry
    for missing in ("rated_torque", "rated_speed_rpm", "max_speed_rpm", "shaft_stiffness"):
        assert missing not in entry


def test_the_premo_voltage_limit_meets_its_no_load_speed():
    entry = catalogue()["motor"][PREMO]
    kwargs = dict(torque_constant=entry["torque_constant"],
                  voltage_constant=entry["voltage_constant"],
                  resistance=entry["winding_resistance"], dc_bus_voltage=320.0,
                  inductance=entry["inductance"], pole_pairs=entry["pole_pairs"])
    # the back-EMF alone takes the whole line-to-line voltage U_D / sqrt(2) at n0 = U / Ke:
    # 226.3 V / 31.6 V per 1000 rpm = 7160 rpm, against the sheet's 7023 rpm (2 %: the sheet's
    # Ke is at 20 degC and rounded; the inverter's voltage reserve is not in the formula)
    n0 = 320.0 / math.sqrt(2.0) / 31.6 * 1000.0
    assert n0 == pytest.approx(7023.0, rel=0.02)
    assert sizing.voltage_limited_torque(n0 * 0.999 * sizing.RPM, **kwargs) > 0.0
    assert sizing.voltage_limited_torque(n0 * 1.001 * sizing.RPM, **kwargs) == 0.0
    # at standstill the voltage allows U / R: far more than the 12.0 A maximum current
    standstill = sizing.voltage_limited_torque(0.0, **kwargs)
    assert standstill == pytest.approx(0.52 * 320.0 / math.sqrt(6.0) / 1.86, rel=1e-9)


@pytest.mark.parametrize("name", ["stiff_coupling", "soft_coupling", "drive_side", "cam_in"])
def test_the_six_newton_metre_scenes_run_on_the_premo(name):
    scene = load_scene(SCENES / f"{name}.toml")
    mechanics = scene.mechanics.build()
    # the scene's own fields win over the catalogue's: the motor side's inertia (the rotor's
    # 0.83e-4 and what turns with it) and the 6 N m clamp
    assert mechanics.motor_inertia == 1.2e-4 > scene.sizing.motor.rotor_inertia
    assert mechanics.motor_torque_limit == 6.0
    assert scene.sizing.motor.model == PREMO and scene.sizing.module.dc_bus_voltage == 320.0
    # the sizing holds the cycle to the motor's own maximum, not to the clamp
    assert scene.sizing.torque_clamp() == 5.53


def test_without_an_s1_point_the_thermal_check_takes_m0_and_says_so():
    run, _ = prepare(load_scene(SCENES / "stiff_coupling.toml"))
    checks = {c.name: c for c in sizing_checks(run)[0]}
    thermal = checks["motor_thermal"]
    assert thermal.limit == 2.11 and "M0 at every speed" in thermal.detail
    # no catalogue maximum speed: the speed check has no limit and says why
    assert checks["motor_speed"].limit is None
    assert checks["motor_speed_torque"].limit == pytest.approx(5.53)


def test_a_rated_torque_needs_its_speed():
    path = SCENES / "stiff_coupling.toml"
    data = tomllib.loads(path.read_text())
    data["motor"]["rated_torque"] = 2.0
    with pytest.raises(CamFileError, match=r"motor\.rated_speed_rpm: missing should be given "
                                           r"with rated_torque"):
        parse_scene(data, base=path.parent, source=path.name)
    data["motor"]["rated_speed_rpm"] = 3000.0
    scene = parse_scene(data, base=path.parent, source=path.name)
    assert scene.sizing.motor.s1_points() == [(0.0, 2.11), (3000.0, 2.0)]


def test_the_akd_dc_link_absorbs_the_energy_kollmorgen_gives_for_it():
    """Kollmorgen Developer Network, "Calculation of brake power": AKD-x00607, 235 uF, 35 Ws
    stored on a 3 x 400 V mains before the brake resistor takes over."""
    entry = catalogue()["module"]["AKD-x00607"]
    assert entry["dc_bus_voltage"] == pytest.approx(400.0 * math.sqrt(2.0))
    energy = sizing.dc_link_energy(entry["dc_link_capacitance"], entry["dc_bus_voltage"],
                                   entry["brake_chopper_voltage"])
    assert energy == pytest.approx(35.0, abs=0.05)  # the table's 35 Ws, to its rounding


def test_the_knifes_regeneration_is_rated_against_the_stand_in_dc_link():
    run, _ = prepare(load_scene(SCENES / "rotary_knife.toml").with_master_speed(1800.0))
    line = {c.name: c for c in sizing_checks(run)[0]}["regeneration"]
    # C (U_chop^2 - U_dc^2) / 2 between the knife's 600 V and the AKD's 786 V: 30.29 J
    assert line.limit == pytest.approx(0.5 * 235e-6 * (786.0**2 - 600.0**2))
    # the Active Line Module returns the braking power to the line: nothing is left for it
    assert line.passed and line.value == 0.0 and "regenerative infeed" in line.detail


def test_the_torque_speed_curves_run_to_the_no_load_speed_without_a_maximum_speed():
    run, _ = prepare(load_scene(SCENES / "stiff_coupling.toml"))
    series = sizing_checks(run)[2]
    # U_D / sqrt 2 over Ke: 320 / sqrt 2 V / 31.6 V per 1000 rpm = 7160 rpm, where the peak
    # curve (the voltage limit) reaches 0
    assert series["sizing_curve_rpm"][-1] == pytest.approx(320.0 / math.sqrt(2.0) / 31.6 * 1000.0)
    assert series["sizing_peak_torque"][-1] == pytest.approx(0.0, abs=1e-9)
    assert series["sizing_peak_torque"][0] == 5.53
