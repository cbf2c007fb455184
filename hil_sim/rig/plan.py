"""Everything about a run that does not depend on the slave: the cycle count, the master's
motion sampled for every cycle, and the set points looked up in the table for all of them.

The CSP timeline (CiA 402): the set point sent before SYNC k is latched at that SYNC and the
drive interpolates towards it over the cycle that follows, so a master leads by one cycle: it
sends the position for SYNC k+1 (``lead_cycles = 1``, the default). A master that sends the
position of now (``lead_cycles = 0``) makes the drive lag one cycle behind it.

Controller-side, the set points are looked up in the table for all cycles at once
(``table.lookup`` for the target, ``table.slope`` times the master speed at the target's time for
the velocity offset). Drive-side, the master position is what goes on the bus; a drive-side cam-in
sends the controller's approach as CSP set points too, with cam mode 0, and switches the drive to
its cam (cam mode 1, in the same RPDO as the master position) at the engagement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ecam.errors import InputError, SimulationError
from ecam.validate import renamed
from ecam.mechanics import Mechanics
from hil_sim.control import Gains
from hil_sim.effects import EffectValues
from hil_sim.events import apply_events
from hil_sim.tappet_edges import tappet_edges
from hil_sim.int32 import saturate_int32_array, wrap_int32_array
from hil_sim.master import ConstantSpeed, StartStop, cam_in
from hil_sim.rig.cam import CompiledCam
from hil_sim.scene import MAX_CYCLES, Scene


@dataclass(frozen=True)
class Plan:
    """Everything about the run that does not depend on the slave, per cycle k (0..cycles-1)."""

    cycles: int
    cycle_s: float
    master_end: np.ndarray       # master counts sent in cycle k (for its target time, jittered)
    targets: np.ndarray          # controller-side target counts (int64)
    velocities: np.ndarray       # controller-side velocity offset [counts/s]
    reference_units: np.ndarray  # ideal slave position at the end of cycle k [slave units]
    master_units: np.ndarray     # true master position at the end of cycle k [master units]
    initial_counts: int
    speed_units: float           # cruise master speed [master units/s]
    start_units: float           # true master position at t = 0 [master units]
    sync_offsets: np.ndarray     # SYNC jitter of cycle k [s]
    engaged_from: int | None = None  # a cam-in: the first cycle whose set point is the cam's
    events: object = None        # what the scene's [[event]]s did (hil_sim.events.EventOutcome)
    tappets: tuple = ()          # the tappet tracks' edges (hil_sim.tappet_edges.TappetEdges)


@dataclass(frozen=True)
class PreparedRun:
    """A scene made ready to run: what is known before the drive boots.

    Attributes
    ----------
    scene : Scene
    cam : CompiledCam
    mechanics : ecam.mechanics.Mechanics
    plan : Plan
    excitation_hz : float
        The cam's highest significant acceleration harmonic at the master speed [Hz], which the
        drive's plant choice is based on.
    effect_values : hil_sim.effects.EffectValues
        Every effect's value for the scene (the scene's, or the default).
    gains : hil_sim.control.Gains
        The drive's gains.
    tuning : hil_sim.tuning.Tuning or None
        How the drive was commissioned (the gains' source and margins on the full model).
    """

    scene: Scene
    cam: CompiledCam
    mechanics: Mechanics
    plan: Plan
    excitation_hz: float
    effect_values: EffectValues | None = None
    gains: Gains | None = None
    tuning: object = None

    @property
    def cam_hz(self) -> float:
        """Cam cycles per second at the cruise master speed [Hz]."""
        return abs(self.plan.speed_units) / self.cam.profile.master_period

    def master_in_period(self, cycle: int) -> float:
        """The master position at the end of ``cycle`` within the cam period [master units]."""
        return self.plan.master_units[cycle] % self.cam.profile.master_period


def count_cycles(scene: Scene, period_units: float, speed_units: float) -> int:
    """Bus cycles of the scene's duration, given as cycles, seconds or cam periods."""
    d, cycle_s = scene.duration, scene.drive.cycle_s
    if d.cycles is not None:
        return d.cycles
    if d.seconds is not None:
        seconds = d.seconds
    else:
        seconds = d.master_periods * period_units / abs(speed_units)
    cycles = math.ceil(seconds / cycle_s - 1e-9)
    if cycles > MAX_CYCLES:
        raise InputError(f"duration {seconds:.6g} s at cycle_s {cycle_s} gives {cycles:.3g} "
                         f"cycles, should be <= {MAX_CYCLES}")
    return max(cycles, 1)


def plan_run(scene: Scene, cam: CompiledCam, jitter: np.ndarray, cycles: int) -> Plan:
    """Sample the master (and a cam-in) for every cycle and look the set points up.

    Parameters
    ----------
    scene : Scene
    cam : CompiledCam
    jitter : numpy.ndarray, shape (cycles,)
        SYNC offset of each cycle [s].
    cycles : int

    Raises
    ------
    InputError
        A master so fast that a bus cycle covers more than half the cam period.
    """
    profile, table, scale = cam.profile, cam.table, cam.scale
    cycle_s = scene.drive.cycle_s
    period = profile.master_period
    per_unit = table.master_counts / period  # master counts per master unit
    spec = scene.master
    speed_units = spec.units_per_second(period)
    speed = speed_units * per_unit
    if abs(speed_units) * cycle_s > period / 2:
        # a cam sampled less than twice per period aliases: the set points would be meaningless
        raise InputError(f"master speed {speed_units:.6g} {profile.master_unit}/s moves "
                         f"{abs(speed_units) * cycle_s:.6g} {profile.master_unit} per bus cycle, "
                         f"more than half the cam period ({period / 2:g}); should be <= "
                         f"{period / 2 / cycle_s:.6g}")
    k = np.arange(cycles, dtype=float)
    t_end = (k + 1.0) * cycle_s            # the drive reaches the target of cycle k at its end
    # The set point sent in cycle k is for SYNC k + lead (the lead's SYNC), sampled at the
    # jittered instant.
    t_set = (k + spec.lead_cycles) * cycle_s + jitter
    master, slave_plan = _master_motion(scene, cam, speed, per_unit)
    if scene.phase:  # an axis of a machine: its cam runs at the master plus its phase offset
        master = _Shifted(master, scene.phase * per_unit)
    master_end = np.rint(master.position(t_set)).astype(np.int64)
    targets = table.lookup(master_end)
    velocities = table.slope(master_end) / 65536.0 * master.velocity(t_set)
    master_true = master.position(t_end)
    reference = profile(master_true / per_unit)
    engaged_from = None
    if slave_plan is None:
        initial = int(table.lookup(int(round(float(master.position(0.0))))))
    else:
        # Before the engagement the set points and the reference follow the ruckig approach
        # (evaluated only there: the plan is a Python call per sample), after it the cam.
        engage_s = slave_plan.engage_s
        approach = t_set < engage_s
        engaged_from = int(np.count_nonzero(approach))  # t_set rises: the approach comes first
        targets = targets.copy()
        velocities = velocities.copy()
        targets[approach] = np.rint(slave_plan.position(t_set[approach])).astype(np.int64)
        velocities[approach] = slave_plan.velocity(t_set[approach])
        approach = t_end < engage_s
        reference[approach] = slave_plan.position(t_end[approach]) / scale
        initial = int(round(spec.slave_start * scale))
    outcome = None
    if scene.events:  # switches, phase shifts, cam-out (hil_sim.events); none: the plan as it was
        if slave_plan is not None:
            raise InputError("event: a scene with master.profile 'cam_in' should have no "
                             "[[event]] (engage with a switch event instead)")
        targets, velocities, reference, outcome, shifted = apply_events(
            scene.events, cam, master, per_unit, t_set, t_end, np.asarray(targets, dtype=np.int64),
            np.asarray(velocities, dtype=float), np.asarray(reference, dtype=float),
            float(t_end[-1]) + cycle_s * max(spec.lead_cycles, 1),
            master_end if scene.cam_mode == "drive" else None, cycle_s)
        if shifted is not None:
            master_end = shifted
    for i, track in enumerate(scene.tappets):  # the scene's, against its cam's period
        try:
            track.within(period)
        except InputError as exc:
            raise renamed(exc, lambda name, i=i: f"tappet[{i}].{name}") from None
    tracks = tuple(profile.tappets) + tuple(scene.tappets)
    edges = (tappet_edges(tracks, master, per_unit, period, table.master_counts, cycle_s, cycles)
             if tracks else ())
    return Plan(cycles=cycles, cycle_s=cycle_s, master_end=master_end,
                targets=np.asarray(targets, dtype=np.int64), velocities=np.asarray(velocities),
                reference_units=np.asarray(reference, dtype=float),
                master_units=np.asarray(master_true, dtype=float) / per_unit,
                initial_counts=initial, speed_units=speed_units,
                start_units=float(master.position(0.0)) / per_unit, sync_offsets=jitter,
                engaged_from=engaged_from, events=outcome, tappets=edges)


def _master_motion(scene: Scene, cam: CompiledCam, speed: float, per_unit: float):
    """The master's motion in counts (and, for a cam-in, the slave's approach plan, else None)."""
    spec = scene.master
    if spec.profile == "start_stop":
        try:
            return StartStop(speed, spec.max_acceleration * per_unit, spec.max_jerk * per_unit,
                             start_s=spec.start_s, stop_s=spec.stop_s), None
        except (InputError, SimulationError) as exc:
            unit = cam.profile.master_unit
            raise SimulationError(
                f"master.profile 'start_stop': no ramp to {speed / per_unit:.6g} {unit}/s with "
                f"master.max_acceleration {spec.max_acceleration:.6g} {unit}/s^2 and "
                f"master.max_jerk {spec.max_jerk:.6g} {unit}/s^3: "
                f"{str(exc).splitlines()[0] if str(exc) else exc!r}") from None
    if spec.profile == "cam_in":
        profile, scale = cam.profile, cam.scale

        def slave_counts(m, order):
            return profile(m / per_unit, order) * scale / per_unit**order

        _check_engagement(spec, profile, speed / per_unit)
        try:
            slave_plan = cam_in(slave_counts, spec.slave_start * scale, 0.0, speed,
                                spec.engage_at * per_unit, spec.max_velocity * scale,
                                spec.slave_max_acceleration * scale, spec.slave_max_jerk * scale)
        except (InputError, SimulationError) as exc:
            # in the scene's words: its fields, its units, the speed tried (counts inside)
            unit = profile.master_unit
            why = str(exc).splitlines()[0] if str(exc) else repr(exc)
            raise SimulationError(
                f"master.profile 'cam_in': no cam-in onto the cam at master.engage_at "
                f"{spec.engage_at:g} {unit} with the master at {speed / per_unit:.6g} {unit}/s "
                f"from master.slave_start {spec.slave_start:g} {profile.slave_unit} within "
                f"master.max_velocity, slave_max_acceleration, slave_max_jerk: "
                f"{why}{' (slave positions in counts)' if 'position' in why else ''}") from None
        return slave_plan.master, slave_plan
    return ConstantSpeed(speed), None


class _Shifted:
    """A master motion shifted by a constant phase [counts]: the master an axis of a machine
    sees (:attr:`hil_sim.scene.Scene.phase`); velocity and timing are the master's."""

    def __init__(self, master, offset_counts: float) -> None:
        self.master, self.offset = master, offset_counts

    def position(self, t):
        return self.master.position(t) + self.offset

    def velocity(self, t):
        return self.master.velocity(t)

    def acceleration(self, t):
        return self.master.acceleration(t)


def _check_engagement(spec, profile, speed_units: float) -> None:
    """The slave limits a cam-in must allow at the engagement, checked in the scene's fields and
    units (before the plan, which works in counts): the cam's velocity and acceleration at
    master.engage_at with the master at the speed tried."""
    at, master_unit, slave_unit = spec.engage_at, profile.master_unit, profile.slave_unit
    for field, order, limit, what, per in (
            ("master.max_velocity", 1, spec.max_velocity, "velocity", "s"),
            ("master.slave_max_acceleration", 2, spec.slave_max_acceleration, "acceleration", "s^2")):
        need = abs(float(profile(at, order)) * speed_units**order)
        if need > limit:
            raise SimulationError(
                f"master.profile 'cam_in': {field} {limit:g} {slave_unit}/{per} should be >= the "
                f"cam's {what} {need:.6g} {slave_unit}/{per} at master.engage_at {at:g} "
                f"{master_unit} with the master at {speed_units:.6g} {master_unit}/s")


def cruise_s(scene: Scene, cam: CompiledCam) -> float:
    """When the master has reached its cruise speed (and a cam-in has engaged) [s]."""
    period = cam.profile.master_period
    per_unit = cam.table.master_counts / period
    speed = scene.master.units_per_second(period) * per_unit
    master, slave_plan = _master_motion(scene, cam, speed, per_unit)
    if slave_plan is not None:
        return float(slave_plan.engage_s)
    return float(getattr(master, "at_speed_s", 0.0))


def cam_modes(plan: Plan) -> np.ndarray:
    """Drive-side, the cam mode (0x2004) each cycle's RPDO carries for a cam-in: 0 (the target
    from the controller, CSP) while the controller plans the approach, 1 (the drive's cam) from
    the engagement on."""
    modes = np.ones(plan.cycles, dtype=np.int64)
    modes[:plan.engaged_from or 0] = 0
    return modes


def wire_set_points(plan: Plan, drive_side: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """What goes on the bus each cycle, as int64 arrays: drive-side the master position
    (0x2003) and None; controller-side the target (0x607A) and the velocity offset (0x60B1,
    rounded and saturated to INTEGER32)."""
    if drive_side:
        return wrap_int32_array(plan.master_end), None
    return wrap_int32_array(plan.targets), saturate_int32_array(np.rint(plan.velocities))
