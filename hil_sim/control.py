"""The drive's control loop: position P -> velocity PI cascade with feed-forward and torque limit.

One :class:`ServoAxis` is what a servo drive in cyclic synchronous position mode does between
two SYNCs: it takes the new target (latched at the SYNC), interpolates from the previous target
over the next cycle in ``substeps`` controller periods, and closes the loops on the plant at
each of them.

Everything is motor side and SI inside (rad, rad/s, N m); targets and positions at the edge are
integer position counts. What the drive has of a real one is chosen by :class:`DriveEffects`:
ideal feedback or an encoder with a filtered speed estimate, an ideal torque or a current loop
with its lag, and the torque applied at once or one controller period later (computation delay).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ecam.mechanics import Mechanics
from ecam.sizing import VoltageLimit
from ecam.validate import choice, fail, integer, number, plain, positive
from hil_sim.feedback import Encoder, IdealFeedback
from hil_sim.filters import Notch
from hil_sim.int32 import wrap_int32
from hil_sim.plant import MechanicalEffects, Plant, choose_model

#: Plant models a :class:`ServoAxis` (and a scene's ``drive.model``) can ask for.
MODELS = ("auto", "rigid", "two_mass")
#: Where the drive takes its feed-forward from (a scene's ``drive.feedforward``).
FEEDFORWARD_SOURCES = ("target", "offset")
_DEFAULT_COUNTS_PER_MOTOR_RAD = 2**20 / (2.0 * math.pi)  # a 20-bit single-turn encoder
#: Time constant of the acceleration feed-forward's low-pass when it is derived from the targets
#: alone [s]: a second difference of integer targets is noise that grows with the cycle rate.
TARGET_ACCELERATION_FILTER_S = 1e-3
#: Below this speed reference [rad/s, motor side] the friction feed-forward is proportional to
#: it (full beyond; AX2000 VSTFR): about 1 rpm, so that it does not chatter at a reversal.
FRICTION_BAND = 0.1


def _non_negative(field: str, value: object) -> float:
    return number(field, plain(value), minimum=0.0)


@dataclass(frozen=True)
class DriveEffects:
    """What the drive has of a real one; the defaults are an ideal drive.

    Parameters
    ----------
    encoder_counts_per_rev : int or None
        Motor encoder counts per revolution; None: the exact angle and speed are fed back.
    velocity_filter_hz : float
        Cut-off of the speed estimate's first-order filter [Hz], with an encoder.
    current_loop_hz : float or None
        Current-loop bandwidth [Hz]: the torque follows the command through a first-order lag;
        None: the torque is the command.
    computation_delay : bool
        The torque computed from one period's samples is applied in the next period (a drive
        samples, computes, then writes its PWM), instead of at once.
    speed_symmetrization : bool
        The speed reference the PI compares with the speed estimate passes the estimate's own
        lag first (half a period of the difference quotient, then the speed filter's first
        order), so that the PI does not fight the feed-forward over the estimate's delay (a
        drive's speed precontrol balancing: SINAMICS S120/S150 List Manual, p1428 "speed
        precontrol balancing dead time" and p1429 "... time constant"; Beckhoff TF5200
        P-AXIS-00361, the setpoint filter time constant for feed-forward symmetrization; both 0,
        i.e. off, by default). No effect with ideal feedback, which has no lag.
    friction_feedforward : float
        Coulomb friction torque fed forward [N m], >= 0, signed by the speed reference and
        proportional to it within :data:`FRICTION_BAND` (the curve of the Beckhoff AX2000's
        ISTFR/VSTFR friction compensation, ASCII object 0x36A4); 0: none, as drives ship it
        (ISTFR default 0; Beckhoff TF5200 P-AXIS-00522, friction compensation, default 0).
    voltage_limit : ecam.sizing.VoltageLimit or None
        The motor's voltage limit on the drive's DC link: the torque clamp at the measured
        speed is the smaller of ``mechanics.motor_torque_limit`` and this curve (a drive's
        current controller runs out of voltage above the speed where the back-EMF and the
        winding's drop take the DC link's); None: the constant clamp alone.
    """

    encoder_counts_per_rev: int | None = None
    velocity_filter_hz: float = 2000.0
    current_loop_hz: float | None = None
    computation_delay: bool = False
    speed_symmetrization: bool = False
    friction_feedforward: float = 0.0
    voltage_limit: VoltageLimit | None = None

    def __post_init__(self) -> None:
        if self.encoder_counts_per_rev is not None:
            object.__setattr__(self, "encoder_counts_per_rev", integer(
                "encoder_counts_per_rev", plain(self.encoder_counts_per_rev), minimum=4,
                maximum=2**40))
        object.__setattr__(self, "velocity_filter_hz",
                           positive("velocity_filter_hz", plain(self.velocity_filter_hz)))
        if self.current_loop_hz is not None:
            object.__setattr__(self, "current_loop_hz",
                               positive("current_loop_hz", plain(self.current_loop_hz)))
        if not isinstance(self.computation_delay, bool):
            raise fail("computation_delay", self.computation_delay, "true or false")
        if not isinstance(self.speed_symmetrization, bool):
            raise fail("speed_symmetrization", self.speed_symmetrization, "true or false")
        object.__setattr__(self, "friction_feedforward",
                           _non_negative("friction_feedforward", self.friction_feedforward))
        if self.voltage_limit is not None and not isinstance(self.voltage_limit, VoltageLimit):
            raise fail("voltage_limit", self.voltage_limit, "an ecam.sizing.VoltageLimit or None")


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
    notch_hz : float
        Centre of the notch on the torque command [Hz] (:mod:`hil_sim.filters`); 0: none.
    notch_width : float
        Its width (the poles' damping ratio), > 0.
    notch_depth_db : float
        Its depth [dB], > 0.
    """

    position_kp: float
    velocity_kp: float
    velocity_ki: float
    velocity_feedforward: float = 1.0
    acceleration_feedforward: float = 1.0
    notch_hz: float = 0.0
    notch_width: float = 0.5
    notch_depth_db: float = 30.0

    def __post_init__(self) -> None:
        for name in ("position_kp", "velocity_kp", "notch_width", "notch_depth_db"):
            object.__setattr__(self, name, positive(name, plain(getattr(self, name))))
        for name in ("velocity_ki", "velocity_feedforward", "acceleration_feedforward",
                     "notch_hz"):
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
        Position counts per motor radian (the unit of targets and positions), > 0.
    model : {"auto", "rigid", "two_mass"}
        Plant model; "auto" asks :func:`hil_sim.plant.choose_model`.
    excitation_hz : float
        Highest significant cam harmonic [Hz] for "auto" (0 if unknown: then only the loop
        bandwidth is compared with the coupling mode).
    initial_counts : int
        Motor position at start [counts]; the axis starts at rest there with zero error.
    model_factor : float
        Separation factor handed to :func:`choose_model`.
    plant_effects : MechanicalEffects, optional
        Backlash (needs the two-mass model: it forces it), Coulomb friction, coupling inertia.
    drive_effects : DriveEffects, optional
        Encoder and speed estimate, current loop, computation delay; default an ideal drive.
    feedforward : {"target", "offset"}
        Where the feed-forward comes from (see the notes).

    Notes
    -----
    Per controller period i of the cycle (t = i dt), from the readings at its start::

        speed_cmd = sqrt_limit(position_kp (theta_ref(t) - theta)) + vff omega_ref(t) [+ offset]
        torque    = clamp(velocity_kp e + velocity_ki integral(e)
                          + aff (J_eq alpha_ref(t) + b_eq omega_ref(t)))
        e         = speed_cmd - omega

    * ``feedforward="offset"`` (a master that streams the velocity offset 0x60B1 with each
      target, or the drive-side cam): theta_ref is the linear interpolation of the targets
      (CiA 402 0x60C0 = 0), omega_ref the velocity offset ramped between its last two values
      and alpha_ref their difference over the cycle; no difference of integer targets is taken,
      so the feed-forward does not grow with the cycle rate or with SYNC jitter.
    * ``feedforward="target"`` (a master that streams targets only): theta_ref is the linear
      interpolation of the targets (CiA 402 0x60C0 = 0); omega_ref and alpha_ref come from the
      parabola through the last three targets, the acceleration through a first-order low-pass of
      :data:`TARGET_ACCELERATION_FILTER_S`; a velocity offset, if any, is ramped between its last
      two values and added to the speed command.
    * The torque is clamped to ``mechanics.motor_torque_limit`` and, with
      ``drive_effects.voltage_limit``, to the motor's voltage limit at the measured speed;
      while clamped the integrator
      only integrates errors that pull it out of the limit (conditional integration), and the
      position correction never asks for more speed than half the limited acceleration can
      brake within the remaining error (square-root law), so a torque-limited axis recovers
      instead of overshooting into a limit cycle.
    * theta and omega are the encoder's reading and speed estimate with
      ``drive_effects.encoder_counts_per_rev``, else exact; the torque goes through the current
      loop when it is modelled, and is applied one period late with the computation delay.
    * An undamped coupling whose mode lies above the controller's Nyquist frequency can be
      destabilized by the sampled loop, as on a real drive; give the coupling its small real
      damping (a damping ratio of 1e-3 is enough at 1e9 N m/rad).
    """

    def __init__(self, mechanics: Mechanics, gains: Gains | None = None, cycle_s: float = 1e-3,
                 substeps: int = 16,
                 counts_per_motor_rad: float = _DEFAULT_COUNTS_PER_MOTOR_RAD,
                 model: str = "auto", excitation_hz: float = 0.0, initial_counts: int = 0,
                 model_factor: float = 10.0, plant_effects: MechanicalEffects | None = None,
                 drive_effects: DriveEffects | None = None, feedforward: str = "target") -> None:
        if not isinstance(mechanics, Mechanics):
            raise fail("mechanics", mechanics, "a Mechanics")
        if gains is None:
            gains = Gains.from_mechanics(mechanics)
        if not isinstance(gains, Gains):
            raise fail("gains", gains, "a Gains")
        plant_effects = MechanicalEffects() if plant_effects is None else plant_effects
        if not isinstance(plant_effects, MechanicalEffects):
            raise fail("plant_effects", plant_effects, "a MechanicalEffects")
        drive_effects = DriveEffects() if drive_effects is None else drive_effects
        if not isinstance(drive_effects, DriveEffects):
            raise fail("drive_effects", drive_effects, "a DriveEffects")
        self.feedforward = choice("feedforward", feedforward, FEEDFORWARD_SOURCES)
        self.cycle_s = positive("cycle_s", plain(cycle_s))
        substeps = integer("substeps", plain(substeps), minimum=1)
        self.counts_per_motor_rad = positive("counts_per_motor_rad", plain(counts_per_motor_rad))
        initial_counts = _counts("initial_counts", initial_counts)
        self.mechanics = mechanics
        self.gains = gains
        self.substeps = substeps
        self.dt = self.cycle_s / substeps
        self.plant_effects = plant_effects
        self.drive_effects = drive_effects

        choice("model", model, MODELS)
        if model == "auto":
            self.model, self.model_reason = choose_model(
                mechanics, excitation_hz, gains.velocity_bandwidth_hz(mechanics), model_factor,
                control_rate_hz=1.0 / self.dt, current_loop_hz=drive_effects.current_loop_hz)
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
        if plant_effects.gear_backlash and self.model == "rigid":
            if mechanics.is_rigid:
                raise fail("gear_backlash", plant_effects.gear_backlash,
                           "0 on an axis without coupling_stiffness (backlash sits in series "
                           "with the coupling spring)")
            self.model = "two_mass"
            self.model_reason = (f"two-mass model: the gear backlash needs it (coupling mode at "
                                 f"{mechanics.torsional_frequency_hz():.4g} Hz).")
        self.plant = Plant(mechanics, self.dt, model=self.model, effects=plant_effects,
                           current_loop_hz=drive_effects.current_loop_hz)
        if drive_effects.encoder_counts_per_rev is None:
            self.feedback = IdealFeedback()
        else:
            self.feedback = Encoder(drive_effects.encoder_counts_per_rev,
                                    drive_effects.velocity_filter_hz, self.dt)
        self._delay = drive_effects.computation_delay
        # the speed reference through the estimate's lag (symmetrization): its filter's gain
        self._symmetrize = (drive_effects.speed_symmetrization
                            and drive_effects.encoder_counts_per_rev is not None)
        self._symmetric_gain = 1.0 - math.exp(-2.0 * math.pi * drive_effects.velocity_filter_hz
                                              * self.dt)
        self._friction_ff = drive_effects.friction_feedforward
        voltage = drive_effects.voltage_limit
        self._voltage = None if voltage is None else voltage.constants
        # below the speed where the voltage still gives the constant clamp the curve cannot
        # bind: the hot loop skips it there (the curve falls with the speed)
        self._voltage_knee = (0.0 if voltage is None or mechanics.motor_torque_limit is None
                              else voltage.speed_at(mechanics.motor_torque_limit))
        # A notch at or above the controller's Nyquist frequency cannot be run (a drive's
        # tuning tool refuses it): none then, e.g. while 0x60C2 still holds its power-on value.
        self._notch = (Notch(gains.notch_hz, gains.notch_width, gains.notch_depth_db, self.dt)
                       if 0.0 < gains.notch_hz < 0.5 / self.dt else None)

        self._j_eq = self.plant.mechanics.reflected_inertia() + (
            plant_effects.coupling_inertia * mechanics.gear_ratio**2 / mechanics.gear_efficiency)
        self._b_eq = mechanics.reflected_damping()
        limit = mechanics.motor_torque_limit
        self._torque_limit = math.inf if limit is None else limit
        # Half the acceleration the torque limit allows: the square-root law of the
        # position loop brakes with it, keeping the other half for the feed-forward.
        self._catch_up_acceleration = 0.5 * self._torque_limit / self._j_eq
        self._acceleration_filter = 1.0 - math.exp(-self.cycle_s / TARGET_ACCELERATION_FILTER_S)
        self._place(initial_counts)
        self._cycles = 0
        self._peaks = (0.0, 0.0, 0.0)
        self._saturated = False

    def _place(self, counts: int, speed: float = 0.0) -> None:
        """The axis at ``counts`` turning at ``speed`` [rad/s], the references on it."""
        angle = counts / self.counts_per_motor_rad
        self.plant.reset(motor_angle=angle, motor_speed=speed)
        self.feedback.reset(angle, speed)
        self._measured = self.feedback.sample(angle, speed)
        # Targets: the last one as the caller numbered it, and an unwrapped copy (int32 wrap).
        self._target_raw = counts
        self._target = counts
        self._reference_speed = 0.0  # target mode: slope of the current interpolation [rad/s]
        self._acceleration = 0.0  # target mode: filtered acceleration feed-forward [rad/s^2]
        self._offset = 0.0  # last velocity offset [rad/s]
        self._integral = 0.0  # integral of the speed error [rad]
        self._pending = 0.0  # torque computed, to be applied next period (computation delay)
        self._symmetric = speed  # the speed reference through the estimate's lag [rad/s]

    # ------------------------------------------------------------------ cycle
    def cycle(self, target_counts: int, velocity_offset_counts_per_s: float = 0.0) -> None:
        """Run one bus cycle towards a new target.

        Parameters
        ----------
        target_counts : int
            Target position (0x607A) [counts] for the end of the cycle. The step from the
            previous target is taken modulo 2^32 into [-2^31, 2^31), as a drive reads an
            INTEGER32 that wraps.
        velocity_offset_counts_per_s : float
            Velocity offset (0x60B1) [counts/s]: the target speed at the target's time.
        """
        if type(target_counts) is not int:  # the common case (a Python int) is checked at once
            target_counts = _counts("target_counts", target_counts)
        offset = velocity_offset_counts_per_s
        if type(offset) not in (int, float) or not math.isfinite(offset):
            offset = number("velocity_offset_counts_per_s", plain(offset))
        step_counts = wrap_int32(target_counts - self._target_raw)  # an INTEGER32 that wraps
        start_counts = self._target
        self._target_raw = target_counts
        self._target = start_counts + step_counts

        cpr = self.counts_per_motor_rad
        t_cycle = self.cycle_s
        step_rad = step_counts / cpr
        offset_start, offset_end = self._offset, offset / cpr
        self._offset = offset_end
        # The cycle's references as polynomials in the time s since the SYNC: the position
        # theta_ref = start + slope s (linear interpolation of the targets, CiA 402 0x60C0 = 0),
        # the speed fed forward, and the acceleration fed forward.
        slope = step_rad / t_cycle
        if self.feedforward == "offset":
            # The speed from the velocity offsets, ramped between the last two, the acceleration
            # as their difference over the cycle: no difference of integer targets, so nothing
            # that grows with the cycle rate or with SYNC jitter.
            acceleration = (offset_end - offset_start) / t_cycle
            speed = (offset_start, acceleration)
            extra = (0.0, 0.0)
        else:
            # Feed-forward from the parabola through the last three targets (smooth within the
            # cycle, unlike the line's impulses at each SYNC), its acceleration low-passed; a
            # velocity offset, if any, ramped and added to the speed command.
            previous_slope, self._reference_speed = self._reference_speed, slope
            raw_acceleration = (slope - previous_slope) / t_cycle
            self._acceleration += self._acceleration_filter * (raw_acceleration
                                                               - self._acceleration)
            acceleration = self._acceleration
            speed = (0.5 * (slope + previous_slope), acceleration)
            extra = (offset_start, (offset_end - offset_start) / t_cycle)
        gains = self.gains
        vff, aff = gains.velocity_feedforward, gains.acceleration_feedforward
        speed_command = (vff * speed[0] + extra[0], vff * speed[1] + extra[1])
        torque_ff = (aff * (self._j_eq * acceleration + self._b_eq * speed[0]),
                     aff * self._b_eq * speed[1])
        self._run(start_counts / cpr, slope, speed_command, torque_ff)
        self._cycles += 1

    def _run(self, start: float, slope: float, speed_command: tuple, torque_ff: tuple) -> None:
        """The controller periods of one cycle (the hot loop: everything looked up once).
        ``speed_command`` and ``torque_ff`` are (value at the SYNC, slope) of the feed-forward."""
        gains = self.gains
        kp, kv, ki = gains.position_kp, gains.velocity_kp, gains.velocity_ki
        limit = self._torque_limit
        catch_up = 2.0 * self._catch_up_acceleration
        limited = math.isfinite(limit)
        plant = self.plant
        advance = plant.advance
        sample = None if isinstance(self.feedback, IdealFeedback) else self.feedback.sample
        delay = self._delay
        notch = self._notch
        pending = self._pending
        integral = self._integral
        angle, speed = self._measured
        dt = self.dt
        v0, v1 = speed_command
        t0, t1 = torque_ff
        symmetrize, symmetric, gain = self._symmetrize, self._symmetric, self._symmetric_gain
        half = 0.5 * dt
        friction = self._friction_ff
        voltage = self._voltage
        if voltage is not None:
            vkt, va, vx, vr, vr2, vu, vu2 = voltage
            knee = self._voltage_knee
            sqrt = math.sqrt
        peak_torque = peak_coupling = peak_twist = 0.0
        saturated = False
        for i in range(self.substeps):
            s = i * dt
            # Sampled at the start of the controller period, whose torque the plant then holds.
            position_error = start + slope * s - angle
            correction = kp * position_error
            # Square-root law: never ask for more speed than can be braked to zero within
            # the remaining error, or a torque-limited axis overshoots into a limit cycle.
            if limited and correction * correction > catch_up * abs(position_error):
                correction = math.copysign(math.sqrt(catch_up * abs(position_error)),
                                           position_error)
            reference = v0 + v1 * s
            if symmetrize:
                # the estimate is the filtered mean speed of the last period, i.e. of half a
                # period ago: the reference passes the same dead time and filter
                symmetric += gain * (reference - half * v1 - symmetric)
                speed_error = correction + symmetric - speed
            else:
                speed_error = correction + reference - speed
            wanted = kv * speed_error + ki * integral + t0 + t1 * s
            if friction:
                # Coulomb friction opposes the motion the reference asks for; linear within
                # FRICTION_BAND so the torque does not chatter at a reversal
                wanted += friction * max(-1.0, min(1.0, reference / FRICTION_BAND))
            if notch is not None:
                wanted = notch(wanted)
            if voltage is None or -knee <= speed <= knee:
                clamp = limit
            else:
                # the voltage limit at the measured speed, as ecam.sizing.VoltageLimit.torque
                # has it, inlined (this loop runs every controller period)
                w = speed if speed >= 0.0 else -speed
                e = va * w
                if e >= vu:
                    clamp = 0.0
                else:
                    xl = vx * w
                    z2 = vr2 + xl * xl
                    clamp = (vkt * (sqrt(e * e * vr2 - z2 * (e * e - vu2)) - e * vr) / z2
                             if z2 > 0.0 else limit)
                    if clamp > limit:
                        clamp = limit
            if wanted > clamp:
                torque, clamped = clamp, True
            elif wanted < -clamp:
                torque, clamped = -clamp, True
            else:
                torque, clamped = wanted, False
            # Anti-windup: while clamped, integrate only errors that pull out of the limit.
            if not clamped or (speed_error > 0.0) != (wanted > 0.0):
                integral += speed_error * dt
            if clamped:
                saturated = True
            if delay:
                pending, torque = torque, pending
            angle, speed, coupling, twist = advance(torque)
            if sample is not None:
                angle, speed = sample(angle, speed)
            # the peaks, by comparisons (max() calls cost more)
            if torque > peak_torque or -torque > peak_torque:
                peak_torque = abs(torque)
            if coupling > peak_coupling or -coupling > peak_coupling:
                peak_coupling = abs(coupling)
            if twist > peak_twist or -twist > peak_twist:
                peak_twist = abs(twist)
        self._measured = (angle, speed)
        self._symmetric = symmetric
        self._pending = pending
        self._integral = integral
        self._peaks = (peak_torque, peak_coupling, peak_twist)
        self._saturated = saturated

    def coast(self) -> None:
        """Run one bus cycle with the power stage off: no torque, the load coasts (friction and
        damping slow it), the encoder still reads it; the targets follow the actual position."""
        plant = self.plant
        peak_coupling = peak_twist = 0.0
        for _ in range(self.substeps):
            plant.step(0.0)
            peak_coupling = max(peak_coupling, abs(plant.coupling_torque))
            peak_twist = max(peak_twist, abs(plant.wind_up))
            self._measured = self.feedback.sample(plant.motor_angle, plant.motor_speed)
        self._peaks = (0.0, peak_coupling, peak_twist)
        self._saturated = False
        self._pending = 0.0
        self._cycles += 1
        self.restart()

    def restart(self) -> None:
        """Forget the previous targets: the next cycle starts from where the motor is.

        A drive that enters OPERATION ENABLED (CiA 402 transition 4, also after a fault reset)
        takes its actual position as the last target; interpolating from a target it held
        before the fault would command the jump that caused the fault again.
        """
        counts = self._motor_counts()
        self._target_raw = self._target = counts
        self._reference_speed = 0.0
        self._acceleration = 0.0
        self._offset = 0.0
        self._integral = 0.0
        self._symmetric = 0.0

    # ------------------------------------------------------------- read-outs
    def _motor_counts(self) -> int:
        """The measured motor position [counts] (the encoder's reading when it is modelled)."""
        return round(self._measured[0] * self.counts_per_motor_rad)

    @property
    def position_counts(self) -> int:
        """Motor position actual value (0x6064) [counts], rounded, numbered like the targets.

        It is the last target minus the following error, so a caller that sends targets
        wrapped to INTEGER32 gets positions next to them.
        """
        return self._target_raw - self.following_error_counts

    @property
    def velocity_counts_per_s(self) -> float:
        """Velocity actual value (0x606C) [counts/s]: the drive's speed estimate."""
        return self._measured[1] * self.counts_per_motor_rad

    @property
    def following_error_counts(self) -> int:
        """Target minus measured motor position (0x60F4) [counts] at the end of the last cycle."""
        return self._target - self._motor_counts()

    @property
    def time_s(self) -> float:
        """Simulated time since start [s]."""
        return self._cycles * self.cycle_s

    #: What :meth:`readings` returns, in order.
    READINGS = ("load_angle", "coupling_torque", "peak_coupling_torque", "peak_twist",
                "peak_motor_torque", "saturated")

    def readings(self) -> tuple[float, ...]:
        """The :data:`READINGS` of the last cycle (a lean :attr:`state` for recording runs)."""
        plant = self.plant
        peaks = self._peaks
        return (plant.load_angle, plant.coupling_torque, peaks[1], peaks[2], peaks[0],
                1.0 if self._saturated else 0.0)

    @property
    def state(self) -> dict[str, float]:
        """Physical state at the end of the last cycle.

        Returns
        -------
        dict of str to float
            ``time_s`` [s]; ``target_angle``, ``motor_angle``, ``load_angle``, ``twist`` [rad]
            (motor side except load_angle, load side, and twist = r motor_angle - load_angle);
            ``motor_speed``, ``load_speed`` [rad/s]; ``coupling_torque`` [N m] (load side);
            ``motor_torque`` [N m] (the current loop's output, else the command);
            ``saturated`` (1.0 if the torque was clamped in any controller period of the
            cycle, else 0.0); ``peak_motor_torque`` (command), ``peak_coupling_torque`` [N m]
            and ``peak_twist`` [rad] (the coupling spring's wind-up, beyond any backlash gap):
            largest magnitudes over the cycle's controller periods.
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
            "motor_torque": plant.motor_torque,
            "saturated": 1.0 if self._saturated else 0.0,
            "peak_motor_torque": self._peaks[0],
            "peak_coupling_torque": self._peaks[1],
            "peak_twist": self._peaks[2],
        }


def _counts(field: str, value: object) -> int:
    """A raw count: a Python or numpy integer (not a float, not a bool)."""
    return integer(field, plain(value))


@dataclass(frozen=True)
class AxisSetup:
    """Everything a :class:`ServoAxis` is built from but its cycle and start position: what a
    drive is configured with. The drive and the rig's bus-free path build their axes from the
    same setup, so they run the same arithmetic.

    Attributes are :class:`ServoAxis`'s parameters of the same names; ``counts_per_motor_rad``
    None takes ServoAxis's default.
    """

    mechanics: Mechanics
    gains: Gains | None = None
    substeps: int = 8
    counts_per_motor_rad: float | None = None
    model: str = "auto"
    excitation_hz: float = 0.0
    plant_effects: MechanicalEffects | None = None
    drive_effects: DriveEffects | None = None
    feedforward: str = "target"

    def build(self, cycle_s: float, initial_counts: int) -> ServoAxis:
        """A new axis at rest at ``initial_counts`` for an interpolation period of ``cycle_s``."""
        extra = {} if self.counts_per_motor_rad is None else {
            "counts_per_motor_rad": self.counts_per_motor_rad}
        return ServoAxis(self.mechanics, self.gains, cycle_s=cycle_s, substeps=self.substeps,
                         model=self.model, excitation_hz=self.excitation_hz,
                         initial_counts=initial_counts, plant_effects=self.plant_effects,
                         drive_effects=self.drive_effects, feedforward=self.feedforward, **extra)
