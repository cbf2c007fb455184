"""Design helpers: combination curves, the modified-sine cam, dwell-rise-return-dwell cams.

Inputs are checked with :mod:`ecam.validate` where they enter; what a segment or a profile
checks itself (spans, slave positions, the chain) is left to :mod:`ecam.profile`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .laws import LAWS, Law, law as _law
from .profile import CamProfile, Segment, check_span

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

    Parameters
    ----------
    first, second : Law or str
        The two laws, e.g. ``"half_cycloid_start"`` then ``"half_harmonic_end"``.
    span : float
        Master span of the whole rise, > 0.
    stroke : float
        Slave stroke of the whole rise, non-zero.
    accel_ratio : float
        Peak |acceleration| of the first piece over that of the second, 1e-6..1e6.

    Returns
    -------
    tuple of CombinationPiece
        (first, second), with spans and strokes in the units of ``span`` and ``stroke``.

    Raises
    ------
    InputError
        ``<field>: <value> should be <expected>`` for a bad argument, or laws that do not meet
        at a non-zero velocity or have an unbounded peak acceleration.
    """
    first, second = _law(first), _law(second)
    span = validate.positive("span", span)
    stroke = validate.number("stroke", stroke)
    if stroke == 0:
        raise validate.fail("stroke", stroke, "non-zero for a combination")
    accel_ratio = validate.number("accel_ratio", accel_ratio, minimum=1e-6, maximum=1e6)
    v1, v2 = first(1.0, 1), second(0.0, 1)
    a1, a2 = _finite_peak(first), _finite_peak(second)
    if v1 <= 0 or v2 <= 0:
        raise validate.fail("laws", (first.name, second.name),
                            f"a pair that meets at a non-zero velocity (end velocity {v1:g}, start velocity {v2:g})")
    x = v2 * a1 / (v1 * accel_ratio * a2)
    k = (v2 / v1) * x
    b1 = span * x / (1 + x)
    h1 = stroke * k / (1 + k)
    return CombinationPiece(first, b1, h1), CombinationPiece(second, span - b1, stroke - h1)


def combination_segments(
    first, second, *, master_start, span, slave_start, stroke, accel_ratio, name=""
) -> tuple[Segment, Segment]:
    """The two segments of :func:`combination`, placed at ``master_start``/``slave_start``
    and named ``"<name> <law>"``."""
    master_start = validate.number("master_start", master_start)
    slave_start = validate.number("slave_start", slave_start)
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
    and its mirror image, ``Cam(theta) = Cam(2 rise - theta)``, as the return.

    ``stroke`` in slave units, ``period`` in master units; ``kwargs`` go to :class:`CamProfile`
    (name, units, table).
    """
    period = validate.positive("period", period)
    stroke = validate.number("stroke", stroke)
    return CamProfile.from_segments(
        [Segment.from_span(period / 2, stroke, "modified_sine", "rise"),
         Segment.from_span(period / 2, -stroke, "modified_sine", "return")],
        period, **kwargs)


def dwell_rise_return_dwell(
    *, stroke, dwell_before, rise, ret, dwell_after, rise_law="cycloidal", return_law=None, **kwargs
) -> CamProfile:
    """A DRRD cam from spans (master units) and one law for the rise and one for the return.

    A dwell of span 0 is left out; ``kwargs`` go to :class:`CamProfile` (name, units, table).
    """
    return_law = rise_law if return_law is None else return_law
    stroke = validate.number("stroke", stroke)
    rise, ret = check_span(rise, field="rise"), check_span(ret, field="ret")
    dwell_before = validate.number("dwell_before", dwell_before, minimum=0.0)
    dwell_after = validate.number("dwell_after", dwell_after, minimum=0.0)
    segments = [Segment.from_span(dwell_before, name="dwell")] if dwell_before > 0 else []
    segments += [Segment.from_span(rise, stroke, rise_law, "rise"),
                 Segment.from_span(ret, -stroke, return_law, "return")]
    if dwell_after > 0:
        segments.append(Segment.from_span(dwell_after, name="dwell"))
    return CamProfile.from_segments(segments, **kwargs)


def smallest_peak_law(order: int = 2, candidates=None) -> Law:
    """The rest-to-rest law with the smallest characteristic value of ``order`` (1 Cv, 2 Ca,
    3 Cj), among ``candidates`` (laws or names; default: every law of :data:`~ecam.laws.LAWS`
    that starts and ends at rest)."""
    order = validate.integer("order", order, minimum=1)
    pool = [_law(c) for c in candidates] if candidates else [
        law for law in LAWS.values() if law.rest_start and law.rest_end
    ]
    return min(pool, key=lambda law: (law.characteristic(order), law.name))


def _finite_peak(law: Law) -> float:
    peak = law.characteristic(2)
    if not math.isfinite(peak):
        raise validate.fail("law", law.name, "a law with a bounded peak acceleration, for a combination")
    return peak
