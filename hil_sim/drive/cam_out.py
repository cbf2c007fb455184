"""The drive-side ``MC_CamOut``: the drive leaves the cam and stops, jerk-limited, by itself.

PLCopen's ``MC_CamOut`` (Function Blocks for Motion Control, TC2, v2.0) disengages the slave; the
rig's controller-side path stops it on ruckig's jerk-limited profile from the cam's position,
velocity and acceleration (:func:`hil_sim.events._cam_out_segment`). A drive that runs the cam
itself does the same when the controller writes 5 to 0x2001:01: in its next cycle it takes the
cam's state there and plans the stop with its own profile limits, the CiA 402 objects a drive's
profile generator uses (CiA 402-2 / IEC 61800-7-201, the profile position mode's parameters; the
clause numbers could not be checked against the published text, so the objects are named):

* 0x6083 profile acceleration [counts/s^2]: the limit while the speed's magnitude grows;
* 0x6084 profile deceleration [counts/s^2]: the limit while it falls (the stop's);
* 0x60A4 profile jerk [counts/s^3], sub-index 1 (the drive supports one jerk for every phase of
  the profile: highest sub-index 1).

In ruckig's terms (velocity control to rest) the deceleration bounds the acceleration against the
direction of motion and the acceleration bounds it along it: moving forwards ``min_acceleration``
is -0x6084 and ``max_acceleration`` 0x6083, backwards the other way round. The plan is offline
and read back at each cycle's time, so the stop is deterministic and costs nothing per cycle
beyond ruckig's ``at_time``.
"""

from __future__ import annotations

from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Trajectory

__all__ = ["CamOut"]


class CamOut:
    """A planned stop from ``start`` = (position, velocity, acceleration) [counts, /s, /s^2].

    Parameters
    ----------
    start : tuple of float
        The cam's state in the cycle the cam-out takes effect.
    acceleration, deceleration, jerk : float
        0x6083, 0x6084, 0x60A4:01 [counts/s^n], all positive.

    Raises
    ------
    ValueError
        ruckig cannot plan the stop (the drive answers the SDO write with an abort).
    """

    def __init__(self, start: tuple, acceleration: float, deceleration: float, jerk: float) -> None:
        position, velocity, accel = start
        self.origin = position
        # plan in units of the limits' size: ruckig's tolerances are absolute
        self.scale = scale = max(abs(velocity), 1.0)
        parameters = InputParameter(1)
        parameters.control_interface = ControlInterface.Velocity
        parameters.current_position = [0.0]
        parameters.current_velocity = [velocity / scale]
        parameters.current_acceleration = [accel / scale]
        parameters.target_velocity = [0.0]
        parameters.target_acceleration = [0.0]
        parameters.max_velocity = [max(abs(velocity) / scale, 1.0)]
        forwards = velocity > 0.0 or (velocity == 0.0 and accel >= 0.0)
        along, against = acceleration / scale, deceleration / scale
        parameters.max_acceleration = [along if forwards else against]
        parameters.min_acceleration = [-(against if forwards else along)]
        parameters.max_jerk = [jerk / scale]
        self.trajectory = Trajectory(1)
        try:
            result = Ruckig(1).calculate(parameters, self.trajectory)
        except RuckigError as error:
            raise ValueError(f"ruckig rejected the cam-out: {str(error).splitlines()[0]}") from None
        if result not in (Result.Working, Result.Finished):
            raise ValueError(f"ruckig result {result.name} for the cam-out")
        self.duration = float(self.trajectory.duration)
        self.end = self.origin + scale * self.trajectory.at_time(self.duration)[0][0]

    def state(self, t: float) -> tuple[float, float, float]:
        """(position, velocity, acceleration) t seconds after the start (at rest after the
        stop, exactly where it ended)."""
        if t >= self.duration:
            return self.end, 0.0, 0.0
        position, velocity, acceleration = self.trajectory.at_time(max(t, 0.0))
        s = self.scale
        return self.origin + s * position[0], s * velocity[0], s * acceleration[0]
