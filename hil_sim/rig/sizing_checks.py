"""The checks a sizing tool makes, for the cam's duty at the scene's cruise speed.

As SIZER and its peers do, the duty is the motion the cam asks for, not what a tuning made of
it: one cam period at the cruise master speed, sampled at :data:`SAMPLES` instants, the motor's
speed and torque from the mechanics (:func:`duty_cycle`: the inertias reflected through the
gear, the viscous damping and the Coulomb friction of both sides as the run's full model has
them). The run's own torques are checked by ``motor_saturation`` (the drive's clamp).

Checks (value, limit, margin and where, as every check of the report):

* ``motor_thermal``: the larger of the RMS torque over the cycle and the thermal model's worst
  window (:func:`ecam.sizing.thermal_torque`), against the S1 torque at the cycle's mean speed;
* ``motor_speed_torque``: the sample whose torque is nearest (or furthest over) what the motor
  and the module give at its speed: the maximum torque, the torque at the module's peak current,
  the voltage limit;
* ``motor_speed``: the highest motor speed against the motor's (and the gearhead's input)
  maximum;
* ``drive_current`` and ``drive_peak_current``: the module's RMS and peak current against its
  rated and peak current (through the motor's torque-current curve);
* ``regeneration``: the most energy braking stores in the DC link at once against what it
  absorbs between its nominal and its brake-chopper voltage, a regenerative infeed returning
  braking power to the line up to its peak power first, a brake resistor taking the rest;
* ``infeed_power``: the power through the infeed (drawn, and returned where it regenerates),
  its RMS over the cycle against the rated power and its peak against the peak power;
* ``inertia_ratio``: reflected load over motor-side inertia against ``limits.inertia_ratio``;
* ``gearhead_torque``: the gearhead's peak output torque against its T2B at the duty's cycles
  per hour.

A scene without the part a check needs reports the check without a limit (not applicable).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ecam import sizing
from hil_sim.report import Check, check
from hil_sim.rig.plan import PreparedRun

#: Samples of the cam period the duty is evaluated at.
SAMPLES = 4096
#: Points of the S1 and peak curves in the report's series (the torque-speed plot).
CURVE_POINTS = 121
#: The sizing checks, in the report's order.
NAMES = ("motor_thermal", "motor_speed_torque", "motor_speed", "drive_current",
         "drive_peak_current", "regeneration", "infeed_power", "inertia_ratio",
         "gearhead_torque")


@dataclass(frozen=True)
class Duty:
    """One cam period at cruise speed, sampled evenly (all arrays of :data:`SAMPLES`).

    Attributes
    ----------
    master : numpy.ndarray
        Master position in the period [master units] of each sample.
    dt : float
        Time per sample [s].
    motor_speed, motor_torque : numpy.ndarray
        At the motor shaft [rad/s, N m] (positive torque along positive speed: motoring).
    output_torque : numpy.ndarray
        At the gear output [N m] (the torque the gearhead passes to coupling and load).
    """

    master: np.ndarray
    dt: float
    motor_speed: np.ndarray
    motor_torque: np.ndarray
    output_torque: np.ndarray

    @property
    def speed_rpm(self) -> np.ndarray:
        """|motor speed| [rpm]."""
        return np.abs(self.motor_speed) / sizing.RPM

    @property
    def power(self) -> np.ndarray:
        """Shaft power [W], positive when motoring."""
        return self.motor_torque * self.motor_speed


def duty_cycle(run: PreparedRun) -> Duty:
    """The motor's speed and torque over one cam period at the cruise speed."""
    scene, mech, profile = run.scene, run.mechanics, run.cam.profile
    period = profile.master_period
    speed = run.plan.speed_units  # master units/s, signed
    master = (np.arange(SAMPLES) + 0.5) * (period / SAMPLES)
    per_radian = scene.mechanics.slave_units_per_load_radian
    load_speed = profile(master, 1) * speed / per_radian
    load_acceleration = profile(master, 2) * speed * speed / per_radian
    r, eta = mech.gear_ratio, mech.gear_efficiency
    values = run.effect_values

    def effect(name: str) -> float:
        if values is None:
            return 0.0
        value = values[name].value
        return float(value) if value else 0.0

    coupling_inertia = effect("coupling_inertia")
    load_inertia = mech.load_inertia + coupling_inertia
    load_friction = effect("load_coulomb_friction")
    output = (load_inertia * load_acceleration + mech.load_damping * load_speed
              + load_friction * np.sign(load_speed))
    motor_speed = load_speed / r
    motor_acceleration = load_acceleration / r
    # the load side reflected through the gear as ecam.mechanics has it (/eta, the safe side)
    motor = (mech.motor_inertia * motor_acceleration + mech.motor_damping * motor_speed
             + effect("motor_coulomb_friction") * np.sign(motor_speed) + output * r / eta)
    dt = period / abs(speed) / SAMPLES
    return Duty(master, dt, motor_speed, motor, output)


def _where(run: PreparedRun, duty: Duty, index: int) -> str:
    return f"at master {duty.master[index]:.6g} {run.cam.profile.master_unit}"


def available_torque(run: PreparedRun, speed) -> np.ndarray:
    """What the motor and the module give at a motor speed [rad/s]: the motor's maximum, the
    torque at the module's peak current, the voltage limit (inf without a motor)."""
    spec = run.scene.sizing
    motor, module = spec.motor, spec.module
    speed = np.asarray(speed, dtype=float)
    if motor is None:
        return np.full(speed.shape, math.inf)
    limit = np.full(speed.shape, spec.torque_clamp())
    if module is not None and module.dc_bus_voltage is not None:
        limit = np.minimum(limit, sizing.voltage_limited_torque(
            speed, torque_constant=motor.torque_constant, voltage_constant=motor.voltage_constant,
            resistance=motor.winding_resistance, dc_bus_voltage=module.dc_bus_voltage,
            inductance=motor.inductance, pole_pairs=motor.pole_pairs))
    return limit


def motor_thermal_check(run: PreparedRun, duty: Duty) -> tuple[Check, dict]:
    """RMS (and worst thermal window) torque against the S1 torque at the mean speed."""
    motor = run.scene.sizing.motor
    rms = sizing.rms_torque(duty.motor_torque)
    mean_rpm = float(np.mean(duty.speed_rpm))
    if motor is None:
        return check("motor_thermal", rms, None, "N m",
                     f"RMS over the cam cycle at mean speed {mean_rpm:.4g} rpm; no [motor]: "
                     "not rated"), {"rms_torque": rms, "mean_speed_rpm": mean_rpm}
    window = sizing.thermal_torque(duty.motor_torque, duty.dt, motor.thermal_time_constant_s)
    s1 = sizing.s1_torque(mean_rpm, motor.s1_points())
    # the larger of the two: the winding's peak temperature within the cycle is a little above
    # its mean (the ripple), and a cycle as long as the time constant heats it by its worst part
    value = max(rms, window)
    detail = (f"RMS over the cam cycle {rms:.4g} N m, thermal model with the "
              f"{motor.thermal_time_constant_s:g} s time constant {window:.4g} N m (the larger "
              f"counts), against S1 {s1:.4g} N m at the mean speed {mean_rpm:.4g} rpm")
    if motor.rated_torque is None:
        detail += ("; the catalogue gives no S1 point above standstill: M0 at every speed (on "
                   "the unsafe side: a real motor's S1 curve falls with the speed)")
    return (check("motor_thermal", value, s1, "N m", detail),
            {"rms_torque": rms, "thermal_window_torque": window, "mean_speed_rpm": mean_rpm,
             "s1_torque_at_mean_speed": s1})


def motor_speed_torque_check(run: PreparedRun, duty: Duty) -> Check:
    """Each sample's torque against what the motor and the module give at its speed."""
    torque = np.abs(duty.motor_torque)
    available = available_torque(run, duty.motor_speed)
    if not np.isfinite(available).any():
        worst = int(np.argmax(torque))
        return check("motor_speed_torque", torque[worst], None, "N m",
                     f"peak torque {_where(run, duty, worst)}; no [motor]: not rated")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(available > 0, torque / available, np.inf)
    worst = int(np.argmax(ratio))
    return check("motor_speed_torque", torque[worst], available[worst], "N m",
                 f"{_where(run, duty, worst)}, {duty.speed_rpm[worst]:.4g} rpm: what motor and "
                 "module give there (maximum torque, peak current, voltage limit)")


def motor_speed_check(run: PreparedRun, duty: Duty) -> Check:
    """The highest motor speed against the motor's and the gearhead's input maximum."""
    spec = run.scene.sizing
    worst = int(np.argmax(duty.speed_rpm))
    limits = []
    if spec.motor is not None and spec.motor.max_speed_rpm is not None:
        limits.append((spec.motor.max_speed_rpm, "the motor's maximum"))
    if spec.gearhead is not None and spec.gearhead.max_input_speed_rpm is not None:
        limits.append((spec.gearhead.max_input_speed_rpm, "the gearhead's maximum input speed"))
    if not limits:
        return check("motor_speed", duty.speed_rpm[worst], None, "rpm",
                     f"{_where(run, duty, worst)}; no motor or gearhead speed rating")
    limit, what = min(limits)
    return check("motor_speed", duty.speed_rpm[worst], limit, "rpm",
                 f"{_where(run, duty, worst)}, against {what}")


def drive_current_checks(run: PreparedRun, duty: Duty) -> tuple[list[Check], dict]:
    """The module's RMS and peak current (through the motor's torque-current curve)."""
    spec = run.scene.sizing
    motor, module = spec.motor, spec.module
    if motor is None:
        return [check("drive_current", None, None, "A", "no [motor]: no torque constant"),
                check("drive_peak_current", None, None, "A", "no [motor]: no torque constant")], {}
    current = sizing.current_for_torque(duty.motor_torque, motor.current_points())
    rms = sizing.rms_torque(current)
    worst = int(np.argmax(current))
    rated = module.rated_current if module is not None else None
    peak = module.peak_current if module is not None else None
    missing = "" if module is not None else "; no module rating in [drive]"
    return [check("drive_current", rms, rated, "A",
                  f"RMS over the cam cycle against the module's rated current{missing}"),
            check("drive_peak_current", current[worst], peak, "A",
                  f"{_where(run, duty, worst)}, against the module's peak current{missing}")], \
        {"rms_current": rms, "peak_current": float(current[worst])}


def regeneration_check(run: PreparedRun, duty: Duty) -> tuple[Check, dict]:
    """The most energy braking stores in the DC link against what it absorbs, a regenerative
    infeed returning braking power to the line up to its peak power first."""
    spec = run.scene.sizing
    module, infeed = spec.module, spec.infeed
    braking = np.maximum(-duty.power, 0.0)
    returned = float(np.sum(braking) * duty.dt)
    line = infeed.regenerative_power if infeed is not None else 0.0
    capacity, brake = math.inf, 0.0
    rated = (module is not None and module.dc_link_capacitance is not None
             and module.dc_bus_voltage is not None and module.brake_chopper_voltage is not None)
    if rated:
        capacity = sizing.dc_link_energy(module.dc_link_capacitance, module.dc_bus_voltage,
                                         module.brake_chopper_voltage)
        brake = module.brake_resistor_power
    stored = sizing.dc_link_stored_energy(duty.power, duty.dt, capacity, brake, line)
    fullest = int(np.argmax(stored))
    hardest = int(np.argmax(braking))
    to_line = sizing.energy_to_line(duty.power, duty.dt, capacity, brake, line)
    facts = {"energy_returned_per_cycle": returned, "largest_stored_energy": float(stored[fullest]),
             "peak_braking_power": float(braking[hardest]),
             "energy_to_line_per_cycle": to_line,
             "dc_link_energy": capacity if rated else None,
             "brake_resistor_power": brake if rated else None}
    # where: the fullest DC link; nothing stored (the infeed took it all, or no braking): no place
    if stored[fullest] > 0.0:
        where = "most energy stored at once " + _where(run, duty, fullest)
    else:
        where = "nothing stored" + (" (the infeed returns all of the braking)" if braking[hardest] > 0.0 else "")
    flow = (f"braking peaks at {braking[hardest]:.4g} W {_where(run, duty, hardest)}, "
            f"{returned:.4g} J per cycle" if braking[hardest] > 0.0 else "no braking in the cycle")
    if infeed is not None and line > 0.0:
        flow += (f"; the {infeed.kind} infeed returns up to {line:g} W of it to the line "
                 f"({to_line:.4g} J per cycle)")
    elif infeed is not None:
        flow += f"; the {infeed.kind} infeed returns none of it"
    if not rated:
        return check("regeneration", float(stored[fullest]), None, "J",
                     f"{where}; {flow}; no DC-link capacitance and "
                     "chopper voltage in [drive]: not rated"), facts
    what = (f"DC link {capacity:.4g} J between {module.dc_bus_voltage:g} and "
            f"{module.brake_chopper_voltage:g} V"
            + (f", brake resistor {brake:g} W above it" if brake else ", no brake resistor"))
    return check("regeneration", float(stored[fullest]), capacity, "J",
                 f"{where}; {flow}; {what}"), facts


def infeed_power_check(run: PreparedRun, duty: Duty) -> tuple[Check, dict]:
    """The power through the infeed (drawn, and returned where it regenerates): its RMS over
    the cycle against the rated power, its peak against the peak power; the larger share
    counts."""
    infeed, motor = run.scene.sizing.infeed, run.scene.sizing.motor
    # the line supplies the winding's copper losses on top of the shaft power (P_line = P_mech +
    # losses, ecam.sizing.infeed_power), the winding hot (the catalogue's 100 K rise); the
    # modules' own losses are not in the catalogue
    losses = 0.0
    if motor is not None and motor.winding_resistance > 0.0:
        losses = sizing.copper_loss(sizing.current_for_torque(duty.motor_torque, motor.current_points()),
                                    sizing.hot_winding_resistance(motor.winding_resistance))
    # without an infeed in the scene, all of the braking returned (the unrated figure)
    returns = (infeed.regenerative_power if infeed is not None
               else float(np.max(-duty.power, initial=0.0)))
    line = sizing.infeed_power(duty.power, returns, losses)
    rms = sizing.rms_torque(line)  # the RMS of any series: the infeed's current at its voltage
    worst = int(np.argmax(np.abs(line)))
    peak = float(abs(line[worst]))
    facts = {"rms_power": rms, "peak_power": peak}
    with_losses = (f"; the winding's copper losses in what is drawn, up to {float(np.max(losses)):.4g} W "
                   "(3 I^2 R at 100 K rise; left out of what braking returns, the safe side)"
                   if motor is not None and motor.winding_resistance > 0.0
                   else "; no winding resistance in [motor]: copper losses left out")
    if infeed is None:
        return check("infeed_power", rms, None, "W",
                     f"RMS of the power through the line over the cam cycle (peak {peak:.4g} W "
                     f"{_where(run, duty, worst)}){with_losses}; no infeed in [drive]: not rated"), facts
    detail = (f"RMS {rms:.4g} W over the cam cycle against the rated {infeed.rated_power:g} W, "
              f"peak {peak:.4g} W {_where(run, duty, worst)} against the peak "
              f"{infeed.peak_power:g} W ({infeed.kind}; the larger share counts; the DC "
              f"link's store left out, the safe side){with_losses}")
    if peak / infeed.peak_power > rms / infeed.rated_power:
        return check("infeed_power", peak, infeed.peak_power, "W", detail), facts
    return check("infeed_power", rms, infeed.rated_power, "W", detail), facts


def inertia_ratio_check(run: PreparedRun) -> Check:
    """Reflected load inertia over the motor side's, against ``limits.inertia_ratio``."""
    mech = run.mechanics
    ratio = mech.reflected_inertia() / mech.motor_inertia - 1.0
    return check("inertia_ratio", ratio, run.scene.limits.inertia_ratio, "",
                 "load (reflected) over motor-side inertia (rotor and gearhead input)")


def gearhead_torque_check(run: PreparedRun, duty: Duty) -> tuple[Check, dict]:
    """The gearhead's peak output torque against T2B at the duty's cycles per hour; the
    emergency-stop torque (the drive's clamp through the gear) in the detail."""
    gear = run.scene.sizing.gearhead
    torque = np.abs(duty.output_torque)
    worst = int(np.argmax(torque))
    cycles_per_hour = 3600.0 * run.cam_hz
    if gear is None or gear.acceleration_torque is None:
        return check("gearhead_torque", torque[worst], None, "N m",
                     f"{_where(run, duty, worst)}; no gearhead T2B: not rated"), {}
    limit, how = sizing.gearhead_cyclic_torque(gear.acceleration_torque, cycles_per_hour,
                                               gear.shock_factor)
    detail = f"{_where(run, duty, worst)}, against {how}"
    facts = {"peak_output_torque": float(torque[worst]), "cyclic_torque_limit": limit,
             "cycles_per_hour": cycles_per_hour}
    clamp = run.mechanics.motor_torque_limit
    if gear.emergency_stop_torque is not None and clamp is not None:
        stop = clamp * run.mechanics.gear_efficiency / run.mechanics.gear_ratio
        facts.update(emergency_torque=stop, emergency_torque_limit=gear.emergency_stop_torque)
        detail += (f"; emergency stop at the drive's {clamp:.4g} N m clamp puts {stop:.4g} N m "
                   f"on it, T2Not {gear.emergency_stop_torque:g} N m"
                   + ("" if stop <= gear.emergency_stop_torque else " (EXCEEDED)"))
    return check("gearhead_torque", torque[worst], limit, "N m", detail), facts


def _utilisation(check_: Check) -> float | None:
    return None if check_.ratio is None else 100.0 * check_.ratio


def sizing_checks(run: PreparedRun) -> tuple[list[Check], dict, dict]:
    """The sizing checks of a prepared run, the report's ``sizing`` summary and the series of
    the torque-speed plot.

    Returns
    -------
    (list of Check, dict, dict)
        The checks in :data:`NAMES` order; the summary (per component: what the cycle needs,
        what the part is rated for, the utilisation in percent); the series
        (``sizing_speed_rpm``, ``sizing_torque``: the cycle's operating points;
        ``sizing_curve_rpm``, ``sizing_s1_torque``, ``sizing_peak_torque``: the motor's curves,
        absent without a motor).
    """
    duty = duty_cycle(run)
    thermal, thermal_facts = motor_thermal_check(run, duty)
    speed_torque = motor_speed_torque_check(run, duty)
    speed = motor_speed_check(run, duty)
    currents, current_facts = drive_current_checks(run, duty)
    regeneration, regeneration_facts = regeneration_check(run, duty)
    infeed_check, infeed_facts = infeed_power_check(run, duty)
    inertia = inertia_ratio_check(run)
    gearhead, gearhead_facts = gearhead_torque_check(run, duty)
    checks = [thermal, speed_torque, speed, *currents, regeneration, infeed_check, inertia,
              gearhead]
    spec = run.scene.sizing
    motor, module, gear, infeed = spec.motor, spec.module, spec.gearhead, spec.infeed
    mech = run.mechanics

    def part(model, source, rows: dict, *verdicts: Check) -> dict:
        used = [u for u in (_utilisation(c) for c in verdicts) if u is not None]
        return {"model": model, "source": source, **rows,
                "utilisation_percent": max(used) if used else None}

    components = {
        "motor": part(motor.model if motor else None, motor.source if motor else None, {
            "required": {"rms_torque": thermal_facts["rms_torque"],
                         "thermal_torque": thermal.value,
                         "mean_speed_rpm": thermal_facts["mean_speed_rpm"],
                         "peak_torque": float(np.max(np.abs(duty.motor_torque))),
                         "max_speed_rpm": speed.value},
            "rated": {"s1_torque_at_mean_speed": thermal.limit,
                      "stall_torque": motor.stall_torque if motor else None,
                      "max_torque": motor.max_torque if motor else None,
                      "max_speed_rpm": motor.max_speed_rpm if motor else None}},
            thermal, speed_torque, speed),
        "module": part(module.model if module else None, module.source if module else None, {
            "required": {"rms_current": current_facts.get("rms_current"),
                         "peak_current": current_facts.get("peak_current")},
            "rated": {"rated_current": module.rated_current if module else None,
                      "peak_current": module.peak_current if module else None}},
            *currents),
        "gearhead": part(gear.model if gear else None, gear.source if gear else None, {
            "required": {"peak_output_torque": gearhead.value,
                         "emergency_torque": gearhead_facts.get("emergency_torque"),
                         "max_input_speed_rpm": speed.value},
            "rated": {"cyclic_torque": gearhead.limit,
                      "emergency_torque": gear.emergency_stop_torque if gear else None,
                      "max_input_speed_rpm": gear.max_input_speed_rpm if gear else None,
                      "cycles_per_hour": gearhead_facts.get("cycles_per_hour")}},
            gearhead),
        "coupling": {"model": None, "source": None,
                     "rated": {"rated_torque": mech.coupling_rated_torque,
                               "max_torque": mech.coupling_max_torque},
                     "utilisation_percent": None},  # filled from the coupling checks
        "infeed": part(infeed.model if infeed else None, infeed.source if infeed else None, {
            "required": {"rms_power": infeed_facts["rms_power"],
                         "peak_power": infeed_facts["peak_power"],
                         "energy_to_line_per_cycle":
                             regeneration_facts["energy_to_line_per_cycle"] if infeed else None},
            "rated": {"kind": infeed.kind if infeed else None,
                      "rated_power": infeed.rated_power if infeed else None,
                      "peak_power": infeed.peak_power if infeed else None}},
            infeed_check),
        "brake_resistor": part(None, None, {
            "required": {"largest_stored_energy": regeneration_facts["largest_stored_energy"],
                         "energy_returned_per_cycle":
                             regeneration_facts["energy_returned_per_cycle"],
                         "peak_braking_power": regeneration_facts["peak_braking_power"]},
            "rated": {"dc_link_energy": regeneration_facts["dc_link_energy"],
                      "brake_resistor_power": regeneration_facts["brake_resistor_power"]}},
            regeneration),
    }
    summary = {"applicable": spec.given, "duty": "one cam period at the cruise speed",
               "components": components,
               "inertia_ratio": {"value": inertia.value, "limit": inertia.limit}}
    series = {"sizing_speed_rpm": duty.speed_rpm * np.sign(duty.motor_speed),
              "sizing_torque": duty.motor_torque}
    if motor is not None:
        fastest = float(np.max(duty.speed_rpm))
        # without a catalogue maximum speed the curves run to the no-load speed of the voltage
        # limit (where the peak curve reaches 0), else to 1.5 x the duty's fastest sample
        if motor.max_speed_rpm is not None:
            top = max(motor.max_speed_rpm, fastest)
        elif module is not None and module.dc_bus_voltage is not None:
            top = max(sizing.VoltageLimit(motor.torque_constant, motor.voltage_constant,
                                          motor.winding_resistance, module.dc_bus_voltage,
                                          motor.inductance, motor.pole_pairs).no_load_speed()
                      / sizing.RPM, fastest)
        else:
            top = 1.5 * fastest
        rpm = np.linspace(0.0, top, CURVE_POINTS)
        series.update(sizing_curve_rpm=rpm,
                      sizing_s1_torque=sizing.s1_torque(rpm, motor.s1_points()),
                      sizing_peak_torque=available_torque(run, rpm * sizing.RPM))
    return checks, summary, series


def fill_coupling(summary: dict, checks: list[Check]) -> None:
    """The coupling's row of the sizing summary from the report's coupling checks."""
    by_name = {c.name: c for c in checks}
    rms, peak = by_name.get("coupling_rms_torque"), by_name.get("coupling_peak_torque")
    row = summary["components"]["coupling"]
    row["required"] = {"rms_torque": rms.value if rms else None,
                       "peak_torque": peak.value if peak else None}
    used = [u for u in (_utilisation(c) for c in (rms, peak) if c is not None) if u is not None]
    row["utilisation_percent"] = max(used) if used else None
