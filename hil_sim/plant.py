"""The axis a servo drive moves: motor, gear, coupling and load, stepped exactly.

One class, :class:`Plant`, runs every model the rig needs:

* ``model="rigid"``: motor and load as one inertia J_eq at the motor shaft (the geared-system
  seed: :meth:`Mechanics.reflected_inertia`, ``reflected_damping``);
* ``model="two_mass"``: motor (with gear) and load joined by the coupling's torsional
  spring-damper on the gear output::

      J_m  motor_speed' = T - b_in motor_speed - g T_c - F_m
      J_L  load_speed'  = T_c - b_out load_speed - F_L
      twist'            = r motor_speed - load_speed,         g = r / eta
      T_c = k (twist - d) + c twist'   (d = +-backlash/2 while the teeth touch)
      T_c = 0                          inside the backlash gap

and, around them, the effects a linear model leaves out (:class:`MechanicalEffects`): gear
backlash (the gear output's free angle at the load shaft, in series with the coupling spring),
Coulomb friction at the motor and at the load, the coupling's own inertia (half to each side of
its spring); and, from the drive, the current loop's lag (``current_loop_hz``: the torque
follows the command through a first-order lag, one more state).

Stepping is exact for each linear piece (:mod:`hil_sim.discretize`): the mode (backlash gap or
contact on either flank) is read from the twist at the start of a step, and that mode's
zero-order-hold matrices advance the state with the torque command, the spring's flank offset
and both friction torques held over the step (a sub-step: see :class:`Plant`'s notes).
Coulomb friction is the torque in [-F, F] that the step needs: it stops a shaft exactly at zero
speed within a step when it can (stiction), and opposes the motion at its full value when it
cannot; with two frictional shafts both torques are found together (a projected Gauss-Seidel on
the 2x2 system of end speeds, which is linear in them). A contact that begins, or a shaft that
stops, inside a step is taken at the next one: the step is cut into sub-steps short against the
coupling mode's period (2 pi sqrt(J/k)).

The two-mass state carries the twist instead of the load angle: that keeps the stiff terms away
from the large, ever-growing angles, so no precision is lost to cancellation after many
revolutions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ecam import validate
from ecam.errors import InputError, SimulationError
from ecam.mechanics import Mechanics
from hil_sim.discretize import (bow, expm, friction_step, hold_trajectory, linear_step,
                                sliding_step, with_lag, zero_order_hold)

__all__ = ["ARCMIN", "MODELS_RUN", "MechanicalEffects", "Plant", "RigidPlant", "TwoMassPlant",
           "FullPlant", "expm", "zero_order_hold", "choose_model", "significant_harmonic_hz"]

ARCMIN = math.pi / (180.0 * 60.0)  # rad
#: The plant models a run can use.
MODELS_RUN = ("rigid", "two_mass")
_STICTION_ITERATIONS = 12
#: Steps per period of the coupling's contact mode at least, while backlash or Coulomb friction
#: is modelled on the two-mass model.
CONTACT_STEPS = 16
#: Samples per sub-step of a shaft's speed when bounding its bow over a whole step.
BOW_SAMPLES = 4
#: Factor on the sampled bow, for the samples' spacing.
BOW_MARGIN = 1.01


@dataclass(frozen=True)
class MechanicalEffects:
    """Physical effects beyond the linear models, SI units; 0 leaves an effect out.

    Attributes
    ----------
    gear_backlash : float
        Free angle of the gear output at the load shaft [rad], >= 0, <= pi.
    motor_coulomb_friction : float
        Friction torque at the motor shaft that does not depend on speed [N m], >= 0 (bearings,
        seals, the gearhead's no-load torque).
    load_coulomb_friction : float
        Friction torque at the load shaft [N m], >= 0 (guides, seals, bearings of the load).
    coupling_inertia : float
        Inertia of the coupling itself [kg m^2], >= 0: half on each side of its spring in the
        two-mass model, all of it on the load in the rigid one.

    :mod:`hil_sim.effects` says where typical values come from.
    """

    gear_backlash: float = 0.0
    motor_coulomb_friction: float = 0.0
    load_coulomb_friction: float = 0.0
    coupling_inertia: float = 0.0

    def __post_init__(self):
        for name in ("gear_backlash", "motor_coulomb_friction", "load_coulomb_friction",
                     "coupling_inertia"):
            object.__setattr__(self, name, validate.number(name, getattr(self, name),
                                                           minimum=0.0))
        if self.gear_backlash > math.pi:
            raise validate.fail("gear_backlash", self.gear_backlash, "<= pi rad (half a turn)")

    @property
    def any(self) -> bool:
        """True when any effect is on."""
        return any((self.gear_backlash, self.motor_coulomb_friction, self.load_coulomb_friction,
                    self.coupling_inertia))


@dataclass(frozen=True)
class _Mode:
    """One linear mode of a plant: its matrices, its step with the three inputs (torque, a
    torque on the motor shaft, one on the load shaft) and with the torque alone, and the
    columns of the two shaft torques as floats (the friction solve's)."""

    phi: np.ndarray
    gamma: np.ndarray
    step: object
    step_torque: object
    motor_column: list
    load_column: list
    a: np.ndarray
    b: np.ndarray


class Plant:
    """Motor, gear, coupling and load of one axis (see the module docstring).

    Parameters
    ----------
    mechanics : Mechanics
        The axis; ``coupling_stiffness`` must be given for ``model="two_mass"``.
    dt : float
        Step [s], > 0.
    model : {"rigid", "two_mass"}
    effects : MechanicalEffects, optional
        Backlash, Coulomb friction, coupling inertia; backlash needs the two-mass model.
    current_loop_hz : float, optional
        Bandwidth of the drive's current loop [Hz]: the motor torque follows the command
        through a first-order lag. None: the torque is the command.
    substeps : int, optional
        Sub-steps of every step, >= 1, while backlash or Coulomb friction is modelled on the
        two-mass model, with no whole steps (the reference the plant's own rule is tested
        against). None: the plant's rule (see the notes).

    Notes
    -----
    ``x`` is [motor angle, motor speed] (rigid) or [motor angle, motor speed, twist, load
    speed] (two-mass), rad and rad/s, followed by the motor torque [N m] when the current loop
    is modelled.

    Backlash and Coulomb friction on the two-mass model are stepped in sub-steps of at most
    1/:data:`CONTACT_STEPS` of the coupling mode's period: a contact begins, and a shaft
    stops or reverses, inside a step of the controller (a 2.6 kHz mode turns round inside a
    250 us step), and friction held for a whole step there is wrong by its full value for
    part of it. With friction and no backlash, a step is taken whole where that is exact:
    while both frictional shafts slide one way throughout the step (their frictions constant)
    or both rest held by stiction throughout it (:func:`hil_sim.discretize.sliding_step`);
    only the steps where a shaft may stop, start or turn are sub-stepped.
    """

    def __init__(self, mechanics: Mechanics, dt: float, model: str = "two_mass",
                 effects: MechanicalEffects | None = None,
                 current_loop_hz: float | None = None, substeps: int | None = None) -> None:
        if not isinstance(mechanics, Mechanics):
            raise InputError(f"mechanics {mechanics!r} should be a Mechanics")
        self.dt = validate.positive("dt", dt)
        validate.choice("model", model, MODELS_RUN)
        effects = MechanicalEffects() if effects is None else effects
        if not isinstance(effects, MechanicalEffects):
            raise InputError(f"effects {effects!r} should be a MechanicalEffects")
        if model == "two_mass" and mechanics.coupling_stiffness is None:
            raise InputError("coupling_stiffness None should be > 0 for a two_mass plant")
        if effects.gear_backlash and model != "two_mass":
            raise validate.fail("gear_backlash", effects.gear_backlash,
                                "0 in the rigid model (backlash sits in series with the "
                                "coupling spring: use the two-mass model)")
        if current_loop_hz is not None:
            current_loop_hz = validate.positive("current_loop_hz", current_loop_hz)
        self.mechanics = m = mechanics
        self.model = model
        self.effects = effects
        self.current_loop_hz = current_loop_hz
        r, eta = m.gear_ratio, m.gear_efficiency
        self._r = r
        self._g = g = r / eta
        jc = effects.coupling_inertia
        # Backlash: the teeth meet inside a step, and the contact is taken at a step's start,
        # so a step must be short against the contact's period or the impact is overshot:
        # at most 1/CONTACT_STEPS of it, by sub-steps with the torque held (still exact).
        # Friction likewise: a shaft the mode turns round inside a step needs its friction
        # turned with it (issue 20: held for a 250 us step against a 2.6 kHz mode, it put
        # stiff_coupling's coupling peak 12.6 % high).
        self._inner = 1
        if (effects.gear_backlash or effects.motor_coulomb_friction
                or effects.load_coulomb_friction) and model == "two_mass":
            contact_hz = m.torsional_frequency_hz()
            self._inner = max(1, math.ceil(self.dt * contact_hz * CONTACT_STEPS))
        if substeps is not None:
            substeps = validate.integer("substeps", substeps, minimum=1)
            if effects.gear_backlash or effects.motor_coulomb_friction or \
                    effects.load_coulomb_friction:
                self._inner = substeps
        self._step_dt = self.dt / self._inner
        if model == "rigid":
            self._jl = jl = m.load_inertia + jc
            self._j_eq = j_eq = m.motor_inertia + jl * r * r / eta
            self._b_eq = b_eq = m.reflected_damping()
            # inputs: motor torque, a torque on the motor shaft, one on the load shaft
            a = np.array([[0.0, 1.0], [0.0, -b_eq / j_eq]])
            b = np.array([[0.0, 0.0, 0.0], [1.0 / j_eq, 1.0 / j_eq, g / j_eq]])
            self._contact, self._gap = self._discretize(a, b), None
            self._k = self._c = 0.0
            self._speeds = (1, 1)  # the shaft speeds friction acts on (state indexes)
        else:
            self._jm = jm = m.motor_inertia + 0.5 * jc * r * r / eta
            self._jl = jl = m.load_inertia + 0.5 * jc
            self._k, self._c = k, c = m.coupling_stiffness, m.coupling_damping

            def system(k_, c_):
                a = np.array([
                    [0.0, 1.0, 0.0, 0.0],
                    [0.0, -(m.motor_damping + g * c_ * r) / jm, -g * k_ / jm, g * c_ / jm],
                    [0.0, r, 0.0, -1.0],
                    [0.0, c_ * r / jl, k_ / jl, -(c_ + m.load_damping) / jl],
                ])
                b = np.array([[0.0, 0.0, 0.0], [1.0 / jm, 1.0 / jm, 0.0], [0.0, 0.0, 0.0],
                              [0.0, 0.0, 1.0 / jl]])
                return self._discretize(a, b)

            self._contact = system(k, c)
            self._gap = system(0.0, 0.0) if effects.gear_backlash else None
            self._speeds = (1, 3)
        self._half_gap = 0.5 * effects.gear_backlash
        phi = self._contact.phi
        #: x[k+1] = phi x[k] + gamma T[k] (the motor torque's column) in contact, no friction
        self.phi, self.gamma = phi, self._contact.gamma[:, 0]
        self._lag = current_loop_hz is not None
        self._torque_state = phi.shape[0] - 1 if self._lag else None
        self._frictional = bool(effects.motor_coulomb_friction or effects.load_coulomb_friction)
        if model == "rigid":  # one shaft: both frictions act on it (the load's through the gear)
            self._friction_limits = (effects.motor_coulomb_friction
                                     + g * effects.load_coulomb_friction, 0.0)
        else:
            self._friction_limits = (effects.motor_coulomb_friction,
                                     effects.load_coulomb_friction)
        # the friction solve of each mode, compiled once (its columns and limits are constants)
        self._friction_steps = {}
        if self._frictional:
            for mode in (self._contact, self._gap):
                if mode is not None:
                    self._friction_steps[id(mode)] = friction_step(
                        mode.motor_column, mode.load_column, self._speeds,
                        self._friction_limits, _STICTION_ITERATIONS)
        self._slide = (self._sliding_step() if self._frictional and model == "two_mass"
                       and not self._half_gap and self._inner > 1 and substeps is None
                       else None)
        self._x = [0.0] * phi.shape[0]
        self._torque = 0.0  # the last command
        self._friction = (0.0, 0.0)
        self.advance = self._advance_function()

    def _discretize(self, a: np.ndarray, b: np.ndarray) -> "_Mode":
        """The stepping of one linear mode."""
        if self.current_loop_hz is not None:
            a, b = with_lag(a, b, self.current_loop_hz)
        phi, gamma = zero_order_hold(a, b, self._step_dt)
        if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(gamma))):
            raise SimulationError(f"discretization at dt {self.dt} gave non-finite matrices")
        phi.setflags(write=False)
        gamma.setflags(write=False)
        return _Mode(phi, gamma, linear_step(phi, gamma), linear_step(phi, gamma[:, :1]),
                     [float(v) for v in gamma[:, 1]], [float(v) for v in gamma[:, 2]], a, b)

    def _sliding_step(self):
        """The whole step where it is exact (:func:`sliding_step`): the contact mode over
        ``dt``, and the bow of each shaft's speed over it, sampled at :data:`BOW_SAMPLES` per
        sub-step, at least 64 per mode period (between samples the bow exceeds its sampled maximum by
        at most about (pi / 64)^2 / 2 = 1.2e-3 of itself: :data:`BOW_MARGIN` covers it)."""
        mode, r = self._contact, self._r
        phi, gamma = zero_order_hold(mode.a, mode.b, self.dt)
        trajectory = hold_trajectory(mode.a, mode.b, self.dt, BOW_SAMPLES * self._inner)
        n = phi.shape[0]
        bows = []
        for index in self._speeds:
            rows = trajectory[:, index, :]
            # the coordinates of sliding_step: [motor speed, relative speed, twist, motor
            # torque, torque command, motor friction, load friction] (x[3] = r x[1] - relative)
            columns = [rows[:, 1] + r * rows[:, 3], -rows[:, 3], rows[:, 2],
                       rows[:, 4] if n == 5 else 0.0 * rows[:, 0], rows[:, n], rows[:, n + 1],
                       rows[:, n + 2]]
            bows.append(BOW_MARGIN * bow(np.stack(columns, axis=1)))
        return sliding_step(phi, gamma, self._speeds, self._friction_limits, r, np.array(bows),
                            self._k, self._g)

    # -------------------------------------------------------------------- state
    def reset(self, motor_angle: float = 0.0, motor_speed: float = 0.0) -> None:
        """Place the axis at ``motor_angle`` [rad] turning at ``motor_speed`` [rad/s], no twist,
        no torque."""
        x = [float(motor_angle), float(motor_speed)]
        if self.model == "two_mass":
            x += [0.0, self._r * float(motor_speed)]
        if self._lag:
            x.append(0.0)
        self._x = x
        self._torque = 0.0
        self._friction = (0.0, 0.0)

    @property
    def x(self) -> np.ndarray:
        """Copy of the state vector (see the class notes for its layout)."""
        return np.array(self._x)

    # --------------------------------------------------------------------- step
    def step(self, torque: float) -> None:
        """Advance one step of ``dt`` with the motor torque command held at ``torque`` [N m]."""
        self._torque = torque = float(torque)
        x = self._x
        if self._half_gap:
            h = self._half_gap
            for _ in range(self._inner):
                twist = x[2]
                mode, offset = ((self._contact, h) if twist > h else
                                (self._contact, -h) if twist < -h else (self._gap, 0.0))
                # The flank offset moves the spring's zero: T_c = k (twist - d) + ..., i.e. an
                # extra torque +g k d on the motor and -k d on the load, held over the step.
                spring = self._k * offset
                x = mode.step(x, torque, self._g * spring, -spring)
                if self._frictional:
                    x = self._with_friction(x, mode)
            self._x = x
            return
        if self._frictional:
            slid = None if self._slide is None else self._slide(x, torque)
            if slid is not None:
                x, f_m, f_l = slid
                self._friction = (f_m, f_l)
            else:
                mode = self._contact
                for _ in range(self._inner):
                    x = self._with_friction(mode.step(x, torque, 0.0, 0.0), mode)
            self._x = x
            return
        self._x = self._contact.step_torque(x, torque)

    def _advance_function(self):
        """``advance(torque) -> (motor angle, motor speed, coupling torque, wind-up)``: one
        :meth:`step` and the readings a controller period needs, in one call. The linear models
        (no backlash, no friction) get a function of their own: the rig calls it several times
        per bus cycle, and attribute lookups cost more than their arithmetic."""
        step = self._contact.step_torque
        plant = self
        if self.model == "two_mass" and self._frictional and not self._half_gap:
            # friction without backlash (the commonest full model): the contact step and the
            # friction solve called directly, the readings as the general branch below gives them
            k, c, r = self._k, self._c, self._r
            step3 = self._contact.step
            correct = self._friction_steps[id(self._contact)]
            inner = range(self._inner)
            slide = self._slide or (lambda x, torque: None)

            def advance(torque):
                torque = float(torque)
                x = plant._x
                slid = slide(x, torque)
                if slid is not None:
                    x, f_m, f_l = slid
                else:
                    for _ in inner:
                        x, f_m, f_l = correct(step3(x, torque, 0.0, 0.0))
                plant._x = x
                plant._torque = torque
                plant._friction = (f_m, f_l)
                twist = x[2]
                if twist > 0.0:
                    wind = twist - 0.0
                elif twist < -0.0:
                    wind = twist + 0.0
                else:
                    return x[0], x[1], 0.0, 0.0
                return x[0], x[1], k * wind + c * (r * x[1] - x[3]), wind
            return advance
        if self.model == "two_mass" and (self._half_gap or self._frictional):
            k, c, r, h = self._k, self._c, self._r, self._half_gap
            full_step = self.step

            def advance(torque):
                full_step(torque)
                x = plant._x
                twist = x[2]
                if twist > h:
                    wind = twist - h
                elif twist < -h:
                    wind = twist + h
                else:
                    return x[0], x[1], 0.0, 0.0  # inside the backlash gap
                return x[0], x[1], k * wind + c * (r * x[1] - x[3]), wind
            return advance
        if self._frictional:
            def advance(torque):
                plant.step(torque)
                x = plant._x
                return x[0], x[1], plant.coupling_torque, 0.0
            return advance
        if self.model == "two_mass":
            k, c, r = self._k, self._c, self._r

            def advance(torque):
                x = step(plant._x, torque)
                plant._x = x
                plant._torque = torque
                twist = x[2]
                return x[0], x[1], k * twist + c * (r * x[1] - x[3]), twist
            return advance
        load_inertia = self._jl * self._r / self._j_eq
        b_eq, load_damping = self._b_eq, self.mechanics.load_damping * self._r
        lag = self._torque_state

        def advance(torque):
            x = step(plant._x, torque)
            plant._x = x
            plant._torque = torque
            applied = torque if lag is None else x[lag]
            # what the load needs: J_L alpha_L + b_out omega_L (see coupling_torque)
            return (x[0], x[1],
                    load_inertia * (applied - b_eq * x[1]) + load_damping * x[1], 0.0)
        return advance

    def _with_friction(self, free: list, mode: _Mode) -> list:
        """The end state with the Coulomb friction torques the step needs (module docstring;
        :func:`hil_sim.discretize.friction_step`)."""
        out, f_m, f_l = self._friction_steps[id(mode)](free)
        self._friction = (f_m, f_l)
        return out

    # ------------------------------------------------------------------ read-outs
    @property
    def torque(self) -> float:
        """Motor torque command of the last step [N m]."""
        return self._torque

    @property
    def motor_torque(self) -> float:
        """Motor torque at the end of the last step [N m]: the current loop's output, or the
        command when the current loop is not modelled."""
        return self._x[self._torque_state] if self._lag else self._torque

    @property
    def friction_torques(self) -> tuple[float, float]:
        """(motor, load) friction torques of the last step [N m], signed as applied (rigid:
        both at the motor, in the first)."""
        return self._friction

    @property
    def motor_angle(self) -> float:
        """Motor shaft angle [rad]."""
        return self._x[0]

    @property
    def motor_speed(self) -> float:
        """Motor shaft speed [rad/s]."""
        return self._x[1]

    @property
    def twist(self) -> float:
        """r motor_angle - load_angle [rad]: the backlash gap plus the spring's wind-up (0 in
        the rigid model)."""
        return self._x[2] if self.model == "two_mass" else 0.0

    @property
    def wind_up(self) -> float:
        """The coupling spring's own twist, beyond the backlash gap [rad]."""
        t, h = self.twist, self._half_gap
        return t - math.copysign(h, t) if abs(t) > h else 0.0

    @property
    def load_angle(self) -> float:
        """Load angle [rad]."""
        return self._r * self._x[0] - (self._x[2] if self.model == "two_mass" else 0.0)

    @property
    def load_speed(self) -> float:
        """Load speed [rad/s]."""
        return self._x[3] if self.model == "two_mass" else self._r * self._x[1]

    @property
    def coupling_torque(self) -> float:
        """Torque in the coupling [N m] (load side).

        Two-mass: k (twist - d) + c twist', 0 inside the backlash gap. Rigid: there is no spring
        to read; this is what a coupling would transmit, J_L alpha_L + b_out omega_L plus the
        load's friction, so torque checks against the coupling rating still mean something (the
        acceleration is the one at the current state under the last torque).
        """
        x = self._x
        if self.model == "two_mass":
            t, h = x[2], self._half_gap
            if h and abs(t) <= h:
                return 0.0
            rate = self._r * x[1] - x[3]
            return self._k * self.wind_up + self._c * rate
        friction, limit = self._friction[0], self._friction_limits[0]
        acceleration = (self.motor_torque - self._b_eq * x[1] + friction) / self._j_eq
        # the load's share of the friction on the one shaft, at the load: F_L / (F_m + g F_L)
        load_friction = friction * self.effects.load_coulomb_friction / limit if limit else 0.0
        return (self._jl * self._r * acceleration + self.mechanics.load_damping * self.load_speed
                - load_friction)

    def energy(self) -> float:
        """Stored energy, kinetic plus spring [J], counting the load side scaled by 1/eta.

        With eta < 1 the model is not symmetric; dividing the load equation by eta makes it a
        passive system (inertia J_L/eta, stiffness k/eta), whose energy is this function. It
        never grows without input when all damping is >= 0.
        """
        x = self._x
        eta = self.mechanics.gear_efficiency
        if self.model == "rigid":
            return 0.5 * self._j_eq * x[1] ** 2
        spring = self._k * self.wind_up ** 2
        return 0.5 * (self._jm * x[1] ** 2 + (self._jl * x[3] ** 2 + spring) / eta)


class RigidPlant(Plant):
    """Motor and load as one inertia J_eq at the motor shaft (no coupling compliance).

    State x = [motor angle (rad), motor speed (rad/s)]; input: motor torque (N m). Its coupling
    stiffness, if any, is ignored.
    """

    def __init__(self, mechanics: Mechanics, dt: float) -> None:
        super().__init__(mechanics, dt, model="rigid")


class TwoMassPlant(Plant):
    """Motor (with gear) and load joined by a torsional spring-damper on the gear output.

    State x = [motor angle, motor speed, twist, load speed] (rad, rad/s); ``coupling_stiffness``
    must be given.
    """

    def __init__(self, mechanics: Mechanics, dt: float) -> None:
        super().__init__(mechanics, dt, model="two_mass")


class FullPlant(Plant):
    """The two-mass plant with backlash, Coulomb friction and coupling inertia."""

    def __init__(self, mechanics: Mechanics, effects: MechanicalEffects, dt: float) -> None:
        super().__init__(mechanics, dt, model="two_mass", effects=effects)


# ------------------------------------------------------------------------- model choice
def significant_harmonic_hz(acceleration: np.ndarray, period_s: float,
                            energy_fraction: float = 0.99) -> float:
    """Highest harmonic of a periodic cam motion that carries significant energy.

    Parameters
    ----------
    acceleration : array_like, shape (n,)
        Slave acceleration over exactly one cam period, uniformly sampled, the end point not
        repeated (any unit: only the spectrum's shape matters).
    period_s : float
        Duration of one cam period at the master speed of interest [s].
    energy_fraction : float
        Fraction of the acceleration energy (excluding the mean) to cover, 0 < f <= 1.

    Returns
    -------
    float
        h / period_s [Hz] for the smallest harmonic number h whose cumulative acceleration
        energy reaches ``energy_fraction``; 0.0 for a motion without acceleration.

    Notes
    -----
    Acceleration is what the motor torque follows and what excites the coupling mode, so its
    spectrum (not the position's) decides how high the cam reaches.
    """
    samples = np.asarray(acceleration, dtype=float)
    if samples.ndim != 1 or samples.size < 4:
        raise InputError(f"acceleration size {samples.size} should be a 1-D array of >= 4")
    if not np.all(np.isfinite(samples)):
        raise InputError("acceleration samples should be finite")
    if not (period_s > 0.0 and math.isfinite(period_s)):
        raise InputError(f"period_s {period_s} should be > 0")
    if not (0.0 < energy_fraction <= 1.0):
        raise InputError(f"energy_fraction {energy_fraction} should be in (0, 1]")
    power = np.abs(np.fft.rfft(samples))[1:] ** 2
    total = power.sum()
    if total <= 0.0:
        return 0.0
    harmonic = int(np.searchsorted(np.cumsum(power) / total, energy_fraction * (1 - 1e-12))) + 1
    return harmonic / period_s


def choose_model(mechanics: Mechanics, excitation_hz: float, loop_bandwidth_hz: float,
                 factor: float = 10.0, control_rate_hz: float | None = None,
                 current_loop_hz: float | None = None) -> tuple[str, str]:
    """Pick the simplest plant model faithful to the scene, by rule.

    Parameters
    ----------
    mechanics : Mechanics
        The axis.
    excitation_hz : float
        Highest cam harmonic that carries significant energy at the scene's master speed
        [Hz], >= 0 (see :func:`significant_harmonic_hz`).
    loop_bandwidth_hz : float
        Velocity-loop bandwidth of the drive [Hz], >= 0.
    factor : float
        Required separation, > 0: rigid when f_torsion >= factor * max(excitation, loop).
    control_rate_hz : float, optional
        The drive's controller rate [Hz]. A coupling mode above its Nyquist frequency (half
        the rate) is beyond what the loop can damp and is rung by the torque's steps every
        controller period, by how much depends on their size: the reason says so, and the
        rig measures it (``fidelity = "auto"``, :mod:`hil_sim.rig.fidelity`), since a rule
        cannot tell.
    current_loop_hz : float, optional
        The current loop's bandwidth [Hz]; None: an ideal torque (every step passes).

    Returns
    -------
    kind : str
        ``"rigid"`` or ``"two_mass"``.
    reason : str
        One sentence with the numbers, for the report.
    """
    if not isinstance(mechanics, Mechanics):
        raise InputError(f"mechanics {mechanics!r} should be a Mechanics")
    for name, value in (("excitation_hz", excitation_hz), ("loop_bandwidth_hz", loop_bandwidth_hz),
                        ("factor", factor)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                math.isfinite(value) and value >= 0.0):
            raise InputError(f"{name} {value!r} should be a finite number >= 0")
    if factor == 0.0:
        raise InputError("factor 0.0 should be > 0")
    if mechanics.coupling_stiffness is None:
        return "rigid", "rigid model: no coupling stiffness given, motor and load move as one."
    torsion = mechanics.torsional_frequency_hz()
    needed = factor * max(excitation_hz, loop_bandwidth_hz)
    numbers = (f"the coupling mode at {torsion:.4g} Hz is {{}} {factor:g} x max(cam excitation "
               f"{excitation_hz:.4g} Hz, velocity loop {loop_bandwidth_hz:.4g} Hz) "
               f"= {needed:.4g} Hz")
    if torsion < needed:
        return "two_mass", "two-mass model: " + numbers.format("below") + "."
    if control_rate_hz is not None:
        nyquist = 0.5 * validate.positive("control_rate_hz", control_rate_hz)
        passes = current_loop_hz is None or torsion <= current_loop_hz
        if torsion > nyquist and passes:
            through = ("an ideal current loop" if current_loop_hz is None else
                       f"the current loop ({current_loop_hz:.4g} Hz)")
            return "rigid", ("rigid model: " + numbers.format("at least") + f", but it lies "
                             f"above the controller's Nyquist frequency {nyquist:.4g} Hz and "
                             f"{through} passes it: the torque steps of each controller period "
                             f"ring it (measure it: fidelity auto).")
    return "rigid", "rigid model: " + numbers.format("at least") + "."
