"""Sizing a servo drive train for a duty cycle: the formulas a sizing tool (Siemens SIZER,
Kollmorgen Motioneering, Schneider Motion Sizer) applies, without the rig.

SI units throughout (torque N m, speed rad/s unless a name says ``_rpm``, current A rms, voltage
V, energy J, power W, stiffness N m/rad, time s).

The procedure is the one of the Siemens 1FT7 configuration manual (PFT7S) 01/2009, section 2.4
"Procedure when engineering", p. 49-50: the motor torque of every time slice from the load
and the inertias; the RMS torque over the duty cycle against the S1 curve at the cycle's mean
speed (thermal); each slice's torque against the torque the motor and the drive can give at
its speed (the voltage limit included); the maximum speed.

* :func:`rms_torque`: the RMS torque of a duty cycle (uniform or weighted samples);
* :func:`s1_torque`: the S1 (continuous duty) curve through catalogue points;
* :func:`thermal_torque`: the equivalent torque of a first-order thermal model with the motor's
  thermal time constant (the worst window of a short or slow duty);
* :func:`voltage_limited_torque`: the torque the DC-link voltage allows at a speed, from kE, kT,
  the winding resistance and inductance; :class:`VoltageLimit` the same curve for one motor on
  one DC link, its constants computed once, for a controller's torque clamp;
* :func:`current_for_torque`, :func:`torque_for_current`: the motor's torque-current relation
  (catalogue points: a servo motor saturates above its stall current);
* :func:`dc_link_energy`, :func:`regenerated_energy`, :func:`dc_link_stored_energy`: what the DC
  link absorbs between its nominal and its brake-chopper voltage, and the energy a braking duty
  puts into it, a regenerative infeed returning braking power to the line up to its rating
  (:func:`energy_to_line`: how much per cycle);
* :func:`copper_loss`, :func:`hot_winding_resistance`: the winding's losses, which the infeed
  supplies on top of the shaft power;
* :func:`infeed_power`: the power the infeed carries (drawn, returned) for a shaft power;
* :func:`series_stiffness`, :func:`stiffness_at_output`, :func:`arcmin_stiffness`: springs in
  series through a gear, the gearhead's catalogue unit;
* :func:`two_mass_frequency_with_gearhead`: the torsional frequency with gearhead and motor
  shaft in series with the coupling;
* :func:`gearhead_cyclic_torque`: the gearhead's permissible cyclic torque T2B at the duty's
  cycles per hour.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .mechanics import two_mass_frequency
from .validate import fail, number, positive

__all__ = [
    "RPM",
    "ARCMIN",
    "rms_torque",
    "s1_torque",
    "thermal_torque",
    "voltage_limited_torque",
    "VoltageLimit",
    "current_for_torque",
    "torque_for_current",
    "dc_link_energy",
    "regenerated_energy",
    "dc_link_stored_energy",
    "infeed_power",
    "series_stiffness",
    "stiffness_at_output",
    "arcmin_stiffness",
    "two_mass_frequency_with_gearhead",
    "gearhead_cyclic_torque",
    "T2B_CYCLES_PER_HOUR",
]

#: rad/s per rpm.
RPM = 2.0 * math.pi / 60.0
#: rad per arcmin.
ARCMIN = math.pi / (180.0 * 60.0)
#: WITTENSTEIN alpha / Beckhoff AG2300 data sheets: T2B is the maximum acceleration torque for
#: at most 1000 cycles per hour; above that the catalogue's shock (impact) factor applies
#: (WITTENSTEIN engineering glossary, "Acceleration torque (T2B)").
T2B_CYCLES_PER_HOUR = 1000.0


def _array(field: str, values) -> np.ndarray:
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise fail(field, values, "numbers") from None
    if array.ndim > 1:
        raise fail(field, values, "a number or a 1-D series")
    return array


def rms_torque(torque, durations=None) -> float:
    """RMS torque of a duty cycle, ``sqrt(sum(T_i^2 dt_i) / sum(dt_i))`` [N m].

    Parameters
    ----------
    torque : array_like, shape (n,)
        Torque of each time slice (or each sample) [N m].
    durations : array_like, shape (n,), optional
        Duration of each slice [s]; evenly spaced samples without it.

    Returns
    -------
    float

    Notes
    -----
    1FT7 configuration manual 01/2009, section 2.4, p. 49: M_rms = sqrt(sum(M_i^2 dt_i) / T).
    """
    t = _array("torque", torque).ravel()
    if t.size == 0:
        raise fail("torque", torque, "at least one sample")
    if durations is None:
        return float(np.sqrt(np.mean(t * t)))
    dt = _array("durations", durations).ravel()
    if dt.shape != t.shape or np.any(dt < 0) or not np.sum(dt) > 0:
        raise fail("durations", durations, "one duration >= 0 per torque, not all 0")
    return float(np.sqrt(np.sum(t * t * dt) / np.sum(dt)))


def s1_torque(speed_rpm, points) -> np.ndarray | float:
    """The S1 (continuous duty) torque at a speed, through the catalogue's points.

    Parameters
    ----------
    speed_rpm : float or array_like
        Motor speed magnitude [rpm].
    points : sequence of (speed_rpm, torque)
        Points of the S1 curve in increasing speed, the first at 0 rpm (the stall torque M0),
        e.g. ``[(0, M0), (n_N, M_N)]``.

    Returns
    -------
    float or numpy.ndarray
        Torque [N m]: linear between the points; past the last point the last segment's slope
        goes on (the S1 curve of a permanent-magnet servo motor falls with the iron losses), and
        never below 0.
    """
    speeds = np.array([p[0] for p in points], dtype=float)
    torques = np.array([p[1] for p in points], dtype=float)
    if speeds.size < 1 or speeds[0] != 0.0 or np.any(np.diff(speeds) <= 0):
        raise fail("points", points, "S1 points in increasing speed, the first at 0 rpm")
    n = np.abs(_array("speed_rpm", speed_rpm))
    value = np.interp(n, speeds, torques)
    if speeds.size > 1:
        slope = (torques[-1] - torques[-2]) / (speeds[-1] - speeds[-2])
        beyond = n > speeds[-1]
        value = np.where(beyond, torques[-1] + slope * (n - speeds[-1]), value)
    value = np.maximum(value, 0.0)
    return float(value) if value.ndim == 0 else value


def thermal_torque(torque, dt: float, time_constant: float, periodic: bool = True) -> float:
    """Equivalent thermal torque of a duty: the largest of ``sqrt(y)`` where ``y`` is the
    square of the torque through a first-order lag of the motor's thermal time constant.

    A winding's temperature rise follows its copper losses (proportional to T^2) through its
    thermal time constant. For a cycle much shorter than the time constant this is the RMS
    torque; for a long or a short duty the temperature follows the torque and the worst window
    of about one time constant decides.

    Parameters
    ----------
    torque : array_like, shape (n,)
        Torque at evenly spaced instants [N m], held over each ``dt``.
    dt : float
        Sample spacing [s], > 0.
    time_constant : float
        Thermal time constant of the motor [s], > 0.
    periodic : bool
        True: the duty repeats for ever (the periodic steady state); False: it runs once from
        a cold motor.

    Returns
    -------
    float
        [N m]
    """
    t = _array("torque", torque).ravel()
    dt = positive("dt", dt)
    tau = positive("time_constant", time_constant)
    if t.size == 0:
        raise fail("torque", torque, "at least one sample")
    a = math.exp(-dt / tau)
    heat = (1.0 - a) * t * t

    def run(start: float) -> tuple[float, float]:
        y, peak = start, start
        for h in heat.tolist():
            y = a * y + h
            if y > peak:
                peak = y
        return y, peak

    end, peak = run(0.0)
    if periodic:
        decay = a ** t.size
        # the periodic steady state starts where one period from it ends: y0 = a^n y0 + end
        start = end / (1.0 - decay) if decay < 1.0 else float(np.mean(t * t))
        _, peak = run(start)
    return math.sqrt(peak)


def voltage_limited_torque(speed, *, torque_constant: float, voltage_constant: float,
                           resistance: float, dc_bus_voltage: float, inductance: float = 0.0,
                           pole_pairs: int = 1):
    """Torque a permanent-magnet synchronous motor can give at a speed without field
    weakening, limited by the inverter's output voltage.

    Parameters
    ----------
    speed : float or array_like
        Motor speed [rad/s] (its magnitude counts).
    torque_constant : float
        kT [N m per A rms], > 0.
    voltage_constant : float
        kE [V s/rad]: the line-to-line rms back-EMF per rad/s (a catalogue's "V per 1000 rpm"
        divided by 1000 rpm in rad/s), > 0.
    resistance : float
        Winding (phase) resistance [ohm], >= 0.
    dc_bus_voltage : float
        DC-link voltage [V], > 0.
    inductance : float
        Rotating-field (phase) inductance [H], >= 0.
    pole_pairs : int
        Pole pairs (electrical speed = pole_pairs x mechanical speed), >= 1.

    Returns
    -------
    float or numpy.ndarray
        [N m], 0 where the back-EMF alone exceeds the voltage.

    Notes
    -----
    Per phase (star), rms, the current in the q axis: U^2 = (E + R I)^2 + (w_el L I)^2 with
    E = kE w / sqrt(3) and the largest phase voltage of a space-vector modulated inverter in
    its linear range, U = U_dc / sqrt(6) (line to line U_dc / sqrt(2)). Solved for I, the
    torque is kT I.
    """
    kt = positive("torque_constant", torque_constant)
    ke = positive("voltage_constant", voltage_constant)
    r = number("resistance", resistance, minimum=0.0)
    u_dc = positive("dc_bus_voltage", dc_bus_voltage)
    inductance = number("inductance", inductance, minimum=0.0)
    pole_pairs = number("pole_pairs", pole_pairs, minimum=1.0)
    w = np.abs(_array("speed", speed))
    u = u_dc / math.sqrt(6.0)
    e = ke * w / math.sqrt(3.0)
    x = pole_pairs * w * inductance
    z2 = r * r + x * x
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = (e * r) ** 2 - z2 * (e * e - u * u)
        current = np.where(z2 > 0.0, (-e * r + np.sqrt(np.maximum(disc, 0.0))) / z2, np.inf)
    current = np.where(e >= u, 0.0, np.maximum(current, 0.0))
    torque = kt * current
    return float(torque) if torque.ndim == 0 else torque


@dataclass(frozen=True)
class VoltageLimit:
    """:func:`voltage_limited_torque` of one motor on one DC link, its constants computed once:
    the speed-dependent part of a drive's torque clamp.

    Parameters are those of :func:`voltage_limited_torque`. :meth:`torque` gives the same value
    for one speed in plain float arithmetic; :attr:`constants` are what a hot loop inlines.
    """

    torque_constant: float
    voltage_constant: float
    resistance: float
    dc_bus_voltage: float
    inductance: float = 0.0
    pole_pairs: int = 1
    #: (kT, kE / sqrt3, pole_pairs L, R, R^2, U_dc / sqrt6, U^2): see :meth:`torque`
    constants: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        kt = positive("torque_constant", self.torque_constant)
        ke = positive("voltage_constant", self.voltage_constant)
        r = number("resistance", self.resistance, minimum=0.0)
        u = positive("dc_bus_voltage", self.dc_bus_voltage) / math.sqrt(6.0)
        inductance = number("inductance", self.inductance, minimum=0.0)
        pole_pairs = number("pole_pairs", self.pole_pairs, minimum=1.0)
        object.__setattr__(self, "constants", (kt, ke / math.sqrt(3.0), pole_pairs * inductance,
                                               r, r * r, u, u * u))

    def torque(self, speed: float) -> float:
        """The torque the voltage allows at ``speed`` [rad/s] (its magnitude) [N m]: 0 from
        the speed where the back-EMF alone takes the voltage; ``math.inf`` at standstill on a
        winding without resistance and inductance."""
        kt, a, x, r, r2, u, u2 = self.constants
        w = abs(speed)
        e = a * w
        if e >= u:
            return 0.0
        xl = x * w
        z2 = r2 + xl * xl
        if z2 <= 0.0:
            return math.inf
        return kt * (math.sqrt(e * e * r2 - z2 * (e * e - u2)) - e * r) / z2

    def no_load_speed(self) -> float:
        """The speed where the back-EMF alone takes the voltage, ``U_dc / (sqrt2 kE)`` [rad/s]:
        no torque is left from there on."""
        _, a, _, _, _, u, _ = self.constants
        return u / a

    def speed_at(self, torque: float) -> float:
        """The highest speed [rad/s] up to which the curve gives at least ``torque`` [N m]
        (the curve falls with the speed): 0 when not even standstill gives it. Bisection to
        the last bit, the lower end kept, so ``torque(speed_at(t)) >= t``."""
        torque = number("torque", torque, minimum=0.0)
        low, high = 0.0, self.no_load_speed()
        if self.torque(low) < torque:
            return 0.0
        while True:
            middle = 0.5 * (low + high)
            if middle <= low or middle >= high:
                return low
            if self.torque(middle) >= torque:
                low = middle
            else:
                high = middle


def _torque_current(points) -> tuple[np.ndarray, np.ndarray]:
    currents = np.array([p[0] for p in points], dtype=float)
    torques = np.array([p[1] for p in points], dtype=float)
    if (currents.size < 2 or currents[0] != 0.0 or torques[0] != 0.0
            or np.any(np.diff(currents) <= 0) or np.any(np.diff(torques) <= 0)):
        raise fail("torque_current_points", points,
                   "(current, torque) points from (0, 0), both increasing")
    return currents, torques


def current_for_torque(torque, points):
    """Motor current [A rms] for a torque [N m] (its magnitude), through the catalogue's
    (current, torque) points from (0, 0); past the last point the last segment's slope goes on.
    """
    currents, torques = _torque_current(points)
    t = np.abs(_array("torque", torque))
    slope = (currents[-1] - currents[-2]) / (torques[-1] - torques[-2])
    value = np.where(t > torques[-1], currents[-1] + slope * (t - torques[-1]),
                     np.interp(t, torques, currents))
    return float(value) if value.ndim == 0 else value


def torque_for_current(current, points):
    """Motor torque [N m] for a current [A rms], the inverse of :func:`current_for_torque`
    (past the last point, the last segment's slope)."""
    currents, torques = _torque_current(points)
    i = np.abs(_array("current", current))
    slope = (torques[-1] - torques[-2]) / (currents[-1] - currents[-2])
    value = np.where(i > currents[-1], torques[-1] + slope * (i - currents[-1]),
                     np.interp(i, currents, torques))
    return float(value) if value.ndim == 0 else value


def dc_link_energy(capacitance: float, nominal_voltage: float, limit_voltage: float) -> float:
    """Energy the DC-link capacitors absorb between the nominal voltage and the limit (the
    brake chopper's switching threshold): ``C (U_limit^2 - U_nominal^2) / 2`` [J]."""
    c = positive("capacitance", capacitance)
    u0 = positive("nominal_voltage", nominal_voltage)
    u1 = positive("limit_voltage", limit_voltage)
    if u1 <= u0:
        raise fail("limit_voltage", u1, f"> nominal_voltage {u0:g}")
    return 0.5 * c * (u1 * u1 - u0 * u0)


def dc_link_stored_energy(power, dt: float, capacity: float = math.inf,
                          brake_power: float = 0.0, line_power: float = 0.0,
                          periodic: bool = True) -> np.ndarray:
    """The energy braking stores in the DC link above its nominal voltage, sample by sample [J].

    The shaft power ``power`` (positive: motoring) returns -power to the link while braking.
    A regenerative infeed returns up to ``line_power`` to the line whenever the link is above
    its nominal voltage (it regulates the voltage back down); motoring draws the link down to
    its nominal voltage first (the infeed supplies only below it), so the stored energy never
    falls below 0. A brake resistor of ``brake_power`` takes what exceeds ``capacity`` (it
    switches in at the chopper threshold).

    Parameters
    ----------
    power : array_like, shape (n,)
        Shaft power at evenly spaced instants [W], held over each ``dt``.
    dt : float
        Sample spacing [s], > 0.
    capacity : float
        What the DC link absorbs before the chopper switches in [J] (:func:`dc_link_energy`).
    brake_power : float
        Continuous power of the brake resistor [W], >= 0 (0: none).
    line_power : float
        The most power the infeed returns to the line at any instant [W], >= 0 (0: a rectifier
        infeed, which returns nothing).
    periodic : bool
        True: the duty repeats (its steady cycle returned: the second pass where the duty draws
        at least what it returns; ``inf`` everywhere where it returns more every cycle and the
        link charges until it trips).

    Returns
    -------
    numpy.ndarray, shape (n,)
        The stored energy after each sample [J]; above ``capacity`` the link would trip on
        overvoltage.

    Notes
    -----
    Losses in the winding, the inverter and the infeed are left out: they take energy from the
    braking, so the values are on the safe side.
    """
    return _dc_link_flow(power, dt, capacity, brake_power, line_power, periodic)[0]


def energy_to_line(power, dt: float, capacity: float = math.inf, brake_power: float = 0.0,
                   line_power: float = 0.0, periodic: bool = True) -> float:
    """The energy a regenerative infeed returns to the line over the duty [J], in the model of
    :func:`dc_link_stored_energy` (the same parameters): the braking power it takes as it
    comes, and the stored energy it takes back down to the nominal voltage afterwards."""
    return float(np.sum(_dc_link_flow(power, dt, capacity, brake_power, line_power, periodic)[1]))


#: The most passes of a periodic duty through the DC link before it counts as charging for ever.
_DC_LINK_PASSES = 64


def _dc_link_flow(power, dt, capacity, brake_power, line_power, periodic) -> tuple[np.ndarray, np.ndarray]:
    """(stored energy after each sample, energy returned to the line in each sample) [J]."""
    p = _array("power", power).ravel()
    dt = positive("dt", dt)
    if capacity != math.inf:  # no limit: the largest stored energy is all there is to say
        capacity = number("capacity", capacity, minimum=0.0)
    brake = number("brake_power", brake_power, minimum=0.0)
    line = number("line_power", line_power, minimum=0.0) * dt
    stored = 0.0
    out = [0.0] * p.size
    returned = [0.0] * p.size
    values = (-p * dt).tolist()
    # A periodic duty repeats from where the last cycle left the link: passes from an empty link
    # until a pass ends where the one before it did (the steady cycle; the second pass where the
    # duty draws at least what it returns, as a rig's losses make it). A duty that still ends
    # higher after _DC_LINK_PASSES passes charges the link a little more every cycle, until it
    # trips whatever its size: inf.
    rounding = 1e-12 * (float(np.sum(np.abs(values))) + 1.0)
    passes, previous = 0, -math.inf
    while True:
        for i, value in enumerate(values):
            charged = stored + value
            returned[i] = min(max(charged, 0.0), line)
            stored = max(0.0, charged - line)
            if stored > capacity and brake > 0.0:
                stored = max(capacity, stored - brake * dt)
            out[i] = stored
        passes += 1
        if not periodic or (passes >= 2 and stored <= previous + rounding):
            return np.array(out), np.array(returned)
        if passes >= _DC_LINK_PASSES:
            return np.full(p.size, math.inf), np.array(returned)
        previous = stored


def regenerated_energy(power, dt: float, capacity: float = math.inf,
                       brake_power: float = 0.0, periodic: bool = True,
                       line_power: float = 0.0) -> float:
    """The most energy a braking duty stores in the DC link at once [J]: the largest of
    :func:`dc_link_stored_energy` (the same parameters), 0 for an empty duty.

    Returns
    -------
    float
        The largest stored energy [J]; above ``capacity`` the link would trip on overvoltage.
    """
    stored = dc_link_stored_energy(power, dt, capacity, brake_power, line_power, periodic)
    return float(stored.max()) if stored.size else 0.0


#: Copper's temperature coefficient of resistance at 20 degC [1/K]: IEC 60028 (International
#: standard of resistance for copper), alpha_20 = 0.00393 /K for annealed copper.
COPPER_ALPHA_20 = 0.00393


def hot_winding_resistance(resistance_20: float, temperature_rise: float = 100.0) -> float:
    """A copper winding's resistance [ohm] at ``temperature_rise`` [K] above 20 degC,
    ``R_20 (1 + alpha_20 rise)`` (:data:`COPPER_ALPHA_20`); the default 100 K is the winding
    rise of the catalogue's "100 K values" (Siemens 1FT7 configuration manual 01/2009, table
    4-8), at which a motor runs its rated duty."""
    return (number("resistance_20", resistance_20, minimum=0.0)
            * (1.0 + COPPER_ALPHA_20 * number("temperature_rise", temperature_rise, minimum=0.0)))


def copper_loss(current, resistance: float) -> np.ndarray | float:
    """The copper losses of a three-phase winding [W], ``3 I^2 R`` for the phase current I
    [A rms] and the phase resistance R [ohm] (the catalogue's R_ph)."""
    i = _array("current", current)
    value = 3.0 * i * i * number("resistance", resistance, minimum=0.0)
    return float(value) if value.ndim == 0 else value


def infeed_power(power, regenerative_power: float = 0.0, losses=0.0) -> np.ndarray | float:
    """The power an infeed carries for a shaft power [W]: positive drawn from the line,
    negative returned to it.

    The line supplies the shaft power and the losses on its way, P_line = P_mech + P_losses
    (Siemens SINAMICS Low Voltage Engineering Manual, November 2015, "Dimensioning of the
    Active Infeed", p. 106/528: P_Line = P_mech + P_L Mot + P_L MoMo + P_L AI): where that is
    drawn, the losses count; where braking returns power, it is the shaft power, the losses
    left out (they would lower it: the safe side for the infeed's rating, as for the DC link's).
    Drawn power comes from the line in full (the DC link's store is left out: the safe side);
    braking power is returned up to ``regenerative_power`` (the rest stays in the DC link,
    :func:`dc_link_stored_energy`), none by a rectifier infeed (0).

    Parameters
    ----------
    power : float or array_like
        Shaft power [W], positive when motoring.
    regenerative_power : float
        The most power the infeed returns to the line [W], >= 0.
    losses : float or array_like
        The losses between the line and the shaft at each sample [W], >= 0 (for example the
        winding's :func:`copper_loss`; 0: none counted).

    Returns
    -------
    float or numpy.ndarray
        ``power + losses`` where that is > 0, else ``max(power, -regenerative_power)`` [W].
    """
    p = _array("power", power)
    limit = number("regenerative_power", regenerative_power, minimum=0.0)
    loss = _array("losses", losses)
    if not np.all(loss >= 0.0):  # (NaN too)
        raise fail("losses", float(np.min(loss)), ">= 0")
    drawn = p + loss
    value = np.where(drawn > 0.0, drawn, np.maximum(p, -limit))
    return float(value) if value.ndim == 0 else value


def series_stiffness(*stiffnesses) -> float:
    """Springs in series, ``1 / sum(1 / k_i)`` [N m/rad]; None entries (rigid) are skipped;
    ``math.inf`` when every entry is rigid."""
    given = [positive("stiffness", k) for k in stiffnesses if k is not None]
    if not given:
        return math.inf
    return 1.0 / sum(1.0 / k for k in given)


def stiffness_at_output(stiffness: float, ratio: float) -> float:
    """A spring on the gear's input as the output feels it, ``k / r^2`` [N m/rad] for the gear
    ratio ``r = omega_out / omega_in`` (the input twists 1/r times the output angle and carries
    r times the output torque)."""
    return positive("stiffness", stiffness) / positive("ratio", ratio) ** 2


def arcmin_stiffness(newton_metre_per_arcmin: float) -> float:
    """A gearhead catalogue's torsional rigidity C_t21 [N m/arcmin] in N m/rad."""
    return positive("newton_metre_per_arcmin", newton_metre_per_arcmin) / ARCMIN


def two_mass_frequency_with_gearhead(*, motor_inertia: float, load_inertia: float, ratio: float,
                                     efficiency: float = 1.0, coupling_stiffness=None,
                                     gearhead_stiffness=None, shaft_stiffness=None,
                                     gearhead_input_inertia: float = 0.0) -> float:
    """Torsional frequency [Hz] of motor and load on the series spring of the motor shaft (on
    the gear input), the gearhead (at its output) and the coupling, with the gearhead's input
    inertia on the motor side.

    ``k = 1 / (r^2 / k_shaft + 1 / k_gearhead + 1 / k_coupling)`` at the load shaft; the motor
    side's inertia as the load feels it, ``eta (J_motor + J_gearhead) / r^2``, as
    :meth:`ecam.mechanics.Mechanics.motor_inertia_at_load`. ``math.inf`` without any spring.
    """
    r = positive("ratio", ratio)
    shaft = None if shaft_stiffness is None else stiffness_at_output(shaft_stiffness, r)
    k = series_stiffness(shaft, gearhead_stiffness, coupling_stiffness)
    if math.isinf(k):
        return math.inf
    j1 = (positive("efficiency", efficiency, maximum=1.0)
          * (positive("motor_inertia", motor_inertia)
             + number("gearhead_input_inertia", gearhead_input_inertia, minimum=0.0)) / (r * r))
    return two_mass_frequency(k, j1, load_inertia) / (2.0 * math.pi)


def gearhead_cyclic_torque(t2b: float, cycles_per_hour: float,
                           shock_factor: float | None = None) -> tuple[float, str]:
    """The gearhead's permissible peak output torque in cyclic operation, and how it follows.

    Parameters
    ----------
    t2b : float
        Maximum acceleration torque T2B [N m] (catalogue, for at most 1000 cycles per hour).
    cycles_per_hour : float
        Acceleration cycles per hour of the duty.
    shock_factor : float, optional
        The catalogue's shock (impact) factor f_s for ``cycles_per_hour`` (>= 1); read from the
        manufacturer's curve.

    Returns
    -------
    (float, str)
        T2B / f_s up to 1000 cycles/h (f_s = 1), or with the given factor above; above 1000
        cycles/h without a factor, T2B and a note that the factor was not applied.
    """
    t2b = positive("t2b", t2b)
    cycles = number("cycles_per_hour", cycles_per_hour, minimum=0.0)
    if cycles <= T2B_CYCLES_PER_HOUR:
        return t2b, f"T2B, rated for <= {T2B_CYCLES_PER_HOUR:g} cycles/h"
    if shock_factor is None:
        return t2b, (f"T2B at {cycles:.4g} cycles/h, above the {T2B_CYCLES_PER_HOUR:g} it is "
                     "rated for: the catalogue's shock factor was not given, not applied")
    fs = number("shock_factor", shock_factor, minimum=1.0)
    return t2b / fs, f"T2B / f_s {fs:g} at {cycles:.4g} cycles/h"
