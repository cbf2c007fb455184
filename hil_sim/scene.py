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

    [master]
    speed = 720.0                      # master units/s; or speed_rpm = master periods/min
    profile = "constant"               # "constant", "start_stop" or "cam_in"
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
    [drive.gains]                      # optional: bandwidths and/or raw gains
    velocity_bandwidth_hz = 200.0

    [mechanics]                        # hil_sim.mechanics.Mechanics fields, SI
    motor_inertia = 1.2e-4
    gear_ratio = 0.1
    slave_units_per_load_radian = 1.0  # slave user units per radian of the load shaft

    [bus]
    bitrate = 1000000
    [bus.faults]                       # optional, see hil_sim.bus.Faults
    seed = 1
    drop_probability = 0.01

    [limits]
    tracking_error = 0.002             # slave units, load side against the cam
    following_error = 40000            # counts, motor side; default the drive's window
    bus_load_percent = 100.0
    wind_up_deg = 0.5                  # optional
    resonance_excitation_percent = 5.0
    motor_saturation_percent = 0.0

    [duration]                         # exactly one of
    master_periods = 3.0               # at the cruise speed
    # cycles = 5000
    # seconds = 5.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from ecam.camfile import CAMS_DIR, load_cam, read_toml
from ecam.errors import CamFileError, InputError
from ecam.profile import CamProfile
from ecam.table import INTERPOLATIONS
from ecam.table_spec import MAX_COUNTS_PER_UNIT, MIN_COUNTS_PER_UNIT, parse_tolerance
from hil_sim.bus import FRAME_KINDS, Faults
from ecam.validate import show as _show

CAM_MODES = ("controller", "drive")
PROFILES = ("constant", "start_stop", "cam_in")
MODELS = ("auto", "rigid", "two_mass")
INTERPS = INTERPOLATIONS
GAIN_BANDWIDTH_KEYS = ("velocity_bandwidth_hz", "position_bandwidth_hz", "integral_ratio")
GAIN_KEYS = ("position_kp", "velocity_kp", "velocity_ki", "velocity_feedforward",
             "acceleration_feedforward")
# Resolution of the slave in counts per user unit: a nanometre encoder on a metre is 1e9, a
# coarse one on a degree 1e-3; bounds far outside both keep the count arithmetic finite.

# Physical range of each mechanics field [SI]: wide enough for a watch motor and a press, narrow
# enough that products of them (torques, energies, the plant matrices) stay finite in float64.
# (Upper bounds; the lower bound is 0, exclusive for POSITIVE_MECHANICS, as the plant needs.)
MECHANICS_RANGES = {
    "motor_inertia": 1e4, "load_inertia": 1e6, "gear_ratio": 1e4, "gear_efficiency": 1.0,
    "motor_damping": 1e6, "load_damping": 1e8, "coupling_stiffness": 1e12,
    "coupling_damping": 1e8, "coupling_rated_torque": 1e8, "coupling_max_torque": 1e8,
    "motor_torque_limit": 1e6,
}
POSITIVE_MECHANICS = frozenset({"motor_inertia", "gear_ratio", "gear_efficiency",
                                "coupling_stiffness", "coupling_rated_torque",
                                "coupling_max_torque", "motor_torque_limit"})

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


@dataclass(frozen=True)
class DriveSpec:
    """The drive: node id, cycle, control loop, following-error window, plant model."""

    node_id: int = 1
    cycle_s: float = 0.001
    substeps: int = 4
    following_error_window: int = 100000
    model: str = "auto"
    gains: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class MechanicsSpec:
    """Keyword arguments of :class:`hil_sim.mechanics.Mechanics`, plus the load scaling."""

    values: tuple[tuple[str, float | None], ...]
    slave_units_per_load_radian: float = 1.0

    def build(self):
        """The :class:`~hil_sim.mechanics.Mechanics` (its own checks name the field)."""
        from hil_sim.mechanics import Mechanics
        return Mechanics(**dict(self.values))


@dataclass(frozen=True)
class BusSpec:
    """Bitrate and faults (:class:`hil_sim.bus.Faults`)."""

    bitrate: int = 1_000_000
    faults: object = None


@dataclass(frozen=True)
class LimitsSpec:
    """Limits of the report's checks (None: the check is reported without a limit)."""

    tracking_error: float
    following_error: int | None = None
    bus_load_percent: float = 100.0
    wind_up_deg: float | None = None
    resonance_excitation_percent: float = 5.0
    motor_saturation_percent: float = 0.0


@dataclass(frozen=True)
class DurationSpec:
    """Exactly one of cycles, seconds, master periods (at cruise speed)."""

    cycles: int | None = None
    seconds: float | None = None
    master_periods: float | None = None


@dataclass(frozen=True)
class Scene:
    """A whole rig run, as read from a scene file."""

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

    def with_master_speed(self, speed: float) -> "Scene":
        """The same scene at another master speed [master units/s]."""
        return replace(self, master=replace(self.master, speed=float(speed), speed_rpm=None))


# ------------------------------------------------------------------------------------------
class _Reader:
    """Field access with one-line errors: '<file>: <section.key>: <value> should be ...'."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, message: str) -> CamFileError:
        return CamFileError(f"scene {self.source}: {where}: {message}")

    def table(self, raw: dict, key: str, allowed, where: str = "", required: bool = False) -> dict:
        name = f"{where}{key}"
        if key not in raw:
            if required:
                raise self.fail(name, "missing; expected a table")
            return {}
        value = raw[key]
        if not isinstance(value, dict):
            raise self.fail(name, f"{_show(value)} should be a table ([{name}])")
        self.unknown(value, allowed, name + ".")
        return value

    def unknown(self, raw: dict, allowed, prefix: str) -> None:
        for key in raw:
            if key not in allowed:
                raise self.fail(f"{prefix}{key}", f"unknown field; expected one of "
                                f"{', '.join(sorted(allowed))}")

    def number(self, raw, key, where, *, required=False, default=None, minimum=None,
               strict=False, maximum=None):
        name = f"{where}.{key}" if where else key
        if key not in raw:
            if required:
                raise self.fail(name, "missing; expected a number")
            return default
        value = raw[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(name, f"{_show(value)} should be a number")
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(name, f"{value!r} should be finite")
        if minimum is not None and (value <= minimum if strict else value < minimum):
            raise self.fail(name, f"{value!r} should be {'>' if strict else '>='} {minimum:g}")
        if maximum is not None and value > maximum:
            raise self.fail(name, f"{value!r} should be <= {maximum:g}")
        return value

    def integer(self, raw, key, where, *, required=False, default=None, minimum=None,
                maximum=None):
        name = f"{where}.{key}" if where else key
        if key not in raw:
            if required:
                raise self.fail(name, "missing; expected an integer")
            return default
        value = raw[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(name, f"{_show(value)} should be an integer")
        if minimum is not None and value < minimum or maximum is not None and value > maximum:
            bounds = f"in {minimum}..{maximum}" if maximum is not None else f">= {minimum}"
            raise self.fail(name, f"{value} should be an integer {bounds}")
        return value

    def choice(self, raw, key, where, choices, default):
        name = f"{where}.{key}" if where else key
        value = raw.get(key, default)
        if value not in choices:
            raise self.fail(name, f"{_show(value)} should be one of {', '.join(choices)}")
        return value

    def string(self, raw, key, default):
        value = raw.get(key, default)
        if not isinstance(value, str):
            raise self.fail(key, f"{_show(value)} should be a string")
        return value


def load_scene(path, cam: CamProfile | None = None) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or Path
        The scene TOML; the cam file inside is resolved relative to it.
    cam : ecam.CamProfile, optional
        A cam built in Python: it replaces the scene's ``cam.file`` (which may then be left
        out); the scene's other ``[cam]`` settings still apply.

    Returns
    -------
    Scene

    Raises
    ------
    CamFileError
        Missing or unreadable file, invalid TOML, or a field out of range; one line naming
        the field, the value and what was expected.
    """
    path = Path(path)
    data = read_toml(path, "scene file")
    return parse_scene(data, base=path.parent, source=path.name, path=path.resolve(), cam=cam)


def parse_scene(data: dict, base: Path = Path("."), source: str = "<scene>",
                path: Path | None = None, cam: CamProfile | None = None) -> Scene:
    """Build a :class:`Scene` from a parsed TOML mapping; ``base`` resolves the cam file and
    ``cam``, an in-memory :class:`ecam.CamProfile`, replaces it (see :func:`load_scene`)."""
    if cam is not None and not isinstance(cam, CamProfile):
        raise InputError(f"cam: {type(cam).__name__} should be an ecam.CamProfile")
    r = _Reader(source)
    r.unknown(data, {"name", "description", "cam_mode", "master", "cam", "drive", "mechanics",
                     "bus", "limits", "duration"}, "")
    name = r.string(data, "name", Path(source).stem)
    description = r.string(data, "description", "")
    cam_mode = r.choice(data, "cam_mode", "", CAM_MODES, "controller")

    master = _master(r, data)
    if cam_mode == "drive" and master.profile == "cam_in":
        raise r.fail("cam_mode", "'drive' should be 'controller' for master.profile 'cam_in' "
                     "(the controller plans the cam-in)")
    cam = _cam(r, data, base, cam)
    drive = _drive(r, data)
    mechanics = _mechanics(r, data)
    bus = _bus(r, data)
    limits = _limits(r, data)
    duration = _duration(r, data)
    return Scene(name=name, path=path, cam_mode=cam_mode, master=master, cam=cam, drive=drive,
                 mechanics=mechanics, bus=bus, limits=limits, duration=duration,
                 description=description)


def _master(r: _Reader, data) -> MasterSpec:
    keys = {"speed", "speed_rpm", "profile", "max_acceleration", "max_jerk", "start_s",
            "stop_s", "engage_at", "slave_start", "max_velocity", "slave_max_acceleration",
            "slave_max_jerk"}
    raw = r.table(data, "master", keys, required=True)
    if ("speed" in raw) == ("speed_rpm" in raw):
        raise r.fail("master", "give exactly one of speed (master units/s) and speed_rpm "
                     "(master periods per minute)")
    profile = r.choice(raw, "profile", "master", PROFILES, "constant")
    allowed = {"constant": set(), "start_stop": {"max_acceleration", "max_jerk", "start_s", "stop_s"},
               "cam_in": {"engage_at", "slave_start", "max_velocity", "slave_max_acceleration",
                          "slave_max_jerk"}}[profile]
    for key in raw:
        if key not in {"speed", "speed_rpm", "profile"} | allowed:
            raise r.fail(f"master.{key}", f"does not apply to profile {profile!r}; expected "
                         f"one of {', '.join(sorted(allowed)) or 'none'}")
    key = "speed" if "speed" in raw else "speed_rpm"
    speed = r.number(raw, key, "master")
    if speed == 0.0:
        raise r.fail(f"master.{key}", "0.0 should be non-zero")
    spec = {key: speed, "profile": profile}
    if profile == "start_stop":
        spec["max_acceleration"] = r.number(raw, "max_acceleration", "master", required=True,
                                            minimum=0.0, strict=True)
        spec["max_jerk"] = r.number(raw, "max_jerk", "master", required=True, minimum=0.0,
                                    strict=True)
        spec["start_s"] = r.number(raw, "start_s", "master", default=0.0, minimum=0.0)
        spec["stop_s"] = r.number(raw, "stop_s", "master", minimum=spec["start_s"])
    elif profile == "cam_in":
        spec["engage_at"] = r.number(raw, "engage_at", "master", required=True)
        spec["slave_start"] = r.number(raw, "slave_start", "master", default=0.0)
        spec["max_velocity"] = r.number(raw, "max_velocity", "master", required=True,
                                        minimum=0.0, strict=True)
        spec["slave_max_acceleration"] = r.number(raw, "slave_max_acceleration", "master",
                                                  required=True, minimum=0.0, strict=True)
        spec["slave_max_jerk"] = r.number(raw, "slave_max_jerk", "master", required=True,
                                          minimum=0.0, strict=True)
    return MasterSpec(**spec)


def _cam(r: _Reader, data, base: Path, profile: CamProfile | None = None) -> CamSpec:
    raw = r.table(data, "cam", {"file", "interp", "points", "tolerance", "master_counts",
                                "slave_counts_per_unit"}, required=profile is None)
    if profile is not None:
        file = None
    elif "file" not in raw:
        raise r.fail("cam.file", "missing; expected the path of a cam TOML file")
    elif not isinstance(raw["file"], str):
        raise r.fail("cam.file", f"{_show(raw['file'])} should be a string")
    else:
        file = _cam_file(r, raw["file"], base)
    interp = raw.get("interp")
    if interp is not None and interp not in INTERPS:
        raise r.fail("cam.interp", f"{_show(interp)} should be one of {', '.join(INTERPS)}")
    if "points" in raw and "tolerance" in raw:
        raise r.fail("cam", "give at most one of points and tolerance")
    tolerance = raw.get("tolerance")
    if tolerance is not None:
        try:
            parse_tolerance(tolerance)  # a number in slave units, or e.g. "2 counts"
        except InputError:
            raise r.fail("cam.tolerance", f"{_show(tolerance)} should be a number > 0 in slave units "
                         "or a string like '2 counts'") from None
    return CamSpec(
        file=file, interp=interp, profile=profile,
        points=r.integer(raw, "points", "cam", minimum=2),
        tolerance=tolerance,
        master_counts=r.integer(raw, "master_counts", "cam", minimum=2, maximum=2**31),
        slave_counts_per_unit=r.number(raw, "slave_counts_per_unit", "cam",
                                       minimum=MIN_COUNTS_PER_UNIT, maximum=MAX_COUNTS_PER_UNIT))


def _cam_file(r: _Reader, written: str, base: Path) -> Path:
    """The cam file a scene names, resolved relative to the scene (or a built-in cam)."""
    try:
        file = (base / written).resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python 3.11)
        raise r.fail("cam.file", f"{written!r} cannot be resolved: {exc}") from None
    if not file.is_file():
        # An installed package has no firmware_tables/ beside it: the shipped scenes' cams are
        # also ecam's built-in cams, found by file name.
        built_in = CAMS_DIR / Path(written).name
        if not built_in.is_file():
            raise r.fail("cam.file", f"{written!r} does not exist (resolved to {str(file)!r})")
        file = built_in.resolve()
    return file


def _drive(r: _Reader, data) -> DriveSpec:
    raw = r.table(data, "drive", {"node_id", "cycle_s", "substeps", "following_error_window",
                                  "model", "gains"})
    gains_raw = r.table(raw, "gains", set(GAIN_BANDWIDTH_KEYS + GAIN_KEYS), where="drive.")
    gains = tuple((key, r.number(gains_raw, key, "drive.gains", minimum=0.0))
                  for key in GAIN_BANDWIDTH_KEYS + GAIN_KEYS if key in gains_raw)
    cycle_s = r.number(raw, "cycle_s", "drive", default=0.001, minimum=1e-5, maximum=0.255)
    # 0x60C2 holds the period as value x 10^index with an 8-bit value: it must be representable.
    if interpolation_period(cycle_s) is None:
        raise r.fail("drive.cycle_s", f"{cycle_s!r} should be n x 10^e s with n in 1..255 "
                     "(the 0x60C2 format), e.g. 0.001 or 0.0025")
    return DriveSpec(
        node_id=r.integer(raw, "node_id", "drive", default=1, minimum=1, maximum=127),
        cycle_s=cycle_s,
        substeps=r.integer(raw, "substeps", "drive", default=4, minimum=1, maximum=1000),
        following_error_window=r.integer(raw, "following_error_window", "drive",
                                         default=100000, minimum=1, maximum=0xFFFFFFFF),
        model=r.choice(raw, "model", "drive", MODELS, "auto"),
        gains=gains)


def interpolation_period(cycle_s: float) -> tuple[int, int] | None:
    """The cycle as CiA 402 object 0x60C2 holds it: (value, index) with value x 10^index ==
    ``cycle_s`` and value in 1..255 (UNSIGNED8), or None when it has no such form."""
    for index in range(-6, 1):
        value = cycle_s / 10.0**index
        if 1 <= round(value) <= 255 and math.isclose(value, round(value), rel_tol=1e-9):
            return round(value), index
    return None


def _mechanics(r: _Reader, data) -> MechanicsSpec:
    raw = r.table(data, "mechanics", set(MECHANICS_KEYS) | {"slave_units_per_load_radian"},
                  required=True)
    values = []
    for key in MECHANICS_KEYS:
        if key in raw:
            high = MECHANICS_RANGES[key]
            values.append((key, r.number(raw, key, "mechanics", minimum=0.0,
                                         strict=key in POSITIVE_MECHANICS, maximum=high)))
    if "motor_inertia" not in raw:
        raise r.fail("mechanics.motor_inertia", "missing; expected a number [kg m^2]")
    spec = MechanicsSpec(values=tuple(values), slave_units_per_load_radian=r.number(
        raw, "slave_units_per_load_radian", "mechanics", default=1.0, minimum=0.0, strict=True))
    try:
        spec.build()
    except InputError as exc:
        raise r.fail("mechanics", str(exc)) from None
    return spec


def _bus(r: _Reader, data) -> BusSpec:
    raw = r.table(data, "bus", {"bitrate", "faults"})
    bitrate = r.integer(raw, "bitrate", "bus", default=1_000_000, minimum=10_000,
                        maximum=1_000_000)
    keys = {f.name for f in fields(Faults)}
    faults_raw = r.table(raw, "faults", keys, where="bus.")
    kwargs = {}
    for key in ("seed", "delay_cycles"):
        if key in faults_raw:
            kwargs[key] = r.integer(faults_raw, key, "bus.faults", minimum=0 if key == "seed" else 1)
    for key in ("drop_probability", "delay_probability"):
        if key in faults_raw:
            kwargs[key] = r.number(faults_raw, key, "bus.faults", minimum=0.0, maximum=1.0)
    if "sync_jitter_s" in faults_raw:
        kwargs["sync_jitter_s"] = r.number(faults_raw, "sync_jitter_s", "bus.faults",
                                           minimum=0.0, maximum=0.1)
    if "kinds" in faults_raw:
        kinds = faults_raw["kinds"]
        if not isinstance(kinds, list) or any(k not in FRAME_KINDS for k in kinds):
            raise r.fail("bus.faults.kinds", f"{_show(kinds)} should be a list of "
                         f"{', '.join(FRAME_KINDS)}")
        kwargs["kinds"] = tuple(kinds)
    if "drop" in faults_raw:
        drops = faults_raw["drop"]
        if not isinstance(drops, list):
            raise r.fail("bus.faults.drop", f"{_show(drops)} should be a list of "
                         "{cycle = N, frame = KIND} tables")
        entries = []
        for i, entry in enumerate(drops):
            where = f"bus.faults.drop[{i}]"
            if not isinstance(entry, dict):
                raise r.fail(where, f"{_show(entry)} should be a table {{cycle = N, frame = KIND}}")
            r.unknown(entry, {"cycle", "frame"}, where + ".")
            cycle = r.integer(entry, "cycle", where, required=True, minimum=0)
            frame = r.choice(entry, "frame", where, FRAME_KINDS, None)
            entries.append((cycle, frame))
        kwargs["drop"] = tuple(entries)
    try:
        faults = Faults(**kwargs)
    except InputError as exc:
        raise r.fail("bus.faults", str(exc)) from None
    return BusSpec(bitrate=bitrate, faults=faults)


def _limits(r: _Reader, data) -> LimitsSpec:
    raw = r.table(data, "limits", {f.name for f in fields(LimitsSpec)}, required=True)
    return LimitsSpec(
        tracking_error=r.number(raw, "tracking_error", "limits", required=True, minimum=0.0,
                                strict=True),
        following_error=r.integer(raw, "following_error", "limits", minimum=1),
        bus_load_percent=r.number(raw, "bus_load_percent", "limits", default=100.0,
                                  minimum=0.0, strict=True),
        wind_up_deg=r.number(raw, "wind_up_deg", "limits", minimum=0.0, strict=True),
        resonance_excitation_percent=r.number(raw, "resonance_excitation_percent", "limits",
                                              default=5.0, minimum=0.0),
        motor_saturation_percent=r.number(raw, "motor_saturation_percent", "limits",
                                          default=0.0, minimum=0.0, maximum=100.0))


def _duration(r: _Reader, data) -> DurationSpec:
    raw = r.table(data, "duration", {"cycles", "seconds", "master_periods"}, required=True)
    if len(raw) != 1:
        raise r.fail("duration", f"{_show(raw)} should give exactly one of cycles, seconds, "
                     "master_periods")
    return DurationSpec(
        cycles=r.integer(raw, "cycles", "duration", minimum=1, maximum=100_000_000),
        seconds=r.number(raw, "seconds", "duration", minimum=0.0, strict=True),
        master_periods=r.number(raw, "master_periods", "duration", minimum=0.0, strict=True))




_interpolation_period = interpolation_period  # the rig's old name, until it imports the public one
