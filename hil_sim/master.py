"""The master axis of the rig, and cam-in planned with ruckig.

Master positions are in master counts and speeds in counts/s, as floats (a rig rounds them
when it puts them on the bus; :meth:`sample` does that for it). Time t is simulated time in
seconds, never the wall clock.

ruckig (free version) is used offline (``Ruckig(1).calculate``) for 1-DoF problems only. Its
waypoint feature calls a cloud service and its position limits are ignored, so neither is used:
position extrema and direction of motion are checked here. Every plan is solved in scaled
units (distances of order one), so master counts in the millions do not stress its tolerances.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Trajectory

from ecam import validate
from ecam.errors import SimulationError
from ecam.validate import fail, integer, plain, show


def phase_extremum_times(phases) -> list:
    """Per constant-jerk phase ``(begin, dt, jerk, acceleration, velocity)`` of a ruckig profile,
    the times in it where velocity (the acceleration's zero) and position (the velocity's zeros)
    can peak, with its ends: one array per phase."""
    times = []
    for begin, dt, jerk, acc, vel in phases:
        candidates = [0.0, dt]
        if jerk != 0.0:
            candidates.append(-acc / jerk)
            disc = acc * acc - 2.0 * jerk * vel
            if disc >= 0.0:
                root = math.sqrt(disc)
                candidates += [(-acc + root) / jerk, (-acc - root) / jerk]
        elif acc != 0.0:
            candidates.append(-vel / acc)
        times.append(np.array([begin + c for c in candidates if 0.0 <= c <= dt]))
    return times


def _number(field: str, value: object, **bounds) -> float:
    """``value`` (a Python or numpy number) checked by :func:`ecam.validate.number`."""
    return validate.number(field, plain(value), **bounds)


def _positive(field: str, value: object) -> float:
    return validate.positive(field, plain(value))


def _first_line(error: Exception) -> str:
    """A library's message as one line (ruckig writes several, the first blank)."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return lines[0] if lines else type(error).__name__


class _Segment:
    """One offline ruckig trajectory, planned in scaled units and read back in real ones.

    Positions are relative to ``origin``; ``scale`` multiplies positions, speeds and so on.
    """

    def __init__(self, what: str, origin: float, scale: float, start: tuple[float, float, float],
                 target: tuple[float, float, float], limits: tuple[float, float, float],
                 interface: ControlInterface, minimum_duration: float | None = None) -> None:
        self.origin = origin
        self.scale = scale
        parameters = InputParameter(1)
        parameters.control_interface = interface
        parameters.current_position = [(start[0] - origin) / scale]
        parameters.current_velocity = [start[1] / scale]
        parameters.current_acceleration = [start[2] / scale]
        parameters.target_position = [(target[0] - origin) / scale]
        parameters.target_velocity = [target[1] / scale]
        parameters.target_acceleration = [target[2] / scale]
        parameters.max_velocity = [limits[0] / scale]
        parameters.max_acceleration = [limits[1] / scale]
        parameters.max_jerk = [limits[2] / scale]
        if minimum_duration is not None:
            parameters.minimum_duration = minimum_duration
        self.trajectory = Trajectory(1)
        try:
            result = Ruckig(1).calculate(parameters, self.trajectory)
        except RuckigError as error:
            raise SimulationError(f"ruckig rejected the {what}: {_first_line(error)}") from None
        except ValueError as error:  # a result code outside ruckig's own Result enum
            raise SimulationError(f"ruckig failed on the {what}: {_first_line(error)}") from None
        if result not in (Result.Working, Result.Finished):
            raise SimulationError(f"ruckig result {result.name} for the {what}, "
                                  f"expected Working or Finished")
        self.duration = float(self.trajectory.duration)
        end = self.state(self.duration)
        # ruckig's contract is 1e-8 in scaled units; allow a little for the scaling back.
        for name, got, wanted, index in zip(("position", "velocity", "acceleration"), end,
                                            target, range(3)):
            if interface == ControlInterface.Velocity and index == 0:
                continue
            if abs(got - wanted) > 1e-7 * scale:
                raise SimulationError(f"ruckig {what} ends at {name} {got}, "
                                      f"expected {wanted}")

    def state(self, t: float) -> tuple[float, float, float]:
        """(position, velocity, acceleration) at time t in [0, duration] after the start."""
        position, velocity, acceleration = self.trajectory.at_time(min(max(t, 0.0),
                                                                       self.duration))
        s = self.scale
        return (self.origin + s * position[0], s * velocity[0], s * acceleration[0])

    def critical_times(self, samples: int = 2049) -> np.ndarray:
        """Times where velocity or position can have an extremum, plus a dense grid.

        Inside a ruckig phase the jerk is constant, so velocity peaks where the acceleration
        crosses zero and position where the velocity does; both are solved per phase.
        """
        profile = self.trajectory.profiles[0][0]
        begin = profile.brake.duration + profile.accel.duration
        phases = []
        for dt, jerk, acc, vel in zip(profile.t, profile.j, profile.a, profile.v):
            phases.append((begin, dt, jerk, acc, vel))
            begin += dt
        times = [np.linspace(0.0, self.duration, samples), *phase_extremum_times(phases)]
        return np.clip(np.concatenate(times), 0.0, self.duration)


class _Master:
    """Common read-out of a 1-D motion given by ``_state(t) -> (position, velocity, accel)``."""

    def _state(self, t: float) -> tuple[float, float, float]:
        raise NotImplementedError

    def _evaluate(self, t, order: int):
        if np.ndim(t) == 0:
            return self._state(_number("t", t))[order]
        times = np.asarray(t, dtype=float)
        return np.array([self._state(float(x))[order] for x in times.ravel()]).reshape(
            times.shape)

    def position(self, t):
        """Position at simulated time t [s] (float or array) [counts]."""
        return self._evaluate(t, 0)

    def velocity(self, t):
        """Velocity at simulated time t [s] [counts/s]."""
        return self._evaluate(t, 1)

    def acceleration(self, t):
        """Acceleration at simulated time t [s] [counts/s^2]."""
        return self._evaluate(t, 2)

    def sample(self, n_cycles: int, cycle_s: float, order: int = 0) -> np.ndarray:
        """Values at t = i cycle_s, i = 0 .. n_cycles - 1.

        Parameters
        ----------
        n_cycles : int
            Number of bus cycles, >= 0.
        cycle_s : float
            Bus cycle [s], > 0.
        order : int
            0: positions rounded to int64 counts; 1: velocity [counts/s]; 2: acceleration
            [counts/s^2] (float64).

        Returns
        -------
        ndarray, shape (n_cycles,)
        """
        n_cycles = integer("n_cycles", plain(n_cycles), minimum=0)
        cycle_s = _positive("cycle_s", cycle_s)
        order = integer("order", plain(order), minimum=0, maximum=2)
        values = self._evaluate(np.arange(n_cycles) * cycle_s, order)
        values = np.asarray(values, dtype=float).reshape(-1)
        return np.rint(values).astype(np.int64) if order == 0 else values


class ConstantSpeed(_Master):
    """A master turning at constant speed.

    Parameters
    ----------
    speed : float
        Master speed [counts/s] (any sign).
    start_position : float
        Position at t = 0 [counts].
    """

    def __init__(self, speed: float, start_position: float = 0.0) -> None:
        self.speed = _number("speed", speed)
        self.start_position = _number("start_position", start_position)

    def _state(self, t: float) -> tuple[float, float, float]:
        return (self.start_position + self.speed * t, self.speed, 0.0)

    def _evaluate(self, t, order: int):
        # Vectorized: this master is sampled a lot.
        times = np.asarray(t, dtype=float)
        if order == 0:
            values = self.start_position + self.speed * times
        else:
            values = np.full(times.shape, self.speed if order == 1 else 0.0)
        return float(values) if values.ndim == 0 else values


class StartStop(_Master):
    """A master at rest that starts to ``speed`` and, optionally, stops again, jerk-limited.

    Both ramps are time-optimal ruckig profiles (velocity interface): acceleration and jerk
    stay within their limits, and acceleration is zero at both ends of each ramp.

    Parameters
    ----------
    speed : float
        Cruise speed [counts/s], non-zero (the sign gives the direction).
    max_acceleration : float
        Acceleration limit [counts/s^2], > 0.
    max_jerk : float
        Jerk limit [counts/s^3], > 0.
    start_s : float
        Time the start ramp begins [s], >= 0.
    stop_s : float or None
        Time the stop ramp begins [s], >= start_s; None never stops. A stop during the start
        ramp is planned from the state at that moment.
    start_position : float
        Position while at rest before the start [counts].

    Attributes
    ----------
    at_speed_s : float
        Time the start ramp reaches ``speed`` [s] (if not stopped before).
    stopped_s : float or None
        Time the master is at rest again [s].
    """

    def __init__(self, speed: float, max_acceleration: float, max_jerk: float,
                 start_s: float = 0.0, stop_s: float | None = None,
                 start_position: float = 0.0) -> None:
        self.speed = _number("speed", speed)
        if self.speed == 0.0:
            raise fail("speed", self.speed, "non-zero")
        self.max_acceleration = _positive("max_acceleration", max_acceleration)
        self.max_jerk = _positive("max_jerk", max_jerk)
        self.start_s = _number("start_s", start_s, minimum=0.0)
        self.start_position = _number("start_position", start_position)
        scale = abs(self.speed)
        limits = (2.0 * scale, self.max_acceleration, self.max_jerk)
        self._up = _Segment("start ramp", self.start_position, scale,
                            (self.start_position, 0.0, 0.0), (0.0, self.speed, 0.0), limits,
                            ControlInterface.Velocity)
        self.at_speed_s = self.start_s + self._up.duration
        self._down = None
        self.stop_s = None
        self.stopped_s = None
        if stop_s is not None:
            self.stop_s = _number("stop_s", stop_s)
            if self.stop_s < self.start_s:
                raise fail("stop_s", self.stop_s, f">= start_s {show(self.start_s)}")
            state = self._running(self.stop_s)
            self._down = _Segment("stop ramp", state[0], scale, state, (0.0, 0.0, 0.0), limits,
                                  ControlInterface.Velocity)
            self.stopped_s = self.stop_s + self._down.duration

    def _running(self, t: float) -> tuple[float, float, float]:
        """State of the start ramp and cruise, ignoring any stop."""
        if t <= self.start_s:
            return (self.start_position, 0.0, 0.0)
        if t < self.at_speed_s:
            return self._up.state(t - self.start_s)
        end = self._up.state(self._up.duration)
        return (end[0] + self.speed * (t - self.at_speed_s), self.speed, 0.0)

    def _state(self, t: float) -> tuple[float, float, float]:
        if self._down is None or t < self.stop_s:
            return self._running(t)
        if t < self.stopped_s:
            return self._down.state(t - self.stop_s)
        return (self._down.state(self._down.duration)[0], 0.0, 0.0)


Cam = Callable[[float, int], float]


class CamIn(_Master):
    """A slave engaging onto a cam driven by a constant-speed master (see :func:`cam_in`).

    ``position(t)`` etc. give the slave [slave counts] at time t after planning: at rest
    before 0, on the ruckig profile until ``engage_s``, on the cam after.

    Attributes
    ----------
    master : ConstantSpeed
        The master, at ``master_position`` at t = 0.
    engage_s : float
        Time of engagement [s].
    engage_master_position : float
        Master position of engagement [master counts].
    position_range : tuple of float
        (min, max) slave position during the cam-in [slave counts].
    """

    def __init__(self, cam: Cam, master: ConstantSpeed, slave_position: float,
                 engage_master_position: float, segment: _Segment,
                 position_range: tuple[float, float]) -> None:
        self.cam = cam
        self.master = master
        self.slave_position = slave_position
        self.engage_master_position = engage_master_position
        self.engage_s = segment.duration
        self.position_range = position_range
        self._segment = segment

    def _state(self, t: float) -> tuple[float, float, float]:
        if t <= 0.0:
            return (self.slave_position, 0.0, 0.0)
        if t < self.engage_s:
            return self._segment.state(t)
        speed = self.master.speed
        m = self.master.start_position + speed * t
        return (float(self.cam(m, 0)), float(self.cam(m, 1)) * speed,
                float(self.cam(m, 2)) * speed * speed)

    def slave(self, master_position: float, order: int = 0) -> float:
        """Slave motion as a function of master position (a cam in its own right).

        Parameters
        ----------
        master_position : float
            [master counts].
        order : int
            0, 1 or 2: position [slave counts], d/dmaster, d2/dmaster2.
        """
        order = integer("order", plain(order), minimum=0, maximum=2)
        speed = self.master.speed
        t = (_number("master_position", master_position) - self.master.start_position) / speed
        return self._state(t)[order] / speed**order


def cam_in(cam: Cam, slave_position: float, master_position: float, master_speed: float,
           engage_master_position: float, max_velocity: float, max_acceleration: float,
           max_jerk: float, min_position: float | None = None,
           max_position: float | None = None) -> CamIn:
    """Plan a jerk-limited engagement of a slave at rest onto a cam, without a jump.

    The slave leaves rest at ``slave_position`` now (t = 0) and arrives exactly when the master
    reaches ``engage_master_position`` with the cam's position, velocity and acceleration
    there, so position, velocity and acceleration are continuous at both ends.

    Parameters
    ----------
    cam : callable
        ``cam(master, order)``: slave position [slave counts] for order 0, and its derivatives
        d^order/dmaster^order [slave counts / master count^order] for orders 1 and 2.
    slave_position : float
        Slave position at rest now [slave counts].
    master_position : float
        Master position now [master counts].
    master_speed : float
        Constant master speed [master counts/s], non-zero.
    engage_master_position : float
        Master position at which the slave joins the cam [master counts]; must lie ahead of
        ``master_position`` in the direction of motion.
    max_velocity, max_acceleration, max_jerk : float
        Slave limits during the cam-in [slave counts/s, /s^2, /s^3], > 0.
    min_position, max_position : float or None
        Optional slave position limits [slave counts], checked here (ruckig ignores them).

    Returns
    -------
    CamIn

    Raises
    ------
    InputError
        A value out of range: engagement behind the master, cam velocity or acceleration at
        engagement above the limits.
    SimulationError
        No plan meets the requirements: the engagement point is too close to reach in time,
        the motion would reverse against the cam's direction, a position limit is crossed,
        or ruckig failed.
    """
    if not callable(cam):
        raise fail("cam", cam, "callable as cam(master, order)")
    slave_position = _number("slave_position", slave_position)
    master_speed = _number("master_speed", master_speed)
    if master_speed == 0.0:
        raise fail("master_speed", master_speed, "non-zero")
    master = ConstantSpeed(master_speed, _number("master_position", master_position))
    engage = _number("engage_master_position", engage_master_position)
    limits = tuple(_positive(name, value) for name, value in (
        ("max_velocity", max_velocity), ("max_acceleration", max_acceleration),
        ("max_jerk", max_jerk)))
    engage_s = (engage - master.start_position) / master.speed
    if not engage_s > 0.0:
        raise fail("engage_master_position", engage, f"ahead of master_position "
                   f"{show(master.start_position)} for master_speed {show(master.speed)}")
    speed = master.speed
    position, slope, curvature = (_number(f"cam(engage_master_position, {order})",
                                        cam(engage, order)) for order in range(3))
    target = (position, slope * speed, curvature * speed * speed)
    for name, value, limit in (("velocity", target[1], limits[0]),
                               ("acceleration", target[2], limits[1])):
        if abs(value) > limit:
            raise fail(f"max_{name}", limit, f">= the cam {name} {show(abs(value))} at "
                       f"engage_master_position {show(engage)}")
    distance = target[0] - slave_position
    direction = math.copysign(1.0, distance) if distance != 0.0 else math.copysign(
        1.0, target[1]) if target[1] != 0.0 else 0.0
    if direction * target[1] < 0.0:
        raise SimulationError(f"cam velocity {target[1]} at engagement runs against the "
                              f"direction to the cam position {target[0]} from {slave_position}: "
                              f"cam-in would reverse")

    scale = max(abs(distance), abs(target[1]) * engage_s, abs(target[2]) * engage_s**2)
    scale = scale if scale > 0.0 else 1.0
    segment = _Segment("cam-in", slave_position, scale, (slave_position, 0.0, 0.0), target,
                       limits, ControlInterface.Position, minimum_duration=engage_s)
    if segment.duration > engage_s * (1.0 + 1e-9):
        raise SimulationError(
            f"cam-in needs {segment.duration:.6g} s but the master reaches the engagement "
            f"point in {engage_s:.6g} s: engage further ahead")

    # The profile is exact in its last phase's end state; check the whole curve ourselves.
    times = segment.critical_times()
    states = np.array([segment.state(t) for t in times])
    tolerance = 1e-9 * max(limits[0], abs(target[1]))
    if direction != 0.0 and np.min(direction * states[:, 1]) < -tolerance:
        worst = times[np.argmin(direction * states[:, 1])]
        raise SimulationError(f"cam-in velocity reverses at t {worst:.6g} s "
                              f"(velocity {segment.state(worst)[1]:.6g})")
    if direction == 0.0 and np.max(np.abs(states[:, 1])) > tolerance:
        raise SimulationError("cam-in moves although start and cam state coincide")
    position_range = (float(states[:, 0].min()), float(states[:, 0].max()))
    if min_position is not None and position_range[0] < _number("min_position", min_position):
        raise SimulationError(f"cam-in position {position_range[0]} should be >= min_position "
                              f"{min_position}")
    if max_position is not None and position_range[1] > _number("max_position", max_position):
        raise SimulationError(f"cam-in position {position_range[1]} should be <= max_position "
                              f"{max_position}")
    return CamIn(cam, master, slave_position, engage, segment, position_range)
