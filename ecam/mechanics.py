"""Mechanics of a cam-driven axis: gears reflected to the motor, couplings, torsional modes.

SI units throughout: inertia kg m^2, damping N m s/rad, stiffness N m/rad, torque N m,
angles rad, speeds rad/s, frequencies Hz unless a name says rad/s.

Conventions (the geared-system seed, Cam Design Handbook p. 359, fig. 11.21):

* The gear ratio is ``r = R_pinion / R_gear = omega_out / omega_in`` (0.1 for a 10:1
  reduction).
* The efficiency eta divides the load-side terms reflected to the motor, and only those::

      J_eq = J_motor + J_load * r**2 / eta        b_eq = b_motor + b_load * r**2 / eta

  It models power flowing from the motor to the load (motoring); a linear plant keeps it
  constant, so it over-estimates the torque needed while braking, which is the safe side for
  sizing checks.
* A flexible coupling sits on the load side of the gear, between the gear output and the load.

Three layers, each formula written once:

* the formulas (:func:`reflected_inertia`, :func:`two_mass_frequency`, :func:`wind_up_angle`,
  ...), which check their arguments;
* :class:`Mechanics`, one axis as an immutable value, checked once when built, whose methods
  reuse the formulas' unchecked cores;
* the coupling checks (:func:`peak_torque_check`, :func:`rms_torque_check`,
  :func:`wind_up_check`, :func:`resonance_excitation_check`), which turn recorded series into
  :class:`CouplingCheck` verdicts; the rig's report is made of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .laws import law as _law
from .validate import fail, number, plain, positive, show

__all__ = [
    "Mechanics",
    "reflected_inertia",
    "reflected_damping",
    "input_torque",
    "two_mass_frequency",
    "wind_up_angle",
    "torsional_harmonic",
    "CouplingCheck",
    "peak_torque_check",
    "rms_torque_check",
    "wind_up_check",
    "resonance_excitation_check",
    "residual_vibration",
]


def _non_negative(field: str, value) -> float:
    return number(field, value, minimum=0.0)


def _efficiency(field: str, value) -> float:
    return positive(field, value, maximum=1.0)


def _series(field: str, values) -> np.ndarray:
    """A recorded series as a 1-D float array of at least one sample. NaN samples are kept (a
    check reports them as its value rather than refusing the run that recorded them)."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise fail(field, values, "a 1-D series of numbers") from None
    if array.ndim != 1 or array.size == 0:
        raise fail(field, values, "a 1-D series of at least one number")
    return array


# The formulas, unchecked: the public functions check their arguments and call these; Mechanics,
# whose fields were checked when it was built, calls them directly.

def _reflected(load_side: float, ratio: float, efficiency: float) -> float:
    return load_side * ratio**2 / efficiency


def _two_mass_omega(stiffness: float, inertia_1: float, inertia_2: float) -> float:
    return math.sqrt(stiffness * (inertia_1 + inertia_2) / (inertia_1 * inertia_2))


def _wind_up(torque: float, stiffness: float) -> float:
    return float(torque) / stiffness


# ------------------------------------------------------------------------------------ formulas

def reflected_inertia(load_inertia: float, ratio: float, efficiency: float = 1.0) -> float:
    """Load inertia seen at the gear input: ``J_eq = J_load * r**2 / eta`` [kg m^2]."""
    return _reflected(_non_negative("load_inertia", load_inertia), positive("ratio", ratio),
                      _efficiency("efficiency", efficiency))


def reflected_damping(input_damping: float, output_damping: float, ratio: float,
                      efficiency: float = 1.0) -> float:
    """Damping seen at the gear input: ``b_eq = b_in + b_out * r**2 / eta`` [N m s/rad]."""
    b_in = _non_negative("input_damping", input_damping)
    b_out = _non_negative("output_damping", output_damping)
    return b_in + _reflected(b_out, positive("ratio", ratio), _efficiency("efficiency", efficiency))


def input_torque(
    speed_in, acceleration_in, *, load_inertia, ratio, efficiency=1.0, input_damping=0.0,
    output_damping=0.0, input_inertia=0.0,
):
    """Torque at the gear input for a given input motion (works on numpy arrays).

    ``T_in = (J_in + J_eq) * alpha_in + b_eq * omega_in`` with J_eq and b_eq reflected as above.
    """
    j = _non_negative("input_inertia", input_inertia) + reflected_inertia(load_inertia, ratio,
                                                                           efficiency)
    b = reflected_damping(input_damping, output_damping, ratio, efficiency)
    return j * acceleration_in + b * speed_in


def two_mass_frequency(stiffness: float, inertia_1: float, inertia_2: float) -> float:
    """Torsional natural frequency of two inertias on a spring, in rad/s:
    ``sqrt(k (J1 + J2) / (J1 J2))``. Divide by 2 pi for Hz."""
    return _two_mass_omega(positive("stiffness", stiffness), positive("inertia_1", inertia_1),
                           positive("inertia_2", inertia_2))


def wind_up_angle(torque: float, stiffness: float) -> float:
    """Twist of a coupling carrying ``torque``: T / k, in rad."""
    return _wind_up(number("torque", plain(torque)), positive("stiffness", stiffness))


def torsional_harmonic(mode_hz: float, cycle_hz: float) -> float | None:
    """The torsional mode as a multiple of the cam cycle frequency: the harmonic of the cam
    that would excite it. None when there is no mode (``mode_hz`` infinite: rigid).

    Raises
    ------
    InputError
        ``mode_hz`` negative or NaN, or ``cycle_hz`` not a finite number > 0.
    """
    cycle_hz = positive("cycle_hz", plain(cycle_hz))
    if plain(mode_hz) == math.inf:
        return None
    return number("mode_hz", plain(mode_hz), minimum=0.0) / cycle_hz


def residual_vibration(natural_hz: float, rise_time_s: float, law) -> float:
    """Amplitude of residual vibration of an undamped follower after a rest-to-rest rise, per
    unit stroke: the magnitude of the Fourier transform of s''(u) at the natural frequency
    w = 2 pi f T (radians per rise), divided by w (single-degree-of-freedom response to the
    law's acceleration: e'' + omega^2 e = -y'' rings on with |int y'' e^(i omega t) dt| / omega).
    ``law`` is a :class:`~ecam.laws.Law` or its name (as :func:`ecam.law` takes it)."""
    f = positive("natural_hz", natural_hz)
    period = positive("rise_time_s", rise_time_s)
    law = _law(law)
    w = 2 * math.pi * f * period  # natural frequency in radians per rise
    u = np.linspace(0.0, 1.0, 20001)
    acc = law(u, 2)
    weights = np.full_like(u, 1.0)
    weights[0] = weights[-1] = 0.5
    du = u[1] - u[0]
    re = float(np.sum(weights * acc * np.cos(w * (1 - u))) * du)
    im = float(np.sum(weights * acc * np.sin(w * (1 - u))) * du)
    return math.hypot(re, im) / w


# ---------------------------------------------------------------------------------- Mechanics

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
        the value and the bound, e.g. ``"coupling_stiffness: -5 should be > 0"``.
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

        store("motor_inertia", positive("motor_inertia", self.motor_inertia))
        store("gear_ratio", positive("gear_ratio", self.gear_ratio))
        store("gear_efficiency", _efficiency("gear_efficiency", self.gear_efficiency))
        for name in ("motor_damping", "load_damping", "coupling_damping", "load_inertia"):
            store(name, _non_negative(name, getattr(self, name)))
        for name in ("coupling_stiffness", "coupling_rated_torque", "coupling_max_torque",
                     "motor_torque_limit"):
            value = getattr(self, name)
            if value is not None:
                store(name, positive(name, value))
        if self.coupling_stiffness is not None and self.load_inertia <= 0.0:
            raise fail("load_inertia", self.load_inertia, "> 0 when coupling_stiffness is given")
        rated, peak = self.coupling_rated_torque, self.coupling_max_torque
        if rated is not None and peak is not None and peak < rated:
            raise fail("coupling_max_torque", peak, f">= coupling_rated_torque {show(rated)}")

    @property
    def is_rigid(self) -> bool:
        """True when no coupling stiffness is given (motor and load connected rigidly)."""
        return self.coupling_stiffness is None

    def reflected_inertia(self) -> float:
        """Total inertia seen at the motor shaft, J_eq = J_motor + J_load r^2 / eta [kg m^2]."""
        return self.motor_inertia + _reflected(self.load_inertia, self.gear_ratio,
                                               self.gear_efficiency)

    def reflected_damping(self) -> float:
        """Total viscous damping seen at the motor shaft, b_in + b_out r^2 / eta [N m s/rad]."""
        return self.motor_damping + _reflected(self.load_damping, self.gear_ratio,
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
        omega = _two_mass_omega(self.coupling_stiffness, self.motor_inertia_at_load(),
                                self.load_inertia)
        return omega / (2.0 * math.pi)


# ---------------------------------------------------------------------------- coupling checks

@dataclass(frozen=True)
class CouplingCheck:
    """One check of a flexible coupling: a measured value against its limit.

    Attributes
    ----------
    name : str
        Stable identifier, the one the rig's report uses (``"coupling_peak_torque"``).
    value : float or None
        Measured value; None when there is nothing to measure (no torsional mode).
    limit : float or None
        Limit; None for an informational check, which always passes.
    unit : str
    detail : str
        How the value was found, one line ("" when the caller says where instead).
    sample : int or None
        Index of the worst sample when the value comes from a series, else None.
    """

    name: str
    value: float | None
    limit: float | None
    unit: str
    detail: str = ""
    sample: int | None = None

    @property
    def passed(self) -> bool:
        """True when ``value <= limit``; always when there is no limit."""
        return self.limit is None or (self.value is not None and self.value <= self.limit)


def _limit(field: str, limit) -> float | None:
    return None if limit is None else number(field, plain(limit), minimum=0.0)


def peak_torque_check(torque, max_torque: float | None) -> CouplingCheck:
    """Peak coupling torque against the coupling's maximum (peak) torque.

    Parameters
    ----------
    torque : array_like, shape (n,)
        Coupling torque per sample, or its peak magnitude within each sample [N m]; n >= 1.
    max_torque : float or None
        The coupling's maximum torque [N m]; None: reported without a limit.

    Returns
    -------
    CouplingCheck
        ``coupling_peak_torque`` [N m]; ``sample`` is the index of the peak.

    Raises
    ------
    InputError
        ``torque`` empty, not 1-D or not numbers.
    """
    magnitude = np.abs(_series("torque", torque))
    worst = int(np.argmax(magnitude))
    return CouplingCheck("coupling_peak_torque", float(magnitude[worst]),
                         _limit("max_torque", max_torque), "N m", sample=worst)


def rms_torque_check(torque, rated_torque: float | None) -> CouplingCheck:
    """RMS coupling torque (the continuous load) against the coupling's rated torque.

    Parameters
    ----------
    torque : array_like, shape (n,)
        Coupling torque at evenly spaced instants [N m]; n >= 1.
    rated_torque : float or None
        The coupling's rated (continuous) torque [N m]; None: reported without a limit.

    Returns
    -------
    CouplingCheck
        ``coupling_rms_torque`` [N m].

    Raises
    ------
    InputError
        ``torque`` empty, not 1-D or not numbers.
    """
    rms = float(np.sqrt(np.mean(_series("torque", torque) ** 2)))
    return CouplingCheck("coupling_rms_torque", rms, _limit("rated_torque", rated_torque), "N m",
                         "continuous load against the rated torque")


def wind_up_check(limit_deg: float | None, *, stiffness: float | None, peak_torque: float,
                  twist=None) -> CouplingCheck:
    """Wind-up of the coupling, in degrees, against its limit.

    Parameters
    ----------
    limit_deg : float or None
        Largest allowed twist [deg]; None: reported without a limit.
    stiffness : float or None
        Coupling stiffness [N m/rad]; None for a rigid connection (wind-up 0).
    peak_torque : float
        Peak coupling torque [N m], used when no twist was measured.
    twist : array_like, optional
        Twist magnitudes per sample [rad] from a plant that modelled the coupling; its peak is
        the wind-up. Without it the wind-up is :func:`wind_up_angle` of ``peak_torque``.

    Returns
    -------
    CouplingCheck
        ``wind_up`` [deg], its detail saying which of the three ways gave it.
    """
    if stiffness is None:
        angle, how = 0.0, "no coupling"
    elif twist is not None:
        angle, how = float(np.max(np.abs(_series("twist", twist)))), "coupling twist"
    else:
        angle = _wind_up(peak_torque, positive("stiffness", stiffness))
        how = "peak torque / stiffness"
    return CouplingCheck("wind_up", math.degrees(angle), _limit("limit_deg", limit_deg), "deg", how)


def resonance_excitation_check(mode_hz: float, cycle_hz: float, spectrum,
                               limit_percent: float | None) -> CouplingCheck:
    """How strongly the cam excites the coupling's torsional mode.

    The mode lies between two harmonics of the cam cycle; the larger of their amplitudes in
    the cam's acceleration spectrum, as a percentage of the strongest harmonic, is the value.

    Parameters
    ----------
    mode_hz : float
        Torsional frequency [Hz] (:meth:`Mechanics.torsional_frequency_hz`); ``math.inf``
        when rigid, which gives an informational check without a value.
    cycle_hz : float
        Cam cycles per second at the master speed [Hz], > 0.
    spectrum : array_like, shape (m,)
        Amplitudes of the cam's acceleration harmonics 0..m-1 over one cycle (e.g.
        ``abs(numpy.fft.rfft(samples))``); harmonics beyond m-1 count as not excited.
    limit_percent : float or None
        Largest allowed share [%].

    Returns
    -------
    CouplingCheck
        ``resonance_excitation`` [%].
    """
    harmonic = torsional_harmonic(mode_hz, cycle_hz)
    if harmonic is None:
        return CouplingCheck("resonance_excitation", None, None, "%",
                             "no coupling: no torsional mode")
    amplitudes = _series("spectrum", spectrum)[1:]
    strongest = float(amplitudes.max()) if amplitudes.size else 0.0
    nearest = [n for n in {max(1, math.floor(harmonic)), max(1, math.ceil(harmonic))}
               if n <= amplitudes.size]
    share = (100.0 * max(amplitudes[n - 1] for n in nearest) / strongest
             if nearest and strongest > 0 else 0.0)
    if nearest:
        hit = max(nearest, key=lambda n: amplitudes[n - 1])
        what = f"harmonic {hit} carries {share:.3g} % of the strongest acceleration harmonic"
    else:
        what = f"above the {amplitudes.size} harmonics resolved"
    return CouplingCheck("resonance_excitation", float(share), _limit("limit_percent", limit_percent), "%",
                         f"torsional mode {mode_hz:.4g} Hz = {harmonic:.4g} x the "
                         f"{cycle_hz:.4g} Hz cam cycle; {what}")
