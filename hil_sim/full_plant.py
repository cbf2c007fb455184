"""The two-mass plant with the effects that a linear model leaves out: gear backlash, Coulomb
friction at the motor and at the load, and the coupling's own inertia.

Equations (r gear ratio, eta efficiency, g = r / eta, T_c coupling torque on the load side)::

    J_m  motor_speed' = T - b_in motor_speed - g T_c - F_m(motor_speed)
    J_L  load_speed'  = T_c - b_out load_speed - F_L(load_speed)
    twist'            = r motor_speed - load_speed
    T_c = k (twist - d) + c twist'   with d = +-backlash/2 while the teeth touch (|twist| > backlash/2)
    T_c = 0                          inside the backlash gap

The backlash is the free angle of the gear output measured at the load shaft (a gearhead's
catalogued backlash, converted from arcmin); it sits in series with the coupling spring, so the
spring carries the twist beyond the gap. The coupling inertia is split half to each side of the
spring: its gear-side half turns with the gear output and is reflected to the motor as the load
is (``J r^2 / eta``), its load-side half adds to the load.

Stepping stays exact for each linear piece: per step the mode is read from the twist at its start
(gap, or contact on either flank), and that mode's zero-order-hold matrices advance the state with
the motor torque, the spring's flank offset and both friction torques held over the step.
Coulomb friction is the torque in [-F, F] that the step needs: it stops a shaft exactly at zero
speed within a step when it can (stiction), and opposes the motion at its full value when it
cannot; with two frictional shafts both torques are found together (a projected Gauss-Seidel on
the 2x2 system of end speeds, which is linear in them). A contact that begins inside a step is
taken at the next step: the caller's step should be short against the contact period
(2 pi sqrt(J/k)), as the rig's controller period is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ecam import validate
from ecam.errors import InputError
from ecam.mechanics import Mechanics
from hil_sim.plant import zero_order_hold

__all__ = ["Effects", "FullPlant", "ARCMIN"]

ARCMIN = math.pi / (180.0 * 60.0)  # rad
_STICTION_ITERATIONS = 12


@dataclass(frozen=True)
class Effects:
    """Physical effects beyond the linear two-mass model, SI units; 0 leaves an effect out.

    Attributes
    ----------
    gear_backlash : float
        Free angle of the gear output at the load shaft [rad], >= 0. Precision planetary servo
        gearheads are catalogued at about 1 arcmin (reduced backlash) to 3 arcmin (standard),
        economy gearheads at 8-15 arcmin.
    motor_coulomb_friction : float
        Friction torque at the motor shaft that does not depend on speed [N m], >= 0 (bearings,
        seals, the gearhead's no-load torque).
    load_coulomb_friction : float
        Friction torque at the load shaft [N m], >= 0 (guides, seals, bearings of the load).
    coupling_inertia : float
        Inertia of the coupling itself [kg m^2], >= 0, half on each side of its spring (bellows
        and disc couplings list it in their catalogues).
    """

    gear_backlash: float = 0.0
    motor_coulomb_friction: float = 0.0
    load_coulomb_friction: float = 0.0
    coupling_inertia: float = 0.0

    def __post_init__(self):
        for name in ("gear_backlash", "motor_coulomb_friction", "load_coulomb_friction", "coupling_inertia"):
            object.__setattr__(self, name, validate.number(name, getattr(self, name), minimum=0.0))
        if self.gear_backlash > math.pi:
            raise validate.fail("gear_backlash", self.gear_backlash, "<= pi rad (half a turn)")

    @property
    def any(self) -> bool:
        return any((self.gear_backlash, self.motor_coulomb_friction, self.load_coulomb_friction,
                    self.coupling_inertia))


def _clamp(value: float, limit: float) -> float:
    return min(max(value, -limit), limit)


class FullPlant:
    """Motor, gear with backlash, coupling (with inertia) and load, with Coulomb friction.

    The interface is that of :class:`hil_sim.plant.TwoMassPlant` (``step``, ``reset``, the angles,
    speeds, ``twist`` and ``coupling_torque``), so the servo axis drives either.

    Parameters
    ----------
    mechanics : Mechanics
        The axis; ``coupling_stiffness`` must be given.
    effects : Effects
    dt : float
        Step [s], > 0.
    """

    def __init__(self, mechanics: Mechanics, effects: Effects, dt: float) -> None:
        if not isinstance(mechanics, Mechanics):
            raise InputError(f"mechanics {mechanics!r} should be a Mechanics")
        if not isinstance(effects, Effects):
            raise InputError(f"effects {effects!r} should be an Effects")
        if mechanics.coupling_stiffness is None:
            raise InputError("mechanics.coupling_stiffness: None should be > 0 for the full plant")
        self.dt = validate.positive("dt", dt)
        self.mechanics = m = mechanics
        self.effects = e = effects
        r, eta = m.gear_ratio, m.gear_efficiency
        self._g = g = r / eta
        self._jm = jm = m.motor_inertia + 0.5 * e.coupling_inertia * r * r / eta
        self._jl = jl = m.load_inertia + 0.5 * e.coupling_inertia
        self._k, self._c = k, c = m.coupling_stiffness, m.coupling_damping
        self._half_gap = 0.5 * e.gear_backlash

        def system(k_, c_):
            a = np.array([
                [0.0, 1.0, 0.0, 0.0],
                [0.0, -(m.motor_damping + g * c_ * r) / jm, -g * k_ / jm, g * c_ / jm],
                [0.0, r, 0.0, -1.0],
                [0.0, c_ * r / jl, k_ / jl, -(c_ + m.load_damping) / jl],
            ])
            # inputs: motor torque, an extra torque on the motor shaft, one on the load shaft
            b = np.array([[0.0, 0.0, 0.0], [1.0 / jm, 1.0 / jm, 0.0], [0.0, 0.0, 0.0],
                          [0.0, 0.0, 1.0 / jl]])
            return zero_order_hold(a, b, self.dt)

        self._contact = system(k, c)
        self._gap = system(0.0, 0.0) if self._half_gap > 0.0 else self._contact
        self._x = np.zeros(4)
        self._torque = 0.0
        self._friction = (0.0, 0.0)

    def reset(self, motor_angle: float = 0.0, motor_speed: float = 0.0) -> None:
        """Place the axis at ``motor_angle`` [rad] turning at ``motor_speed`` [rad/s], no twist."""
        r = self.mechanics.gear_ratio
        self._x = np.array([float(motor_angle), float(motor_speed), 0.0, r * float(motor_speed)])
        self._torque = 0.0
        self._friction = (0.0, 0.0)

    def _mode(self):
        """(phi, gamma, flank offset d) of the mode the twist is in at the start of a step."""
        twist, h = self._x[2], self._half_gap
        if h == 0.0:
            return (*self._contact, 0.0)
        if twist > h:
            return (*self._contact, h)
        if twist < -h:
            return (*self._contact, -h)
        return (*self._gap, 0.0)

    def step(self, torque: float) -> None:
        """Advance one step of ``dt`` with the motor torque held at ``torque`` [N m]."""
        self._torque = float(torque)
        phi, gamma, d = self._mode()
        # The flank offset moves the spring's zero: T_c = k (twist - d) + ..., i.e. an extra
        # torque +k d on the load and -g k d on the motor, held over the step.
        spring = self._k * d if d else 0.0
        free = phi @ self._x + gamma @ np.array([self._torque, self._g * spring, -spring])
        f_m = f_l = 0.0
        limit_m, limit_l = self.effects.motor_coulomb_friction, self.effects.load_coulomb_friction
        if limit_m or limit_l:
            # End speeds are linear in the two friction torques: w_end = free + G f.
            g11, g12 = gamma[1, 1], gamma[1, 2]
            g21, g22 = gamma[3, 1], gamma[3, 2]
            for _ in range(_STICTION_ITERATIONS if limit_m and limit_l else 1):
                if limit_m:
                    f_m = _clamp(-(free[1] + g12 * f_l) / g11, limit_m)
                if limit_l:
                    f_l = _clamp(-(free[3] + g21 * f_m) / g22, limit_l)
            free = free + gamma[:, 1] * f_m + gamma[:, 2] * f_l
            # A shaft held by stiction ends exactly at rest, not at a rounding residue.
            if limit_m and abs(f_m) < limit_m:
                free[1] = 0.0
            if limit_l and abs(f_l) < limit_l:
                free[3] = 0.0
        self._friction = (f_m, f_l)
        self._x = free

    @property
    def x(self) -> np.ndarray:
        """[motor angle, motor speed, twist, load speed] (rad, rad/s)."""
        return self._x.copy()

    @property
    def torque(self) -> float:
        """Motor torque applied during the last step [N m]."""
        return self._torque

    @property
    def friction_torques(self) -> tuple[float, float]:
        """(motor, load) friction torques of the last step [N m], signed as applied."""
        return self._friction

    @property
    def motor_angle(self) -> float:
        return float(self._x[0])

    @property
    def motor_speed(self) -> float:
        return float(self._x[1])

    @property
    def twist(self) -> float:
        """r motor_angle - load_angle [rad]: the backlash gap plus the spring's wind-up."""
        return float(self._x[2])

    @property
    def wind_up(self) -> float:
        """The coupling spring's own twist, beyond the backlash gap [rad]."""
        t, h = self.twist, self._half_gap
        return t - math.copysign(h, t) if abs(t) > h else 0.0

    @property
    def load_angle(self) -> float:
        return self.mechanics.gear_ratio * float(self._x[0]) - float(self._x[2])

    @property
    def load_speed(self) -> float:
        return float(self._x[3])

    @property
    def coupling_torque(self) -> float:
        """Torque in the coupling [N m] (load side): 0 inside the backlash gap."""
        t, h = self.twist, self._half_gap
        if h and abs(t) <= h:
            return 0.0
        rate = self.mechanics.gear_ratio * float(self._x[1]) - float(self._x[3])
        return self._k * self.wind_up + self._c * rate
