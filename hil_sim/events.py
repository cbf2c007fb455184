"""A scene's events: what the master and the drive see when cams change while the machine runs.

A scene lists ``[[event]]`` tables; each happens at a master period number (``at_period``: the
start of that period of the scene's cam, master position N x period), a master position
(``at_position``) or a time (``at_s``), and does one ``action``. The PLCopen names (Technical
Specification "Function Blocks for Motion Control", TC2, Version 2.0, 2011: the function
blocks ``MC_CamTableSelect``, ``MC_CamIn``, ``MC_CamOut``, ``MC_Phasing``; the section numbers
could not be checked against the published PDF, so the blocks are named, not numbered) and the
vendors' documentation of those blocks:

* ``switch``: a new cam (``MC_CamTableSelect`` + ``MC_CamIn`` on a coupled axis). Its activation
  is ``immediate``, ``period_end`` (the running cam's period end: CODESYS places the new cam
  "exactly at the end of the previous one", TwinCAT ``MC_CamActivationMode`` "next cam cycle")
  or ``master_position`` (TwinCAT "at master axis position", ``activation_position``). Master and
  slave are ``absolute`` or ``relative`` as PLCopen's ``MasterAbsolute`` / ``SlaveAbsolute``
  define them (Beckhoff ``MC_StartMode``: "With StartModeRelativ the origin of the cam plate
  coordinate system is at the axis position of the respective axis ... at the time of coupling
  or cam plate switching"); the rule is :mod:`ecam.cam_join`'s. Offsets and scaling are
  ``MC_CamIn``'s: the cam is evaluated at X = MasterScaling x master + MasterOffset (CODESYS
  SoftMotion, "MC_CamIn.MasterOffset, MC_CamIn.MasterScaling") and the slave is SlaveScaling x
  cam(X) + SlaveOffset (Beckhoff ``ST_CamScalingData``), plus, relative, the slave's position at
  the switch. ``start_mode = "ramp_in"`` (``MC_CamIn.StartMode``) brings the slave onto the new
  cam by a jerk-limited correction instead of a jump (:mod:`hil_sim.ramp_in`).
* ``offset``: the running cam with new offsets and scaling, activated like a switch.
* ``phase``: ``MC_Phasing``: a jerk-limited shift of the master position the slave sees
  ("MasterPos from the perspective of the SlaveAxis = PhysicalMasterPos + PhaseShift", SEW's
  ``MC_PhasingRelative``), planned by ruckig from the running shift's state to ``shift`` more,
  within ``max_velocity``, ``max_acceleration`` and ``max_jerk`` of the shift (master units/s^n:
  Beckhoff, "the dynamics values refer to the change in the 'apparent' master position").
* ``cam_out``: ``MC_CamOut``: the slave leaves the cam from its position, velocity and
  acceleration to a stop, on ruckig's jerk-limited profile within the event's slave limits.

Every switch (and offset) is reported with the jump it makes at its activation: position,
velocity, acceleration and jerk of the running cam's left limit against the new one's right
limit, per master unit (and per second at the master's speed there); a position, velocity or
acceleration jump is an error of the report unless the event says ``allow_jump = true``, a jerk
jump a warning, as :func:`ecam.cam_join.join_cams` judges a join.

Sources (the vendors' pages quoted above): CODESYS SoftMotion, "Function Blocks: MC_CamTableSelect
and MC_CamIn" (content.helpme-codesys.com, _sm_basic_function_blocks.html); Beckhoff TwinCAT NC
Camming, ``MC_StartMode`` (infosys.beckhoff.com tf5050_tc3_nc_camming/1003815691.html) and
``ST_CamScalingData`` (tf5050_tc3_nc_camming/1003864075.html); Beckhoff CNC ``MC_Phasing``
(tccncmcplatform_fb/15306202763.html); SEW-EURODRIVE ``MC_PhasingRelative``
(download.sew-eurodrive.com, 31988954/en-EN/56796799627.html).

One module for both paths: :func:`apply_events` turns the events into what the master and the
drive see. Controller-side (cam mode "controller"), the set points the controller streams (the
plan's targets and velocity offsets); drive-side (cam mode "drive"), the master position it
streams (shifted by the phase) and the commands a controller sends the drive's cam slot
(:mod:`hil_sim.drive.cam_slot`) by SDO: the new table downloaded into 0x2000, its coordinates
into 0x2001:05 and 0x2001:07..0C (MC_CamIn's offsets and scaling), a master position into
0x2001:06, and the activation into 0x2001:01 (1 at once, 3 at the running table's period end, 4
at the master position), in the cycle the event is requested; a cam-out writes the profile
limits (0x6083, 0x6084, 0x60A4:01) and 0x2001:01 = 5, and the drive stops by itself from the
cam's state in the next cycle (:mod:`hil_sim.drive.cam_out`), where the ideal path's stop starts. The bus-free path (:mod:`hil_sim.rig.fast`) applies
the same commands to its cam slot. Both paths check against the same ideal slave path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from ruckig import ControlInterface

import ecam
from ecam.camfile import load_cam, read_bounded
from ecam.errors import InputError, SimulationError
from ecam.profile import ORDER_NAMES
from ecam.table_spec import TableSpec
from hil_sim.drive.cam_coupling import scaling_ratio
from hil_sim.drive.cam_slot import (
    CAM_COMMAND_ACTIVATE, CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION, CAM_COMMAND_ACTIVATE_AT_PERIOD_END,
    CAM_COMMAND_CAM_OUT, SWITCH_MASTER_RELATIVE, SWITCH_SLAVE_RELATIVE,
)
from hil_sim.drive.objects import (
    CAM_ACTIVATION_POSITION, CAM_COMMAND, CAM_MASTER_OFFSET, CAM_MASTER_SCALING_DENOMINATOR,
    CAM_MASTER_SCALING_NUMERATOR, CAM_SLAVE_OFFSET, CAM_SLAVE_SCALING_DENOMINATOR,
    CAM_SLAVE_SCALING_NUMERATOR, CAM_SWITCH_MODE, CAM_TABLE_DOWNLOAD, PROFILE_ACCELERATION,
    PROFILE_DECELERATION, PROFILE_JERK,
)
from hil_sim import ramp_in
from hil_sim.event_spec import Event
from hil_sim.master import _Segment

__all__ = ["DriveCommand", "EventOutcome", "Motion", "Switch", "apply_events"]

# A jump is what exceeds float noise at the join, measured as ecam.cam_join measures it: relative
# to the values there, and to what the two cams can produce in that derivative.
_RELATIVE_NOISE = (1e-12, 1e-9, 1e-9, 1e-9)
_SCALE_SAMPLES = 1024


# ------------------------------------------------------------------------------ the report
@dataclass(frozen=True)
class Switch:
    """A switch (or offset) as it happened: when, where, and what jumped.

    Attributes
    ----------
    event : Event
    requested_s, active_s : float
        When it was requested and when it took effect [s]; ``active_s`` None: not reached
        within the run.
    master : float
        The master position (as the slave sees it) at the activation [master units].
    entry : float
        Where the new cam is entered, in its own master coordinate [master units].
    cam : str
        The new cam's name.
    left, right : tuple of float
        The running cam's left limit and the new cam's right limit there: position, velocity,
        acceleration, jerk per master unit^k [slave units].
    jumps : tuple of (order, size)
        The derivatives that jump (0..3) and by how much (right - left).
    speed : float
        The master's speed there [master units/s], to state the jumps per second.
    ramp : hil_sim.ramp_in.RampIn or None
        start_mode ramp_in: the correction that brought the slave onto the new cam (then
        ``jumps`` holds no position, velocity or acceleration jump: they are its start).
    superseded_by : str
        The later event that took its place before it activated (then ``active_s`` is None).
    """

    event: Event
    requested_s: float
    active_s: float | None
    master: float = math.nan
    entry: float = math.nan
    cam: str = ""
    left: tuple = ()
    right: tuple = ()
    jumps: tuple = ()
    speed: float = 0.0
    ramp: ramp_in.RampIn | None = None
    superseded_by: str = ""

    @property
    def errors(self) -> tuple:
        """The jumps that are errors (position, velocity, acceleration)."""
        return tuple((order, size) for order, size in self.jumps if order < 3)

    @property
    def failed(self) -> bool:
        return bool(self.errors) and not self.event.allow_jump

    def jump_text(self, slave_unit: str = "", master_unit: str = "") -> str:
        """The jumps in words: per master unit and per second."""
        if self.ramp is not None:
            return "no jump, " + self.ramp.text(slave_unit, master_unit)
        if not self.jumps:
            return "no jump"
        parts = []
        for order, size in self.jumps:
            per_s = size * self.speed**order
            unit = slave_unit + (f"/{master_unit}" + (f"^{order}" if order > 1 else "") if order else "")
            timed = (f" ({per_s:+.4g} {slave_unit}/s" + (f"^{order}" if order > 1 else "") + ")"
                     if order else "")
            parts.append(f"{ORDER_NAMES[order]} {size:+.4g} {unit}{timed}")
        return ", ".join(parts)

    def to_dict(self) -> dict:
        return {"event": self.event.index, "name": self.event.name, "action": self.event.action,
                "activation": self.event.activation, "cam": self.cam,
                "requested_s": self.requested_s, "active_s": self.active_s,
                "master": None if math.isnan(self.master) else self.master,
                "entry": None if math.isnan(self.entry) else self.entry,
                "master_coordinates": self.event.master, "slave_coordinates": self.event.slave,
                "left": list(self.left), "right": list(self.right),
                "jumps": {ORDER_NAMES[o]: s for o, s in self.jumps},
                "allowed": self.event.allow_jump, "failed": self.failed,
                **({"start_mode": "ramp_in", "ramp_in": self.ramp and self.ramp.to_dict()}
                   if self.event.start_mode == "ramp_in" else {}),
                **({"superseded_by": self.superseded_by} if self.superseded_by else {})}


@dataclass(frozen=True)
class Motion:
    """A phase shift or a cam-out as planned: when, how long, and its peaks against its limits
    (velocity, acceleration, jerk; the phase's in master units, the cam-out's in slave units)."""

    event: Event
    start_s: float
    duration_s: float
    peaks: tuple
    limits: tuple
    covered: float

    @property
    def ratio(self) -> float:
        """The largest peak / limit."""
        return max(p / lim for p, lim in zip(self.peaks, self.limits))

    def to_dict(self) -> dict:
        return {"event": self.event.index, "name": self.event.name, "action": self.event.action,
                "start_s": self.start_s, "duration_s": self.duration_s,
                "peaks": list(self.peaks), "limits": list(self.limits), "covered": self.covered}


@dataclass(frozen=True)
class DriveCommand:
    """An SDO write a controller sends the drive's cam slot after cycle ``cycle``'s SYNC:
    ``value`` bytes (a table blob into 0x2000) or an integer."""

    cycle: int
    index: int
    subindex: int
    value: bytes | int
    event: int

    @property
    def key(self) -> tuple:
        return (self.index, self.subindex)


@dataclass(frozen=True)
class EventOutcome:
    """What the events did in a run: the switches with their jumps, the phase shifts and
    cam-outs with their peaks, the phase shift per cycle [master units] for the plots, and
    drive-side the cam slot's commands."""

    switches: tuple = ()
    motions: tuple = ()
    phase: np.ndarray | None = field(default=None, repr=False, compare=False)
    drive_commands: tuple = field(default=(), repr=False, compare=False)

    def to_dict(self) -> dict:
        return {"switches": [s.to_dict() for s in self.switches],
                "motions": [m.to_dict() for m in self.motions]}


# ---------------------------------------------------------------------------- the program
class _Piece:
    """One cam as the slave runs it from ``start_s`` on: X = scaling (m - origin) + offset,
    slave = base + offset + scaling cam(X) (a cam that does not repeat holds its ends)."""

    def __init__(self, start_s, profile, table, origin, master_offset, master_scaling,
                 base, slave_offset, slave_scaling, per_unit):
        self.start_s = start_s
        self.profile, self.table = profile, table
        self.origin, self.master_offset, self.master_scaling = origin, master_offset, master_scaling
        self.base, self.slave_offset, self.slave_scaling = base, slave_offset, slave_scaling
        self.period = profile.master_period
        # table master counts per (scene) master count: 1 for the scene's own table unscaled
        self.table_per_unit = table.master_counts / self.period
        self.ratio = master_scaling * self.table_per_unit / per_unit
        self.identity = (self.ratio == 1.0 and origin == 0.0 and master_offset == 0.0
                         and base == 0.0 and slave_offset == 0.0 and slave_scaling == 1.0)
        self.ramp = None  # start_mode ramp_in: its correction (hil_sim.ramp_in.RampIn)

    def x(self, master):
        return self.master_scaling * (master - self.origin) + self.master_offset

    def state(self, master: float, side: str = "right") -> list:
        """Slave position and derivatives 1..3 per master unit at ``master`` (one side)."""
        x = self.x(master)
        profile, period = self.profile, self.period
        out = []
        for order in range(len(ORDER_NAMES)):
            if not profile.periodic and (x > period or x < 0.0 or (x == period and side == "right")
                                         or (x == 0.0 and side == "left")):
                value = float(profile(min(max(x, 0.0), period), 0)) if order == 0 else 0.0
            elif profile.periodic and side == "left" and x % period == 0.0:
                value = _left_of_seam(profile, x, order)
            else:
                value = float(profile(x, order, side=side))
            scale = self.slave_scaling * self.master_scaling**order
            out.append(scale * value + (self.base + self.slave_offset if order == 0 else 0.0))
        return out


def _left_of_seam(profile, x: float, order: int) -> float:
    """A periodic cam's left limit at a multiple of its period: its last segment's end, and the
    net strokes of the periods before."""
    last = profile.segments[-1]
    if order:
        return last.at(1.0, order)
    turns = round(x / profile.master_period)
    return last.slave_end + (turns - 1) * (profile.net_stroke or 0.0)


class _Phases:
    """The phase shift superimposed on the master [master units], as planned so far."""

    def __init__(self):
        self.plans = []  # (start_s, segment)

    def state(self, t: float) -> tuple:
        for start, segment in reversed(self.plans):
            if t >= start:
                return segment.state(t - start)
        return (0.0, 0.0, 0.0)

    def sample(self, times: np.ndarray, order: int) -> np.ndarray:
        out = np.zeros(len(times))
        for i, (start, segment) in enumerate(self.plans):
            end = self.plans[i + 1][0] if i + 1 < len(self.plans) else math.inf
            inside = (times >= start) & (times < end)
            if not inside.any():
                continue
            moving = inside & (times < start + segment.duration)
            out[moving] = [segment.state(t - start)[order] for t in times[moving]]
            out[inside & ~moving] = segment.state(segment.duration)[order]
        return out


class _Program:
    """The master as the slave sees it (the master plus the phase shifts) and the cams."""

    def __init__(self, master, per_unit: float, end_s: float):
        self.master, self.per_unit, self.end_s = master, per_unit, end_s
        self.phases = _Phases()
        self.pieces = []
        self.out = None  # (start_s, segment) of a cam-out

    def master_at(self, t: float, order: int = 0) -> float:
        """The master the slave sees at time t [master units (per s^order)]."""
        raw = (self.master.position, self.master.velocity, self.master.acceleration)[order](t)
        return float(raw) / self.per_unit + self.phases.state(t)[order]

    def piece_at(self, t: float):
        for piece in reversed(self.pieces):
            if t >= piece.start_s:
                return piece
        return self.pieces[0]

    def slave_state_s(self, t: float, side: str = "right") -> tuple:
        """The slave's position, velocity and acceleration at time t [slave units, per s]."""
        piece = self.piece_at(t)
        m, v, a = (self.master_at(t, order) for order in range(3))
        s = piece.state(m, side)
        return ramp_in.add_correction(piece, t, (s[0], s[1] * v, s[2] * v * v + s[1] * a))

    def time_of(self, master: float, after: float) -> float | None:
        """The first time >= ``after`` the master the slave sees reaches ``master`` (None: not
        within the run). The axis moves forward; a phase shift faster than it backwards makes
        the master the slave sees go back, and then the first crossing is bracketed on a grid
        over each phase shift (the drive switches at the first crossing)."""
        if self.master_at(after) >= master:
            return after
        low, high = after, self.end_s
        bracket = self._first_crossing(master, after)
        if bracket is not None:
            if bracket[0] == math.inf:
                return None
            low, high = bracket
        elif self.master_at(self.end_s) < master:
            return None
        for _ in range(200):
            middle = 0.5 * (low + high)
            if middle in (low, high):
                break
            if self.master_at(middle) >= master:
                high = middle
            else:
                low = middle
        return high


    def _first_crossing(self, master: float, after: float):
        """Where the master the slave sees goes back (during a phase shift): (low, high) around
        its first reaching ``master`` after ``after``, or (inf, inf) if it never does; None where
        it only goes forward (outside phase shifts the phase is constant and the axis forward),
        so a plain bisection over the run finds the one crossing."""
        if not self.phases.plans:
            return None
        times = [after, self.end_s]
        for start, segment in self.phases.plans:
            times += np.linspace(start, start + segment.duration, _PHASE_GRID).tolist()
        grid = np.unique(np.clip(times, after, self.end_s))
        seen = np.asarray(self.master.position(grid), dtype=float) / self.per_unit + self.phases.sample(grid, 0)
        if not np.any(np.diff(seen) < 0.0):
            return None
        reached = np.flatnonzero(seen >= master)
        if not reached.size:
            return math.inf, math.inf
        return float(grid[reached[0] - 1]), float(grid[reached[0]])


#: Samples over each phase shift where the first crossing of a master position is looked for.
_PHASE_GRID = 257

_tables: dict = {}  # (cam content, counts per unit, master counts) -> (profile, table)


def _compile(path: Path, slave_counts_per_unit: float, per_unit: float):
    """A switch's cam and its table, at the scene cam's slave counts and (where the period
    allows a whole number of counts) its master counts per unit."""
    content = read_bounded(path, "cam file")
    profile = load_cam(path)
    counts = profile.master_period * per_unit
    master_counts = int(round(counts)) if abs(counts - round(counts)) < 1e-9 * counts else None
    key = (content, slave_counts_per_unit, master_counts)
    if key not in _tables:
        spec = TableSpec.resolve(profile.table, slave_counts_per_unit=slave_counts_per_unit,
                                 master_counts=master_counts)
        if len(_tables) >= 8:
            _tables.pop(next(iter(_tables)))
        _tables[key] = (profile, ecam.compile_table(profile, spec))
    return _tables[key]


def _request_s(event: Event, program: _Program, period: float) -> float | None:
    """When the event is given: its time, or when the master reaches its position."""
    if event.at_s is not None:
        return event.at_s
    position = event.at_position if event.at_position is not None else event.at_period * period
    # the master axis itself (not the phase-shifted one) reaches the position
    master = program.master
    raw = position * program.per_unit
    if float(master.position(0.0)) >= raw:
        return 0.0
    if float(master.position(program.end_s)) < raw:
        return None
    low, high = 0.0, program.end_s
    for _ in range(200):
        middle = 0.5 * (low + high)
        if middle in (low, high):
            break
        if float(master.position(middle)) >= raw:
            high = middle
        else:
            low = middle
    return high


def _activation(event: Event, program: _Program, requested: float):
    """(time, master) where a switch or offset takes effect, or (None, nan)."""
    running = program.piece_at(requested)
    if event.activation == "immediate":
        return requested, program.master_at(requested)
    if event.activation == "master_position":
        target = event.activation_position
    else:
        x = running.x(program.master_at(requested))
        period = running.period
        if running.profile.periodic:
            turns = math.ceil(x / period - 1e-12)
            x_end = turns * period
        else:
            x_end = period if x < period else x
        target = running.origin + (x_end - running.master_offset) / running.master_scaling
    t = program.time_of(target, requested)
    return t, target


def _scale(piece: _Piece) -> list:
    """What a piece's cam can produce per derivative (the noise of a jump is measured on it)."""
    x = np.linspace(0.0, piece.period, _SCALE_SAMPLES)
    return [piece.slave_scaling * piece.master_scaling**order * float(np.max(np.abs(piece.profile(x, order))))
            for order in range(len(ORDER_NAMES))]


def _jumps(left: list, right: list, scales: list) -> tuple:
    found = []
    for order in range(len(ORDER_NAMES)):
        a, b = left[order], right[order]
        noise = _RELATIVE_NOISE[order] * max(abs(a), abs(b), scales[order]) + 1e-12
        if abs(b - a) > noise:
            found.append((order, b - a))
    return tuple(found)


def _cam_out_segment(event: Event, state: tuple) -> _Segment:
    position, velocity, acceleration = state
    limits = (event.max_velocity, event.max_acceleration, event.max_jerk)
    try:
        return _Segment(f"cam-out of {event.label}", position, event.max_velocity,
                        (position, velocity, acceleration), (0.0, 0.0, 0.0), limits,
                        ControlInterface.Velocity)
    except SimulationError as exc:
        raise SimulationError(f"{event.label}: cam_out: {exc}") from None


def _phase_segment(event: Event, state: tuple) -> _Segment:
    position, velocity, acceleration = state
    limits = (event.max_velocity, event.max_acceleration, event.max_jerk)
    try:
        return _Segment(f"phase shift of {event.label}", position, event.max_velocity,
                        (position, velocity, acceleration), (position + event.shift, 0.0, 0.0),
                        limits, ControlInterface.Position)
    except SimulationError as exc:
        raise SimulationError(f"{event.label}: phase: {exc}") from None


def _motion(event: Event, start: float, segment: _Segment) -> Motion:
    times = segment.critical_times(257)
    states = np.array([segment.state(t) for t in times])
    # the jerk is constant inside each ruckig phase: its largest |value| is the profile's
    profile = segment.trajectory.profiles[0][0]
    jerk = max((abs(j) for j in profile.j), default=0.0) * segment.scale
    peaks = (float(np.max(np.abs(states[:, 1]))), float(np.max(np.abs(states[:, 2]))), jerk)
    covered = segment.state(segment.duration)[0] - segment.state(0.0)[0]
    return Motion(event, start, segment.duration, peaks,
                  (event.max_velocity, event.max_acceleration, event.max_jerk), covered)


def apply_events(events: tuple, cam, master, per_unit: float, t_set: np.ndarray,
                 t_end: np.ndarray, targets: np.ndarray, velocities: np.ndarray,
                 reference: np.ndarray, end_s: float, master_end: np.ndarray | None = None,
                 cycle_s: float | None = None):
    """The set points and the ideal slave path with the scene's events.

    Parameters
    ----------
    events : tuple of Event
    cam : hil_sim.rig.cam.CompiledCam
        The scene's cam (running from the start, absolute, unscaled).
    master : object
        The master's motion in counts (``position``, ``velocity``, ``acceleration`` of t).
    per_unit : float
        Master counts per master unit of the scene's cam.
    t_set, t_end : numpy.ndarray
        Each cycle's set-point time and end time [s].
    targets, velocities, reference : numpy.ndarray
        The plan without events: targets [counts], velocity offsets [counts/s], the ideal slave
        at each cycle's end [slave units]; returned changed from the first event on.
    end_s : float
        The run's last instant [s].
    master_end : numpy.ndarray, optional
        Drive-side: the master counts streamed each cycle (returned shifted by the phase), and
        the cam slot's commands go into the outcome; None: controller-side.
    cycle_s : float, optional
        The bus cycle [s] (drive-side: the cycle of each command).

    Returns
    -------
    targets, velocities, reference : numpy.ndarray
    outcome : EventOutcome
    master_end : numpy.ndarray or None

    Raises
    ------
    InputError
        A switch cam in other units than the scene's; a switch or offset after a cam-out.
    SimulationError
        A phase shift or cam-out ruckig cannot plan within its limits.
    """
    profile, scale = cam.profile, cam.scale
    drive_side = master_end is not None
    if drive_side:
        ramp_in.refuse_drive_side(events)
    program = _Program(master, per_unit, end_s)
    program.pieces.append(_Piece(0.0, profile, cam.table, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, per_unit))
    switches, motions, commands = [], [], []
    requests = []
    for event in events:
        requested = _request_s(event, program, profile.master_period)
        requests.append((math.inf if requested is None else requested, event.index, event))
    ordered = sorted(requests, key=lambda r: (r[0], r[1]))
    phased = _plan_phases(ordered, program)
    for requested, _, event in ordered:
        if requested == math.inf:  # the master never gets there within the run
            if event.action in ("switch", "offset"):
                switches.append(Switch(event, math.nan, None, cam=event.cam.stem if event.cam else ""))
            continue
        if program.out is not None:
            raise InputError(f"{event.label}: at {requested:.6g} s should come before the cam_out "
                             f"at {program.out[0]:.6g} s (the slave has left the cam)")
        if event.action != "phase":  # it takes the cam slot: a switch queued before is dropped
            cut = float(t_set[_command_cycle(requested, cycle_s, t_set)]) if drive_side else requested
            _supersede(program, switches, motions, cut, event)
        if event.action == "phase":
            motions.append(phased[event.index])
        elif event.action == "cam_out":
            if drive_side:  # the drive stops from the cam's state in the cycle after the write
                requested, writes = _drive_cam_out(event, requested, cycle_s, t_set, scale)
                commands += writes
            state = program.slave_state_s(requested)
            segment = _cam_out_segment(event, state)
            program.out = (requested, segment)
            motions.append(_motion(event, requested, segment))
        else:
            drive_at = None
            if drive_side and event.activation == "immediate":  # where the drive takes it
                cycle = _command_cycle(requested, cycle_s, t_set)
                drive_at = (float(t_set[cycle]), _streamed(program, float(t_set[cycle])))
            switch = _switch(event, program, requested, scale, per_unit, drive_at)
            switches.append(switch)
            if switch.ramp is not None:  # its correction is checked against its limits
                ramp = switch.ramp
                motions.append(Motion(event, ramp.start_s, ramp.duration_s, ramp.profile.peaks,
                                      ramp.limits, -ramp.start[0]))
            if drive_side and switch.active_s is not None:
                commands += _drive_commands(event, program, requested, cycle_s, t_set, per_unit)
    targets, velocities, reference = _sample(program, cam, t_set, t_end, targets, velocities,
                                             reference, scale)
    targets, velocities, reference = ramp_in.apply_corrections(
        program.pieces, program.out and program.out[0], t_set, t_end, targets, velocities,
        reference, scale)
    phase = program.phases.sample(t_end, 0) if program.phases.plans else None
    if drive_side and program.phases.plans:  # the master the drive sees: shifted by the phase
        master_end = np.rint(master.position(t_set) + program.phases.sample(t_set, 0) * per_unit
                             ).astype(np.int64)
    outcome = EventOutcome(tuple(switches), tuple(motions), phase, tuple(commands))
    return targets, velocities, reference, outcome, master_end


def _plan_phases(ordered: list, program: _Program) -> dict:
    """Every phase shift requested before the first cam-out, planned into ``program`` before
    any switch: a switch queued for a period end or a master position takes effect where the
    master the slave sees (the axis plus the phase) gets there, and a phase requested between
    the switch's request and its activation moves that place, as it moves the master the drive
    is streamed. A phase depends only on the phases before it (its request time is the master
    axis's). Returns event index -> its Motion."""
    planned = {}
    for requested, _, event in ordered:
        if requested == math.inf:
            continue
        if event.action == "cam_out":  # what follows is refused in the events' loop
            break
        if event.action == "phase":
            segment = _phase_segment(event, program.phases.state(requested))
            program.phases.plans.append((requested, segment))
            planned[event.index] = _motion(event, requested, segment)
    return planned


def _command_cycle(requested: float, cycle_s: float, t_set: np.ndarray) -> int:
    """The cycle after whose SYNC a request's SDO writes are sent: the first whose SYNC
    (k x cycle_s) is not before the request."""
    return min(max(math.ceil(requested / cycle_s - 1e-9), 0), len(t_set) - 1)


def _supersede(program: _Program, switches: list, motions: list, cut: float, event: Event) -> None:
    """A switch, offset or cam-out requested while an earlier switch waits for its activation
    (later than ``cut`` [s]) takes its place: the drive's cam slot holds one pending table, which a
    new download replaces and a cam-out clears (:mod:`hil_sim.drive.cam_slot`), as a new
    ``MC_CamIn`` / ``MC_CamOut`` aborts the pending one (PLCopen TC2 v2.0, BufferMode
    ``mcAborting``, the default). The waiting switch never activates: its piece and its ramp_in go,
    and it is reported as superseded instead of with jumps it never made. Drive-side ``cut`` is
    the set-point time of the cycle the writes follow (a switch due by then has happened in the
    drive); controller-side the request's time."""
    dropped = set()
    for i, switch in enumerate(switches):
        if switch.active_s is not None and switch.active_s > cut:
            switches[i] = Switch(switch.event, switch.requested_s, None, cam=switch.cam,
                                 superseded_by=event.label)
            dropped.add(switch.event.index)
    if dropped:
        program.pieces[:] = [p for p in program.pieces if p.start_s <= cut]
        motions[:] = [m for m in motions if m.event.index not in dropped]


def _drive_cam_out(event: Event, requested: float, cycle_s: float, t_set: np.ndarray,
                   scale: float) -> tuple:
    """A cam-out drive-side: the profile limits into 0x6083, 0x6084 and 0x60A4:01 [counts/s^n]
    and 0x2001:01 = 5 after the SYNC of the cycle it is requested in; the drive stops from the
    cam's state in the next cycle, whose set-point time is returned as the stop's start."""
    cycle = _command_cycle(requested, cycle_s, t_set)
    if cycle + 1 >= len(t_set):  # the run ends before the drive acts
        return requested, []
    writes = []
    for key, name, value in ((PROFILE_ACCELERATION, "max_acceleration", event.max_acceleration),
                             (PROFILE_DECELERATION, "max_acceleration", event.max_acceleration),
                             (PROFILE_JERK, "max_jerk", event.max_jerk)):
        counts = round(value * scale)
        if not 1 <= counts <= 0xFFFFFFFF:
            order = 2 if name == "max_acceleration" else 3
            raise InputError(f"{event.label}.{name}: {value:g} should be within {1 / scale:g}.."
                             f"{0xFFFFFFFF / scale:g} slave units/s^{order} with cam_mode 'drive' "
                             f"(0x{key.index:04X} is UNSIGNED32 counts/s^{order})")
        writes.append(DriveCommand(cycle, *key, counts, event.index))
    writes.append(DriveCommand(cycle, *CAM_COMMAND, CAM_COMMAND_CAM_OUT, event.index))
    return float(t_set[cycle + 1]), writes


def _drive_commands(event: Event, program: _Program, requested: float, cycle_s: float,
                    t_set: np.ndarray, per_unit: float) -> list:
    """The SDO writes of a switch (or offset: the running table again, with its new
    coordinates): the table into 0x2000 (pending), its coordinates into 0x2001:05 and MC_CamIn's
    offsets and scaling into 0x2001:07..0C (:mod:`hil_sim.drive.cam_coupling`), a master position
    activation's position into 0x2001:06, and the activation into 0x2001:01, after the SYNC of
    the cycle it is requested in."""
    piece = program.pieces[-1]
    if piece.table_per_unit != per_unit:
        raise InputError(f"{event.label}.cam: {piece.profile.master_period:g} "
                         f"{piece.profile.master_unit} should be a whole number of the scene's master "
                         f"counts ({per_unit:g} per {piece.profile.master_unit}) with cam_mode 'drive': "
                         "the drive looks the table up at the master counts it is sent")
    cycle = _command_cycle(requested, cycle_s, t_set)
    mode = ((SWITCH_MASTER_RELATIVE if event.master == "relative" else 0)
            | (SWITCH_SLAVE_RELATIVE if event.slave == "relative" else 0))
    slave_per_unit = float(piece.table.certificate.slave_counts_per_unit)
    out = [DriveCommand(cycle, *CAM_TABLE_DOWNLOAD, piece.table.to_bytes(), event.index),
           DriveCommand(cycle, *CAM_SWITCH_MODE, mode, event.index)]
    for key, value in _coupling_values(event, per_unit, slave_per_unit):
        out.append(DriveCommand(cycle, *key, value, event.index))
    if event.activation == "master_position":
        position = _counts(event, "activation_position", event.activation_position, per_unit, 64, "master")
        seen = program.master_at(float(t_set[cycle]))
        # the drive compares whole counts (the master streamed rounded, as master_end): one that
        # stands on the position has not crossed it going forwards, and never will
        seen_counts = int(np.rint(seen * per_unit))
        if seen_counts >= position:
            raise InputError(f"{event.label}.activation_position: {event.activation_position:g} should be "
                             f"ahead of the master the drive has seen at the request ({seen:.6g}: "
                             f"{seen_counts} counts, the position {position}) with cam_mode 'drive': the "
                             "drive activates where the master crosses it (TwinCAT MC3 "
                             "ECamActivationMode.AtMasterAbsolutePosition)")
        out.append(DriveCommand(cycle, *CAM_ACTIVATION_POSITION, position, event.index))
    activate = {"immediate": CAM_COMMAND_ACTIVATE, "period_end": CAM_COMMAND_ACTIVATE_AT_PERIOD_END,
                "master_position": CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION}[event.activation]
    out.append(DriveCommand(cycle, *CAM_COMMAND, activate, event.index))
    return out


def _coupling_values(event: Event, per_unit: float, slave_per_unit: float) -> list:
    """MC_CamIn's offsets [counts] and scaling (numerator, denominator: the nearest fraction
    whose terms fit UNSIGNED32) as the drive takes them (0x2001:07..0C)."""
    out = [(CAM_MASTER_OFFSET, _counts(event, "master_offset", event.master_offset, per_unit, 64, "master")),
           (CAM_SLAVE_OFFSET, _counts(event, "slave_offset", event.slave_offset, slave_per_unit, 32, "slave"))]
    for numerator, denominator, scaling in (
            (CAM_MASTER_SCALING_NUMERATOR, CAM_MASTER_SCALING_DENOMINATOR, event.master_scaling),
            (CAM_SLAVE_SCALING_NUMERATOR, CAM_SLAVE_SCALING_DENOMINATOR, event.slave_scaling)):
        ratio = scaling_ratio(scaling)
        out += [(numerator, ratio[0]), (denominator, ratio[1])]
    return out


def _counts(event: Event, name: str, value: float, per_unit: float, bits: int, axis: str) -> int:
    """``value`` [units] in the counts of a signed object of ``bits`` (0x2001:06/07 INTEGER64,
    0x2001:08 INTEGER32), or a one-line error naming the field, the value and the range."""
    counts = round(value * per_unit)
    limit = 1 << (bits - 1)
    if not -limit <= counts < limit:
        raise InputError(f"{event.label}.{name}: {value:g} should be within {-limit / per_unit:.6g}.."
                         f"{(limit - 1) / per_unit:.6g} {axis} units with cam_mode 'drive' (INTEGER{bits} "
                         f"counts, {per_unit:g} per unit)")
    return counts


def _streamed(program: _Program, t: float) -> float:
    """The master the drive is sent at time t, in whole counts (as master_end) [master units]."""
    return float(np.rint(program.master_at(t) * program.per_unit)) / program.per_unit


def _switch(event: Event, program: _Program, requested: float, scale: float,
            per_unit: float, drive_at: tuple | None = None) -> Switch:
    """A switch or offset as it happens; ``drive_at`` (time, master): drive-side, an immediate
    one is taken by the drive with the write after the request's SYNC, at the master it
    received last (0x2001:01 = 1: :meth:`hil_sim.drive.cam_slot.CamSlot.write_command`), so the
    ideal path switches there too, as a drive-side cam-out starts where the drive starts it."""
    running = program.piece_at(requested)
    if event.action == "switch":
        new_profile, table = _compile(event.cam, scale, per_unit)
        for unit in ("master_unit", "slave_unit"):
            if getattr(new_profile, unit) != getattr(running.profile, unit):
                raise InputError(f"{event.label}.cam: {getattr(new_profile, unit)!r} "
                                 f"({unit}) should be {getattr(running.profile, unit)!r}, the "
                                 "running cam's")
    else:
        new_profile, table = running.profile, running.table
    active, master = drive_at or _activation(event, program, requested)
    if active is None:
        return Switch(event, requested, None, cam=new_profile.name or "")
    running = program.piece_at(active)
    speed, acceleration = program.master_at(active, 1), program.master_at(active, 2)
    left = ramp_in.with_correction(running.state(master, side="left"), running, active, speed,
                                   acceleration, event.label)
    origin = master if event.master == "relative" else 0.0
    base = left[0] if event.slave == "relative" else 0.0
    piece = _Piece(active, new_profile, table, origin, event.master_offset, event.master_scaling,
                   base, event.slave_offset, event.slave_scaling, per_unit)
    right = piece.state(master, side="right")
    scales = [max(a, b) for a, b in zip(_scale(running), _scale(piece))]
    program.pieces.append(piece)
    jumps = _jumps(left, right, scales)
    compensated = tuple((order, size) for order, size in jumps if order < 3)
    if event.start_mode == "ramp_in" and compensated:
        piece.ramp = ramp_in.plan_ramp_in(event, active, left, right, compensated, speed,
                                          acceleration)
        jumps = tuple((order, size) for order, size in jumps if order == 3)
    return Switch(event, requested, active, master, piece.x(master), new_profile.name or "",
                  tuple(left), tuple(right), jumps, speed, piece.ramp)


def _sample(program: _Program, cam, t_set, t_end, targets, velocities, reference, scale):
    """The set points and the reference with the events: sampled per cycle from the program."""
    first = min([p.start_s for p in program.pieces[1:]]
                + ([program.phases.plans[0][0]] if program.phases.plans else [])
                + ([program.out[0]] if program.out else []) + [math.inf])
    if first == math.inf:
        return targets, velocities, reference
    targets, velocities, reference = targets.copy(), velocities.copy(), reference.copy()
    per_unit = program.per_unit
    for times, kind in ((t_set, "set"), (t_end, "end")):
        changed = times >= first
        if program.out is not None:
            changed &= times < program.out[0]
        t = times[changed]
        if t.size:
            phase = program.phases.sample(t, 0) if program.phases.plans else 0.0
            counts = program.master.position(t) + phase * per_unit  # the master the slave sees
            starts = np.array([p.start_s for p in program.pieces])
            which = np.searchsorted(starts, t, side="right") - 1
            for i, piece in enumerate(program.pieces):
                mask = which == i
                if not mask.any():
                    continue
                idx = np.flatnonzero(changed)[mask]
                if kind == "set":
                    speed = program.master.velocity(t[mask])
                    if program.phases.plans:
                        speed = speed + program.phases.sample(t[mask], 1) * per_unit
                    targets[idx], velocities[idx] = _set_points(piece, counts[mask], speed, per_unit)
                else:
                    reference[idx] = _reference(piece, counts[mask] / per_unit)
        if program.out is not None:
            start, segment = program.out
            idx = np.flatnonzero(times >= start)
            # at rest after the stop: ruckig ends within its 1e-8 contract, the stop is exact
            states = np.zeros((idx.size, 3))
            states[:, 0] = segment.state(segment.duration)[0]
            moving = times[idx] - start < segment.duration
            if moving.any():  # a cam-out from rest has no duration
                states[moving] = [segment.state(tt - start) for tt in times[idx][moving]]
            if kind == "set":
                targets[idx] = np.rint(states[:, 0] * scale).astype(np.int64)
                velocities[idx] = states[:, 1] * scale
            else:
                reference[idx] = states[:, 0]
    return targets, velocities, reference


def _set_points(piece: _Piece, master_counts: np.ndarray, speed_counts: np.ndarray,
                per_unit: float):
    """Targets [counts] and velocity offsets [counts/s] from the piece's table, as the plan
    computes them without events (the same bits for the scene's own cam, unscaled)."""
    table = piece.table
    if piece.identity:
        x_counts = np.rint(master_counts).astype(np.int64)
    else:
        x = piece.x(master_counts / per_unit)
        if not piece.profile.periodic:
            x = np.clip(x, 0.0, piece.period)
        x_counts = np.rint(x * piece.table_per_unit).astype(np.int64)
    looked, slope = table.lookup(x_counts, with_slope=True)
    if piece.identity:
        targets = np.asarray(looked, dtype=np.int64)
    else:
        base = (piece.base + piece.slave_offset) * float(table.certificate.slave_counts_per_unit)
        targets = np.rint(base + piece.slave_scaling * np.asarray(looked, dtype=float)).astype(np.int64)
    moving = speed_counts
    if not piece.profile.periodic:  # a cam that does not repeat holds its ends: no speed there
        x = piece.x(master_counts / per_unit)
        moving = np.where((x > 0.0) & (x < piece.period), speed_counts, 0.0)
    velocities = (np.asarray(slope, dtype=float) / 65536.0 * piece.slave_scaling * piece.ratio * moving)
    return targets, velocities


def _reference(piece: _Piece, master_units: np.ndarray) -> np.ndarray:
    x = piece.x(master_units)
    if not piece.profile.periodic:
        x = np.clip(x, 0.0, piece.period)
    return piece.base + piece.slave_offset + piece.slave_scaling * np.asarray(piece.profile(x), dtype=float)
