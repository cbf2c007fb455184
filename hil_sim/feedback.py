"""What the drive measures of its motor: an incremental encoder and the speed estimated from it.

A drive does not know the motor's angle and speed; it reads an encoder every controller period
and estimates the speed from the difference of two readings, filtered (a difference quotient of
a quantized angle is noisy: one count in one period is a speed of 2 pi / (N dt)). The rig's
ideal feedback (the exact angle and speed) is :class:`IdealFeedback`; :class:`Encoder` is the
real one.
"""

from __future__ import annotations

import math

from ecam import validate


class IdealFeedback:
    """The exact motor angle and speed (no encoder modelled)."""

    resolution_rad = 0.0

    def reset(self, angle: float, speed: float) -> None:
        """Nothing to remember."""

    def sample(self, angle: float, speed: float) -> tuple[float, float]:
        """(angle, speed) as measured: exactly the plant's."""
        return angle, speed


class Encoder:
    """A motor encoder of ``counts_per_rev`` and a first-order filtered speed estimate.

    Parameters
    ----------
    counts_per_rev : int
        Encoder counts per motor revolution (after interpolation of sine/cosine tracks:
        2^20 for a 20-bit single-turn encoder), >= 4.
    velocity_filter_hz : float
        Cut-off of the first-order low-pass on the speed estimate [Hz], > 0.
    dt : float
        Controller period [s]: one reading per period.

    Notes
    -----
    Each period: angle = theta_0 + floor((theta - theta_0) N / 2 pi) 2 pi / N (the count the
    encoder reports, as an angle, counted from the reference theta_0 the drive was homed to at
    :meth:`reset`), raw = (angle - previous angle) / dt, speed += a (raw - speed) with
    a = 1 - exp(-2 pi f dt) (the filter discretized exactly for a held input).
    """

    def __init__(self, counts_per_rev: int, velocity_filter_hz: float, dt: float) -> None:
        counts = validate.integer("encoder_counts_per_rev", counts_per_rev, minimum=4,
                                  maximum=2**40)
        self.counts_per_rev = counts
        self.velocity_filter_hz = validate.positive("velocity_filter_hz", velocity_filter_hz)
        self.dt = validate.positive("dt", dt)
        self._per_rad = counts / (2.0 * math.pi)
        self.resolution_rad = 2.0 * math.pi / counts
        self._gain = 1.0 - math.exp(-2.0 * math.pi * self.velocity_filter_hz * self.dt)
        self._origin = 0.0
        self._angle = 0.0
        self._speed = 0.0

    def reset(self, angle: float, speed: float) -> None:
        """Home the encoder at ``angle`` (it reads exactly that there) turning at ``speed``."""
        self._origin = float(angle)
        self._angle = float(angle)
        self._speed = float(speed)

    def sample(self, angle: float, speed: float) -> tuple[float, float]:
        """(angle, speed) as the drive measures them this period (``speed`` is not read: a
        drive has no speed sensor)."""
        origin = self._origin
        measured = origin + math.floor((angle - origin) * self._per_rad) * self.resolution_rad
        raw = (measured - self._angle) / self.dt
        self._angle = measured
        self._speed += self._gain * (raw - self._speed)
        return measured, self._speed
