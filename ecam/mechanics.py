"""Mechanics of a cam-driven axis: gears reflected to the motor, couplings, torsional modes.

SI units throughout: inertia kg m^2, damping N m s/rad, stiffness N m/rad, torque N m,
angles rad, speeds rad/s. Following the geared-system seed (Cam Design Handbook, fig. 11.21),
the gear ratio is ``r = R_pinion / R_gear = omega_out / omega_in`` and the efficiency ``eta``
divides only the terms reflected from the output side.
"""

from __future__ import annotations

import math

from .errors import InputError

__all__ = [
    "reflected_inertia",
    "reflected_damping",
    "input_torque",
    "two_mass_frequency",
    "wind_up_angle",
    "coupling_check",
    "residual_vibration",
]


def _positive(name, value, allow_zero=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{name} {value!r} should be a finite number")
    if value < 0 or (value == 0 and not allow_zero):
        raise InputError(f"{name} {value!r} should be {'>= 0' if allow_zero else '> 0'}")
    return float(value)


def _efficiency(eta):
    eta = _positive("efficiency", eta)
    if eta > 1:
        raise InputError(f"efficiency {eta!r} should be <= 1")
    return eta


def reflected_inertia(load_inertia: float, ratio: float, efficiency: float = 1.0) -> float:
    """Load inertia seen at the gear input: ``J_eq = J_load * r**2 / eta``."""
    return _positive("load_inertia", load_inertia, True) * _positive("ratio", ratio) ** 2 / _efficiency(efficiency)


def reflected_damping(input_damping: float, output_damping: float, ratio: float, efficiency: float = 1.0) -> float:
    """Damping seen at the gear input: ``b_eq = b_in + b_out * r**2 / eta``."""
    b_in = _positive("input_damping", input_damping, True)
    b_out = _positive("output_damping", output_damping, True)
    return b_in + b_out * _positive("ratio", ratio) ** 2 / _efficiency(efficiency)


def input_torque(
    speed_in, acceleration_in, *, load_inertia, ratio, efficiency=1.0, input_damping=0.0, output_damping=0.0,
    input_inertia=0.0,
):
    """Torque at the gear input for a given input motion (works on numpy arrays).

    ``T_in = (J_in + J_eq) * alpha_in + b_eq * omega_in`` with J_eq and b_eq reflected as above.
    """
    j = _positive("input_inertia", input_inertia, True) + reflected_inertia(load_inertia, ratio, efficiency)
    b = reflected_damping(input_damping, output_damping, ratio, efficiency)
    return j * acceleration_in + b * speed_in


def two_mass_frequency(stiffness: float, inertia_1: float, inertia_2: float) -> float:
    """Torsional natural frequency of two inertias on a spring, in rad/s:
    ``sqrt(k (J1 + J2) / (J1 J2))``. Divide by 2 pi for Hz."""
    k = _positive("stiffness", stiffness)
    j1, j2 = _positive("inertia_1", inertia_1), _positive("inertia_2", inertia_2)
    return math.sqrt(k * (j1 + j2) / (j1 * j2))


def wind_up_angle(torque: float, stiffness: float) -> float:
    """Twist of a coupling carrying ``torque``: T / k, in rad."""
    return float(torque) / _positive("stiffness", stiffness)


def coupling_check(peak_torque, *, rated_torque, max_torque, stiffness, excitation_hz, inertia_1, inertia_2):
    """Checks of a flexible coupling: peak torque against its ratings, wind-up angle, and the
    margin between its torsional mode and the highest excitation frequency.

    Returns
    -------
    list of dict
        Items with ``name``, ``value``, ``limit``, ``passed``, ``unit``.
    """
    rated = _positive("rated_torque", rated_torque)
    maximum = _positive("max_torque", max_torque)
    peak = abs(float(peak_torque))
    mode_hz = two_mass_frequency(stiffness, inertia_1, inertia_2) / (2 * math.pi)
    return [
        {"name": "coupling_torque_rated", "value": peak, "limit": rated, "passed": peak <= rated, "unit": "N m"},
        {"name": "coupling_torque_max", "value": peak, "limit": maximum, "passed": peak <= maximum, "unit": "N m"},
        {"name": "wind_up_angle", "value": peak / stiffness, "limit": maximum / stiffness,
         "passed": peak <= maximum, "unit": "rad"},
        {"name": "resonance_margin", "value": mode_hz / max(excitation_hz, 1e-300), "limit": 3.0,
         "passed": mode_hz >= 3.0 * excitation_hz, "unit": "ratio"},
    ]


def residual_vibration(natural_hz: float, rise_time_s: float, law) -> float:
    """Amplitude of residual vibration of an undamped follower after a rest-to-rest rise, per
    unit stroke: the magnitude of the Fourier transform of s''(u) at the natural frequency,
    divided by (2 pi f T)^2 (single-degree-of-freedom response to the law's acceleration)."""
    import numpy as np

    f = _positive("natural_hz", natural_hz)
    period = _positive("rise_time_s", rise_time_s)
    w = 2 * math.pi * f * period  # natural frequency in radians per rise
    u = np.linspace(0.0, 1.0, 20001)
    acc = law(u, 2)
    weights = np.full_like(u, 1.0)
    weights[0] = weights[-1] = 0.5
    du = u[1] - u[0]
    re = float(np.sum(weights * acc * np.cos(w * (1 - u))) * du)
    im = float(np.sum(weights * acc * np.sin(w * (1 - u))) * du)
    return math.hypot(re, im) / w
