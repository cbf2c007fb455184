"""Mechanics of one servo axis: motor, gear, coupling and load, as one immutable value.

Conventions (the geared-system seed, Cam Design Handbook p. 359):

* ``gear_ratio`` r = omega_load / omega_motor = R_pinion / R_gear (0.1 for a 10:1 reduction).
* Efficiency eta divides the load-side terms reflected to the motor, and only those::

      J_eq = J_motor + J_load * r**2 / eta        b_eq = b_motor + b_load * r**2 / eta

  It models power flowing from the motor to the load (motoring); the linear plant keeps it
  constant, so it over-estimates the torque needed while braking, which is the safe side for
  sizing checks.
* The coupling sits on the load side of the gear, between the gear output and the load.

All values are SI: kg m^2, N m, N m s/rad, N m/rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ecam import mechanics
from ecam.errors import InputError


def _check_number(name: str, value: object) -> float:
    """Return ``value`` as a finite float or raise InputError naming the field."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{name} {value!r} should be a real number")
    number = float(value)
    if not math.isfinite(number):
        raise InputError(f"{name} {number} should be finite")
    return number


def _check_positive(name: str, value: object) -> float:
    number = _check_number(name, value)
    if number <= 0.0:
        raise InputError(f"{name} {number} should be > 0")
    return number


def _check_non_negative(name: str, value: object) -> float:
    number = _check_number(name, value)
    if number < 0.0:
        raise InputError(f"{name} {number} should be >= 0")
    return number


@dataclass(frozen=True)
class Mechanics:
    """Motor, gear, optional torsional coupling and load of one axis (SI units).

    Parameters
    ----------
    motor_inertia : float
        Rotor inertia plus everything turning at motor speed (gear input side) [kg m^2], > 0.
    gear_ratio : float
        r = omega_load / omega_motor [-], > 0. 0.1 is a 10:1 reduction.
    gear_efficiency : float
        eta, 0 < eta <= 1 [-].
    motor_damping : float
        Viscous damping on the motor side, b_in [N m s/rad], >= 0.
    load_damping : float
        Viscous damping on the load side, b_out [N m s/rad], >= 0.
    coupling_stiffness : float or None
        Torsional stiffness k of the coupling between gear output and load [N m/rad], > 0.
        None means a rigid connection.
    coupling_damping : float
        Viscous damping c across the coupling [N m s/rad], >= 0.
    load_inertia : float
        Load inertia on the output side [kg m^2], >= 0 (> 0 when a coupling is given).
    coupling_rated_torque : float or None
        Rated (continuous) torque of the coupling [N m], > 0, or None if unrated.
    coupling_max_torque : float or None
        Maximum (peak) torque of the coupling [N m], >= rated torque, or None if unrated.
    motor_torque_limit : float or None
        Peak torque the drive may command [N m], > 0, or None for no limit.

    Raises
    ------
    InputError
        If a field is not a finite number or is out of its range; the message names the field,
        the value and the bound, e.g. ``"coupling_stiffness -5.0 should be > 0"``.
    """

    motor_inertia: float
    gear_ratio: float = 1.0
    gear_efficiency: float = 1.0
    motor_damping: float = 0.0
    load_damping: float = 0.0
    coupling_stiffness: float | None = None
    coupling_damping: float = 0.0
    load_inertia: float = 0.0
    coupling_rated_torque: float | None = None
    coupling_max_torque: float | None = None
    motor_torque_limit: float | None = None

    def __post_init__(self) -> None:
        # Fields are normalized to float here, once, so the math below never sees an int/bool.
        def store(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        store("motor_inertia", _check_positive("motor_inertia", self.motor_inertia))
        store("gear_ratio", _check_positive("gear_ratio", self.gear_ratio))
        eta = _check_positive("gear_efficiency", self.gear_efficiency)
        if eta > 1.0:
            raise InputError(f"gear_efficiency {eta} should be <= 1")
        store("gear_efficiency", eta)
        for name in ("motor_damping", "load_damping", "coupling_damping", "load_inertia"):
            store(name, _check_non_negative(name, getattr(self, name)))
        for name in ("coupling_stiffness", "coupling_rated_torque", "coupling_max_torque",
                     "motor_torque_limit"):
            value = getattr(self, name)
            if value is not None:
                store(name, _check_positive(name, value))
        if self.coupling_stiffness is not None and self.load_inertia <= 0.0:
            raise InputError(
                f"load_inertia {self.load_inertia} should be > 0 when coupling_stiffness is given")
        rated, peak = self.coupling_rated_torque, self.coupling_max_torque
        if rated is not None and peak is not None and peak < rated:
            raise InputError(
                f"coupling_max_torque {peak} should be >= coupling_rated_torque {rated}")

    @property
    def is_rigid(self) -> bool:
        """True when no coupling stiffness is given (motor and load connected rigidly)."""
        return self.coupling_stiffness is None

    def reflected_inertia(self) -> float:
        """Total inertia seen at the motor shaft, J_eq = J_motor + J_load r^2 / eta [kg m^2]."""
        return self.motor_inertia + mechanics.reflected_inertia(self.load_inertia, self.gear_ratio,
                                                                self.gear_efficiency)

    def reflected_damping(self) -> float:
        """Total viscous damping seen at the motor shaft, b_in + b_out r^2 / eta [N m s/rad]."""
        return mechanics.reflected_damping(self.motor_damping, self.load_damping, self.gear_ratio,
                                           self.gear_efficiency)

    def motor_inertia_at_load(self) -> float:
        """Motor-side inertia as the load side of the gear feels it, J1 = eta J_motor / r^2.

        Returns
        -------
        float
            J1 [kg m^2].

        Notes
        -----
        The gear delivers eta / r times the torque left after accelerating the rotor, so the
        rotor appears on the output side as eta J_motor / r^2. This is the same convention as
        the seed (reflecting the load to the motor divides by eta; reflecting the motor to the
        load multiplies by eta), and it is exactly the inertia the two-mass plant integrates,
        so :meth:`torsional_frequency_hz` is the frequency the plant rings at.
        """
        r = self.gear_ratio
        return self.gear_efficiency * self.motor_inertia / (r * r)

    def torsional_frequency_hz(self) -> float:
        """Undamped torsional frequency of the coupling, sqrt(k (J1 + J2) / (J1 J2)) / (2 pi).

        Returns
        -------
        float
            Frequency [Hz]; ``math.inf`` for a rigid connection (no coupling).

        Notes
        -----
        J1 is :meth:`motor_inertia_at_load` (eta J_motor / r^2), J2 the load inertia.
        """
        if self.coupling_stiffness is None:
            return math.inf
        omega = mechanics.two_mass_frequency(self.coupling_stiffness, self.motor_inertia_at_load(),
                                             self.load_inertia)
        return omega / (2.0 * math.pi)
