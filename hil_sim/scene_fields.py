"""Every field of a scene file (TOML), as :func:`hil_sim.scene.parse_scene` reads it: the table the
reference page is generated from (see :mod:`ecam.field_table`; ``tests/test_field_tables.py``
holds it to the parser: a field the parser accepts without a row here fails that test, and so
does a row whose limits the parser does not enforce).

To add a field: add its row here, in its table's place, with the unit, the default and where
that default comes from.
"""

from __future__ import annotations

from ecam.cam_fields import CAM_FIELDS
from ecam.field_table import REQUIRED, Field
from ecam.table import INTERPOLATIONS, MAX_MASTER_COUNTS
from ecam.table_spec import MAX_COUNTS_PER_UNIT, MAX_POINTS, MIN_COUNTS_PER_UNIT
from hil_sim.control import FEEDFORWARD_SOURCES, MODELS
from hil_sim.effects import (DEFAULT_BACKLASH_ARCMIN, DEFAULT_CURRENT_LOOP_HZ, DEFAULT_ENCODER_COUNTS,
                             DEFAULT_LOAD_FRICTION_SHARE, DEFAULT_MOTOR_FRICTION_SHARE, FIDELITIES,
                             VELOCITY_FILTER_SHARE)
from hil_sim.event_spec import (ACTIONS, ACTIVATIONS, MAX_EVENT_POSITION, MAX_EVENTS, SCALING_RANGE,
                                START_MODES)
from hil_sim.faults import FRAME_KINDS, MAX_SYNC_JITTER_S
from hil_sim.sync_schedule import MASTER_POSITION_PDOS, MAX_SYNC_COUNTER_OVERFLOW, MAX_TRANSMISSION_TYPE
from hil_sim.sizing_spec import INFEEDS
from hil_sim.scene import (CAM_MODES, EFFECT_RANGES, MAX_BANDWIDTH_HZ, MAX_CYCLES, MAX_LEAD_CYCLES,
                           MAX_MASTER_SPEED, MAX_SETTLE_S, MECHANICS_MINIMA, MECHANICS_RANGES, MIN_LOAD_INERTIA,
                           MIN_MASTER_SPEED, PROFILES, SLAVE_UNITS_PER_RADIAN_RANGE)

__all__ = ["SCENE_FIELDS", "SCENE_TABLES"]

_PARSER = "hil_sim.scene"
_EFFECTS = "hil_sim.effects (the catalogue sources are cited there)"
_START_STOP = (("master.profile", "start_stop"), ("master.max_acceleration", 1000.0),
               ("master.max_jerk", 1e5))
_CAM_IN = (("master.profile", "cam_in"), ("master.engage_at", 0.0), ("master.max_velocity", 1.0),
           ("master.slave_max_acceleration", 10.0), ("master.slave_max_jerk", 1000.0))
_NOT_SPEED = (("master.speed", None),)
_EVENTS = "hil_sim.events"
_AT = (("event.at_s", None),)
_SWITCH = (("event.action", "switch"), ("event.cam", "combination_drrd.toml"))
_PHASE = (("event.action", "phase"), ("event.shift", 1.0), ("event.max_velocity", 1.0),
          ("event.max_acceleration", 1.0), ("event.max_jerk", 1.0))
_EVENT_FIELDS = (
    Field("event", "name", "string", "A name for the report.", default="", source=_EVENTS),
    Field("event", "action", "choice", "switch: a new cam; offset: the running cam with new offsets "
          "and scaling; phase: a jerk-limited shift of the master the slave sees; cam_out: the "
          "slave leaves the cam to a jerk-limited stop.", default=REQUIRED, choices=ACTIONS,
          source=_EVENTS),
    Field("event", "at_period", "integer", "When: at the start of this master period of the "
          "scene's cam (master position N x period).", unit="periods",
          default_text="give exactly one of at_period, at_position, at_s", minimum=0, maximum=2**31,
          when=_AT, source=_EVENTS),
    Field("event", "at_position", "number", "When: as the master axis reaches this position.",
          unit="master units", default_text="give exactly one of at_period, at_position, at_s",
          minimum=-MAX_EVENT_POSITION, maximum=MAX_EVENT_POSITION, when=_AT, source=_EVENTS),
    Field("event", "at_s", "number", "When: at this time of the run.", unit="s",
          default_text="give exactly one of at_period, at_position, at_s", minimum=0.0, maximum=1e6,
          source=_EVENTS),
    Field("event", "cam", "string", "switch: the new cam file, relative to the scene (or a built-in "
          "cam's name); same units as the scene's cam.", default=REQUIRED, when=_SWITCH,
          source=_EVENTS),
    Field("event", "activation", "choice", "switch, offset: when it takes effect: at once, at the "
          "running cam's period end (CODESYS: the new cam placed at the end of the previous one) or "
          "when the master reaches activation_position (TwinCAT MC_CamActivationMode).",
          default="period_end", choices=ACTIVATIONS, source=_EVENTS),
    Field("event", "activation_position", "number", "activation master_position: the master "
          "position (as the slave sees it) where it takes effect; cam_mode drive: within INTEGER64 "
          "master counts (0x2001:06).", unit="master units",
          default=REQUIRED, minimum=-MAX_EVENT_POSITION, maximum=MAX_EVENT_POSITION,
          when=(("event.activation", "master_position"),), source=_EVENTS),
    Field("event", "master", "choice", "switch, offset: the cam's master coordinate: absolute, or "
          "relative to the master at the activation (PLCopen MasterAbsolute; ecam.cam_join).",
          default="absolute", choices=("absolute", "relative"), source=_EVENTS),
    Field("event", "slave", "choice", "switch, offset: absolute, or relative: the slave's position "
          "at the activation is added (PLCopen SlaveAbsolute, MC_CamIn StartMode).",
          default="absolute", choices=("absolute", "relative"), source=_EVENTS),
    Field("event", "master_offset", "number", "switch, offset: MC_CamIn MasterOffset: the cam is "
          "evaluated at X = master_scaling x master + master_offset; cam_mode drive: within INTEGER64 "
          "master counts (0x2001:07).", unit="master units",
          default=0.0, minimum=-MAX_EVENT_POSITION, maximum=MAX_EVENT_POSITION, source=_EVENTS),
    Field("event", "slave_offset", "number", "switch, offset: MC_CamIn SlaveOffset, added to the "
          "slave; cam_mode drive: within INTEGER32 slave counts (0x2001:08).", unit="slave units", default=0.0, minimum=-MAX_EVENT_POSITION,
          maximum=MAX_EVENT_POSITION, source=_EVENTS),
    Field("event", "master_scaling", "number", "switch, offset: MC_CamIn MasterScaling.", default=1.0,
          minimum=SCALING_RANGE[0], maximum=SCALING_RANGE[1], source=_EVENTS),
    Field("event", "slave_scaling", "number", "switch, offset: MC_CamIn SlaveScaling.", default=1.0,
          minimum=SCALING_RANGE[0], maximum=SCALING_RANGE[1], source=_EVENTS),
    Field("event", "allow_jump", "boolean", "switch, offset: a jump at the activation is reported but "
          "does not fail the switch_jumps check.", default=False, source=_EVENTS),
    Field("event", "start_mode", "choice", "switch, offset: MC_CamIn StartMode: direct, the slave takes "
          "the new cam at once (a jump where it is elsewhere); ramp_in, a correction from the jump to 0 "
          "within max_velocity, max_acceleration, max_jerk (CODESYS VelocityDiff, Acceleration/"
          "Deceleration, Jerk; hil_sim.ramp_in). Controller-side only.", default="direct",
          choices=START_MODES, source="hil_sim.ramp_in"),
    Field("event", "shift", "number", "phase: the shift of the master the slave sees (MC_Phasing "
          "PhaseShift), added to the running one.", unit="master units", default=REQUIRED,
          minimum=-MAX_EVENT_POSITION, maximum=MAX_EVENT_POSITION, when=_PHASE, source=_EVENTS),
    *(Field("event", key, "number", f"phase, cam_out, start_mode ramp_in: the {what} limit of the "
            f"phase shift (master units), of the slave's stop or of the ramp_in correction (slave "
            f"units).", unit=f"units/s{power}", default=REQUIRED,
            minimum=0.0, exclusive_minimum=True, maximum=1e15, when=_PHASE, source=_EVENTS)
      for key, what, power in (("max_velocity", "velocity", ""), ("max_acceleration", "acceleration", "^2"),
                               ("max_jerk", "jerk", "^3"))),
)

#: The tables of a scene file and what each holds, in the reference's order.
SCENE_TABLES = {
    "": "The scene: its name, where the cam runs and how much the rig models.",
    "master": "How the master axis moves.",
    "cam": "The cam file and the table the rig compiles from it (the cam file's own `[table]` "
           "fills in what is not given).",
    "drive": "The virtual CiA 402 drive: node, cycle, control loop and the drive's effects.",
    "drive.gains": "The cascade's gains, auto-tuned when left out: bandwidths (the gains from the mechanics) "
                   "and/or raw gains, which win.",
    "mechanics": "Motor, gear, coupling and load (ecam.Mechanics), SI units, and the mechanical "
                 "effects.",
    "bus": "The CAN bus.",
    "bus.faults": "Faults injected on the bus, from a seeded generator (hil_sim.faults.Faults).",
    "motor": "The servo motor, for the sizing checks (hil_sim.sizing_spec): a catalogue name "
             "(hil_sim/catalogue.toml) and/or its fields, SI units, rpm where the name says so.",
    "limits": "The limits of the report's checks.",
    "duration": "How long to run: exactly one of these.",
    "event": "One `[[event]]` per change while the machine runs (hil_sim.events, docs/cam_changes.md): a "
             "cam switched (PLCopen MC_CamTableSelect/MC_CamIn), offsets and scaling changed, a phase "
             "shift (MC_Phasing) or the cam left (MC_CamOut); each at exactly one of at_period, "
             "at_position, at_s.",
    "tappet": "One `[[tappet]]` per digital cam switch on the master (ecam.tappet, as in a cam file); "
              "the rig checks every edge against the programmed position (hil_sim.tappet_edges).",
}

_MECHANICS_TEXT = {
    "motor_inertia": ("Rotor inertia plus everything turning at motor speed; the gearhead's "
                      "input inertia is added to it.", "kg m^2", REQUIRED,
                      "required unless [motor] gives rotor_inertia"),
    "gear_ratio": ("r = load speed / motor speed; 0.1 is a 10:1 reduction.", "", 1.0, ""),
    "gear_efficiency": ("The gear's efficiency eta.", "", 1.0, ""),
    "motor_damping": ("Viscous damping on the motor side.", "N m s/rad", 0.0, ""),
    "load_damping": ("Viscous damping on the load side.", "N m s/rad", 0.0, ""),
    "coupling_stiffness": ("Torsional stiffness of the coupling between gear output and load; "
                           "absent: a rigid connection.", "N m/rad", None, "rigid"),
    "coupling_damping": ("Viscous damping across the coupling.", "N m s/rad", 0.0, ""),
    "load_inertia": ("Load inertia on the output side.", "kg m^2", 0.0, ""),
    "coupling_rated_torque": ("The coupling's rated (continuous) torque.", "N m", None, "unrated"),
    "coupling_max_torque": ("The coupling's maximum (peak) torque.", "N m", None, "unrated"),
    "motor_torque_limit": ("The peak torque the drive may command.", "N m", None, "no limit"),
}
_POSITIVE = {"coupling_stiffness", "coupling_rated_torque", "coupling_max_torque", "motor_torque_limit"}
_MECHANICS_LIMITS = {
    "load_inertia": f"0 or >= {MIN_LOAD_INERTIA:g}; > 0 when coupling_stiffness is given",
    "coupling_max_torque": ">= coupling_rated_torque",
    "gear_efficiency": "",
}


def _mechanics() -> list[Field]:
    rows = []
    for key, (text, unit, default, default_text) in _MECHANICS_TEXT.items():
        minimum = MECHANICS_MINIMA.get(key, 0.0)
        rows.append(Field("mechanics", key, "number", text, unit=unit, default=default,
                          default_text=default_text, source="ecam.mechanics (Mechanics)",
                          minimum=minimum, maximum=MECHANICS_RANGES[key],
                          exclusive_minimum=key in _POSITIVE and key not in MECHANICS_MINIMA, limits=_MECHANICS_LIMITS.get(key, "")))
    return rows


_SIZING = "hil_sim.sizing_spec (catalogue values: hil_sim/catalogue.toml, each with its source)"
_CATALOGUE = "the catalogue entry named, else none"


def _sizing(table: str, key: str, text: str, unit: str = "", *, zero: bool = False,
            maximum: float, minimum: float = 0.0, default_text: str = _CATALOGUE,
            limits: str = "", probe: bool = True, when=()) -> Field:
    return Field(table, key, "number", text, unit=unit, default_text=default_text,
                 minimum=minimum, maximum=maximum, exclusive_minimum=not zero and minimum == 0.0,
                 limits=limits, probe=probe, when=when, source=_SIZING)


_MODEL = (("motor.model", "1FT7044-AK7"),)
_SIZING_FIELDS = (
    Field("motor", "model", "string", "A motor of the catalogue (hil_sim/catalogue.toml): its "
          "fields are the defaults of the ones below.", default_text="none: every required field "
          "given here", source=_SIZING),
    _sizing("motor", "stall_torque", "M0: the S1 curve at standstill (required).", "N m",
            maximum=1e6, limits=">= rated_torque, <= max_torque", probe=False),
    _sizing("motor", "rated_torque", "M_N, the S1 curve's point at rated_speed_rpm (given with "
            "it; without them the S1 check takes M0 at every speed and says so).", "N m",
            maximum=1e6, limits="<= stall_torque; with rated_speed_rpm", probe=False),
    _sizing("motor", "rated_speed_rpm", "n_N (given with rated_torque).", "rpm", maximum=1e6,
            limits="with rated_torque", when=_MODEL),
    _sizing("motor", "max_torque", "The motor's peak torque (required).", "N m", maximum=1e6,
            limits=">= stall_torque", when=_MODEL),
    _sizing("motor", "max_speed_rpm", "The motor's maximum speed: the motor_speed check's "
            "limit.", "rpm", maximum=1e6, when=_MODEL),
    _sizing("motor", "torque_constant", "kT (required).", "N m/A", maximum=1e4, when=_MODEL),
    _sizing("motor", "voltage_constant", "kE, line-to-line rms back-EMF per rad/s (a catalogue's "
            "V/1000 rpm divided by 104.72) (required).", "V s/rad", maximum=1e4, when=_MODEL),
    _sizing("motor", "thermal_time_constant_s", "The winding's thermal time constant (required).",
            "s", maximum=1e7, when=_MODEL),
    _sizing("motor", "rotor_inertia", "The rotor's inertia: mechanics.motor_inertia when that is "
            "not given (required).", "kg m^2", maximum=1e4, when=_MODEL),
    _sizing("motor", "winding_resistance", "Phase resistance, for the voltage limit.", "ohm",
            zero=True, maximum=1e4, default_text="the catalogue's, else 0", when=_MODEL),
    _sizing("motor", "inductance", "Rotating-field inductance, for the voltage limit.", "H",
            zero=True, maximum=1e2, default_text="the catalogue's, else 0", when=_MODEL),
    Field("motor", "pole_pairs", "integer", "Pole pairs (the inductance's electrical speed).",
          default_text="the catalogue's, else 1", minimum=1, maximum=1000, when=_MODEL,
          source=_SIZING),
    _sizing("motor", "shaft_stiffness", "The motor shaft's torsional stiffness: in series with "
            "the coupling and the gearhead on an axis with a spring.", "N m/rad", maximum=1e12,
            default_text="the catalogue's, else rigid", when=_MODEL),
    Field("motor", "torque_current_points", "array", "[[current, torque], ...] from [0, 0]: the "
          "motor's torque over current (it saturates); the drive current checks and the clamp "
          "read it.", unit="A, N m", default_text="the catalogue's, else the line of "
          "torque_constant", limits="both increasing", source=_SIZING),
    Field("drive", "module", "string", "A drive module of the catalogue: its fields are the "
          "defaults of the ones below.", default_text="none", source=_SIZING),
    _sizing("drive", "rated_current", "The module's continuous current: the drive_current "
            "check's limit.", "A", maximum=1e5),
    _sizing("drive", "peak_current", "The module's peak current: the drive_peak_current check's "
            "limit and, through the motor's curve, the torque clamp.", "A", maximum=1e5,
            limits=">= rated_current"),
    _sizing("drive", "dc_bus_voltage", "The DC link's nominal voltage: the motor's voltage limit.",
            "V", maximum=1e5),
    _sizing("drive", "dc_link_capacitance", "The module's DC-link capacitance: the regeneration "
            "check.", "F", maximum=1e3),
    _sizing("drive", "brake_chopper_voltage", "Where the brake chopper switches in.", "V",
            maximum=1e5, limits="> dc_bus_voltage"),
    _sizing("drive", "brake_resistor_power", "The brake resistor's continuous power; 0: none.",
            "W", zero=True, maximum=1e8, default_text="the catalogue's, else 0 (none)"),
    Field("drive", "line_module", "string", "An infeed (line module) of the catalogue: its "
          "fields are the defaults of the infeed ones below.", default_text="none",
          source=_SIZING),
    Field("drive", "infeed", "choice", "The infeed's kind: regenerative returns braking power "
          "to the line up to infeed_peak_power (the DC link and the brake resistor take only "
          "the excess); rectifier returns none. Without it the regeneration check takes the DC "
          "link alone and infeed_power is not rated.", choices=INFEEDS,
          default_text="the line module's, else none", limits="with infeed_power",
          when=(("drive.infeed_power", 16000.0),), source=_SIZING),
    _sizing("drive", "infeed_power", "The infeed's rated power P_n, drawn or returned: the "
            "infeed_power check's limit for the cycle's RMS power.", "W", maximum=1e8,
            limits="with infeed", when=(("drive.infeed", "regenerative"),)),
    _sizing("drive", "infeed_peak_power", "The infeed's peak power: the most it returns at "
            "once, and the infeed_power check's limit for the cycle's peak.", "W",
            maximum=1e8, default_text="the line module's, else infeed_power",
            limits=">= infeed_power", when=(("drive.infeed", "regenerative"),
                                             ("drive.infeed_power", 1.0))),
    Field("mechanics", "gearhead", "string", "A gearhead of the catalogue: its fields are the "
          "defaults of the gearhead_* ones, its ratio and efficiency those of gear_ratio and "
          "gear_efficiency.", default_text="none", limits="gear_ratio, if given, is its ratio",
          source=_SIZING),
    _sizing("mechanics", "gearhead_stiffness", "C_t21 at the output: in series with the coupling "
            "and the motor shaft.", "N m/rad", maximum=1e12),
    _sizing("mechanics", "gearhead_input_inertia", "J1: added to the motor side.", "kg m^2",
            zero=True, maximum=1e4),
    _sizing("mechanics", "gearhead_idle_torque", "T012 at the input: the default of "
            "motor_coulomb_friction.", "N m", zero=True, maximum=1e6),
    _sizing("mechanics", "gearhead_acceleration_torque", "T2B (at most 1000 cycles/h): the "
            "gearhead_torque check's limit.", "N m", maximum=1e8),
    _sizing("mechanics", "gearhead_emergency_torque", "T2Not, against the drive's clamp through "
            "the gear.", "N m", maximum=1e8),
    _sizing("mechanics", "gearhead_max_input_speed_rpm", "n1Max: the motor_speed check's limit "
            "where lower than the motor's.", "rpm", maximum=1e6),
    _sizing("mechanics", "gearhead_shock_factor", "The catalogue's shock factor f_s at the duty's "
            "cycles per hour (above 1000/h T2B is divided by it).", minimum=1.0, maximum=100.0,
            default_text="not applied (the check says so)"),
)


SCENE_FIELDS: tuple[Field, ...] = (
    Field("", "name", "string", "The scene's name in reports.", default_text="the file name without "
          ".toml", source=_PARSER),
    Field("", "description", "string", "Free text, shown in the HTML report.", default="",
          source=_PARSER),
    Field("", "cam_mode", "choice", "Where the cam runs: the controller streams cyclic synchronous "
          "position targets, or the drive runs the downloaded table from the streamed master position.",
          default="controller", choices=CAM_MODES, source=_PARSER),
    Field("", "fidelity", "choice", "Which effects a run models: measured (auto), every one (full), "
          "none (ideal); `ecam sim --fidelity` overrides it.", default="auto", choices=FIDELITIES,
          source="hil_sim.effects"),
    Field("", "master", "table", "The `[master]` table.", default=REQUIRED),
    Field("", "cam", "table", "The `[cam]` table.", default=REQUIRED,
          default_text="optional with load_scene(path, cam=profile)"),
    Field("", "drive", "table", "The `[drive]` table.", default_text="the defaults below"),
    Field("", "mechanics", "table", "The `[mechanics]` table.", default=REQUIRED),
    Field("", "bus", "table", "The `[bus]` table.", default_text="the defaults below"),
    Field("", "limits", "table", "The `[limits]` table.", default=REQUIRED),
    Field("", "duration", "table", "The `[duration]` table.", default=REQUIRED),
    Field("", "sweep", "table", "A robustness sweep over manufacturing spread, read by `ecam sweep` "
          "(hil_sim.sweep_spec; its fields in docs/sweep.md); a run of the scene ignores it.",
          default_text="no sweep", source="hil_sim.sweep_spec"),
    Field("", "motor", "table", "The `[motor]` table.", default_text="no motor: the sizing checks "
          "are reported without limits"),
    Field("", "event", "array of tables", "The `[[event]]` entries below.", default_text="none",
          limits=f"at most {MAX_EVENTS}"),
    Field("", "tappet", "array of tables", "The `[[tappet]]` entries below (the cam file's own "
          "tappets are checked too).", default_text="none"),

    Field("master", "speed", "number", "The cruise speed.", unit="master units/s",
          default_text="give exactly one of speed and speed_rpm", minimum=-MAX_MASTER_SPEED,
          maximum=MAX_MASTER_SPEED, limits=f"magnitude >= {MIN_MASTER_SPEED:g}; at most half a cam "
          "period per bus cycle", source=_PARSER),
    Field("master", "speed_rpm", "number", "The cruise speed in master periods (cam cycles) per "
          "minute.", unit="periods/min", default_text="give exactly one of speed and speed_rpm",
          minimum=-MAX_MASTER_SPEED, maximum=MAX_MASTER_SPEED,
          limits=f"magnitude >= {MIN_MASTER_SPEED:g}", when=_NOT_SPEED, source=_PARSER),
    Field("master", "profile", "choice", "Constant speed from the first cycle, a jerk-limited start "
          "(and stop) planned by ruckig, or a cam-in: the slave engaged onto the moving master.",
          default="constant", choices=PROFILES, source=_PARSER),
    Field("master", "lead_cycles", "integer", "Set points sent this many cycles ahead (1: the CSP "
          "timeline of a real drive; 0: a master that sends the position of now, so the drive lags a "
          "cycle).", unit="cycles", default=1, minimum=0, maximum=MAX_LEAD_CYCLES, source=_PARSER),
    Field("master", "max_acceleration", "number", "start_stop: the master's acceleration limit.",
          unit="master units/s^2", default=REQUIRED, minimum=0.0, exclusive_minimum=True,
          when=_START_STOP, source=_PARSER),
    Field("master", "max_jerk", "number", "start_stop: the master's jerk limit.",
          unit="master units/s^3", default=REQUIRED, minimum=0.0, exclusive_minimum=True,
          when=_START_STOP, source=_PARSER),
    Field("master", "start_s", "number", "start_stop: when the master starts.", unit="s", default=0.0,
          minimum=0.0, when=_START_STOP, source=_PARSER),
    Field("master", "stop_s", "number", "start_stop: when the master starts to stop.", unit="s",
          default_text="no stop", minimum=0.0, limits=">= start_s", when=_START_STOP, source=_PARSER),
    Field("master", "engage_at", "number", "cam_in: the master position where the slave is on the cam.",
          unit="master units", default=REQUIRED, when=_CAM_IN, source=_PARSER),
    Field("master", "slave_start", "number", "cam_in: where the slave rests before the cam-in.",
          unit="slave units", default=0.0, when=_CAM_IN, source=_PARSER),
    Field("master", "max_velocity", "number", "cam_in: the slave's speed limit during the approach.",
          unit="slave units/s", default=REQUIRED, minimum=0.0, exclusive_minimum=True, when=_CAM_IN,
          source=_PARSER),
    Field("master", "slave_max_acceleration", "number", "cam_in: the slave's acceleration limit.",
          unit="slave units/s^2", default=REQUIRED, minimum=0.0, exclusive_minimum=True, when=_CAM_IN,
          source=_PARSER),
    Field("master", "slave_max_jerk", "number", "cam_in: the slave's jerk limit.",
          unit="slave units/s^3", default=REQUIRED, minimum=0.0, exclusive_minimum=True, when=_CAM_IN,
          source=_PARSER),

    Field("cam", "file", "string", "The cam file, relative to the scene file; a name of a built-in "
          "cam (ecam/cams/) is found when no such file exists.", default=REQUIRED, source=_PARSER),
    Field("cam", "interp", "choice", "The table's interpolation kind.", default_text="the cam "
          "file's [table]", choices=INTERPOLATIONS, source="ecam.table_spec"),
    Field("cam", "points", "integer", "Stored points of the table.", default_text="the cam file's "
          "[table]", minimum=2, limits=f"<= {MAX_POINTS} when compiled; points - 1 divides "
          "master_counts; at most one of points and tolerance", source="ecam.table_spec"),
    Field("cam", "tolerance", "number or string", "The table's largest error: slave units, or "
          "\"2 counts\", \"0.01 deg\".", unit="slave units or counts",
          default_text="the cam file's [table]", limits="> 0", source="ecam.table_spec"),
    Field("cam", "master_counts", "integer", "The master period in counts.", unit="counts",
          default_text="the cam file's [table], else 65536", minimum=2, maximum=MAX_MASTER_COUNTS,
          source="ecam.table_spec"),
    Field("cam", "slave_counts_per_unit", "number", "Slave counts per slave unit: what a rig "
          "\"count\" is (a table slave count, not an encoder increment).", unit="counts / slave unit",
          default_text="the cam file's [table], else 1000", minimum=MIN_COUNTS_PER_UNIT,
          maximum=MAX_COUNTS_PER_UNIT, source="ecam.table_spec"),

    Field("drive", "node_id", "integer", "The drive's CANopen node id.", default=1, minimum=1,
          maximum=127, source="CiA 301 (node ids 1..127)"),
    Field("drive", "cycle_s", "number", "The interpolation period (0x60C2) = the bus cycle.",
          unit="s", default=0.001, minimum=1e-5, maximum=0.255,
          limits="n x 10^e s with n in 1..255 (the 0x60C2 format)", source=_PARSER),
    Field("drive", "substeps", "integer", "Controller periods per bus cycle.", default=4, minimum=1,
          maximum=1000, source=_PARSER),
    Field("drive", "following_error_window", "integer", "The following error window (0x6065): "
          "beyond it the drive faults.", unit="counts", default=100000, minimum=1,
          maximum=0xFFFFFFFF, source=_PARSER),
    Field("drive", "tpdo_transmission_type", "integer", "The drive's TPDOs go on every n-th SYNC "
          "(0x1800..0x1803 sub 2): fewer frames per SYNC; the controller reads the following error "
          "and statusword on those SYNCs only (the bus-free path alike).", default=1, minimum=1,
          maximum=MAX_TRANSMISSION_TYPE, source="CiA 301 7.5.2.37 (types 1..240: synchronous, cyclic)"),
    Field("drive", "tpdo_sync_start", "integer", "The SYNC start value (0x1800..0x1803 sub 6): the "
          "TPDOs first go on the SYNC whose counter is this, then every n-th; give the axes of a "
          "machine different ones to spread their TPDOs over the SYNCs. 0: not used.", default=0,
          minimum=0, maximum=MAX_SYNC_COUNTER_OVERFLOW,
          limits="0 without bus.sync_counter_overflow, else <= it",
          when=(("bus.sync_counter_overflow", MAX_SYNC_COUNTER_OVERFLOW),),
          source="CiA 301 7.5.2.37 (sub-index 06h)"),
    Field("drive", "model", "choice", "The plant model: measured (auto), rigid or two-mass.",
          default="auto", choices=MODELS, source="hil_sim.control"),
    Field("drive", "feedforward", "choice", "Where the velocity feed-forward comes from: the velocity "
          "offset 0x60B1 streamed with the targets, or differences of the targets.",
          default="offset", choices=FEEDFORWARD_SOURCES, source="hil_sim.control"),
    Field("drive", "gains", "table", "The `[drive.gains]` table.", default_text="auto-tuned "
          "(hil_sim.tuning, docs/tuning.md)"),
    Field("drive", "encoder_counts_per_rev", "integer", "The motor encoder's resolution; 0 = ideal "
          "feedback.", unit="counts/rev", default=DEFAULT_ENCODER_COUNTS, minimum=0, maximum=2**40,
          limits="0 or >= 4", source=_EFFECTS),
    Field("drive", "velocity_filter_hz", "number", "The speed estimate's low-pass.", unit="Hz",
          default_text=f"{VELOCITY_FILTER_SHARE:g} x the controller rate", minimum=0.0,
          exclusive_minimum=True, maximum=MAX_BANDWIDTH_HZ, source=_EFFECTS),
    Field("drive", "current_loop_bandwidth_hz", "number", "The torque loop's bandwidth; 0 = ideal "
          "torque.", unit="Hz", default=DEFAULT_CURRENT_LOOP_HZ, minimum=0.0, maximum=MAX_BANDWIDTH_HZ,
          source=_EFFECTS),
    Field("drive", "computation_delay", "boolean", "One controller period between sampling and "
          "the applied torque.", default=True, source=_EFFECTS),
    Field("drive", "speed_symmetrization", "boolean", "The speed reference passes the speed "
          "estimate's own lag before the PI compares them (speed precontrol balancing).",
          default=False, source="hil_sim.control (DriveEffects; SINAMICS p1428/p1429 default 0)"),
    Field("drive", "friction_feedforward", "boolean", "Feed the machine's Coulomb friction "
          "forward, signed by the speed reference.", default=False,
          source="hil_sim.control (DriveEffects; Beckhoff AX2000 ISTFR default 0)"),

    *(Field("drive.gains", key, "number", text, unit=unit, default=default, default_text=default_text,
            minimum=0.0, limits=limits, source=source)
      for key, text, unit, default, default_text, limits, source in (
          ("velocity_bandwidth_hz", "The velocity loop's bandwidth (kp = J_eq 2 pi f).", "Hz", None,
           "auto-tuned: the highest that keeps the loop's margins on the full model", "> 0 at run time",
           "hil_sim.tuning"),
          ("position_bandwidth_hz", "The position loop's bandwidth.", "Hz", None,
           "auto-tuned: the highest that keeps the position loop's margins", "> 0 at run time",
           "hil_sim.tuning"),
          ("integral_ratio", "The velocity integrator's corner over the velocity bandwidth.", "", 0.25,
           "", "", "hil_sim.tuning (INTEGRAL_RATIO, the symmetrical optimum with a = 4)"),
          ("position_kp", "Position loop gain (rad/s per rad).", "1/s", None, "from the bandwidths",
           "> 0 at run time", "hil_sim.control"),
          ("velocity_kp", "Velocity loop proportional gain.", "N m s/rad", None, "from the bandwidths",
           "> 0 at run time", "hil_sim.control"),
          ("velocity_ki", "Velocity loop integral gain.", "N m/rad", None, "from the bandwidths", "",
           "hil_sim.control"),
          ("velocity_feedforward", "Share of the target's speed fed forward.", "", 1.0, "", "",
           "hil_sim.control (Gains)"),
          ("acceleration_feedforward", "Share of the model torque fed forward.", "", 1.0, "", "",
           "hil_sim.control (Gains)"),
          ("notch_hz", "Centre of the notch on the torque command; 0: none.", "Hz", None,
           "auto-tuned: at the torsional mode where it allows a higher bandwidth, else none",
           "below the controller's Nyquist frequency", "hil_sim.tuning"),
          ("notch_width", "The notch's width (its poles' damping ratio).", "", 0.5, "", "> 0 at run time",
           "hil_sim.control (Gains)"),
          ("notch_depth_db", "The notch's depth.", "dB", 30.0, "", "> 0 at run time",
           "hil_sim.control (Gains)"),
      )),

    *_mechanics(),
    Field("mechanics", "slave_units_per_load_radian", "number", "Slave user units per radian of the "
          "load shaft (1 for a slave in rad; 57.3 for deg; the lead / 2 pi of a ballscrew).",
          unit="slave units/rad", default=1.0, minimum=SLAVE_UNITS_PER_RADIAN_RANGE[0],
          maximum=SLAVE_UNITS_PER_RADIAN_RANGE[1], source=_PARSER),
    Field("mechanics", "gear_backlash", "number", "Backlash at the load shaft; 0: none.", unit="rad",
          default_text=f"{DEFAULT_BACKLASH_ARCMIN:g} arcmin with a gear (a standard-class precision "
          "planetary gearhead), none at ratio 1", minimum=0.0, maximum=EFFECT_RANGES["gear_backlash"],
          source=_EFFECTS),
    Field("mechanics", "motor_coulomb_friction", "number", "Coulomb friction on the motor side; 0: "
          "none.", unit="N m", default_text="the gearhead's catalogue idle torque T012 where the "
          f"scene names a gearhead, else {DEFAULT_MOTOR_FRICTION_SHARE:.0%} of the motor torque "
          "limit", minimum=0.0, maximum=EFFECT_RANGES["motor_coulomb_friction"], source=_EFFECTS),
    Field("mechanics", "load_coulomb_friction", "number", "Coulomb friction on the load side; 0: "
          "none.", unit="N m", default_text=f"{DEFAULT_LOAD_FRICTION_SHARE:.0%} of the torque the "
          "motor can put on the load shaft", minimum=0.0,
          maximum=EFFECT_RANGES["load_coulomb_friction"], source=_EFFECTS),
    Field("mechanics", "coupling_inertia", "number", "The coupling's own inertia, half to each side; "
          "0: none.", unit="kg m^2", default_text="J = 5.4e-7 T_KN^1.48 for a metal bellows of the "
          "rated torque T_KN (RINGFEDER GWB tables)", minimum=0.0,
          maximum=EFFECT_RANGES["coupling_inertia"], source=_EFFECTS),

    *_SIZING_FIELDS,

    Field("bus", "bitrate", "integer", "The CAN bitrate: the rig adds up each cycle's frame bits "
          "(worst-case bit stuffing) against it.", unit="bit/s", default=1_000_000, minimum=10_000,
          maximum=1_000_000, source="CiA 301 bit rates (10 kbit/s .. 1 Mbit/s)"),
    Field("bus", "sync_counter_overflow", "integer", "The SYNC counter (0x1019): 0, the SYNC carries "
          "no data; 2..240, it carries a 1-byte counter running 1..this value (10 bits more per "
          "SYNC), which drive.tpdo_sync_start needs.", default=0, minimum=0,
          maximum=MAX_SYNC_COUNTER_OVERFLOW, limits="not 1 (reserved)",
          source="CiA 301 7.5.2.22"),
    Field("bus", "master_position_pdo", "choice", "Drive-side axes: one master position RPDO per "
          "axis, or one PDO on one COB-ID that every drive-side drive consumes (counted once on the "
          "bus); shared needs the same master position on every drive-side axis (same phase and "
          "master_counts).", default="per_axis", choices=MASTER_POSITION_PDOS,
          source="CiA 301 7.2.2 (one producer, any number of consumers of a PDO)"),
    Field("bus", "faults", "table", "The `[bus.faults]` table.", default_text="no faults"),
    Field("bus.faults", "seed", "integer", "Seed of the fault generator: same seed, same faults.",
          default=0, minimum=0, source="hil_sim.faults"),
    Field("bus.faults", "kinds", "array", "The frame kinds random drops and delays apply to.",
          default_text='["rpdo", "tpdo"]', limits="each one of " + ", ".join(f'"{k}"' for k in FRAME_KINDS),
          source="hil_sim.faults"),
    Field("bus.faults", "drop_probability", "number", "Probability that a frame of those kinds is "
          "lost.", default=0.0, minimum=0.0, maximum=1.0, source="hil_sim.faults"),
    Field("bus.faults", "drop", "array", "Frames always lost: [{cycle = N, frame = KIND}, ...].",
          default_text="none", source="hil_sim.faults"),
    Field("bus.faults", "delay_probability", "number", "Probability that a frame of those kinds "
          "(SYNC excepted) arrives whole cycles late.", default=0.0, minimum=0.0, maximum=1.0,
          source="hil_sim.faults"),
    Field("bus.faults", "delay_cycles", "integer", "A delayed frame arrives 1..delay_cycles cycles "
          "late.", unit="cycles", default=1, minimum=1, source="hil_sim.faults"),
    Field("bus.faults", "sync_jitter_s", "number", "The SYNC instants move by a uniform draw in "
          "[-jitter, +jitter].", unit="s", default=0.0, minimum=0.0, maximum=MAX_SYNC_JITTER_S,
          source="hil_sim.faults"),

    Field("limits", "tracking_error", "number", "Load-side tracking error against the cam.",
          unit="slave units", default=REQUIRED, minimum=0.0, exclusive_minimum=True, source=_PARSER),
    Field("limits", "following_error", "integer", "Motor-side following error.", unit="counts",
          default_text="the drive's following_error_window", minimum=1, source=_PARSER),
    Field("limits", "bus_load_percent", "number", "The bus load.", unit="%", default=100.0,
          minimum=0.0, exclusive_minimum=True, source=_PARSER),
    Field("limits", "wind_up_deg", "number", "The coupling's twist.", unit="deg",
          default_text="reported without a limit", minimum=0.0, exclusive_minimum=True, source=_PARSER),
    Field("limits", "resonance_excitation_percent", "number", "The share of the strongest "
          "acceleration harmonic that the harmonic at the torsional mode carries.", unit="%",
          default=5.0, minimum=0.0, source=_PARSER),
    Field("limits", "motor_saturation_percent", "number", "The share of cycles with the torque "
          "clamped at the motor torque limit.", unit="%", default=0.0, minimum=0.0, maximum=100.0,
          source=_PARSER),
    Field("limits", "tracking_window", "array", "[start, end]: the master positions where the "
          "tracking check applies (the cut zone of a knife); end < start spans the seam.",
          unit="master units", default_text="the whole period", limits="two numbers, start != end, "
          "each within +-1e12", source=_PARSER),
    Field("limits", "phase_margin_deg", "number", "The loop_stability check: least phase margin "
          "of the velocity and position loops as they run.", unit="deg", default=45.0, minimum=0.0,
          maximum=90.0, source="hil_sim.tuning (MarginLimits)"),
    Field("limits", "gain_margin_db", "number", "The loop_stability check: least gain margin.",
          unit="dB", default=6.0, minimum=0.0, maximum=60.0, source="hil_sim.tuning (MarginLimits)"),
    Field("limits", "sensitivity_peak", "number", "The loop_stability check: largest sensitivity "
          "peak Ms = max |1 / (1 + L)|.", default=2.0, minimum=1.0, exclusive_minimum=True,
          maximum=100.0, source="hil_sim.tuning (MarginLimits)"),
    Field("limits", "inertia_ratio", "number", "The inertia_ratio check: largest load (reflected) "
          "over motor-side inertia.", default_text="reported without a limit", minimum=0.0,
          exclusive_minimum=True, source=_PARSER),
    Field("limits", "tappet_error", "number", "The tappet_edges check: the largest distance of a "
          "tappet edge (where the master is when the actuator acts, after its dead time = "
          "-compensation) from its programmed position.", unit="master units",
          default_text="reported without a limit", minimum=0.0, exclusive_minimum=True,
          source="hil_sim.tappet_edges"),
    Field("limits", "settle_s", "number", "Left out of the tracking and following-error checks at "
          "the start.", unit="s", default=0.0, minimum=0.0, maximum=MAX_SETTLE_S, source=_PARSER),

    Field("duration", "master_periods", "number", "Cam periods at the cruise speed (a start ramp "
          "or a cam-in takes part of them: the report says how many ran at cruise speed).",
          unit="periods", default_text="give exactly one", minimum=0.0, exclusive_minimum=True,
          limits=f"at most {MAX_CYCLES} cycles", source=_PARSER),
    Field("duration", "cycles", "integer", "Bus cycles.", unit="cycles",
          default_text="give exactly one", minimum=1, maximum=MAX_CYCLES,
          when=(("duration.master_periods", None),), source=_PARSER),
    Field("duration", "seconds", "number", "Seconds of simulated time.", unit="s",
          default_text="give exactly one", minimum=0.0, exclusive_minimum=True,
          limits=f"at most {MAX_CYCLES} cycles at drive.cycle_s", when=(("duration.master_periods", None),),
          source=_PARSER),

    *_EVENT_FIELDS,
    *(f for f in CAM_FIELDS if f.table == "tappet"),
)
