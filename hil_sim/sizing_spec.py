"""The drive train a scene sizes: its motor (``[motor]``), its drive module and its infeed (the
sizing fields of ``[drive]``) and its gearhead (the ``gearhead*`` fields of ``[mechanics]``),
read from the scene or from the catalogue file (:data:`CATALOGUE`, ``model`` / ``module`` /
``line_module`` / ``gearhead`` naming an entry; the scene's own fields override the entry's).

What they change in the machine (:meth:`SizingSpec.fold`): the gearhead's input inertia is added
to the motor side, its torsional stiffness and the motor shaft's are put in series with the
coupling (so the plant, the two-mass model and the tuner see the combined spring, as
:func:`ecam.sizing.two_mass_frequency_with_gearhead` has it), and the drive's torque clamp
follows from the motor and the module (peak current through the motor's torque-current curve,
capped by the motor's maximum torque) unless the scene gives ``motor_torque_limit``. The voltage
limit at speed is the clamp's speed-dependent part (:meth:`SizingSpec.voltage_limit`, applied
by the drive's controller, ``hil_sim.control.DriveEffects.voltage_limit``), again unless the
scene gives ``motor_torque_limit``.

Layout (units: SI, rpm where the name says so)::

    [motor]
    model = "1FT7044-AK7"          # a catalogue entry (optional); the fields below override it
    stall_torque = 5.0             # M0 [N m]
    rated_torque = 2.0             # a point of the S1 curve [N m] ... (optional, with
    rated_speed_rpm = 6000.0       # ... at this speed [rpm]          rated_speed_rpm)
    max_torque = 23.0              # [N m]
    max_speed_rpm = 9000.0         # optional
    torque_constant = 0.88         # kT [N m/A]
    voltage_constant = 0.5443      # kE [V s/rad], line-to-line rms
    winding_resistance = 0.61      # [ohm], phase; optional (0)
    inductance = 4.2e-3            # [H]; optional (0)
    pole_pairs = 3                 # optional (1)
    thermal_time_constant_s = 2100.0
    rotor_inertia = 5.43e-4        # [kg m^2]: mechanics.motor_inertia when that is not given
    shaft_stiffness = 9500.0       # [N m/rad]; optional
    torque_current_points = [[0, 0], [5.7, 5.0], [18, 15], [30, 23]]  # optional [A, N m]

    [drive]                        # besides the control fields
    module = "6SL3120-1TE21-0AA"   # a catalogue entry (optional)
    rated_current = 9.0            # [A]
    peak_current = 18.0            # [A]
    dc_bus_voltage = 600.0         # [V]
    dc_link_capacitance = 1.1e-4   # [F]; optional
    brake_chopper_voltage = 774.0  # [V]; optional
    brake_resistor_power = 0.0     # [W]; 0 = none
    line_module = "6SL3130-7TE21-6AA4"  # the infeed, a catalogue entry (optional)
    infeed = "regenerative"        # or "rectifier" (returns no braking energy to the line)
    infeed_power = 16000.0         # [W] rated power P_n (drawn or returned)
    infeed_peak_power = 16000.0    # [W] optional (default infeed_power)

    [mechanics]                    # besides the mechanics fields
    gearhead = "SP075-MF1-5"       # a catalogue entry (optional)
    gearhead_stiffness = 34377.0   # [N m/rad] at the output
    gearhead_input_inertia = 0.68e-4
    gearhead_idle_torque = 0.96    # T012 [N m] at the input: the motor friction's default
    gearhead_acceleration_torque = 132.0   # T2B [N m]
    gearhead_emergency_torque = 250.0      # T2Not [N m]
    gearhead_max_input_speed_rpm = 7500.0
    gearhead_shock_factor = 1.0    # f_s above 1000 cycles/h, from the catalogue's curve
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields
from pathlib import Path

from ecam.errors import CamFileError
from ecam.sizing import VoltageLimit, series_stiffness, stiffness_at_output, torque_for_current
from ecam.validate import Fields, show

#: The catalogue of motors, modules and gearheads a scene can name (package data).
CATALOGUE = Path(__file__).with_name("catalogue.toml")


@dataclass(frozen=True)
class MotorData:
    """A servo motor's catalogue data (SI; see the module docstring for each field)."""

    stall_torque: float
    max_torque: float
    torque_constant: float
    voltage_constant: float
    thermal_time_constant_s: float
    rotor_inertia: float
    rated_torque: float | None = None
    rated_speed_rpm: float | None = None
    max_speed_rpm: float | None = None
    winding_resistance: float = 0.0
    inductance: float = 0.0
    pole_pairs: int = 1
    shaft_stiffness: float | None = None
    torque_current_points: tuple = ()
    model: str = ""
    source: str = ""

    def s1_points(self) -> list[tuple[float, float]]:
        """The S1 curve's catalogue points: (0, M0) and (n_N, M_N) [rpm, N m]; only (0, M0)
        where the catalogue gives no rated point (M0 at every speed: on the unsafe side, the
        S1 curve of a real motor falls with the speed, and the thermal check says so)."""
        if self.rated_torque is None:
            return [(0.0, self.stall_torque)]
        return [(0.0, self.stall_torque), (self.rated_speed_rpm, self.rated_torque)]

    def current_points(self) -> list[tuple[float, float]]:
        """(current, torque) points: the catalogue's, else the line through kT."""
        if self.torque_current_points:
            return [tuple(p) for p in self.torque_current_points]
        return [(0.0, 0.0), (1.0, self.torque_constant)]


@dataclass(frozen=True)
class ModuleData:
    """A drive (motor) module: currents [A rms], DC link [V, F] and brake resistor [W]."""

    rated_current: float | None = None
    peak_current: float | None = None
    dc_bus_voltage: float | None = None
    dc_link_capacitance: float | None = None
    brake_chopper_voltage: float | None = None
    brake_resistor_power: float = 0.0
    model: str = ""
    source: str = ""


#: The kinds of infeed: one that returns braking energy to the line (an Active Line Module),
#: and a rectifier (a diode or a thyristor bridge, a Basic Line Module) that returns none.
INFEEDS = ("regenerative", "rectifier")


@dataclass(frozen=True)
class InfeedData:
    """The drive line-up's infeed (line module): its kind (:data:`INFEEDS`) and its rated and
    peak power [W], drawn from the line or, where it regenerates, returned to it."""

    kind: str
    rated_power: float
    peak_power: float
    model: str = ""
    source: str = ""

    @property
    def regenerative_power(self) -> float:
        """The most power it returns to the line at any instant [W] (0: a rectifier)."""
        return self.peak_power if self.kind == "regenerative" else 0.0


@dataclass(frozen=True)
class GearheadData:
    """A gearhead's catalogue data (stiffness at the output, inertia and idle torque at the
    input, torques at the output)."""

    torsional_stiffness: float | None = None
    input_inertia: float = 0.0
    idle_torque: float | None = None
    acceleration_torque: float | None = None
    emergency_stop_torque: float | None = None
    max_input_speed_rpm: float | None = None
    shock_factor: float | None = None
    ratio: float | None = None
    efficiency: float | None = None
    model: str = ""
    source: str = ""


@dataclass(frozen=True)
class SizingSpec:
    """The drive train of a scene (each part None when the scene has none)."""

    motor: MotorData | None = None
    module: ModuleData | None = None
    gearhead: GearheadData | None = None
    infeed: InfeedData | None = None
    #: True when the scene gives ``mechanics.motor_torque_limit``: its clamp, not the drive
    #: train's (no voltage limit in the drive's clamp then)
    scene_clamp: bool = False

    @property
    def given(self) -> bool:
        """True when the scene names a motor, a module, a gearhead or an infeed."""
        return any(part is not None
                   for part in (self.motor, self.module, self.gearhead, self.infeed))

    def torque_clamp(self) -> float | None:
        """The drive's torque limit from the motor and the module [N m]: the torque at the
        module's peak current, capped by the motor's maximum; None without a motor."""
        if self.motor is None:
            return None
        limit = self.motor.max_torque
        if self.module is not None and self.module.peak_current is not None:
            limit = min(limit, torque_for_current(self.module.peak_current,
                                                  self.motor.current_points()))
        return limit

    def voltage_limit(self) -> VoltageLimit | None:
        """The speed-dependent part of the drive's torque clamp: the motor's voltage limit on
        the module's DC link (:class:`ecam.sizing.VoltageLimit`); None without a motor, without
        a DC-link voltage, or when the scene gives its own ``motor_torque_limit``."""
        motor, module = self.motor, self.module
        if (motor is None or module is None or module.dc_bus_voltage is None
                or self.scene_clamp):
            return None
        return VoltageLimit(motor.torque_constant, motor.voltage_constant,
                            motor.winding_resistance, module.dc_bus_voltage,
                            motor.inductance, motor.pole_pairs)

    def fold(self, values: dict) -> dict:
        """The :class:`ecam.mechanics.Mechanics` fields with the drive train in: the rotor and
        the gearhead's input inertia on the motor side, the motor shaft and the gearhead in
        series with the coupling (only on an axis with a spring: a rigid one stays rigid), the
        torque clamp. ``values``: the scene's fields."""
        out = dict(values)
        gear = self.gearhead
        if gear is not None:
            if gear.ratio is not None:
                out.setdefault("gear_ratio", gear.ratio)
            if gear.efficiency is not None:
                out.setdefault("gear_efficiency", gear.efficiency)
        if "motor_inertia" not in out and self.motor is not None:
            out["motor_inertia"] = self.motor.rotor_inertia
        if gear is not None and gear.input_inertia:
            out["motor_inertia"] = out["motor_inertia"] + gear.input_inertia
        springs = [out.get("coupling_stiffness"), gear.torsional_stiffness if gear else None]
        if any(k is not None for k in springs):
            shaft = self.motor.shaft_stiffness if self.motor is not None else None
            ratio = out.get("gear_ratio", 1.0)
            if shaft is not None:
                springs.append(stiffness_at_output(shaft, ratio))
            if sum(k is not None for k in springs) > 1:  # the coupling alone stays as given
                out["coupling_stiffness"] = series_stiffness(*springs)
        if "motor_torque_limit" not in out:
            clamp = self.torque_clamp()
            if clamp is not None:
                out["motor_torque_limit"] = clamp
        return out


MOTOR_FIELDS = tuple(f.name for f in fields(MotorData) if f.name not in ("model", "source"))
MODULE_FIELDS = tuple(f.name for f in fields(ModuleData) if f.name not in ("model", "source"))
#: The [drive] keys of the infeed (its catalogue entry and the InfeedData fields).
INFEED_KEYS = ("line_module", "infeed", "infeed_power", "infeed_peak_power")
#: The [drive] keys of the module and the infeed (besides the drive's control fields).
DRIVE_SIZING_KEYS = ("module", *MODULE_FIELDS, *INFEED_KEYS)
_GEARHEAD_KEYS = {"gearhead_stiffness": "torsional_stiffness",
                  "gearhead_input_inertia": "input_inertia",
                  "gearhead_idle_torque": "idle_torque",
                  "gearhead_acceleration_torque": "acceleration_torque",
                  "gearhead_emergency_torque": "emergency_stop_torque",
                  "gearhead_max_input_speed_rpm": "max_input_speed_rpm",
                  "gearhead_shock_factor": "shock_factor"}
#: The [mechanics] keys of the gearhead (besides the mechanics fields).
GEARHEAD_KEYS = ("gearhead", *_GEARHEAD_KEYS)
# rated_torque with rated_speed_rpm (the S1 point) and max_speed_rpm are optional: a catalogue
# that does not give them (hil_sim/catalogue.toml says which) leaves them out
_REQUIRED_MOTOR = ("stall_torque", "max_torque", "torque_constant", "voltage_constant",
                   "thermal_time_constant_s", "rotor_inertia")
# Physical ranges [SI]: a watch motor to a press; the lower bounds of what divides are > 0.
_MAX = {"stall_torque": 1e6, "rated_torque": 1e6, "rated_speed_rpm": 1e6, "max_torque": 1e6,
        "max_speed_rpm": 1e6, "torque_constant": 1e4, "voltage_constant": 1e4,
        "thermal_time_constant_s": 1e7, "rotor_inertia": 1e4, "winding_resistance": 1e4,
        "inductance": 1e2, "shaft_stiffness": 1e12, "rated_current": 1e5, "peak_current": 1e5,
        "dc_bus_voltage": 1e5, "dc_link_capacitance": 1e3, "brake_chopper_voltage": 1e5,
        "brake_resistor_power": 1e8, "torsional_stiffness": 1e12, "input_inertia": 1e4,
        "idle_torque": 1e6, "acceleration_torque": 1e8, "emergency_stop_torque": 1e8,
        "max_input_speed_rpm": 1e6, "shock_factor": 100.0, "infeed_power": 1e8,
        "infeed_peak_power": 1e8}
_MAY_BE_ZERO = {"winding_resistance", "inductance", "brake_resistor_power", "input_inertia",
                "idle_torque"}

_catalogue_cache: dict | None = None


def catalogue() -> dict:
    """The catalogue file, parsed (``motor``, ``module``, ``gearhead``, ``line_module`` tables by
    name)."""
    global _catalogue_cache
    if _catalogue_cache is None:
        with CATALOGUE.open("rb") as file:
            _catalogue_cache = tomllib.load(file)
    return _catalogue_cache


def _entry(raw: Fields, key: str, kind: str) -> dict:
    """The catalogue entry a scene names with ``key`` ({} when it names none)."""
    if key not in raw:
        return {}
    name = raw.text(key)
    entries = catalogue().get(kind, {})
    if name not in entries:
        raise raw.error(f"{raw.name(key)}: {show(name)} is not in the catalogue; expected one "
                        f"of {', '.join(sorted(entries))}")
    return dict(entries[name], model=name)


#: Lower bounds other than 0 (inclusive): a shock factor never lowers the load.
_MIN = {"shock_factor": 1.0}


def _number(raw: Fields, key: str, value, name: str):
    """A field's number, checked against its range (the scene's key named in messages)."""
    probe = Fields({key: value}, raw.where, raw.source)
    if name in _MIN:
        return probe.number(key, minimum=_MIN[name], maximum=_MAX[name])
    return probe.number(key, minimum=0.0, maximum=_MAX[name],
                        strict=name not in _MAY_BE_ZERO)


def _motor(top: Fields) -> MotorData | None:
    if "motor" not in top:
        return None
    raw = top.table("motor", {"model", *MOTOR_FIELDS})
    entry = _entry(raw, "model", "motor")
    values = {}
    for name in MOTOR_FIELDS:
        given = raw.raw.get(name, entry.get(name))
        if given is None:
            continue
        if name == "pole_pairs":
            values[name] = Fields({name: given}, raw.where, raw.source).integer(
                name, minimum=1, maximum=1000)
        elif name == "torque_current_points":
            values[name] = _points(raw, name, given)
        else:
            values[name] = _number(raw, name, given, name)
    missing = [name for name in _REQUIRED_MOTOR if name not in values]
    if missing:
        raise raw.error(f"motor: {', '.join(missing)} missing; expected in [motor] or from its "
                        "catalogue model")
    if ("rated_torque" in values) != ("rated_speed_rpm" in values):
        given, other = (("rated_torque", "rated_speed_rpm") if "rated_torque" in values
                        else ("rated_speed_rpm", "rated_torque"))
        raise raw.error(f"{raw.name(other)}: missing should be given with {given} (the S1 "
                        "curve's point)")
    if values.get("rated_torque", 0.0) > values["stall_torque"]:
        raise raw.error(f"{raw.name('rated_torque')}: {show(values['rated_torque'])} should be <= "
                        f"stall_torque {show(values['stall_torque'])}")
    if values["max_torque"] < values["stall_torque"]:
        raise raw.error(f"{raw.name('max_torque')}: {show(values['max_torque'])} should be >= "
                        f"stall_torque {show(values['stall_torque'])}")
    return MotorData(**values, model=entry.get("model", ""), source=entry.get("source", ""))


def _points(raw: Fields, name: str, value) -> tuple:
    expected = "[[current, torque], ...] from [0, 0], both increasing"
    if (not isinstance(value, list) or len(value) < 2
            or not all(isinstance(p, list) and len(p) == 2 for p in value)):
        raise raw.error(f"{raw.name(name)}: {show(value)} should be {expected}")
    points = []
    for i, (current, torque) in enumerate(value):
        pair = Fields({"current": current, "torque": torque}, f"{raw.name(name)}[{i}]", raw.source)
        points.append((pair.number("current", minimum=0.0, maximum=1e5),
                       pair.number("torque", minimum=0.0, maximum=1e6)))
    if (points[0] != (0.0, 0.0) or any(b[0] <= a[0] or b[1] <= a[1]
                                       for a, b in zip(points, points[1:]))):
        raise raw.error(f"{raw.name(name)}: {show(value)} should be {expected}")
    return tuple(points)


def _infeed(drive: Fields) -> InfeedData | None:
    if not any(key in drive for key in INFEED_KEYS):
        return None
    entry = _entry(drive, "line_module", "line_module")
    kind = drive.raw.get("infeed", entry.get("infeed"))
    if kind is None:
        raise drive.error(f"{drive.name('infeed')}: missing should be one of "
                          f"{', '.join(INFEEDS)} (with infeed_power)")
    kind = Fields({"infeed": kind}, drive.where, drive.source).choice("infeed", INFEEDS)
    values = {}
    for name in ("infeed_power", "infeed_peak_power"):
        given = drive.raw.get(name, entry.get(name))
        if given is not None:
            values[name] = _number(drive, name, given, name)
    if "infeed_power" not in values:
        raise drive.error(f"{drive.name('infeed_power')}: missing should be given with infeed "
                          f"{kind!r} (the infeed's rated power, W)")
    rated = values["infeed_power"]
    peak = values.get("infeed_peak_power", rated)
    if peak < rated:
        raise drive.error(f"{drive.name('infeed_peak_power')}: {show(peak)} should be >= "
                          f"infeed_power {show(rated)}")
    return InfeedData(kind, rated, peak, model=entry.get("model", ""),
                      source=entry.get("source", ""))


def _module(drive: Fields) -> ModuleData | None:
    if not any(key in drive for key in ("module", *MODULE_FIELDS)):
        return None
    entry = _entry(drive, "module", "module")
    values = {}
    for name in MODULE_FIELDS:
        given = drive.raw.get(name, entry.get(name))
        if given is not None:
            values[name] = _number(drive, name, given, name)
    rated, peak = values.get("rated_current"), values.get("peak_current")
    if rated is not None and peak is not None and peak < rated:
        raise drive.error(f"{drive.name('peak_current')}: {show(peak)} should be >= rated_current "
                          f"{show(rated)}")
    bus, chopper = values.get("dc_bus_voltage"), values.get("brake_chopper_voltage")
    if bus is not None and chopper is not None and chopper <= bus:
        raise drive.error(f"{drive.name('brake_chopper_voltage')}: {show(chopper)} should be > "
                          f"dc_bus_voltage {show(bus)}")
    return ModuleData(**values, model=entry.get("model", ""), source=entry.get("source", ""))


def _gearhead(mechanics: Fields) -> GearheadData | None:
    if not any(key in mechanics for key in GEARHEAD_KEYS):
        return None
    entry = _entry(mechanics, "gearhead", "gearhead")
    values = {}
    for key, name in _GEARHEAD_KEYS.items():
        given = mechanics.raw.get(key, entry.get(name))
        if given is not None:
            values[name] = _number(mechanics, key, given, name)
    if entry:
        ratio = 1.0 / entry["ratio"]
        scene_ratio = mechanics.raw.get("gear_ratio")
        if scene_ratio is not None and not math.isclose(scene_ratio, ratio, rel_tol=1e-9):
            raise mechanics.error(f"{mechanics.name('gear_ratio')}: {show(scene_ratio)} should be "
                                  f"{ratio:g}, the ratio of gearhead {entry['model']!r} "
                                  f"(i = {entry['ratio']:g})")
        values["ratio"], values["efficiency"] = ratio, entry.get("efficiency")
    return GearheadData(**values, model=entry.get("model", ""), source=entry.get("source", ""))


def parse_sizing(top: Fields) -> SizingSpec:
    """The drive train of a scene (its ``[motor]``, and the sizing fields of ``[drive]`` (module
    and infeed) and ``[mechanics]``, whose other keys the scene reader checks).

    Raises
    ------
    CamFileError
        A field out of range, a catalogue name that is not in the catalogue, a gear ratio
        that is not the named gearhead's; one line naming the field.
    """
    try:
        mechanics = top.table("mechanics")
        drive = top.table("drive")
        return SizingSpec(motor=_motor(top), module=_module(drive),
                          gearhead=_gearhead(mechanics), infeed=_infeed(drive),
                          scene_clamp="motor_torque_limit" in mechanics)
    except (OSError, tomllib.TOMLDecodeError) as exc:  # the catalogue itself, not the scene
        raise CamFileError(f"catalogue {CATALOGUE.name}: {exc}") from None
