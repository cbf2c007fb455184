"""Scene files (TOML): what the rig runs, checked once, where it enters.

A scene names a cam file and its table format, how the master moves, where the cam runs
(controller or drive), the drive, the mechanics, the bus and its faults, the limits of the
report and how long to run. Every field is validated here; a bad one raises
:class:`~ecam.errors.CamFileError` with one line naming the field, the value and what was
expected. Unknown keys are rejected (a typo must not silently fall back to a default).

Layout (units in the names or below; SI unless said otherwise)::

    name = "stiff_coupling"            # optional, default the file name
    description = "..."                # optional
    cam_mode = "controller"            # "controller" (CSP targets) or "drive" (drive-side cam)
    fidelity = "auto"                  # "auto" (measured), "full" (every effect) or "ideal"

    [master]
    speed = 720.0                      # master units/s; or speed_rpm = master periods/min
    profile = "constant"               # "constant", "start_stop" or "cam_in"
    lead_cycles = 1                    # set points for 1 cycle ahead (CSP), or 0: a master that
                                       # sends the position of now (the drive then lags a cycle)
    # start_stop: max_acceleration (master units/s^2), max_jerk (units/s^3), start_s, stop_s
    # cam_in: engage_at (master units), slave_start (slave units), max_velocity (slave
    #         units/s), slave_max_acceleration (units/s^2), slave_max_jerk (units/s^3)

    [cam]
    file = "../../firmware_tables/cams/combination_drrd.toml"   # relative to the scene file
    interp = "cubic"                   # optional, default the cam file's [table]
    points = 257                       # or tolerance = 2e-5 (slave units); optional
    master_counts = 36864              # optional
    slave_counts_per_unit = 100000     # optional

    [drive]
    node_id = 1
    cycle_s = 0.001                    # interpolation period = bus cycle [s]
    substeps = 4                       # controller periods per cycle
    following_error_window = 50000     # counts (0x6065)
    model = "auto"                     # "auto", "rigid" or "two_mass"
    feedforward = "offset"             # "offset" (0x60B1 streamed with the targets) or "target"
    # effects (hil_sim.effects: each has a documented default when left out)
    encoder_counts_per_rev = 1048576   # 0 = ideal feedback
    velocity_filter_hz = 1000.0        # the speed estimate's low-pass
    current_loop_bandwidth_hz = 1000.0 # 0 = ideal torque
    computation_delay = true           # one controller period
    speed_symmetrization = false       # the speed reference through the estimate's lag
    friction_feedforward = false       # Coulomb friction fed forward (hil_sim.control)
    [drive.gains]                      # optional: bandwidths and/or raw gains
    velocity_bandwidth_hz = 200.0

    [mechanics]                        # ecam.mechanics.Mechanics fields, SI
    motor_inertia = 1.2e-4
    gear_ratio = 0.1
    slave_units_per_load_radian = 1.0  # slave user units per radian of the load shaft
    # effects (hil_sim.effects: each has a documented default when left out; 0 = none)
    gear_backlash = 8.7e-4             # rad at the load shaft (3 arcmin)
    motor_coulomb_friction = 0.05      # N m
    load_coulomb_friction = 1.0        # N m
    coupling_inertia = 2e-4            # kg m^2, half to each side of the spring

    # sizing (hil_sim.sizing_spec): the motor, the drive module and the gearhead, by catalogue
    # name (hil_sim/catalogue.toml) and/or field by field; all optional
    [motor]
    model = "1FT7044-AK7"              # stall_torque, rated_torque, rated_speed_rpm, ...
    # [drive]: module = "...", rated_current, peak_current, dc_bus_voltage,
    #          dc_link_capacitance, brake_chopper_voltage, brake_resistor_power,
    #          line_module = "...", infeed, infeed_power, infeed_peak_power
    # [mechanics]: gearhead = "...", gearhead_stiffness, gearhead_input_inertia,
    #          gearhead_idle_torque, gearhead_acceleration_torque, gearhead_emergency_torque,
    #          gearhead_max_input_speed_rpm, gearhead_shock_factor

    [bus]
    bitrate = 1000000
    [bus.faults]                       # optional, see hil_sim.faults.Faults
    seed = 1
    drop_probability = 0.01

    [limits]
    tracking_error = 0.002             # slave units, load side against the cam
    following_error = 40000            # counts, motor side; default the drive's window
    bus_load_percent = 100.0
    wind_up_deg = 0.5                  # optional
    tracking_window = [330.0, 30.0]    # optional: master positions (within the period, may
                                       # span the seam) where the tracking check applies
    settle_s = 0.5                     # optional: left out of tracking and following error
    resonance_excitation_percent = 5.0
    motor_saturation_percent = 0.0
    phase_margin_deg = 45.0            # the loop_stability check (hil_sim.tuning)
    gain_margin_db = 6.0
    sensitivity_peak = 2.0             # Ms = max |1 / (1 + L)|
    inertia_ratio = 10.0               # optional: load (reflected) over motor-side inertia

    [duration]                         # exactly one of
    master_periods = 3.0               # at the cruise speed
    # cycles = 5000
    # seconds = 5.0
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from ecam.camfile import CAMS_DIR, load_cam, read_tappets, read_toml
from ecam.errors import CamFileError, InputError
from ecam.mechanics import Mechanics
from ecam.profile import CamProfile
from ecam.table import INTERPOLATIONS, MAX_MASTER_COUNTS
from ecam.table_spec import MAX_COUNTS_PER_UNIT, MIN_COUNTS_PER_UNIT, TableSpec, parse_tolerance
from ecam.validate import MAX_DESCRIPTION_CHARS, Fields, choice, fail, number, show, show_path
from hil_sim.control import FEEDFORWARD_SOURCES, MODELS
from hil_sim.drive.objects import interpolation_period
from hil_sim.effects import DRIVE_FIELDS, FIDELITIES, MECHANICS_FIELDS
from hil_sim.event_spec import parse_events
from hil_sim.faults import FRAME_KINDS, Faults
from hil_sim.filters import check_notch_hz
from hil_sim.sizing_spec import DRIVE_SIZING_KEYS, GEARHEAD_KEYS, SizingSpec, parse_sizing
from hil_sim.sync_schedule import (MASTER_POSITION_PDOS, MAX_SYNC_COUNTER_OVERFLOW,
                                   MAX_TRANSMISSION_TYPE, check_sync_start)

#: Where the cam runs: the controller streams CSP targets, or the drive runs the table itself.
CAM_MODES = ("controller", "drive")
#: How the master moves (``master.profile``).
PROFILES = ("constant", "start_stop", "cam_in")
#: The ``master`` fields each profile takes besides ``speed``/``speed_rpm`` and ``profile``.
PROFILE_KEYS = {
    "constant": (),
    "start_stop": ("max_acceleration", "max_jerk", "start_s", "stop_s"),
    "cam_in": ("engage_at", "slave_start", "max_velocity", "slave_max_acceleration",
               "slave_max_jerk"),
}
GAIN_BANDWIDTH_KEYS = ("velocity_bandwidth_hz", "position_bandwidth_hz", "integral_ratio")
GAIN_KEYS = ("position_kp", "velocity_kp", "velocity_ki", "velocity_feedforward",
             "acceleration_feedforward", "notch_hz", "notch_width", "notch_depth_db")

# Physical range of each mechanics field [SI]: wide enough for a watch motor and a press, narrow
# enough that products and quotients of them (torques, energies, the plant matrices, the reflected
# inertia) stay finite in float64. The lower bounds of the fields that divide are positive; the
# rules between fields are ecam.mechanics.Mechanics' own checks.
MECHANICS_RANGES = {
    "motor_inertia": 1e4, "load_inertia": 1e6, "gear_ratio": 1e4, "gear_efficiency": 1.0,
    "motor_damping": 1e6, "load_damping": 1e8, "coupling_stiffness": 1e12,
    "coupling_damping": 1e8, "coupling_rated_torque": 1e8, "coupling_max_torque": 1e8,
    "motor_torque_limit": 1e6,
}
MECHANICS_MINIMA = {
    "motor_inertia": 1e-10, "gear_ratio": 1e-4, "gear_efficiency": 0.01,
    "coupling_stiffness": 1e-6,
}
#: Master speed magnitudes ([master] speed, master units/s, or speed_rpm).
MIN_MASTER_SPEED, MAX_MASTER_SPEED = 1e-9, 1e12
#: A load inertia is 0 (none) or at least this [kg m^2].
MIN_LOAD_INERTIA = 1e-12
#: Slave units per load radian: from a micrometre per radian to a kilometre.
SLAVE_UNITS_PER_RADIAN_RANGE = (1e-9, 1e9)
#: Master positions of a check window: the master period's own range (ecam cam files).
MAX_WINDOW_POSITION = 1e12

# Ranges of the effect fields [SI]: finite arithmetic, and a backlash of at most half a turn.
EFFECT_RANGES = {"gear_backlash": math.pi, "motor_coulomb_friction": 1e6,
                 "load_coulomb_friction": 1e8, "coupling_inertia": 1e6}
MAX_BANDWIDTH_HZ = 1e7
MAX_LEAD_CYCLES = 4
MAX_SETTLE_S = 1e6
#: The longest run the rig records: its memory is about 0.2 kB per cycle (see
#: hil_sim.rig.loop), so this many cycles stay within about 1 GB.
MAX_CYCLES = 5_000_000

MECHANICS_KEYS = ("motor_inertia", "gear_ratio", "gear_efficiency", "motor_damping",
                  "load_damping", "coupling_stiffness", "coupling_damping", "load_inertia",
                  "coupling_rated_torque", "coupling_max_torque", "motor_torque_limit")


@dataclass(frozen=True)
class MasterSpec:
    """How the master moves. Speeds and positions in master units (per second).

    Exactly one of ``speed`` [master units/s] and ``speed_rpm`` [master periods per minute]
    is set; :meth:`units_per_second` resolves either.
    """

    speed: float | None = None
    speed_rpm: float | None = None
    profile: str = "constant"
    max_acceleration: float | None = None
    max_jerk: float | None = None
    start_s: float = 0.0
    stop_s: float | None = None
    engage_at: float | None = None
    slave_start: float = 0.0
    max_velocity: float | None = None
    slave_max_acceleration: float | None = None
    slave_max_jerk: float | None = None
    lead_cycles: int = 1

    def units_per_second(self, master_period: float) -> float:
        """Cruise speed [master units/s] for a cam of ``master_period`` master units."""
        if self.speed is not None:
            return self.speed
        return self.speed_rpm * master_period / 60.0


@dataclass(frozen=True)
class CamSpec:
    """The cam and the table format; None = the cam file's own ``[table]`` setting.

    Attributes
    ----------
    file : Path or None
        The cam file (absolute path); None when the cam was given in Python.
    profile : ecam.CamProfile or None
        A cam given in Python (``load_scene(path, cam=profile)``); it replaces ``file``.
    interp, points, tolerance, master_counts, slave_counts_per_unit
        The table settings (see :class:`ecam.TableSpec`); tolerance in slave units, counts
        (``"2 counts"``) or ``"0.01 deg"``.
    """

    file: Path | None
    interp: str | None = None
    points: int | None = None
    tolerance: float | str | None = None
    master_counts: int | None = None
    slave_counts_per_unit: float | None = None
    profile: CamProfile | None = field(default=None, compare=False, repr=False)

    def load_profile(self) -> CamProfile:
        """The cam: the one given in Python, else the cam file read and checked."""
        return self.profile if self.profile is not None else load_cam(self.file)

    def table_spec(self, profile: CamProfile) -> TableSpec:
        """The table to compile: these settings over the cam's own ``[table]``."""
        return TableSpec.resolve(profile.table, interp=self.interp, points=self.points,
                                 tolerance=self.tolerance, master_counts=self.master_counts,
                                 slave_counts_per_unit=self.slave_counts_per_unit)


@dataclass(frozen=True)
class DriveSpec:
    """The drive: node id, cycle, control loop, following-error window, plant model,
    feed-forward source and the drive's effects (``effects``: the keys of
    :data:`hil_sim.effects.DRIVE_FIELDS` the scene gives)."""

    node_id: int = 1
    cycle_s: float = 0.001
    substeps: int = 4
    following_error_window: int = 100000
    model: str = "auto"
    gains: tuple[tuple[str, float], ...] = ()
    feedforward: str = "offset"
    effects: tuple[tuple[str, float | bool], ...] = ()
    speed_symmetrization: bool = False
    friction_feedforward: bool = False
    tpdo_transmission_type: int = 1  # CiA 301 7.5.2.37: the TPDOs go on every n-th SYNC
    tpdo_sync_start: int = 0  # CiA 301 7.5.2.37 sub-index 06h: 0 unused

    @property
    def control_rate_hz(self) -> float:
        """Controller periods per second."""
        return self.substeps / self.cycle_s


@dataclass(frozen=True)
class MechanicsSpec:
    """Keyword arguments of :class:`ecam.mechanics.Mechanics`, plus the load scaling and the
    mechanical effects the scene gives (``effects``: keys of
    :data:`hil_sim.effects.MECHANICS_FIELDS`)."""

    values: tuple[tuple[str, float | None], ...]
    slave_units_per_load_radian: float = 1.0
    effects: tuple[tuple[str, float], ...] = ()

    def build(self) -> Mechanics:
        """The :class:`~ecam.mechanics.Mechanics` (its own checks name the field)."""
        return Mechanics(**dict(self.values))


@dataclass(frozen=True)
class BusSpec:
    """Bitrate and faults (:class:`hil_sim.faults.Faults`)."""

    bitrate: int = 1_000_000
    faults: object = None
    sync_counter_overflow: int = 0  # CiA 301 7.5.2.22 (0x1019): 0, the SYNC carries no counter
    master_position_pdo: str = "per_axis"  # drive-side axes: "shared", one PDO all consume


@dataclass(frozen=True)
class LimitsSpec:
    """Limits of the report's checks (None: the check is reported without a limit)."""

    tracking_error: float
    following_error: int | None = None
    bus_load_percent: float = 100.0
    wind_up_deg: float | None = None
    resonance_excitation_percent: float = 5.0
    motor_saturation_percent: float = 0.0
    tracking_window: tuple[float, float] | None = None
    settle_s: float = 0.0
    phase_margin_deg: float = 45.0
    gain_margin_db: float = 6.0
    sensitivity_peak: float = 2.0
    inertia_ratio: float | None = None
    tappet_error: float | None = None


@dataclass(frozen=True)
class DurationSpec:
    """Exactly one of cycles, seconds, master periods (at cruise speed)."""

    cycles: int | None = None
    seconds: float | None = None
    master_periods: float | None = None


@dataclass(frozen=True)
class Scene:
    """A whole rig run, as read from a scene file (see the module docstring for the layout).

    Attributes
    ----------
    name : str
        The scene's name (default: the file name without ``.toml``).
    path : Path or None
        The scene file (absolute), None for a scene parsed from a mapping.
    cam_mode : {"controller", "drive"}
        Where the cam runs: the controller streams CSP targets, or the drive runs the table.
    master : MasterSpec
        How the master moves: speed, profile (``constant``, ``start_stop``, ``cam_in``).
    cam : CamSpec
        The cam (a file or an in-memory profile, see :meth:`CamSpec.load_profile`) and its
        table settings.
    drive : DriveSpec
        Node id, cycle [s], controller substeps, following-error window [counts], plant
        model, gains.
    mechanics : MechanicsSpec
        Motor, gear, coupling and load (:meth:`MechanicsSpec.build` gives the
        :class:`~ecam.mechanics.Mechanics`), and slave units per load radian.
    bus : BusSpec
        Bitrate [bit/s] and faults (:class:`hil_sim.faults.Faults`).
    limits : LimitsSpec
        Limits of the report's checks.
    duration : DurationSpec
        How long to run: cycles, seconds or master periods.
    description : str
        Free text.
    fidelity : {"auto", "full", "ideal"}
        How much of the effects a run models (:mod:`hil_sim.effects`).
    sizing : hil_sim.sizing_spec.SizingSpec
        The motor, drive module and gearhead (``[motor]``, and the sizing fields of
        ``[drive]`` and ``[mechanics]``); empty when the scene gives none.
    phase : float
        The axis's phase offset against the master [master units]: the cam is looked up at the
        master position plus this (an axis of a machine, :mod:`hil_sim.machine`; 0 in a scene
        file).
    """

    name: str
    path: Path | None
    cam_mode: str
    master: MasterSpec
    cam: CamSpec
    drive: DriveSpec
    mechanics: MechanicsSpec
    bus: BusSpec
    limits: LimitsSpec
    duration: DurationSpec
    description: str = ""
    fidelity: str = "auto"
    sizing: SizingSpec = field(default_factory=SizingSpec)
    phase: float = 0.0
    events: tuple = ()
    tappets: tuple = ()

    def with_master_speed(self, speed: float) -> "Scene":
        """The same scene at another master speed [master units/s]."""
        return replace(self, master=replace(self.master, speed=float(speed), speed_rpm=None))

    def with_fidelity(self, fidelity: str) -> "Scene":
        """The same scene with another fidelity (``"auto"``, ``"full"`` or ``"ideal"``)."""
        return replace(self, fidelity=choice("fidelity", fidelity, FIDELITIES))


# ------------------------------------------------------------------------------------------
def load_scene(path, cam: CamProfile | None = None) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or Path
        The scene TOML; the cam file inside is resolved relative to it.
    cam : ecam.CamProfile, optional
        A cam built in Python: it replaces the scene's ``cam.file`` (which may then be left
        out); the scene's other ``[cam]`` settings (interp, points or tolerance, counts) still
        apply.

    Returns
    -------
    Scene
        The fields a user reads: ``name``, ``cam_mode``, ``master`` (speed, profile),
        ``cam`` (``cam.load_profile()`` gives the cam), ``drive`` (``cycle_s``, ``substeps``,
        ``model``), ``mechanics`` (``mechanics.build()``), ``bus``, ``limits``, ``duration``.

    Raises
    ------
    CamFileError
        Missing or unreadable file, invalid TOML, or a field out of range; one line naming
        the field, the value and what was expected (``scene x.toml: drive.substeps: 0 should
        be an integer in 1..1000``).
    InputError
        ``path`` is not a path, or ``cam`` is not an :class:`ecam.CamProfile`.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise fail("path", path, "a scene file path (str or Path)")
    path = Path(path)
    data = read_toml(path, "scene file")
    return parse_scene(data, base=path.parent, source=path.name, path=path.resolve(), cam=cam)


def parse_scene(data: dict, base: Path = Path("."), source: str = "<scene>",
                path: Path | None = None, cam: CamProfile | None = None) -> Scene:
    """Build a :class:`Scene` from a parsed TOML mapping.

    Parameters
    ----------
    data : dict
        The scene, as ``tomllib`` parses it.
    base : Path
        The directory the cam file is resolved against (the scene file's).
    source : str
        The scene's name in messages (``scene <source>: ...``) and its default ``name``.
    path : Path or None
        Recorded as :attr:`Scene.path`.
    cam : ecam.CamProfile, optional
        An in-memory cam replacing ``cam.file``, as in :func:`load_scene`.

    Returns
    -------
    Scene

    Raises
    ------
    CamFileError, InputError
        As :func:`load_scene`.
    """
    if cam is not None and not isinstance(cam, CamProfile):
        raise fail("cam", cam, "an ecam.CamProfile")
    if isinstance(data, dict) and "master" not in data and ("master_period" in data or "segment" in data):
        # A cam file where a scene belongs: say so, not "master_period: unknown field".
        raise CamFileError(f"scene {source}: this is a cam file (it has master_period and "
                           "[[segment]]), not a scene: a scene names its cam in [cam] file = ...; "
                           "`ecam check` and `ecam compile` take cam files")
    if isinstance(data, dict) and "axis" in data:
        # A machine file (hil_sim.machine) in a directory run or a sweep: say so, not "axis: unknown field".
        raise InputError(f"scene {source}: this is a machine file (it has [[axis]]), not a single-axis "
                         "scene: `ecam sim FILE` runs it alone (docs/machine.md); several scene files, "
                         "`--find-max-speed`, `--plot`, `--html` and `ecam sweep` take single-axis scenes")
    top = Fields(data, "", f"scene {source}", {"name", "description", "cam_mode", "fidelity",
                                              "master", "cam", "drive", "mechanics", "bus",
                                              "limits", "duration", "sweep",
                                              "motor", "event", "tappet"})
    # [sweep] describes a robustness sweep over this scene (hil_sim.sweep_spec, ecam sweep);
    # a run of the scene itself ignores it.
    name = top.text("name", default=Path(source).stem)
    description = top.text("description", default="", maximum=MAX_DESCRIPTION_CHARS)
    cam_mode = top.choice("cam_mode", CAM_MODES, default="controller")
    fidelity = top.choice("fidelity", FIDELITIES, default="auto")
    master = _master(top)
    cam_spec = _cam(top, base, cam)
    drive = _drive(top)
    sizing = parse_sizing(top)
    # [[event]]: cams switched, phase shifts, cam-out while the machine runs (hil_sim.events);
    # [[tappet]]: digital cam switches on the master, their edges checked (hil_sim.tappet_edges)
    events = parse_events(top, lambda raw, written: _cam_file(raw, written, base, "cam"))
    bus = _bus(top)
    check_sync_start(top, drive, bus)
    return Scene(name=name, path=path, cam_mode=cam_mode, master=master,
                 cam=cam_spec, drive=drive, mechanics=_mechanics(top, sizing),
                 bus=bus, limits=_limits(top), duration=_duration(top, drive.cycle_s),
                 description=description, fidelity=fidelity, sizing=sizing, events=events,
                 tappets=read_tappets(top))


def _master(top: Fields) -> MasterSpec:
    common = ("speed", "speed_rpm", "profile", "lead_cycles")
    raw = top.table("master", {*common, *(k for keys in PROFILE_KEYS.values() for k in keys)},
                    required=True)
    if ("speed" in raw) == ("speed_rpm" in raw):
        raise raw.error("master: give exactly one of speed (master units/s) and speed_rpm "
                        "(master periods per minute)")
    profile = raw.choice("profile", PROFILES, default="constant")
    allowed = PROFILE_KEYS[profile]
    for key in raw.raw:
        if key not in common + allowed:
            raise raw.error(f"{raw.name(key)}: does not apply to profile {profile!r}; expected "
                            f"one of {', '.join(sorted(allowed)) or 'none'}")
    key = "speed" if "speed" in raw else "speed_rpm"
    speed = raw.number(key, minimum=-MAX_MASTER_SPEED, maximum=MAX_MASTER_SPEED)
    if abs(speed) < MIN_MASTER_SPEED:
        raise raw.error(f"{raw.name(key)}: {show(speed)} should be non-zero, at least "
                        f"{MIN_MASTER_SPEED:g} in magnitude")
    spec = {key: speed, "profile": profile,
            "lead_cycles": raw.integer("lead_cycles", default=1, minimum=0, maximum=MAX_LEAD_CYCLES)}
    if profile == "start_stop":
        spec["max_acceleration"] = raw.number("max_acceleration", required=True, minimum=0.0,
                                              strict=True)
        spec["max_jerk"] = raw.number("max_jerk", required=True, minimum=0.0, strict=True)
        spec["start_s"] = raw.number("start_s", default=0.0, minimum=0.0)
        spec["stop_s"] = raw.number("stop_s", minimum=spec["start_s"])
    elif profile == "cam_in":
        spec["engage_at"] = raw.number("engage_at", required=True)
        spec["slave_start"] = raw.number("slave_start", default=0.0)
        for limit in ("max_velocity", "slave_max_acceleration", "slave_max_jerk"):
            spec[limit] = raw.number(limit, required=True, minimum=0.0, strict=True)
    return MasterSpec(**spec)


def _cam(top: Fields, base: Path, profile: CamProfile | None = None) -> CamSpec:
    raw = top.table("cam", {"file", "interp", "points", "tolerance", "master_counts",
                            "slave_counts_per_unit"}, required=profile is None)
    if profile is not None:
        file = None
    elif "file" not in raw:
        raise raw.error(f"{raw.name('file')}: missing; expected the path of a cam TOML file")
    else:
        file = _cam_file(raw, raw.string("file"), base)
    if "points" in raw and "tolerance" in raw:
        raise raw.error("cam: give at most one of points and tolerance")
    tolerance = raw.get("tolerance")
    if tolerance is not None:
        with raw.calling():
            parse_tolerance(tolerance)  # a number in slave units, or e.g. "2 counts"
    return CamSpec(
        file=file, profile=profile,
        interp=raw.choice("interp", INTERPOLATIONS),
        points=raw.integer("points", minimum=2),
        tolerance=tolerance,
        master_counts=raw.integer("master_counts", minimum=2, maximum=MAX_MASTER_COUNTS),
        slave_counts_per_unit=raw.number("slave_counts_per_unit", minimum=MIN_COUNTS_PER_UNIT,
                                         maximum=MAX_COUNTS_PER_UNIT))


def _cam_file(raw: Fields, written: str, base: Path, key: str = "file") -> Path:
    """The cam file a scene names (in ``key``), resolved relative to the scene (or a built-in
    cam)."""
    name = raw.name(key)
    try:
        file = (base / written).resolve()
        exists, regular = file.exists(), file.is_file()
    except (OSError, RuntimeError, ValueError) as exc:  # RuntimeError: a symlink loop (3.11)
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise raw.error(f"{name}: {show(written)} cannot be resolved: {reason[:120]}") from None
    if exists and not regular:
        raise raw.error(f"{name}: {show(written)} should be a regular file (resolved to "
                        f"{show_path(file)})")
    if not regular:
        # An installed package has no firmware_tables/ beside it: the shipped scenes' cams are
        # also ecam's built-in cams, found by file name.
        built_in = CAMS_DIR / Path(written).name
        if not built_in.is_file():
            raise raw.error(f"{name}: {show(written)} does not exist (resolved to "
                            f"{show_path(file)})")
        file = built_in.resolve()
    return file


def _drive(top: Fields) -> DriveSpec:
    raw = top.table("drive", {"node_id", "cycle_s", "substeps", "following_error_window",
                              "model", "gains", "feedforward", "speed_symmetrization",
                              "friction_feedforward", "tpdo_transmission_type",
                              "tpdo_sync_start", *DRIVE_FIELDS, *DRIVE_SIZING_KEYS})
    gains_raw = raw.table("gains", GAIN_BANDWIDTH_KEYS + GAIN_KEYS)
    gains = tuple((key, gains_raw.number(key, minimum=0.0))
                  for key in GAIN_BANDWIDTH_KEYS + GAIN_KEYS if key in gains_raw)
    if "notch_hz" in gains_raw:  # one that cannot be designed is refused here, not in the run
        with gains_raw.calling(lambda field: field):
            check_notch_hz(gains_raw.name("notch_hz"), gains_raw.get("notch_hz"))
    cycle_s = raw.number("cycle_s", default=0.001, minimum=1e-5, maximum=0.255)
    # 0x60C2 holds the period as value x 10^index with an 8-bit value: it must be representable.
    if interpolation_period(cycle_s) is None:
        raise raw.error(f"{raw.name('cycle_s')}: {show(cycle_s)} should be n x 10^e s with n in "
                        "1..255 (the 0x60C2 format), e.g. 0.001 or 0.0025")
    return DriveSpec(
        node_id=raw.integer("node_id", default=1, minimum=1, maximum=127),
        cycle_s=cycle_s,
        substeps=raw.integer("substeps", default=4, minimum=1, maximum=1000),
        following_error_window=raw.integer("following_error_window", default=100000,
                                           minimum=1, maximum=0xFFFFFFFF),
        model=raw.choice("model", MODELS, default="auto"),
        gains=gains,
        feedforward=raw.choice("feedforward", FEEDFORWARD_SOURCES, default="offset"),
        effects=_drive_effects(raw),
        # both off by default, as drives ship them (SINAMICS p1428/p1429 = 0, Beckhoff
        # P-AXIS-00361 = 0; hil_sim.control.DriveEffects), and as measured on the shipped scenes
        # (docs/tuning.md): neither lowers every scene's tracking error
        speed_symmetrization=raw.boolean("speed_symmetrization", default=False),
        friction_feedforward=raw.boolean("friction_feedforward", default=False),
        tpdo_transmission_type=raw.integer("tpdo_transmission_type", default=1, minimum=1,
                                           maximum=MAX_TRANSMISSION_TYPE),
        tpdo_sync_start=raw.integer("tpdo_sync_start", default=0, minimum=0,
                                    maximum=MAX_SYNC_COUNTER_OVERFLOW))


def _drive_effects(raw: Fields) -> tuple:
    """The drive effect fields the scene gives (0 for a number: the effect is absent)."""
    out = []
    if "encoder_counts_per_rev" in raw:
        counts = raw.integer("encoder_counts_per_rev", minimum=0, maximum=2**40)
        if 0 < counts < 4:
            raise raw.error(f"{raw.name('encoder_counts_per_rev')}: {counts} should be 0 (ideal "
                            "feedback) or an integer in 4..2^40")
        out.append(("encoder_counts_per_rev", counts))
    for key in ("velocity_filter_hz", "current_loop_bandwidth_hz"):
        if key in raw:
            out.append((key, raw.number(key, minimum=0.0, maximum=MAX_BANDWIDTH_HZ,
                                        strict=key == "velocity_filter_hz")))
    if "computation_delay" in raw:
        out.append(("computation_delay", raw.boolean("computation_delay")))
    return tuple(out)


def _mechanics(top: Fields, sizing: SizingSpec = SizingSpec()) -> MechanicsSpec:
    raw = top.table("mechanics", {*MECHANICS_KEYS, "slave_units_per_load_radian",
                                  *MECHANICS_FIELDS, *GEARHEAD_KEYS}, required=True)
    values = []
    for key in MECHANICS_KEYS:
        # a [motor] gives the rotor's inertia (hil_sim.sizing_spec)
        required = key == "motor_inertia" and sizing.motor is None
        value = raw.number(key, required=required, maximum=MECHANICS_RANGES[key],
                           minimum=MECHANICS_MINIMA.get(key))
        if key == "load_inertia" and value is not None and 0.0 < value < MIN_LOAD_INERTIA:
            raise raw.error(f"{raw.name(key)}: {show(value)} should be 0 or >= {MIN_LOAD_INERTIA:g}")
        if value is not None:
            values.append((key, value))
    if sizing.given:  # the drive train folded into the machine (hil_sim.sizing_spec)
        values = list(sizing.fold(dict(values)).items())
    effects = tuple((key, raw.number(key, minimum=0.0, maximum=EFFECT_RANGES[key]))
                    for key in MECHANICS_FIELDS if key in raw)
    spec = MechanicsSpec(values=tuple(values), slave_units_per_load_radian=raw.number(
        "slave_units_per_load_radian", default=1.0, minimum=SLAVE_UNITS_PER_RADIAN_RANGE[0],
        maximum=SLAVE_UNITS_PER_RADIAN_RANGE[1]), effects=effects)
    with raw.calling():  # the lower bounds and the rules between fields are Mechanics' own
        spec.build()
    return spec


def _bus(top: Fields) -> BusSpec:
    raw = top.table("bus", {"bitrate", "faults", "sync_counter_overflow", "master_position_pdo"})
    bitrate = raw.integer("bitrate", default=1_000_000, minimum=10_000, maximum=1_000_000)
    overflow = raw.integer("sync_counter_overflow", default=0, minimum=0,
                           maximum=MAX_SYNC_COUNTER_OVERFLOW)
    if overflow == 1:  # CiA 301 7.5.2.22: 1 is reserved
        raise raw.error(f"{raw.name('sync_counter_overflow')}: 1 should be 0 (no SYNC counter) "
                        f"or 2..{MAX_SYNC_COUNTER_OVERFLOW} (CiA 301 0x1019: 1 is reserved)")
    master_pdo = raw.choice("master_position_pdo", MASTER_POSITION_PDOS, default="per_axis")
    faults_raw = raw.table("faults", {f.name for f in fields(Faults)})
    # Faults checks its own values; the reader supplies the file's names for its messages.
    kwargs = {key: value for key, value in faults_raw.raw.items() if key != "drop"}
    if "drop" in faults_raw:
        drops = faults_raw.get("drop")
        name = faults_raw.name("drop")
        if not isinstance(drops, list):
            raise faults_raw.error(f"{name}: {show(drops)} should be a list of "
                                   "{cycle = N, frame = KIND} tables")
        entries = []
        for i, entry in enumerate(drops):
            entry = Fields(entry, f"{name}[{i}]", faults_raw.source, {"cycle", "frame"})
            entries.append((entry.integer("cycle", required=True),
                            entry.choice("frame", FRAME_KINDS, required=True)))
        kwargs["drop"] = tuple(entries)
    with faults_raw.calling():
        faults = Faults(**kwargs)
    return BusSpec(bitrate=bitrate, faults=faults, sync_counter_overflow=overflow,
                   master_position_pdo=master_pdo)


def _limits(top: Fields) -> LimitsSpec:
    raw = top.table("limits", {f.name for f in fields(LimitsSpec)}, required=True)
    return LimitsSpec(
        tracking_error=raw.number("tracking_error", required=True, minimum=0.0, strict=True),
        following_error=raw.integer("following_error", minimum=1),
        bus_load_percent=raw.number("bus_load_percent", default=100.0, minimum=0.0,
                                    strict=True),
        wind_up_deg=raw.number("wind_up_deg", minimum=0.0, strict=True),
        resonance_excitation_percent=raw.number("resonance_excitation_percent", default=5.0,
                                                minimum=0.0),
        motor_saturation_percent=raw.number("motor_saturation_percent", default=0.0,
                                            minimum=0.0, maximum=100.0),
        tracking_window=_window(raw, "tracking_window"),
        settle_s=raw.number("settle_s", default=0.0, minimum=0.0, maximum=MAX_SETTLE_S),
        # the loop_stability check's limits (hil_sim.tuning.MarginLimits has the same bounds)
        phase_margin_deg=raw.number("phase_margin_deg", default=45.0, minimum=0.0, maximum=90.0),
        gain_margin_db=raw.number("gain_margin_db", default=6.0, minimum=0.0, maximum=60.0),
        sensitivity_peak=raw.number("sensitivity_peak", default=2.0, minimum=1.0,
                                    maximum=100.0, strict=True),
        inertia_ratio=raw.number("inertia_ratio", minimum=0.0, strict=True),
        tappet_error=raw.number("tappet_error", minimum=0.0, strict=True))


def _window(raw: Fields, key: str) -> tuple[float, float] | None:
    """A window [start, end] of master positions; end < start spans the seam."""
    if key not in raw:
        return None
    value = raw.get(key)
    name = raw.name(key)
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise raw.error(f"{name}: {show(value)} should be [start, end] in master units (two "
                        "numbers; end < start spans the seam)")
    with raw.calling():
        start, end = (number(f"{key}[{i}]", v, minimum=-MAX_WINDOW_POSITION,
                             maximum=MAX_WINDOW_POSITION) for i, v in enumerate(value))
    if start == end:
        raise raw.error(f"{name}: {show(value)} should have start != end")
    return start, end


def _duration(top: Fields, cycle_s: float) -> DurationSpec:
    raw = top.table("duration", {"cycles", "seconds", "master_periods"}, required=True)
    if len(raw.raw) != 1:
        raise raw.error(f"duration: {show(dict(raw.raw))} should give exactly one of cycles, "
                        "seconds, master_periods")
    seconds = raw.number("seconds", minimum=0.0, strict=True)
    # Seconds are bounded here, where the file and the field are known, by the cycles they make
    # at the scene's own cycle time (the rig counts them the same way, hil_sim.rig.plan); cam
    # periods need the cam and the master speed, so the rig bounds those.
    if seconds is not None and math.ceil(seconds / cycle_s - 1e-9) > MAX_CYCLES:
        raise raw.error(f"{raw.name('seconds')}: {show(seconds)} should be <= "
                        f"{MAX_CYCLES * cycle_s:g} ({MAX_CYCLES} cycles at drive.cycle_s "
                        f"{cycle_s:g})")
    return DurationSpec(
        cycles=raw.integer("cycles", minimum=1, maximum=MAX_CYCLES),
        seconds=seconds,
        master_periods=raw.number("master_periods", minimum=0.0, strict=True))

