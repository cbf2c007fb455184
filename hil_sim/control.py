"""The drive's control loop: position P -> velocity PI cascade with feed-forward and torque limit.

One :class:`ServoAxis` is what a servo drive in cyclic synchronous position mode does between
two SYNCs: it takes the new target, interpolates linearly from the previous target over
``substeps`` controller periods, and closes the loops on the plant at each of them.

Everything is motor side and SI inside (rad, rad/s, N m); targets and positions at the edge are
integer encoder counts. Feedback is ideal (exact motor angle and speed, no encoder quantization,
no computation delay).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ecam.mechanics import Mechanics
from ecam.validate import choice, fail, integer, number, plain, positive
from hil_sim.plant import RigidPlant, TwoMassPlant, choose_model

#: Plant models a :class:`ServoAxis` (and a scene's ``drive.model``) can ask for.
MODELS = ("auto", "rigid", "two_mass")
_DEFAULT_COUNTS_PER_MOTOR_RAD = 2**20 / (2.0 * math.pi)  # a 20-bit single-turn encoder


def _non_negative(field: str, value: object) -> float:
    return number(field, plain(value), minimum=0.0)


@dataclass(frozen=True)
class Gains:
    """Cascade gains, motor side.

    Parameters
    ----------
    position_kp : float
        Position loop gain [1/s] (rad/s of speed command per rad of position error), > 0.
    velocity_kp : float
        Velocity loop proportional gain [N m s/rad], > 0.
    velocity_ki : float
        Velocity loop integral gain [N m/rad] (N m per rad of integrated speed error), >= 0.
    velocity_feedforward : float
        Fraction of the interpolated target's speed fed forward to the speed command [-], >= 0.
    acceleration_feedforward : float
        Fraction of the model torque J_eq alpha_ref + b_eq omega_ref fed forward [-], >= 0.
    """

    position_kp: float
    velocity_kp: float
    velocity_ki: float
    velocity_feedforward: float = 1.0
    acceleration_feedforward: float = 1.0

    def __post_init__(self) -> None:
        for name in ("position_kp", "velocity_kp"):
            object.__setattr__(self, name, positive(name, plain(getattr(self, name))))
        for name in ("velocity_ki", "velocity_feedforward", "acceleration_feedforward"):
            object.__setattr__(self, name, _non_negative(name, getattr(self, name)))

    @classmethod
    def from_mechanics(cls, mechanics: Mechanics, velocity_bandwidth_hz: float = 200.0,
                       position_bandwidth_hz: float = 30.0, integral_ratio: float = 0.25,
                       velocity_feedforward: float = 1.0,
                       acceleration_feedforward: float = 1.0) -> Gains:
        """Gains from the inertia by the usual cascade rule.

        Parameters
        ----------
        mechanics : Mechanics
            The axis; its reflected inertia J_eq [kg m^2] sets the velocity gain.
        velocity_bandwidth_hz : float
            Velocity loop crossover f_v [Hz]: velocity_kp = J_eq 2 pi f_v.
        position_bandwidth_hz : float
            Position loop crossover f_p [Hz]: position_kp = 2 pi f_p (keep f_p << f_v).
        integral_ratio : float
            PI corner as a fraction of f_v: velocity_ki = velocity_kp 2 pi f_v integral_ratio.
        velocity_feedforward, acceleration_feedforward : float
            Feed-forward fractions (1.0 = full).

        Returns
        -------
        Gains
        """
        if not isinstance(mechanics, Mechanics):
            raise fail("mechanics", mechanics, "a Mechanics")
        f_v = positive("velocity_bandwidth_hz", plain(velocity_bandwidth_hz))
        f_p = positive("position_bandwidth_hz", plain(position_bandwidth_hz))
        ratio = _non_negative("integral_ratio", integral_ratio)
        velocity_kp = mechanics.reflected_inertia() * 2.0 * math.pi * f_v
        return cls(position_kp=2.0 * math.pi * f_p, velocity_kp=velocity_kp,
                   velocity_ki=velocity_kp * 2.0 * math.pi * f_v * ratio,
                   velocity_feedforward=velocity_feedforward,
                   acceleration_feedforward=acceleration_feedforward)

    def velocity_bandwidth_hz(self, mechanics: Mechanics) -> float:
        """Velocity loop crossover these gains give on ``mechanics``, kp / (2 pi J_eq) [Hz]."""
        return self.velocity_kp / (2.0 * math.pi * mechanics.reflected_inertia())


class ServoAxis:
    """A servo drive in cyclic synchronous position mode on a simulated motor, gear and load.

    Parameters
    ----------
    mechanics : Mechanics
        Motor, gear, coupling and load.
    gains : Gains or None
        Control gains; None takes :meth:`Gains.from_mechanics` (200 Hz / 30 Hz).
    cycle_s : float
        Bus (SYNC) cycle [s], > 0.
    substeps : int
        Controller periods per bus cycle, >= 1; the controller and plant step is
        ``cycle_s / substeps``.
    counts_per_motor_rad : float
        Motor encoder resolution [counts/rad], > 0.
    model : {"auto", "rigid", "two_mass"}
        Plant model; "auto" asks :func:`hil_sim.plant.choose_model`.
    excitation_hz : float
        Highest significant cam harmonic [Hz] for "auto" (0 if unknown: then only the loop
        bandwidth is compared with the coupling mode).
    initial_counts : int
        Motor position at start [counts]; the axis starts at rest there with zero error.
    model_factor : float
        Separation factor handed to :func:`choose_model`.

    Notes
    -----
    Per controller period, everything sampled at its start and the torque then held::

        speed_cmd = sqrt_limit(position_kp (theta_ref - theta)) + vff omega_ff + offset_ref
        torque    = clamp(velocity_kp e + velocity_ki integral(e) + aff (J_eq alpha_ff
                                                                        + b_eq omega_ff))
        e         = speed_cmd - omega

    * theta_ref is the linear interpolation from the previous to the current target; it
      reaches the target at the end of the cycle, where the following error is read.
      offset_ref ramps the same way between the last two velocity offsets.
    * omega_ff and alpha_ff come from the parabola through the last three targets, not from
      the straight line, whose acceleration is an impulse at each SYNC (measured on a
      cycloid: 46 counts of following error instead of 132).
    * The torque is clamped to ``mechanics.motor_torque_limit``; while clamped the integrator
      only integrates errors that pull it out of the limit (conditional integration), and
      the position correction never asks for more speed than half the limited acceleration
      can brake within the remaining error (square-root law), so a torque-limited axis
      recovers instead of overshooting into a limit cycle.
    * Feedback is ideal (exact angle and speed, no computation delay). An undamped coupling
      (``coupling_damping`` 0) whose mode lies above the controller's Nyquist frequency can
      be destabilized by the sampled loop, as on a real drive; give the coupling its small
      real damping (a damping ratio of 1e-3 is enough at 1e9 N m/rad).
    * A master that sends the full target speed as velocity offset (0x60B1) should set
      ``velocity_feedforward`` to 0, or the speed is fed forward twice.
    """

    def __init__(self, mechanics: Mechanics, gains: Gains | None = None, cycle_s: float = 1e-3,
                 substeps: int = 16,
                 counts_per_motor_rad: float = _DEFAULT_COUNTS_PER_MOTOR_RAD,
                 model: str = "auto", excitation_hz: float = 0.0, initial_counts: int = 0,
                 model_factor: float = 10.0) -> None:
        if not isinstance(mechanics, Mechanics):
            raise fail("mechanics", mechanics, "a Mechanics")
        if gains is None:
            gains = Gains.from_mechanics(mechanics)
        if not isinstance(gains, Gains):
            raise fail("gains", gains, "a Gains")
        self.cycle_s = positive("cycle_s", plain(cycle_s))
        substeps = integer("substeps", plain(substeps), minimum=1)
        self.counts_per_motor_rad = positive("counts_per_motor_rad", plain(counts_per_motor_rad))
        initial_counts = _counts("initial_counts", initial_counts)
        self.mechanics = mechanics
        self.gains = gains
        self.substeps = substeps
        self.dt = self.cycle_s / substeps

        choice("model", model, MODELS)
        if model == "auto":
            self.model, self.model_reason = choose_model(
                mechanics, excitation_hz, gains.velocity_bandwidth_hz(mechanics), model_factor)
        elif model == "rigid":
            self.model = "rigid"
            self.model_reason = ("rigid model: chosen by the caller." if mechanics.is_rigid else
                                 f"rigid model: chosen by the caller (coupling mode at "
                                 f"{mechanics.torsional_frequency_hz():.4g} Hz ignored).")
        else:
            if mechanics.is_rigid:
                raise fail("model", model, "'auto' or 'rigid' when mechanics has no "
                           "coupling_stiffness (a rigid axis)")
            self.model = "two_mass"
            self.model_reason = (f"two-mass model: chosen by the caller (coupling mode at "
                                 f"{mechanics.torsional_frequency_hz():.4g} Hz).")
        plant_class = RigidPlant if self.model == "rigid" else TwoMassPlant
        self.plant = plant_class(mechanics, self.dt)
        self.plant.reset(motor_angle=initial_counts / self.counts_per_motor_rad)

        self._j_eq = mechanics.reflected_inertia()
        self._b_eq = mechanics.reflected_damping()
        limit = mechanics.motor_torque_limit
        self._torque_limit = math.inf if limit is None else limit
        # Half the acceleration the torque limit allows: the square-root law of the
        # position loop brakes with it, keeping the other half for the feed-forward.
        self._catch_up_acceleration = 0.5 * self._torque_limit / self._j_eq
        # Targets: the last one as the caller numbered it, and an unwrapped copy (int32 wrap).
        self._target_raw = initial_counts
        self._target = initial_counts
        self._reference_speed = 0.0  # slope of the current interpolation [rad/s]
        self._offset = 0.0  # last velocity offset [rad/s]
        self._integral = 0.0  # integral of the speed error [rad]
        self._cycles = 0
        self._peaks = (0.0, 0.0, 0.0)
        self._saturated = False

    # ------------------------------------------------------------------ cycle
    def cycle(self, target_counts: int, velocity_offset_counts_per_s: float = 0.0) -> None:
        """Run one bus cycle towards a new target.

        Parameters
        ----------
        target_counts : int
            Target position (0x607A) [counts]. The step from the previous target is taken
            modulo 2^32 into [-2^31, 2^31), as a drive reads an INTEGER32 that wraps.
        velocity_offset_counts_per_s : float
            Velocity offset (0x60B1) [counts/s]: the target speed at the target's own time.
            It is ramped linearly from the previous offset across the cycle, as the
            position is, and added to the speed command.
        """
        target_counts = _counts("target_counts", target_counts)
        offset = number("velocity_offset_counts_per_s", plain(velocity_offset_counts_per_s))
        step_counts = (target_counts - self._target_raw + 2**31) % 2**32 - 2**31
        start_counts = self._target
        self._target_raw = target_counts
        self._target = start_counts + step_counts

        cpr = self.counts_per_motor_rad
        gains = self.gains
        # Feed-forward follows the parabola through the last three targets: the linear
        # interpolation's own acceleration is a train of impulses at the SYNCs, while the
        # parabola is smooth within the cycle and still ends on the target.
        slope = step_counts / cpr / self.cycle_s
        previous_slope, self._reference_speed = self._reference_speed, slope
        acceleration_ff = (slope - previous_slope) / self.cycle_s
        speed_at_start = 0.5 * (slope + previous_slope)
        # The velocity offset is a sample at the target's time, like the target: ramp to it
        # from the previous one, as the position is interpolated.
        offset_start = self._offset
        offset_step = offset / cpr - offset_start
        self._offset = offset / cpr
        start_rad = start_counts / cpr
        step_rad = step_counts / cpr
        limit = self._torque_limit
        catch_up_acceleration = self._catch_up_acceleration
        limited = math.isfinite(limit)
        plant = self.plant
        dt = self.dt
        n = self.substeps
        peak_torque = peak_coupling = peak_twist = 0.0
        saturated = False
        for i in range(n):
            # Sampled at the start of the controller period, whose torque the plant then
            # holds; the reference arrives on the target as the cycle ends.
            reference = start_rad + step_rad * (i / n)
            speed_ff = speed_at_start + acceleration_ff * (i * dt)
            position_error = reference - plant.motor_angle
            correction = gains.position_kp * position_error
            # Square-root law: never ask for more speed than can be braked to zero within
            # the remaining error, or a torque-limited axis overshoots into a limit cycle.
            if limited:
                brake_speed = math.sqrt(2.0 * catch_up_acceleration * abs(position_error))
                if abs(correction) > brake_speed:
                    correction = math.copysign(brake_speed, position_error)
            speed_error = (correction + gains.velocity_feedforward * speed_ff
                           + offset_start + offset_step * (i / n)
                           - plant.motor_speed)
            torque_ff = gains.acceleration_feedforward * (self._j_eq * acceleration_ff
                                                          + self._b_eq * speed_ff)
            wanted = (gains.velocity_kp * speed_error + gains.velocity_ki * self._integral
                      + torque_ff)
            torque = min(max(wanted, -limit), limit)
            clamped = torque != wanted
            # Anti-windup: while clamped, integrate only errors that pull out of the limit.
            if not clamped or (speed_error > 0.0) != (wanted > 0.0):
                self._integral += speed_error * dt
            saturated = saturated or clamped
            plant.step(torque)
            peak_torque = max(peak_torque, abs(torque))
            peak_coupling = max(peak_coupling, abs(plant.coupling_torque))
            peak_twist = max(peak_twist, abs(plant.twist))
        self._peaks = (peak_torque, peak_coupling, peak_twist)
        self._saturated = saturated
        self._cycles += 1

    def restart(self) -> None:
        """Forget the previous targets: the next cycle starts from where the motor is.

        A drive that enters OPERATION ENABLED (CiA 402 transition 4, also after a fault reset)
        takes its actual position as the last target; interpolating from a target it held
        before the fault would command the jump that caused the fault again.
        """
        counts = self._motor_counts()
        self._target_raw = self._target = counts
        self._reference_speed = 0.0
        self._offset = 0.0
        self._integral = 0.0

    # ------------------------------------------------------------- read-outs
    def _motor_counts(self) -> int:
        return round(self.plant.motor_angle * self.counts_per_motor_rad)

    @property
    def position_counts(self) -> int:
        """Motor encoder position (0x6064) [counts], rounded, numbered like the targets.

        It is the last target minus the following error, so a caller that sends targets
        wrapped to INTEGER32 gets positions next to them.
        """
        return self._target_raw - self.following_error_counts

    @property
    def following_error_counts(self) -> int:
        """Target minus actual motor position (0x60F4) [counts] at the end of the last cycle."""
        return self._target - self._motor_counts()

    @property
    def time_s(self) -> float:
        """Simulated time since start [s]."""
        return self._cycles * self.cycle_s

    @property
    def state(self) -> dict[str, float]:
        """Physical state at the end of the last cycle.

        Returns
        -------
        dict of str to float
            ``time_s`` [s]; ``target_angle``, ``motor_angle``, ``load_angle``, ``twist`` [rad]
            (motor side except load_angle, load side, and twist = r motor_angle - load_angle);
            ``motor_speed``, ``load_speed`` [rad/s]; ``coupling_torque`` [N m] (load side);
            ``motor_torque`` [N m]; ``saturated`` (1.0 if the torque was clamped in any
            controller period of the cycle, else 0.0); ``peak_motor_torque``,
            ``peak_coupling_torque`` [N m] and ``peak_twist`` [rad]: largest magnitudes over
            the cycle's controller periods.
        """
        plant = self.plant
        return {
            "time_s": self.time_s,
            "target_angle": self._target / self.counts_per_motor_rad,
            "motor_angle": plant.motor_angle,
            "motor_speed": plant.motor_speed,
            "load_angle": plant.load_angle,
            "load_speed": plant.load_speed,
            "twist": plant.twist,
            "coupling_torque": plant.coupling_torque,
            "motor_torque": plant.torque,
            "saturated": 1.0 if self._saturated else 0.0,
            "peak_motor_torque": self._peaks[0],
            "peak_coupling_torque": self._peaks[1],
            "peak_twist": self._peaks[2],
        }


def _counts(field: str, value: object) -> int:
    """A raw count: a Python or numpy integer (not a float, not a bool)."""
    return integer(field, plain(value))
