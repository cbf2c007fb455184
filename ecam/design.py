"""Design helpers: combination curves, the modified-sine cam, dwell-rise-return-dwell cams."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import InputError
from .laws import LAWS, Law, law as _law
from .profile import CamProfile, Segment, dwell

__all__ = [
    "CombinationPiece",
    "combination",
    "combination_segments",
    "modified_sine_cam",
    "dwell_rise_return_dwell",
    "smallest_peak_law",
]


@dataclass(frozen=True)
class CombinationPiece:
    """One solved piece of a combination curve: a law over ``span`` with ``stroke``."""

    law: Law
    span: float
    stroke: float


def combination(first, second, *, span: float, stroke: float, accel_ratio: float):
    """Split a rise into two laws with matched velocity and a chosen ratio of peak accelerations.

    The unknowns are the strokes h1, h2 and spans b1, b2 of the two pieces (the combination-curve
    seed: C1 then H2). The four conditions are
    ``h1 + h2 = stroke``, ``b1 + b2 = span``,
    ``h1 * v1 / b1 = h2 * v2 / b2`` (velocity matched where they meet) and
    ``h1 * A1 / b1**2 = accel_ratio * h2 * A2 / b2**2`` (peak accelerations),
    with v1 = s1'(1), v2 = s2'(0) and A1, A2 the laws' peak |s''|. Writing x = b1/b2, the
    velocity condition gives h1/h2 = (v2/v1) x and the acceleration condition then reduces to
    ``x = v2 A1 / (v1 accel_ratio A2)``: the nonlinear system has this one closed-form solution.

    Returns
    -------
    tuple of CombinationPiece
        (first, second), with spans and strokes in the units of ``span`` and ``stroke``.
    """
    first, second = _as_law(first), _as_law(second)
    for name, value in (("span", span), ("stroke", stroke), ("accel_ratio", accel_ratio)):
        if not (isinstance(value, (int, float)) and math.isfinite(value)) or value == 0:
            raise InputError(f"combination {name} {value!r} should be finite and non-zero")
    if span < 0:
        raise InputError(f"combination span {span!r} should be > 0")
    if not 1e-6 <= accel_ratio <= 1e6:
        raise InputError(f"combination accel_ratio {accel_ratio!r} should be in 1e-06..1e+06")
    v1, v2 = first(1.0, 1), second(0.0, 1)
    a1, a2 = _finite_peak(first), _finite_peak(second)
    if v1 <= 0 or v2 <= 0:
        raise InputError(
            f"combination laws {first.name!r} -> {second.name!r} should meet at a non-zero "
            f"velocity (end velocity {v1:g}, start velocity {v2:g})"
        )
    x = v2 * a1 / (v1 * accel_ratio * a2)
    k = (v2 / v1) * x
    b1 = span * x / (1 + x)
    h1 = stroke * k / (1 + k)
    return CombinationPiece(first, b1, h1), CombinationPiece(second, span - b1, stroke - h1)


def combination_segments(
    first, second, *, master_start, span, slave_start, stroke, accel_ratio, name=""
) -> tuple[Segment, Segment]:
    """The two segments of :func:`combination`, placed at ``master_start``/``slave_start``."""
    p1, p2 = combination(first, second, span=span, stroke=stroke, accel_ratio=accel_ratio)
    mid_master = master_start + p1.span
    mid_slave = slave_start + p1.stroke
    prefix = f"{name} " if name else ""
    return (
        Segment(master_start, mid_master, slave_start, mid_slave, p1.law, prefix + p1.law.name),
        Segment(mid_master, master_start + span, mid_slave, slave_start + stroke, p2.law, prefix + p2.law.name),
    )


def modified_sine_cam(stroke: float, period: float = 360.0, **kwargs) -> CamProfile:
    """The mechatronics seed's cam (eqs 3.140-3.145): a modified-sine rise over half the period
    and its mirror image, ``Cam(theta) = Cam(2 rise - theta)``, as the return."""
    half = period / 2
    law = _law("modified_sine")
    segments = (
        Segment(0.0, half, 0.0, stroke, law, "rise"),
        Segment(half, period, stroke, 0.0, law, "return"),
    )
    return CamProfile(segments, period, True, **kwargs)


def dwell_rise_return_dwell(
    *, stroke, dwell_before, rise, ret, dwell_after, rise_law="cycloidal", return_law=None, **kwargs
) -> CamProfile:
    """A DRRD cam from spans (master units) and one law for the rise and one for the return."""
    return_law = return_law or rise_law
    x = 0.0
    segments = []
    if dwell_before > 0:
        segments.append(dwell(0.0, dwell_before, 0.0))
        x = dwell_before
    segments.append(Segment(x, x + rise, 0.0, stroke, _as_law(rise_law), "rise"))
    x += rise
    segments.append(Segment(x, x + ret, stroke, 0.0, _as_law(return_law), "return"))
    x += ret
    if dwell_after > 0:
        segments.append(dwell(x, x + dwell_after, 0.0))
        x += dwell_after
    return CamProfile(tuple(segments), x, True, **kwargs)


def smallest_peak_law(order: int = 2, candidates=None) -> Law:
    """The rest-to-rest law with the smallest characteristic value of ``order`` (1 Cv, 2 Ca,
    3 Cj), among ``candidates`` (default: every law that starts and ends at rest)."""
    pool = [_as_law(c) for c in candidates] if candidates else [
        law for law in LAWS.values() if law.rest_start and law.rest_end
    ]
    return min(pool, key=lambda law: (law.characteristic(order), law.name))


def _as_law(value) -> Law:
    return value if isinstance(value, Law) else _law(value)


def _finite_peak(law: Law) -> float:
    peak = law.characteristic(2)
    if not math.isfinite(peak):
        raise InputError(f"law {law.name!r} has an unbounded peak acceleration; a combination needs a finite one")
    return peak
