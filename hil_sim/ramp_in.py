"""A switch's start mode ``ramp_in``: the slave brought onto the new cam by a jerk-limited
correction instead of jumping to it.

PLCopen Motion Control Part 1 names the start modes of ``MC_CamIn``: absolute, relative and
ramp_in. CODESYS SoftMotion documents ramp_in in "Function Blocks: MC_CamTableSelect and
MC_CamIn" (content.helpme-codesys.com, CODESYS SoftMotion/_sm_basic_function_blocks.html,
``MC_CamIn.StartMode``): a compensating movement keeps the jumps from happening when the cam
starts, its dynamics bounded by the block's inputs ``VelocityDiff``, ``Acceleration`` and
``Deceleration``; SM3_Basic's ``MC_CamIn`` (FB) page (.../libs/SM3_Basic/Current/SM3_Basic/POUs/
Movement/MasterSlave/MC_CamIn.html) adds ``Jerk`` and gives the units (u/s, u/s^2, u/s^3;
VelocityDiff is the largest velocity difference). Its example project
BasicMotion_CamIn_StartModes ("Distance-Based Ramping") shows the ramp_in slave synchronising as
fast as the limits of velocity, acceleration, deceleration and jerk let it. That is what this
module plans, controller-side:

    slave(t) = cam(t) + correction(t),  correction(t0) = slave's state - cam's state at t0,
    correction -> (0, 0, 0) on ruckig's time-optimal jerk-limited profile,

with the event's ``max_velocity`` as VelocityDiff, ``max_acceleration`` as both Acceleration and
Deceleration (ruckig takes one limit for both) and ``max_jerk`` as Jerk, all in slave units/s^n.
The correction starts at the jump in position, velocity and acceleration (per second, at the
master's speed and acceleration there), so the slave's path is continuous in all three at the
activation and joins the cam exactly when the correction ends. A jump larger than the limits
allow at once (a velocity jump above ``max_velocity``) is braked by ruckig from outside its limits;
its peaks then show above 100 % in the report's ``event_motion``, as a cam-out's would.
Not modelled: CODESYS's ``ramp_in_pos`` / ``ramp_in_neg`` (a rotary slave compensating in one
direction only; for a linear slave they are ramp_in) and ``ramp_in_dist`` (a master distance to
synchronise over). Beckhoff's TwinCAT NC camming has no ramp-in start mode (``MC_StartMode``:
absolute and relative per axis only, infosys.beckhoff.com tf5050_tc3_nc_camming/1003815691.html;
``MC_CamIn_V2``'s ``ST_CamInOptions`` hold the activation mode and position, the scaling modes and
the interpolation type, 1003826699.html, no start mode; its hydraulics library's
``MC_StartMode_RampIn`` is "not supported", tf5810_tc3_hydraulic_positioning/1599729803.html).

The drive's cam slot switches tables itself and has no correction: a drive-side scene with a
ramp_in switch is refused (:func:`refuse_drive_side`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from ecam.errors import InputError, SimulationError
from ecam.profile import ORDER_NAMES
from hil_sim.master import phase_extremum_times

__all__ = ["Correction", "RampIn", "add_correction", "apply_corrections", "plan_ramp_in", "refuse_drive_side",
           "with_correction"]


class Correction:
    """ruckig's time-optimal profile of a correction from ``start`` (position, velocity,
    acceleration) to rest at 0 within ``limits`` (velocity, acceleration, jerk).

    Solved in the correction's own units of time and distance: tau, the time the jerk limit
    needs to undo the largest part of the start (|a|/j, sqrt(|v|/j), cbrt(|p|/j)), and j tau^3.
    A jump is often tiny beside what the limits could move (an acceleration-only jump of a few
    in/s^2 against 200 in/s^2 and 20000 in/s^3); in the limits' units ruckig 0.19 then meets its
    own 1e-8 thresholds and rejects some of these starts ("error in step 1"), in these it does
    not (measured on 57 000 random starts the limits can hold: none rejected).
    """

    def __init__(self, what: str, start: tuple, limits: tuple) -> None:
        self.start = tuple(float(x) for x in start)
        self.limits = tuple(float(x) for x in limits)
        p, v, a = self.start
        jerk = self.limits[2]
        self.tau = max(abs(a) / jerk, math.sqrt(abs(v) / jerk), (abs(p) / jerk) ** (1.0 / 3.0))
        self.trajectory = None
        self.duration = 0.0
        self.distance = jerk * self.tau**3
        if self.distance == 0.0:  # nothing to correct, or less than a float can scale
            return
        tau, distance = self.tau, self.distance
        parameters = InputParameter(1)
        parameters.current_position = [p / distance]
        parameters.current_velocity = [v * tau / distance]
        parameters.current_acceleration = [a * tau * tau / distance]
        parameters.target_position = [0.0]
        parameters.target_velocity = [0.0]
        parameters.target_acceleration = [0.0]
        parameters.max_velocity = [self.limits[0] * tau / distance]
        parameters.max_acceleration = [self.limits[1] * tau * tau / distance]
        parameters.max_jerk = [1.0]
        self.trajectory = Trajectory(1)
        try:
            result = Ruckig(1).calculate(parameters, self.trajectory)
        except (RuckigError, ValueError) as error:
            lines = [line.strip() for line in str(error).splitlines() if line.strip()]
            raise SimulationError(f"ruckig rejected the {what}: {lines[0] if lines else error}") from None
        if result not in (Result.Working, Result.Finished):
            raise SimulationError(f"ruckig result {result.name} for the {what}, expected Working or Finished")
        self.duration = tau * float(self.trajectory.duration)
        end = self.state(self.duration)
        # ruckig's contract is 1e-8 in the units it solved in
        for name, got, unit in zip(("position", "velocity", "acceleration"), end,
                                   (distance, distance / tau, distance / tau**2)):
            if abs(got) > 1e-7 * unit:
                raise SimulationError(f"ruckig {what} ends at {name} {got}, expected 0")

    def state(self, t: float) -> tuple:
        """(position, velocity, acceleration) at t in [0, duration] after the start."""
        if self.trajectory is None:
            return (0.0, 0.0, 0.0)
        tau, distance = self.tau, self.distance
        position, velocity, acceleration = self.trajectory.at_time(min(max(t, 0.0), self.duration) / tau)
        return (distance * position[0], distance / tau * velocity[0], distance / tau**2 * acceleration[0])

    def _phases(self):
        """(start, duration, jerk, acceleration, velocity) of each constant-jerk phase, scaled."""
        profile = self.trajectory.profiles[0][0]
        begin = 0.0
        phases = []
        for part in (profile.brake, profile.accel):
            for dt, jerk, acc, vel in zip(part.t, part.j, part.a, part.v):
                phases.append((begin, dt, jerk, acc, vel))
                begin += dt
        for dt, jerk, acc, vel in zip(profile.t, profile.j, profile.a, profile.v):
            phases.append((begin, dt, jerk, acc, vel))
            begin += dt
        return phases

    def critical_times(self, samples: int = 257) -> np.ndarray:
        """A grid over the profile plus, per constant-jerk phase, where the velocity (the
        acceleration's zero) and the position (the velocity's zeros) can peak [s]."""
        if self.trajectory is None:
            return np.zeros(1)
        times = [np.linspace(0.0, self.duration / self.tau, samples), *phase_extremum_times(self._phases())]
        return np.clip(np.concatenate(times) * self.tau, 0.0, self.duration)

    @property
    def peaks(self) -> tuple:
        """The largest |velocity|, |acceleration| and |jerk| on the way."""
        if self.trajectory is None:
            return (0.0, 0.0, 0.0)
        states = np.array([self.state(t) for t in self.critical_times()])
        jerk = max((abs(p[2]) for p in self._phases()), default=0.0) * self.distance / self.tau**3
        return (float(np.max(np.abs(states[:, 1]))), float(np.max(np.abs(states[:, 2]))), jerk)

    @property
    def peak_position(self) -> float:
        """The largest |position| on the way."""
        return float(max(abs(self.state(t)[0]) for t in self.critical_times()))


@dataclass(frozen=True)
class RampIn:
    """The correction of one ramp_in switch (see the module docstring).

    Attributes
    ----------
    event : hil_sim.event_spec.Event
    start_s : float
        The switch's activation [s]: the correction starts here.
    start : tuple of float
        The correction at ``start_s``: the slave's state minus the new cam's, position, velocity,
        acceleration [slave units, per s, per s^2].
    compensated : tuple of (order, size)
        The jumps it compensates, per master unit as the switch reports jumps (right - left).
    profile : Correction
        ruckig's profile of the correction, from ``start`` to rest at 0.
    """

    event: object
    start_s: float
    start: tuple
    compensated: tuple
    profile: Correction = field(repr=False, compare=False)

    @property
    def duration_s(self) -> float:
        """How long the correction runs [s]."""
        return self.profile.duration

    @property
    def end_s(self) -> float:
        return self.start_s + self.profile.duration

    @property
    def peak(self) -> float:
        """The largest |correction| of the slave's position on the way [slave units]."""
        return self.profile.peak_position

    @property
    def limits(self) -> tuple:
        return self.profile.limits

    def state(self, t: float) -> tuple:
        """The correction at time t: (position, velocity, acceleration); 0 outside the ramp
        (ruckig ends within its 1e-8 contract, the cam is joined exactly)."""
        if t < self.start_s or t >= self.end_s:
            return (0.0, 0.0, 0.0)
        return self.profile.state(t - self.start_s)

    def sample(self, times: np.ndarray) -> np.ndarray:
        """The correction at each time, shape (n, 3)."""
        out = np.zeros((len(times), 3))
        inside = (times >= self.start_s) & (times < self.end_s)
        if inside.any():
            out[inside] = [self.profile.state(t - self.start_s) for t in times[inside]]
        return out

    def text(self, slave_unit: str, master_unit: str) -> str:
        """The ramp in words for the switch's line of the report."""
        jumps = ", ".join(f"{ORDER_NAMES[order]} {size:+.4g} {slave_unit}"
                          + (f"/{master_unit}" + (f"^{order}" if order > 1 else "") if order else "")
                          for order, size in self.compensated)
        return (f"ramp_in over {self.duration_s:.4g} s, peak correction {self.peak:.4g} {slave_unit} "
                f"(compensates {jumps})")

    def to_dict(self) -> dict:
        return {"start_s": self.start_s, "duration_s": self.duration_s, "peak_correction": self.peak,
                "start": list(self.start),
                "compensated": {ORDER_NAMES[o]: s for o, s in self.compensated}}


def refuse_drive_side(events: tuple) -> None:
    """A drive-side scene's switches cannot ramp in: the drive's cam slot has no correction."""
    for event in events:
        if getattr(event, "start_mode", "direct") == "ramp_in":
            raise InputError(f"{event.label}.start_mode: 'ramp_in' should be 'direct' with cam_mode "
                             "'drive' (the drive's cam slot switches tables without a correction)")


def per_second(state, speed: float, acceleration: float) -> tuple:
    """A cam state per master unit^k (position, d/dm, d2/dm2) as time derivatives at the master's
    speed and acceleration [slave units, per s, per s^2]."""
    return (state[0], state[1] * speed, state[2] * speed * speed + state[1] * acceleration)


def plan_ramp_in(event, start_s: float, left: tuple, right: tuple, compensated: tuple,
                 speed: float, acceleration: float) -> RampIn:
    """The correction that takes the slave from ``left`` (where it is) onto ``right`` (the new
    cam), per master unit^k, at the master's ``speed`` [master units/s] and ``acceleration``.

    Raises
    ------
    SimulationError
        ruckig cannot plan it within the event's limits.
    """
    here, there = per_second(left, speed, acceleration), per_second(right, speed, acceleration)
    start = tuple(a - b for a, b in zip(here, there))
    limits = (event.max_velocity, event.max_acceleration, event.max_jerk)
    try:
        profile = Correction(f"ramp_in of {event.label}", start, limits)
    except SimulationError as exc:
        raise SimulationError(f"{event.label}: ramp_in: {exc}") from None
    return RampIn(event, start_s, start, compensated, profile)


def with_correction(left: list, piece, t: float, speed: float, acceleration: float, label: str) -> list:
    """``left`` (a piece's cam state per master unit^k at t) with the piece's running correction
    added, per master unit^k: where the slave is when another switch takes over during a ramp."""
    ramp = getattr(piece, "ramp", None)
    if ramp is None or not ramp.start_s <= t < ramp.end_s:
        return left
    p, v, a = ramp.state(t)
    if speed == 0.0:
        raise InputError(f"{label}: activation at {t:.6g} s should come after the ramp_in of "
                         f"{ramp.event.label} ends ({ramp.end_s:.6g} s): the master stands still there")
    return [left[0] + p, left[1] + v / speed, left[2] + (a - v / speed * acceleration) / speed**2,
            *left[3:]]


def add_correction(piece, t: float, state: tuple) -> tuple:
    """A slave state per second (position, velocity, acceleration) with the piece's correction."""
    ramp = getattr(piece, "ramp", None)
    if ramp is None:
        return state
    return tuple(s + c for s, c in zip(state, ramp.state(t)))


def apply_corrections(pieces: list, out_s: float | None, t_set: np.ndarray, t_end: np.ndarray,
                      targets: np.ndarray, velocities: np.ndarray, reference: np.ndarray,
                      scale: float):
    """The set points and the reference with each ramp's correction added while its piece runs
    (until the next switch or a cam-out takes over): targets [counts], velocity offsets
    [counts/s], reference [slave units]. Returned unchanged (the same arrays) without ramps."""
    ramps = [p.ramp for p in pieces if getattr(p, "ramp", None) is not None]
    if not ramps:
        return targets, velocities, reference
    targets, velocities, reference = targets.copy(), velocities.copy(), reference.copy()
    for ramp in ramps:
        until = min([p.start_s for p in pieces if p.start_s > ramp.start_s]
                    + ([out_s] if out_s is not None else []) + [math.inf])
        for times, kind in ((t_set, "set"), (t_end, "end")):
            idx = np.flatnonzero((times >= ramp.start_s) & (times < min(until, ramp.end_s)))
            if not idx.size:
                continue
            correction = ramp.sample(times[idx])
            if kind == "set":
                targets[idx] += np.rint(correction[:, 0] * scale).astype(np.int64)
                velocities[idx] += correction[:, 1] * scale
            else:
                reference[idx] += correction[:, 0]
    return targets, velocities, reference
