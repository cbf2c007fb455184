"""Commissioning: the drive's loops as they run, their frequency response and stability
margins, and the auto-tuner that chooses the gains from them.

The loop is derived from the control law as :meth:`hil_sim.control.ServoAxis._run` codes it,
one controller period ``dt`` at a time (k counts periods):

* at the start of period k the drive reads the encoder: the angle theta_k and the speed
  estimate omega_k (the exact speed with ideal feedback; else the filtered difference quotient
  of :class:`hil_sim.feedback.Encoder`, omega_k = omega_{k-1} + a ((theta_k - theta_{k-1}) / dt
  - omega_{k-1}), a = 1 - exp(-2 pi f_filter dt));
* it computes e_k = kp (theta_ref - theta_k) + omega_ref - omega_k and the torque command
  w_k = kv e_k + ki I_k, with I_k = dt (e_0 + ... + e_{k-1}) (the integral is updated after the
  torque is computed): C(z) = kv + ki dt / (z - 1);
* w_k passes the notch (:class:`hil_sim.filters.Notch`, its own difference equation, N(z));
* with the computation delay the torque applied over period k is the one computed in period
  k - 1 (D(z) = 1/z), else w_k itself;
* the plant holds it over the period (zero-order hold) with the current loop's lag in its
  state: x_{k+1} = Phi x_k + Gamma T_k, the very matrices :class:`hil_sim.plant.Plant`
  steps with (rigid or two-mass, with the coupling's damping and inertia), so P(z) =
  c (zI - Phi)^-1 Gamma for the angle and speed rows c.

So, broken at the torque command, the velocity loop's open-loop response is
L_v = C N D P_omega (P_omega the speed estimate's response to the torque) and the position
loop's, with the velocity loop closed, L_p = kp C N D P_theta / (1 + L_v); the whole cascade
broken there is L = C N D (P_omega + kp P_theta), and 1 + L = (1 + L_v)(1 + L_p). Friction,
encoder quantization and the square-root law of the position loop are the nonlinear parts a
small-signal analysis leaves out; the backlash is two linear plants (in contact; in the gap the
motor alone, :func:`gap_model`), and the loop must keep its margins on both, or it limit-cycles
through the gap. Closed-loop stability is proven separately, by the eigenvalues of the same
period map (:meth:`LoopModel.closed_loop_matrix`), so a margin is never read off an unstable loop.

The margins are the loop-at-a-time margins a drive's tuning tool measures on each loop's
open-loop Bode plot: phase margin (180 deg - |arg L| where |L| = 1), gain margin (-20 log10 |L|
where arg L = -180 deg and |L| < 1) and the sensitivity peak Ms = max |1 / (1 + L)|, of the
velocity loop and of the position loop; the worst of the two is the axis's.

The tuner (:func:`auto_tune`) follows the rule of a drive's frequency-response autotuning
(Beckhoff TwinCAT 3 Autotuning TE5960, "Configuration": the speed controller's Kp and Tn and the
current setpoint filters are calculated from the measured frequency response against "the gain
maximum, the phase margin and the gain margin"): the highest velocity-loop gain that keeps phase
margin >= 45 deg, gain margin >= 6 dB and Ms <= 2 (:class:`MarginLimits`), with the PI's corner
at a quarter of the nominal crossover kv / (2 pi J) (the symmetrical optimum with a = 4: Tn =
a^2 T_sigma for a crossover at 1 / (a T_sigma); Kessler 1958, Schroeder, Elektrische Antriebe -
Regelung von Antriebssystemen, ch. 3.3), and a notch at the torsional mode when it raises that
gain; then the highest position-loop gain with the same margins on the position loop.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ecam import validate
from ecam.mechanics import Mechanics
from hil_sim.control import AxisSetup, DriveEffects, Gains
from hil_sim.effects import EffectValues
from hil_sim.filters import Notch
from hil_sim.plant import MechanicalEffects, Plant

#: PI corner as a share of the nominal velocity crossover (symmetrical optimum, a = 4).
INTEGRAL_RATIO = 0.25
#: The notch the tuner places: its width (pole damping) and depth, :class:`Gains`' defaults.
NOTCH_WIDTH, NOTCH_DEPTH_DB = 0.5, 30.0
#: Bandwidths the tuner tries: a geometric grid of this ratio, then bisection.
_GRID_RATIO = 2.0 ** 0.125
_BISECTIONS = 6
_LOWEST_VELOCITY_HZ = 0.5
_LOWEST_POSITION_HZ = 0.02
#: Frequency grid of the responses: points per decade, from this lowest frequency.
_PER_DECADE = 300
_LOWEST_HZ = 0.01
#: Where a plant mode is, the grid is refined within this share of its frequency.
_MODE_SPAN, _MODE_POINTS = 0.25, 400
#: An eigenvalue of the closed-loop period map counts as stable below this magnitude.
_STABLE_RADIUS = 1.0 - 1e-12


@dataclass(frozen=True)
class MarginLimits:
    """What a tuned loop must keep (the scene's ``[limits]`` ``phase_margin_deg``,
    ``gain_margin_db``, ``sensitivity_peak``).

    Attributes
    ----------
    phase_margin_deg : float
        Least phase margin [deg].
    gain_margin_db : float
        Least gain margin [dB].
    sensitivity_peak : float
        Largest sensitivity peak Ms = max |1 / (1 + L)| [-], > 1.
    """

    phase_margin_deg: float = 45.0
    gain_margin_db: float = 6.0
    sensitivity_peak: float = 2.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "phase_margin_deg", validate.number(
            "phase_margin_deg", self.phase_margin_deg, minimum=0.0, maximum=90.0))
        object.__setattr__(self, "gain_margin_db", validate.number(
            "gain_margin_db", self.gain_margin_db, minimum=0.0, maximum=60.0))
        object.__setattr__(self, "sensitivity_peak", validate.number(
            "sensitivity_peak", self.sensitivity_peak, minimum=1.0, maximum=100.0, strict=True))

    def met(self, margins: "Margins") -> bool:
        """True when ``margins`` are stable and within every limit."""
        return (margins.stable and margins.phase_margin_deg >= self.phase_margin_deg
                and margins.gain_margin_db >= self.gain_margin_db
                and margins.sensitivity_peak <= self.sensitivity_peak)


@dataclass(frozen=True)
class Margins:
    """Stability margins of one open loop L (or the worst of several).

    Attributes
    ----------
    phase_margin_deg : float
        Least 180 - |arg L| [deg] where |L| crosses 1 (inf when it never does).
    gain_margin_db : float
        Least -20 log10 |L| [dB] where arg L crosses -180 deg with |L| < 1 (inf: none).
    sensitivity_peak : float
        max |1 / (1 + L)| over the frequency grid.
    crossover_hz : float or None
        Frequency where |L| crosses 1 with the least phase margin [Hz].
    phase_crossover_hz : float or None
        Frequency of the gain margin [Hz].
    stable : bool
        The closed loop's period map has every eigenvalue inside the unit circle.
    """

    phase_margin_deg: float
    gain_margin_db: float
    sensitivity_peak: float
    crossover_hz: float | None
    phase_crossover_hz: float | None
    stable: bool

    def to_dict(self) -> dict:
        return {"phase_margin_deg": _finite(self.phase_margin_deg),
                "gain_margin_db": _finite(self.gain_margin_db),
                "sensitivity_peak": _finite(self.sensitivity_peak),
                "crossover_hz": self.crossover_hz, "phase_crossover_hz": self.phase_crossover_hz,
                "stable": self.stable}


def _finite(value: float) -> float | None:
    """None for an infinite margin (JSON has no infinity)."""
    return value if math.isfinite(value) else None


def worst(*margins: Margins) -> Margins:
    """The worst of several loops' margins: least PM and GM, largest Ms, stable if all are (the
    crossover of the loop with the least phase margin)."""
    least = min(margins, key=lambda m: m.phase_margin_deg)
    gain = min(margins, key=lambda m: m.gain_margin_db)
    return Margins(least.phase_margin_deg, gain.gain_margin_db,
                   max(m.sensitivity_peak for m in margins), least.crossover_hz,
                   gain.phase_crossover_hz, all(m.stable for m in margins))


def margins_of(frequencies: np.ndarray, loop: np.ndarray, stable: bool = True) -> Margins:
    """Phase margin, gain margin and sensitivity peak of the open loop ``loop`` sampled at
    ``frequencies`` [Hz] (increasing), read at its crossings by linear interpolation."""
    magnitude = np.abs(loop)
    sensitivity = float(np.max(1.0 / np.abs(1.0 + loop)))
    pm, crossover = math.inf, None
    above = magnitude >= 1.0
    for i in np.flatnonzero(above[1:] != above[:-1]):
        t = (1.0 - magnitude[i]) / (magnitude[i + 1] - magnitude[i])
        value = loop[i] + t * (loop[i + 1] - loop[i])
        margin = 180.0 - abs(math.degrees(math.atan2(value.imag, value.real)))
        if margin < pm:
            pm = margin
            crossover = float(frequencies[i] + t * (frequencies[i + 1] - frequencies[i]))
    gm, phase_crossover = math.inf, None
    imag = loop.imag
    sign = imag >= 0.0
    for i in np.flatnonzero(sign[1:] != sign[:-1]):
        t = imag[i] / (imag[i] - imag[i + 1])
        value = loop[i] + t * (loop[i + 1] - loop[i])
        if value.real < 0.0 and abs(value) < 1.0:
            margin = -20.0 * math.log10(max(abs(value), 1e-300))
            if margin < gm:
                gm = margin
                phase_crossover = float(frequencies[i] + t * (frequencies[i + 1] - frequencies[i]))
    return Margins(pm, gm, sensitivity, crossover, phase_crossover, stable)


class LoopModel:
    """The blocks of one axis's loop at the controller period ``dt`` (module docstring), with the
    plant's responses on a frequency grid computed once.

    Parameters
    ----------
    plant : Plant
        The linear plant (no backlash, no friction): its ``phi`` and ``gamma`` are the loop's.
    inertia : float
        The inertia the velocity gain is scaled by, J [kg m^2] (kv = J 2 pi f_v).
    drive_effects : DriveEffects
        Encoder and speed filter, computation delay (the current loop is in ``plant``).
    modes_hz : tuple of float
        The plant's torsional modes [Hz] (notch candidates).
    frequencies : array_like, optional
        Where to evaluate the responses [Hz]; default a log grid up to the Nyquist frequency,
        refined at the modes.
    """

    def __init__(self, plant: Plant, inertia: float, drive_effects: DriveEffects,
                 modes_hz: tuple = (), frequencies=None) -> None:
        self._arguments = (plant, inertia, drive_effects, modes_hz)
        self.dt = dt = plant.dt
        self.phi = np.array(plant.phi)
        self.gamma = np.array(plant.gamma)
        self.inertia = inertia
        self.delay = drive_effects.computation_delay
        self.encoder = drive_effects.encoder_counts_per_rev is not None
        # the speed estimate's filter gain, as hil_sim.feedback.Encoder computes it
        self.filter_gain = (1.0 - math.exp(-2.0 * math.pi * drive_effects.velocity_filter_hz * dt)
                            if self.encoder else None)
        self.modes_hz = tuple(f for f in modes_hz if math.isfinite(f))
        self.nyquist_hz = 0.5 / dt
        self.frequencies = (_grid(self.nyquist_hz, self.modes_hz) if frequencies is None else
                            np.asarray(frequencies, dtype=float))
        self.z = np.exp(2j * math.pi * self.frequencies * dt)
        n = self.phi.shape[0]
        # P(z) = (zI - Phi)^-1 Gamma at every frequency: rows 0 (angle) and 1 (speed)
        stack = self.z[:, None, None] * np.eye(n)[None] - self.phi[None]
        response = np.linalg.solve(stack, np.broadcast_to(self.gamma[:, None],
                                                           (self.z.size, n, 1)))[:, :, 0]
        self.angle = response[:, 0]
        speed = response[:, 1]
        if self.encoder:
            a = self.filter_gain
            inverse = 1.0 / self.z
            speed = a * (1.0 - inverse) / dt / (1.0 - (1.0 - a) * inverse) * self.angle
        self.speed = speed  # the speed estimate's response to the applied torque

    def at(self, frequencies) -> "LoopModel":
        """The same loop evaluated at ``frequencies`` [Hz]."""
        return LoopModel(*self._arguments, frequencies=frequencies)

    def cascade(self, gains: Gains) -> np.ndarray:
        """L = C N D (P_omega + kp P_theta): the whole cascade broken at the torque."""
        return self.controller(gains) * (self.speed + gains.position_kp * self.angle)

    # ---------------------------------------------------------------- responses
    def controller(self, gains: Gains) -> np.ndarray:
        """C(z) N(z) D(z): PI, notch and computation delay, at every grid frequency."""
        z = self.z
        response = gains.velocity_kp + gains.velocity_ki * self.dt / (z - 1.0)
        notch = self.notch(gains)
        if notch is not None:
            (b0, b1, b2), (a1, a2) = notch.coefficients
            inverse = 1.0 / z
            response = response * ((b0 + b1 * inverse + b2 * inverse**2)
                                   / (1.0 + a1 * inverse + a2 * inverse**2))
        if self.delay:
            response = response / z
        return response

    def notch(self, gains: Gains) -> Notch | None:
        """The notch the axis runs with ``gains`` (none at or above the Nyquist frequency, as
        :class:`hil_sim.control.ServoAxis` does)."""
        if 0.0 < gains.notch_hz < self.nyquist_hz:
            return Notch(gains.notch_hz, gains.notch_width, gains.notch_depth_db, self.dt)
        return None

    def loops(self, gains: Gains) -> tuple[np.ndarray, np.ndarray]:
        """(L_v, L_p): the velocity loop's and the position loop's open-loop responses."""
        c = self.controller(gains)
        velocity = c * self.speed
        position = gains.position_kp * c * self.angle / (1.0 + velocity)
        return velocity, position

    # ---------------------------------------------------------------- the period map
    def closed_loop_matrix(self, gains: Gains, position: bool = True) -> np.ndarray:
        """The closed loop's state map over one controller period, built from the control law
        in the order :meth:`ServoAxis._run` runs it (references zero; ``position=False``: the
        velocity loop alone). States: plant, speed estimate (encoder), integral, notch (x1, x2,
        y1, y2), pending torque (delay)."""
        a, b, c = self.open_loop_matrices(gains, position)
        return a + np.outer(b, c)

    def open_loop_matrices(self, gains: Gains, position: bool = True):
        """(A, B, C) of the loop broken at the torque command: s_{k+1} = A s_k + B v_k with v_k
        the notch's input, and the command the controller computes w_k = C s_k; the open loop is
        L(z) = -C (zI - A)^-1 B."""
        n = self.phi.shape[0]
        notch = self.notch(gains)
        size = n + int(self.encoder) + 1 + (4 if notch is not None else 0) + int(self.delay)
        kp = gains.position_kp if position else 0.0
        kv, ki, dt = gains.velocity_kp, gains.velocity_ki, self.dt

        def period(s: np.ndarray, v: float) -> tuple[np.ndarray, float]:
            x = s[:n]
            at = n
            if self.encoder:
                speed, at = s[at], at + 1
            else:
                speed = x[1]
            integral, at = s[at], at + 1
            e = -(kp * x[0] + speed)
            w = kv * e + ki * integral
            nxt = np.zeros(size)
            torque = v
            k = n + int(self.encoder) + 1
            if notch is not None:
                (b0, b1, b2), (a1, a2) = notch.coefficients
                x1, x2, y1, y2 = s[k:k + 4]
                torque = b0 * v + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
                nxt[k:k + 4] = (v, x1, torque, y1)
                k += 4
            if self.delay:
                applied, nxt[k] = s[k], torque
            else:
                applied = torque
            x_next = self.phi @ x + self.gamma * applied
            nxt[:n] = x_next
            at = n
            if self.encoder:
                nxt[at] = speed + self.filter_gain * ((x_next[0] - x[0]) / dt - speed)
                at += 1
            nxt[at] = integral + e * dt
            return nxt, w

        eye = np.eye(size)
        a = np.empty((size, size))
        c = np.empty(size)
        for j in range(size):
            a[:, j], c[j] = period(eye[:, j], 0.0)
        b, _ = period(np.zeros(size), 1.0)
        return a, b, c

    def stable(self, gains: Gains, position: bool = True) -> bool:
        """All closed-loop eigenvalues inside the unit circle (the velocity loop alone keeps the
        angle's integrator, which it does not feed back: that one eigenvalue at 1 is left out)."""
        eigenvalues = np.linalg.eigvals(self.closed_loop_matrix(gains, position))
        if not position:
            eigenvalues = np.delete(eigenvalues, int(np.argmin(np.abs(eigenvalues - 1.0))))
        return bool(np.all(np.abs(eigenvalues) < _STABLE_RADIUS))

    # ---------------------------------------------------------------- margins
    def velocity_margins(self, gains: Gains) -> Margins:
        """Margins of the velocity loop L_v."""
        velocity, _ = self.loops(gains)
        return margins_of(self.frequencies, velocity, self.stable(gains, position=False))

    def position_margins(self, gains: Gains) -> Margins:
        """Margins of the position loop L_p (the velocity loop closed); stable: the cascade."""
        _, position = self.loops(gains)
        return margins_of(self.frequencies, position, self.stable(gains, position=True))


def _grid(nyquist_hz: float, modes_hz: tuple) -> np.ndarray:
    """Log-spaced frequencies up to just below the Nyquist frequency, refined at the modes."""
    top = nyquist_hz * (1.0 - 1e-6)
    count = max(int(_PER_DECADE * math.log10(top / _LOWEST_HZ)), 16)
    parts = [np.geomspace(_LOWEST_HZ, top, count)]
    for mode in modes_hz:
        if mode < top:
            parts.append(np.linspace(mode * (1.0 - _MODE_SPAN), min(mode * (1.0 + _MODE_SPAN),
                                                                     top), _MODE_POINTS))
    return np.unique(np.concatenate(parts))


# ------------------------------------------------------------------------- the axis's loops
def torsional_modes_hz(mechanics: Mechanics, coupling_inertia: float) -> tuple:
    """The two-mass plant's torsional mode [Hz] with half the coupling's inertia on each side
    (as :class:`hil_sim.plant.Plant` places it): sqrt(k (r^2 / (eta J_m') + 1 / J_L')) / 2 pi."""
    if mechanics.coupling_stiffness is None:
        return ()
    r, eta = mechanics.gear_ratio, mechanics.gear_efficiency
    jm = mechanics.motor_inertia + 0.5 * coupling_inertia * r * r / eta
    jl = mechanics.load_inertia + 0.5 * coupling_inertia
    omega = math.sqrt(mechanics.coupling_stiffness * (r * r / (eta * jm) + 1.0 / jl))
    return (omega / (2.0 * math.pi),)


def loop_model(mechanics: Mechanics, dt: float, model: str, plant_effects: MechanicalEffects,
               drive_effects: DriveEffects) -> LoopModel:
    """The loop in contact: the plant ``model`` with the coupling's inertia and the current
    loop, without the nonlinear effects (backlash, friction)."""
    coupling_inertia = plant_effects.coupling_inertia
    plant = Plant(mechanics, dt, model=model,
                  effects=MechanicalEffects(coupling_inertia=coupling_inertia),
                  current_loop_hz=drive_effects.current_loop_hz)
    r, eta = mechanics.gear_ratio, mechanics.gear_efficiency
    # the inertia the drive's feed-forward and gains are scaled by (ServoAxis._j_eq)
    inertia = mechanics.reflected_inertia() + coupling_inertia * r * r / eta
    modes = torsional_modes_hz(mechanics, coupling_inertia) if model == "two_mass" else ()
    return LoopModel(plant, inertia, drive_effects, modes)


def gap_model(mechanics: Mechanics, dt: float, plant_effects: MechanicalEffects,
              drive_effects: DriveEffects) -> LoopModel | None:
    """The loop inside the backlash gap: the motor with its half of the coupling alone (the
    two-mass plant's gap mode, k = c = 0); None without backlash."""
    if not plant_effects.gear_backlash:
        return None
    r, eta = mechanics.gear_ratio, mechanics.gear_efficiency
    motor = Mechanics(motor_inertia=mechanics.motor_inertia
                      + 0.5 * plant_effects.coupling_inertia * r * r / eta,
                      motor_damping=mechanics.motor_damping)
    plant = Plant(motor, dt, model="rigid", current_loop_hz=drive_effects.current_loop_hz)
    inertia = mechanics.reflected_inertia() + plant_effects.coupling_inertia * r * r / eta
    return LoopModel(plant, inertia, drive_effects)


@dataclass(frozen=True)
class AxisLoops:
    """The loops of one axis: in contact, and in the backlash gap (None without backlash)."""

    contact: LoopModel
    gap: LoopModel | None = None

    @classmethod
    def from_setup(cls, setup: AxisSetup, cycle_s: float) -> "AxisLoops":
        """The loops of the axis ``setup`` builds, as it runs (its model and effects); the same
        object for the same loop (a search's trials at other speeds share it)."""
        if setup.model != "auto":
            # what the loop does not depend on (the position scale, the cam's excitation, which
            # only an "auto" model reads) is left out of the key
            setup = replace(setup, excitation_hz=0.0, counts_per_motor_rad=None)
        return _loops_of(setup, cycle_s)

    @classmethod
    def _build(cls, setup: AxisSetup, cycle_s: float) -> "AxisLoops":
        axis = setup.build(cycle_s, 0)
        dt = axis.dt
        return cls(loop_model(axis.mechanics, dt, axis.model, axis.plant_effects,
                              axis.drive_effects),
                   gap_model(axis.mechanics, dt, axis.plant_effects, axis.drive_effects)
                   if axis.model == "two_mass" else None)

    @property
    def models(self) -> tuple:
        return (self.contact,) if self.gap is None else (self.contact, self.gap)

    def assess(self, gains: Gains) -> "Assessment":
        """Every loop's margins with ``gains`` (the same object for the same gains)."""
        cache = self.__dict__.setdefault("_assessed", {})
        if gains not in cache:
            cache[gains] = self._assess(gains)
        return cache[gains]

    def _assess(self, gains: Gains) -> "Assessment":
        velocity = [m.velocity_margins(gains) for m in self.models]
        position = [m.position_margins(gains) for m in self.models]
        return Assessment(velocity[0], position[0],
                          None if self.gap is None else worst(velocity[1], position[1]))


@functools.lru_cache(maxsize=32)
def _loops_of(setup: AxisSetup, cycle_s: float) -> AxisLoops:
    return AxisLoops._build(setup, cycle_s)


@dataclass(frozen=True)
class Assessment:
    """Margins of an axis's loops: velocity and position loop in contact, and the worst of the
    two in the backlash gap (None without backlash)."""

    velocity: Margins
    position: Margins
    gap: Margins | None = None

    @property
    def overall(self) -> Margins:
        """The worst of every loop."""
        parts = [self.velocity, self.position] + ([self.gap] if self.gap else [])
        return worst(*parts)

    def to_dict(self) -> dict:
        out = {"velocity_loop": self.velocity.to_dict(), "position_loop": self.position.to_dict()}
        if self.gap is not None:
            out["backlash_gap"] = self.gap.to_dict()
        return out


# ------------------------------------------------------------------------- the tuner
def _velocity_gains(inertia: float, bandwidth_hz: float, notch_hz: float, base: Gains) -> Gains:
    kv = inertia * 2.0 * math.pi * bandwidth_hz
    return replace(base, velocity_kp=kv, velocity_ki=kv * 2.0 * math.pi * bandwidth_hz
                   * INTEGRAL_RATIO, notch_hz=notch_hz, notch_width=NOTCH_WIDTH,
                   notch_depth_db=NOTCH_DEPTH_DB)


def _highest(passes, lowest: float, highest: float) -> float | None:
    """The highest value of a geometric grid from ``lowest`` that passes with every grid value
    below it from the first passing one, refined by bisection against the next failing one;
    None when none passes. Deterministic: the same grid and the same steps every time."""
    grid = []
    value = lowest
    while value <= highest:
        grid.append(value)
        value *= _GRID_RATIO
    good = bad = None
    for value in grid:
        if passes(value):
            good = value
        elif good is not None:
            bad = value
            break
    if good is None:
        return None
    if bad is None:
        return good
    for _ in range(_BISECTIONS):
        middle = math.sqrt(good * bad)
        if passes(middle):
            good = middle
        else:
            bad = middle
    return good


def auto_tune(loops: AxisLoops, limits: MarginLimits, base: Gains) -> tuple[Gains, bool]:
    """The auto-tuner's gains for ``loops`` (module docstring), and whether they meet ``limits``.

    ``base`` gives the feed-forward fractions, kept. The velocity loop first: the highest
    nominal bandwidth f_v (kv = J 2 pi f_v, ki = kv 2 pi f_v :data:`INTEGRAL_RATIO`) whose
    velocity loop keeps the margins in contact and in the backlash gap, without a notch and with
    one at each torsional mode below the Nyquist frequency (the notch is kept only where it
    allows a higher f_v); then the highest position gain kp = 2 pi f_p, f_p <= f_v, whose
    position loop keeps them. When nothing meets the limits, the lowest bandwidths tried.
    """
    contact = loops.contact
    inertia = contact.inertia
    top = 0.5 * contact.nyquist_hz

    def velocity_ok(notch_hz: float):
        def passes(bandwidth: float) -> bool:
            gains = _velocity_gains(inertia, bandwidth, notch_hz, base)
            return all(limits.met(m.velocity_margins(gains)) for m in loops.models)
        return passes

    best_hz, best_notch = None, 0.0
    for notch_hz in (0.0,) + tuple(f for f in contact.modes_hz if f < contact.nyquist_hz):
        found = _highest(velocity_ok(notch_hz), _LOWEST_VELOCITY_HZ, top)
        if found is not None and (best_hz is None or found > best_hz * (1.0 + 1e-9)):
            best_hz, best_notch = found, notch_hz
    met = best_hz is not None
    velocity_hz = best_hz if met else _LOWEST_VELOCITY_HZ
    gains = _velocity_gains(inertia, velocity_hz, best_notch, base)

    def position_ok(bandwidth: float) -> bool:
        trial = replace(gains, position_kp=2.0 * math.pi * bandwidth)
        return all(limits.met(m.position_margins(trial)) for m in loops.models)

    position_hz = _highest(position_ok, _LOWEST_POSITION_HZ, velocity_hz) if met else None
    if position_hz is None:
        met = False
        position_hz = _LOWEST_POSITION_HZ
    return replace(gains, position_kp=2.0 * math.pi * position_hz), met


# ------------------------------------------------------------------------- commissioning
#: The [drive.gains] keys that set the velocity loop, the position loop and the notch.
VELOCITY_KEYS = ("velocity_bandwidth_hz", "integral_ratio", "velocity_kp", "velocity_ki")
POSITION_KEYS = ("position_bandwidth_hz", "position_kp")
NOTCH_KEYS = ("notch_hz", "notch_width", "notch_depth_db")


@dataclass(frozen=True)
class Tuning:
    """How an axis was commissioned: its gains, where they came from, and their margins on the
    full model.

    Attributes
    ----------
    source : {"auto", "scene"}
        ``"auto"``: :func:`auto_tune`; ``"scene"``: the scene's ``[drive.gains]`` set the loop
        gains or the notch (``from_scene`` says which keys).
    gains : Gains
    inertia : float
        The inertia the bandwidths are reckoned on [kg m^2].
    assessment : Assessment
        The margins of ``gains`` on the full model.
    limits : MarginLimits
    met : bool
        ``assessment`` meets ``limits``.
    from_scene : tuple of str
    auto : Tuning or None
        What auto-tuning gives, when the scene's gains were used instead.
    """

    source: str
    gains: Gains
    inertia: float
    assessment: Assessment
    limits: MarginLimits
    met: bool
    from_scene: tuple = ()
    auto: "Tuning | None" = field(default=None, repr=False)

    @property
    def velocity_bandwidth_hz(self) -> float:
        """kv / (2 pi J) [Hz]."""
        return self.gains.velocity_kp / (2.0 * math.pi * self.inertia)

    @property
    def position_bandwidth_hz(self) -> float:
        """kp / (2 pi) [Hz]."""
        return self.gains.position_kp / (2.0 * math.pi)

    @property
    def notch_hz(self) -> list:
        return [self.gains.notch_hz] if self.gains.notch_hz > 0.0 else []

    def to_dict(self) -> dict:
        """The report's ``tuning`` object."""
        overall = self.assessment.overall
        out = {"source": self.source, "velocity_kp": self.gains.velocity_kp,
               "velocity_ki": self.gains.velocity_ki, "position_kp": self.gains.position_kp,
               "velocity_bandwidth_hz": self.velocity_bandwidth_hz,
               "position_bandwidth_hz": self.position_bandwidth_hz,
               "notch_hz": self.notch_hz, "integral_ratio": INTEGRAL_RATIO,
               "phase_margin_deg": _finite(overall.phase_margin_deg),
               "gain_margin_db": _finite(overall.gain_margin_db),
               "sensitivity_peak": overall.sensitivity_peak, "stable": overall.stable,
               "velocity_crossover_hz": self.assessment.velocity.crossover_hz,
               "position_crossover_hz": self.assessment.position.crossover_hz,
               "meets_limits": self.met,
               "limits": {"phase_margin_deg": self.limits.phase_margin_deg,
                          "gain_margin_db": self.limits.gain_margin_db,
                          "sensitivity_peak": self.limits.sensitivity_peak},
               "loops": self.assessment.to_dict(), "model": "full"}
        if self.from_scene:
            out["from_scene"] = list(self.from_scene)
        if self.auto is not None:
            out["auto"] = {k: v for k, v in self.auto.to_dict().items()
                           if k not in ("loops", "limits", "model", "source")}
        return out

    def line(self) -> str:
        """One line for the text report."""
        overall = self.assessment.overall
        notch = (", notch " + ", ".join(f"{f:.4g} Hz" for f in self.notch_hz)
                 if self.notch_hz else ", no notch")
        return (f"tuning ({self.source}): velocity loop {self.velocity_bandwidth_hz:.4g} Hz "
                f"(kp {self.gains.velocity_kp:.4g} N m s/rad, ki {self.gains.velocity_ki:.4g} "
                f"N m/rad), position loop {self.position_bandwidth_hz:.4g} Hz (kp "
                f"{self.gains.position_kp:.4g} 1/s){notch}; on the full model "
                + describe_margins(overall, self.limits))

    def summary(self) -> str:
        """The gains and margins in a phrase (for a failing check's line)."""
        notch = (", notch " + ", ".join(f"{f:.4g} Hz" for f in self.notch_hz)
                 if self.notch_hz else "")
        overall = self.assessment.overall
        return (f"velocity loop {self.velocity_bandwidth_hz:.4g} Hz, position loop "
                f"{self.position_bandwidth_hz:.4g} Hz{notch}: "
                + describe_margins(overall, self.limits))


def describe_margins(margins: Margins, limits: MarginLimits) -> str:
    """"phase margin .. deg, gain margin .. dB, Ms .." with the limits, and unstable if so."""
    pm = ("inf" if not math.isfinite(margins.phase_margin_deg)
          else f"{margins.phase_margin_deg:.3g}")
    gm = "inf" if not math.isfinite(margins.gain_margin_db) else f"{margins.gain_margin_db:.3g}"
    text = (f"phase margin {pm} deg (>= {limits.phase_margin_deg:g}), gain margin {gm} dB "
            f"(>= {limits.gain_margin_db:g}), Ms {margins.sensitivity_peak:.3g} "
            f"(<= {limits.sensitivity_peak:g})")
    return text if margins.stable else text + ", UNSTABLE"


def full_loops(mechanics: Mechanics, values: EffectValues, dt: float) -> AxisLoops:
    """The loops of the full model (every applicable effect on), as a machine is commissioned."""
    model, plant_effects, drive_effects = values.build(values.applicable)
    contact = loop_model(mechanics, dt, model, plant_effects, drive_effects)
    gap = gap_model(mechanics, dt, plant_effects, drive_effects) if model == "two_mass" else None
    return AxisLoops(contact, gap)


def commission(mechanics: Mechanics, values: EffectValues, dt: float, given: dict,
               feedforward: str, limits: MarginLimits | None = None) -> Tuning:
    """The axis's tuning: auto-tuned on the full model, unless the scene's ``[drive.gains]``
    (``given``) sets the loop gains or the notch, which then win.

    Parameters
    ----------
    mechanics : Mechanics
    values : EffectValues
        Every effect's value (the full model is built from them).
    dt : float
        Controller period [s].
    given : dict
        The scene's ``[drive.gains]``.
    feedforward : {"offset", "target"}
        The drive's feed-forward source: with ``"target"`` the streamed velocity offset is
        added as it is, so the drive's own velocity feed-forward defaults to 0.
    limits : MarginLimits, optional

    Returns
    -------
    Tuning
    """
    limits = MarginLimits() if limits is None else limits
    given = dict(given)
    loops = full_loops(mechanics, values, dt)
    base = Gains(position_kp=1.0, velocity_kp=1.0, velocity_ki=0.0,
                 velocity_feedforward=given.get("velocity_feedforward",
                                                1.0 if feedforward == "offset" else 0.0),
                 acceleration_feedforward=given.get("acceleration_feedforward", 1.0))
    auto_gains, auto_met = auto_tune(loops, limits, base)
    inertia = loops.contact.inertia
    auto = Tuning("auto", auto_gains, inertia, loops.assess(auto_gains), limits, auto_met)
    from_scene = tuple(k for k in VELOCITY_KEYS + POSITION_KEYS + NOTCH_KEYS if k in given)
    if not from_scene:
        return auto
    gains = auto_gains
    reflected = mechanics.reflected_inertia()
    if any(k in given for k in VELOCITY_KEYS):
        # the scene's bandwidth as Gains.from_mechanics reads it (on the reflected inertia)
        f_v = given.get("velocity_bandwidth_hz", auto.velocity_bandwidth_hz)
        ratio = given.get("integral_ratio", INTEGRAL_RATIO)
        kv = reflected * 2.0 * math.pi * f_v
        gains = replace(gains, velocity_kp=given.get("velocity_kp", kv),
                        velocity_ki=given.get("velocity_ki", kv * 2.0 * math.pi * f_v * ratio))
        if not any(k in given for k in NOTCH_KEYS):
            # the scene's own velocity gains with the usual one-button notch: at the coupling's
            # resonance where the controller can still filter it
            resonance = mechanics.torsional_frequency_hz()
            gains = replace(gains, notch_hz=resonance if resonance < 0.5 / dt else 0.0,
                            notch_width=Gains.notch_width, notch_depth_db=Gains.notch_depth_db)
    if any(k in given for k in POSITION_KEYS):
        kp = 2.0 * math.pi * given.get("position_bandwidth_hz", auto.position_bandwidth_hz)
        gains = replace(gains, position_kp=given.get("position_kp", kp))
    gains = replace(gains, **{k: given[k] for k in NOTCH_KEYS if k in given})
    assessment = loops.assess(gains)
    return Tuning("scene", gains, inertia, assessment, limits,
                  limits.met(assessment.overall), from_scene, auto)
