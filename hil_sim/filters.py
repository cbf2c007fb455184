"""The drive's current-setpoint filter: a notch on the torque command.

A lightly damped torsional mode (a metal bellows coupling has a damping ratio of a few
hundredths) puts a tall resonance peak into what the velocity loop sees at the motor; with the
loop's delays (sampling, computation, current loop) that peak makes the loop unstable at any
useful gain. Drives answer with notch filters in the current setpoint channel (SINAMICS:
current setpoint filters 1..4, p1656 ff.; Kollmorgen AKD: the AR1..AR4 biquads), set by their
one-button tuning at the mechanics' resonance. The rig's drive does the same with one notch.

The filter is the analog notch H(s) = (s^2 + 2 z w s + w^2) / (s^2 + 2 p w s + w^2), width p,
depth 20 log10(z / p) dB at w, discretized by the bilinear transform prewarped at w (the notch
stays exactly at its frequency), and run once per controller period.
"""

from __future__ import annotations

import math

from ecam import validate

#: Lowest notch centre [Hz]. The design divides by tan(w dt / 2), which is 0 for a frequency
#: such as 5e-324 Hz (a ZeroDivisionError, issue 28); and far above that underflow a notch is
#: pointless: a current-setpoint notch is set against a mechanical resonance of hertz to
#: kilohertz, and below 0.1 Hz its octave-wide stop band (width 0.5) only slows a rigid motion.
MIN_NOTCH_HZ = 0.1


def check_notch_hz(field: str, frequency_hz) -> float:
    """A notch centre: 0 (no notch) or at least :data:`MIN_NOTCH_HZ` [Hz]. (The Nyquist bound
    depends on the controller period and is checked where the filter is designed.)"""
    frequency_hz = validate.number(field, frequency_hz, minimum=0.0)
    if 0.0 < frequency_hz < MIN_NOTCH_HZ:
        raise validate.fail(field, frequency_hz, f"0 (no notch) or >= {MIN_NOTCH_HZ:g} Hz")
    return frequency_hz


class Notch:
    """A discrete notch filter (direct form I).

    Parameters
    ----------
    frequency_hz : float
        Centre frequency [Hz], below the Nyquist frequency of ``dt``.
    width : float
        Damping ratio p of the poles, > 0: the notch's width (0.5: about one octave).
    depth_db : float
        Attenuation at the centre [dB], > 0.
    dt : float
        Sample period [s].
    """

    def __init__(self, frequency_hz: float, width: float, depth_db: float, dt: float) -> None:
        frequency_hz = validate.number("notch_hz", frequency_hz, minimum=MIN_NOTCH_HZ)
        validate.positive("notch_width", width)
        validate.positive("notch_depth_db", depth_db)
        if frequency_hz >= 0.5 / dt:
            raise validate.fail("notch_hz", frequency_hz, f"< {0.5 / dt:.6g} Hz (the controller's "
                                "Nyquist frequency)")
        w = 2.0 * math.pi * frequency_hz
        k = w / math.tan(0.5 * w * dt)  # bilinear prewarped at w
        z = width * 10.0 ** (-depth_db / 20.0)
        a0 = k * k + 2.0 * width * w * k + w * w
        self._b = ((k * k + 2.0 * z * w * k + w * w) / a0, 2.0 * (w * w - k * k) / a0,
                   (k * k - 2.0 * z * w * k + w * w) / a0)
        self._a = (2.0 * (w * w - k * k) / a0, (k * k - 2.0 * width * w * k + w * w) / a0)
        self.reset()

    @property
    def coefficients(self) -> tuple[tuple[float, float, float], tuple[float, float]]:
        """((b0, b1, b2), (a1, a2)): y_k = b0 x_k + b1 x_k-1 + b2 x_k-2 - a1 y_k-1 - a2 y_k-2
        (the loop analysis, :mod:`hil_sim.tuning`, reads the filter the drive runs)."""
        return self._b, self._a

    def reset(self) -> None:
        """Forget the past (a filter at rest)."""
        self._x1 = self._x2 = self._y1 = self._y2 = 0.0

    def __call__(self, x: float) -> float:
        """The next output for input ``x``."""
        b0, b1, b2 = self._b
        a1, a2 = self._a
        y = b0 * x + b1 * self._x1 + b2 * self._x2 - a1 * self._y1 - a2 * self._y2
        self._x2, self._x1 = self._x1, x
        self._y2, self._y1 = self._y1, y
        return y
