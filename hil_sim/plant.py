"""Linear plant models of one axis, discretized exactly by zero-order hold.

Each model is x' = A x + B u with the motor torque u held constant over a step of ``dt``. The
step is exact: ``[[Phi, Gamma], [0, 1]] = expm([[A, B], [0, 0]] dt)``, so a coupling of
1e9 N m/rad runs at the same step as one of 10 N m/rad (an explicit integrator would need a
step below 2/omega, i.e. microseconds, to stay stable).

The matrix exponential is written here (numpy only): balancing by powers of two, then
scaling and squaring with the degree-13 Pade approximant of Higham (2005).
"""

from __future__ import annotations

import math

import numpy as np

from ecam.errors import InputError, SimulationError
from ecam.mechanics import Mechanics

# Higham (2005), "The scaling and squaring method for the matrix exponential revisited",
# Table 2.3 / eq. (2.3): coefficients b_0..b_13 of the [13/13] Pade approximant, and the
# 1-norm below which it is accurate to double precision without scaling.
_PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
           1187353796428800.0, 129060195264000.0, 10559470521600.0, 670442572800.0,
           33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0)
_THETA13 = 5.371920351148152


def _balance(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (D^-1 A D, d) with d = diag(D) powers of two that even out row and column norms.

    Physical states differ by many orders of magnitude (an angle and a speed of a 1e9 N m/rad
    coupling); balancing shrinks the norm, so expm needs fewer squarings and loses less
    precision. Powers of two make the similarity transform itself exact.
    """
    b = a.copy()
    d = np.ones(b.shape[0])
    for _ in range(100):
        changed = False
        for i in range(b.shape[0]):
            col = np.abs(b[:, i]).sum() - abs(b[i, i])
            row = np.abs(b[i, :]).sum() - abs(b[i, i])
            if col == 0.0 or row == 0.0:
                continue  # an input column or a pure integrator row: nothing to even out
            f = 2.0 ** round(0.5 * math.log2(row / col))
            if col * f + row / f < 0.95 * (col + row):
                b[:, i] *= f
                b[i, :] /= f
                d[i] *= f
                changed = True
        if not changed:
            break
    return b, d


def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential of a real square matrix.

    Parameters
    ----------
    a : ndarray, shape (n, n)
        Finite real matrix.

    Returns
    -------
    ndarray, shape (n, n)
        exp(a).

    Raises
    ------
    InputError
        If ``a`` is not square or not finite.

    Notes
    -----
    Balancing (diagonal similarity by powers of two), then scaling by 2^-s so that
    ||a||_1 <= 5.37, the [13/13] Pade approximant, and s squarings (Higham 2005). Accurate
    to a few ulps times the condition of the problem; validated against scipy in the tests.
    """
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise InputError(f"matrix shape {a.shape} should be square")
    if not np.all(np.isfinite(a)):
        raise InputError("matrix entries should be finite")
    n = a.shape[0]
    b, d = _balance(a)
    norm = np.abs(b).sum(axis=0).max()
    s = max(0, math.ceil(math.log2(norm / _THETA13))) if norm > 0.0 else 0
    b = b / 2.0**s
    c = _PADE13
    ident = np.eye(n)
    b2 = b @ b
    b4 = b2 @ b2
    b6 = b4 @ b2
    u = b @ (b6 @ (c[13] * b6 + c[11] * b4 + c[9] * b2)
             + c[7] * b6 + c[5] * b4 + c[3] * b2 + c[1] * ident)
    v = (b6 @ (c[12] * b6 + c[10] * b4 + c[8] * b2)
         + c[6] * b6 + c[4] * b4 + c[2] * b2 + c[0] * ident)
    e = np.linalg.solve(v - u, v + u)
    for _ in range(s):
        e = e @ e
    # Undo the balancing: exp(D^-1 A D) = D^-1 exp(A) D.
    return e * d[:, None] / d[None, :]


def zero_order_hold(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretization of x' = A x + B u with u held over ``dt``.

    Parameters
    ----------
    a : ndarray, shape (n, n)
        System matrix [1/s].
    b : ndarray, shape (n, m)
        Input matrix.
    dt : float
        Step [s], > 0.

    Returns
    -------
    phi, gamma : ndarray, shapes (n, n) and (n, m)
        x[k+1] = phi x[k] + gamma u[k].
    """
    n, m = b.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n] = a * dt
    augmented[:n, n:] = b * dt
    e = expm(augmented)
    return e[:n, :n].copy(), e[:n, n:].copy()


def _unrolled_step(phi: np.ndarray, gamma: np.ndarray):
    """x -> phi x + gamma u for a small n, as straight-line float arithmetic (same sums, same
    order of terms as the matrix product, so the result does not depend on the path)."""
    n = phi.shape[0]
    rows = [[float(v) for v in row] for row in phi]
    g = [float(v) for v in gamma]
    if n == 2:
        (a, b), (c, d) = rows
        g0, g1 = g

        def advance(x, u):
            x0, x1 = x
            return [a * x0 + b * x1 + g0 * u, c * x0 + d * x1 + g1 * u]
        return advance
    if n == 4:
        (a0, a1, a2, a3), (b0, b1, b2, b3), (c0, c1, c2, c3), (d0, d1, d2, d3) = rows
        g0, g1, g2, g3 = g

        def advance(x, u):
            x0, x1, x2, x3 = x
            return [a0 * x0 + a1 * x1 + a2 * x2 + a3 * x3 + g0 * u,
                    b0 * x0 + b1 * x1 + b2 * x2 + b3 * x3 + g1 * u,
                    c0 * x0 + c1 * x1 + c2 * x2 + c3 * x3 + g2 * u,
                    d0 * x0 + d1 * x1 + d2 * x2 + d3 * x3 + g3 * u]
        return advance

    def advance(x, u):
        return [sum(r * xi for r, xi in zip(row, x)) + gi * u for row, gi in zip(rows, g)]
    return advance


class _LinearPlant:
    """Shared stepping of a ZOH-discretized plant; subclasses define A, B and the outputs."""

    def __init__(self, mechanics: Mechanics, dt: float, a: np.ndarray, b: np.ndarray) -> None:
        if not isinstance(mechanics, Mechanics):
            raise InputError(f"mechanics {mechanics!r} should be a Mechanics")
        if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (
                math.isfinite(dt) and dt > 0.0):
            raise InputError(f"dt {dt!r} should be a finite number > 0")
        self.mechanics = mechanics
        self.dt = float(dt)
        phi, gamma = zero_order_hold(a, b, self.dt)
        if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(gamma))):
            raise SimulationError(f"discretization at dt {dt} gave non-finite matrices")
        phi.setflags(write=False)
        gamma.setflags(write=False)
        self.phi = phi
        self.gamma = gamma[:, 0].copy()
        self.gamma.setflags(write=False)
        # The state is a list of floats and the step is unrolled: a 2x2 or 4x4 numpy product
        # costs more in call overhead than the arithmetic, and the rig runs it 4..16 times a cycle.
        self._advance = _unrolled_step(phi, self.gamma)
        self._x = [0.0] * phi.shape[0]
        self._torque = 0.0

    @property
    def x(self) -> np.ndarray:
        """Copy of the internal state vector (see the class docstring for its layout)."""
        return np.array(self._x)

    @property
    def torque(self) -> float:
        """Motor torque applied during the last step [N m]."""
        return self._torque

    def step(self, torque: float) -> None:
        """Advance one step of ``dt`` with the motor torque held at ``torque`` [N m]."""
        self._torque = float(torque)
        self._x = self._advance(self._x, self._torque)

    @property
    def motor_angle(self) -> float:
        """Motor shaft angle [rad]."""
        return float(self._x[0])

    @property
    def motor_speed(self) -> float:
        """Motor shaft speed [rad/s]."""
        return float(self._x[1])


class RigidPlant(_LinearPlant):
    """Motor and load as one inertia J_eq at the motor shaft (no coupling compliance).

    State x = [motor angle (rad), motor speed (rad/s)]; input: motor torque (N m).
    J_eq and b_eq follow the seed (:meth:`Mechanics.reflected_inertia`, ``reflected_damping``).

    Parameters
    ----------
    mechanics : Mechanics
        The axis; its coupling stiffness, if any, is ignored.
    dt : float
        Step [s].
    """

    def __init__(self, mechanics: Mechanics, dt: float) -> None:
        if not isinstance(mechanics, Mechanics):
            raise InputError(f"mechanics {mechanics!r} should be a Mechanics")
        self._j_eq = j_eq = mechanics.reflected_inertia()
        self._b_eq = b_eq = mechanics.reflected_damping()
        a = np.array([[0.0, 1.0], [0.0, -b_eq / j_eq]])
        b = np.array([[0.0], [1.0 / j_eq]])
        super().__init__(mechanics, dt, a, b)

    def reset(self, motor_angle: float = 0.0, motor_speed: float = 0.0) -> None:
        """Place the axis at ``motor_angle`` [rad] turning at ``motor_speed`` [rad/s]."""
        self._x = [float(motor_angle), float(motor_speed)]
        self._torque = 0.0

    @property
    def load_angle(self) -> float:
        """Load angle, r times the motor angle [rad]."""
        return self.mechanics.gear_ratio * self.motor_angle

    @property
    def load_speed(self) -> float:
        """Load speed [rad/s]."""
        return self.mechanics.gear_ratio * self.motor_speed

    @property
    def twist(self) -> float:
        """Coupling wind-up angle: always 0 in the rigid model [rad]."""
        return 0.0

    @property
    def coupling_torque(self) -> float:
        """Torque the load needs, J_load alpha_load + b_out omega_load [N m] (load side).

        A rigid model has no spring to read; this is what a coupling would transmit, so
        torque checks against the coupling rating still mean something. The acceleration is
        the one at the current state under the last applied torque.
        """
        m = self.mechanics
        motor_acceleration = (self._torque - self._b_eq * self.motor_speed) / self._j_eq
        return (m.load_inertia * m.gear_ratio * motor_acceleration
                + m.load_damping * self.load_speed)


class TwoMassPlant(_LinearPlant):
    """Motor (with gear) and load joined by a torsional spring-damper on the gear output.

    Equations (r gear ratio, eta efficiency, T_c coupling torque on the load side)::

        J_m  motor_speed' = T - b_in motor_speed - (r / eta) T_c
        J_L  load_speed'  = T_c - b_out load_speed
        T_c = k twist + c twist',      twist = r motor_angle - load_angle

    The internal state is x = [motor angle, motor speed, twist, load speed] (rad, rad/s):
    carrying the twist instead of the load angle keeps the stiff terms away from the large,
    ever-growing angles, so no precision is lost to cancellation after many revolutions.
    ``load_angle`` is derived as r motor_angle - twist.

    Parameters
    ----------
    mechanics : Mechanics
        The axis; ``coupling_stiffness`` must be given.
    dt : float
        Step [s].
    """

    def __init__(self, mechanics: Mechanics, dt: float) -> None:
        if not isinstance(mechanics, Mechanics):
            raise InputError(f"mechanics {mechanics!r} should be a Mechanics")
        if mechanics.coupling_stiffness is None:
            raise InputError("coupling_stiffness None should be > 0 for a two_mass plant")
        m = mechanics
        r, eta = m.gear_ratio, m.gear_efficiency
        k, c = m.coupling_stiffness, m.coupling_damping
        jm, jl = m.motor_inertia, m.load_inertia
        g = r / eta
        a = np.array([
            [0.0, 1.0, 0.0, 0.0],
            [0.0, -(m.motor_damping + g * c * r) / jm, -g * k / jm, g * c / jm],
            [0.0, r, 0.0, -1.0],
            [0.0, c * r / jl, k / jl, -(c + m.load_damping) / jl],
        ])
        b = np.array([[0.0], [1.0 / jm], [0.0], [0.0]])
        super().__init__(mechanics, dt, a, b)

    def reset(self, motor_angle: float = 0.0, motor_speed: float = 0.0) -> None:
        """Place the axis at ``motor_angle`` [rad] turning at ``motor_speed`` [rad/s], no twist."""
        r = self.mechanics.gear_ratio
        self._x = [float(motor_angle), float(motor_speed), 0.0, r * float(motor_speed)]
        self._torque = 0.0

    @property
    def twist(self) -> float:
        """Coupling wind-up, r motor_angle - load_angle [rad]."""
        return float(self._x[2])

    @property
    def load_angle(self) -> float:
        """Load angle [rad]."""
        return self.mechanics.gear_ratio * float(self._x[0]) - float(self._x[2])

    @property
    def load_speed(self) -> float:
        """Load speed [rad/s]."""
        return float(self._x[3])

    @property
    def coupling_torque(self) -> float:
        """Torque in the coupling, k twist + c twist' [N m] (load side)."""
        m = self.mechanics
        twist_rate = m.gear_ratio * float(self._x[1]) - float(self._x[3])
        return m.coupling_stiffness * self.twist + m.coupling_damping * twist_rate

    def energy(self) -> float:
        """Stored energy, kinetic plus spring [J], counting the load side scaled by 1/eta.

        With eta < 1 the model is not symmetric; dividing the load equation by eta makes it
        a passive system (inertia J_L/eta, stiffness k/eta), whose energy is this function.
        It never grows without input when all damping is >= 0.
        """
        m = self.mechanics
        eta = m.gear_efficiency
        speed, twist, load_speed = float(self._x[1]), float(self._x[2]), float(self._x[3])
        return 0.5 * (m.motor_inertia * speed**2
                      + (m.load_inertia * load_speed**2 + m.coupling_stiffness * twist**2) / eta)


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
                 factor: float = 10.0) -> tuple[str, str]:
    """Pick the simplest plant model faithful to the scene.

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
    if torsion >= needed:
        return "rigid", "rigid model: " + numbers.format("at least") + "."
    return "two_mass", "two-mass model: " + numbers.format("below") + "."
