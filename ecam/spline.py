"""Spline segments: a piecewise quintic written out knot by knot, the law of ``law = "spline"``.

A spline segment (what :func:`ecam.fit_points` makes from a point table, or anyone writes by hand)
is given by its knots and, at each knot but the last, the slave's position and its first five
derivatives there (from the right), in user units::

    knots       = [0.0, k1, k2, ..., span]          master units from the segment's start
    derivatives = [[y, v, a, j, s, c], ...]         one row per knot interval

``y`` is the slave position from the segment's start (0 in the first row), ``v`` ... ``c`` are
d^k y/dx^k for k = 1..5 (slave units per master unit^k). On interval i the slave follows the
Taylor polynomial of row i, ``y_i + v_i t + a_i t^2/2 + j_i t^3/6 + s_i t^4/24 + c_i t^5/120``
with ``t = x - knots[i]``: a polynomial of degree 5 per interval, exactly what the numbers say.
Nothing makes the rows agree at the knots: :meth:`ecam.CamProfile.check` reports every jump of
position, velocity, acceleration and jerk between them as it does at any joint, so a fitted
spline (C4 by construction) checks clean and a hand-edited one shows where it breaks.

The segment's law (:class:`SplineLaw`) holds these numbers as given, so that
:meth:`ecam.CamProfile.to_toml` writes them back unchanged, and the same polynomials in the
normalized form every law has: ``u = t / span`` in [0, 1] and the slave in units of the spline's
``amplitude`` (its largest position from the start), not of its stroke -- a periodic fit ends
where it starts, with a stroke of 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .laws import Law, LawTable, Piece

__all__ = ["SplineLaw", "spline_law", "MAX_SPLINE_PIECES", "SPLINE_DEGREE"]

SPLINE_DEGREE = 5
# Knot intervals of one spline segment. A fit uses at most a few thousand; each interval is a
# row of six numbers in the cam file (about 150 bytes), and cam files are at most 4 MiB.
MAX_SPLINE_PIECES = 20_000


@dataclass(frozen=True)
class SplineLaw(Law):
    """The law of a spline segment: pieces of degree 5 between knots (see the module docstring).

    ``s(u) = (y - y_start) / amplitude`` with ``u = (x - x_start) / span``; ``s(1)`` is the end
    position over the amplitude, not 1. Build it with :func:`spline_law`.
    """

    knots: tuple = ()
    derivatives: tuple = ()
    amplitude: float = 1.0
    _table: object = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "_table", LawTable([self]))

    def __call__(self, u, order: int = 0, side: str = "right"):
        """As :meth:`Law.__call__`, by bisection among the knots (a spline has thousands)."""
        order = validate.integer("order", int(order) if isinstance(order, np.integer) else order, minimum=0)
        validate.choice("side", side, ("right", "left"))
        scalar = np.ndim(u) == 0
        u = np.atleast_1d(np.asarray(u, dtype=float))
        out = self._table(np.zeros(u.shape, dtype=np.int64), u, order, side == "left")
        return float(out[0]) if scalar else out

    @property
    def span(self) -> float:
        """Master length (the last knot)."""
        return self.knots[-1]

    def local_scale(self, order: int) -> float:
        """The largest |d^order y/dx^order| the rows give at the knots (user units; for orders
        above 5, the 5th over the shortest interval to the power of the difference): what the
        spline can produce, the scale a jump at its knots is told from float noise by."""
        if order <= SPLINE_DEGREE:
            return max(abs(row[order]) for row in self.derivatives) or self.amplitude / self.span**order
        shortest = min(b - a for a, b in zip(self.knots, self.knots[1:]))
        return self.local_scale(SPLINE_DEGREE) / shortest ** (order - SPLINE_DEGREE)

    @property
    def end_position(self) -> float:
        """Slave position at the end, from the segment's start (the last piece at its end)."""
        return float(self._table(np.zeros(1, dtype=np.int64), np.ones(1), 0, True)[0]) * self.amplitude


def spline_law(knots, derivatives, name: str = "spline") -> SplineLaw:
    """A :class:`SplineLaw` from knots and per-interval derivatives (module docstring).

    Parameters
    ----------
    knots : sequence of float
        Master positions from the segment's start: 0 first, strictly increasing; ``m + 1`` of
        them for ``m`` intervals, 1 <= m <= ``MAX_SPLINE_PIECES``.
    derivatives : sequence of sequence of float
        ``m`` rows of 6 numbers: position from the segment's start (0 in the first row) and
        d^k y/dx^k, k = 1..5, at the row's knot (user units).

    Raises
    ------
    InputError
        ``knots: ... should be ...`` / ``derivatives[i]: ... should be ...``.
    """
    knots = _numbers("knots", knots)
    if not 2 <= len(knots) <= MAX_SPLINE_PIECES + 1:
        raise validate.fail("knots", len(knots), f"2 to {MAX_SPLINE_PIECES + 1} knots (a count)")
    if knots[0] != 0.0:
        raise validate.fail("knots[0]", knots[0], "0 (knots are master positions from the segment's start)")
    for i in range(1, len(knots)):
        if not knots[i] > knots[i - 1]:
            raise validate.fail(f"knots[{i}]", knots[i], f"greater than knots[{i - 1}] ({knots[i - 1]!r})")
    if isinstance(derivatives, (str, bytes)) or not hasattr(derivatives, "__len__"):
        raise validate.fail("derivatives", derivatives, "a list of rows of 6 numbers")
    if len(derivatives) != len(knots) - 1:
        raise validate.fail("derivatives", f"{len(derivatives)} rows",
                            f"{len(knots) - 1} rows, one per knot interval")
    rows = tuple(_numbers(f"derivatives[{i}]", row) for i, row in enumerate(derivatives))
    for i, row in enumerate(rows):
        if len(row) != SPLINE_DEGREE + 1:
            raise validate.fail(f"derivatives[{i}]", list(row), "6 numbers: position, velocity, acceleration, "
                                "jerk, snap, crackle")
    if rows[0][0] != 0.0:
        raise validate.fail("derivatives[0][0]", rows[0][0], "0 (positions are from the segment's start)")
    span = knots[-1]
    if not math.isfinite(span) or span <= 0:
        raise validate.fail("knots[-1]", span, "a finite span > 0")
    # the unit of s: the largest position, or of what the derivatives add over the span
    amplitude = max(abs(row[0]) for row in rows)
    if amplitude == 0.0:
        amplitude = max((abs(row[k]) * span**k / math.factorial(k) for row in rows for k in range(1, 6)),
                        default=0.0)
    if not (math.isfinite(amplitude) and amplitude < validate.MAX_MAGNITUDE):
        raise validate.fail("derivatives", "a value", f"such that every |value * span^k / k!| stays below "
                            f"{validate.MAX_MAGNITUDE:g} (span {validate.show(span)})")
    amplitude = amplitude or 1.0
    pieces = []
    for i, row in enumerate(rows):
        start, end = knots[i] / span, knots[i + 1] / span
        if i == len(rows) - 1:
            end = 1.0
        poly = tuple(row[k] * span**k / math.factorial(k) / amplitude for k in range(SPLINE_DEGREE + 1))
        pieces.append(Piece(0.0 if i == 0 else start, end, poly))
    for i in range(1, len(pieces)):
        if not pieces[i].start > pieces[i - 1].start:
            raise validate.fail(f"knots[{i}]", knots[i], "far enough from its neighbours to stay apart once "
                                "divided by the span")
    return SplineLaw(name, tuple(pieces), False, False, "piecewise quintic through given knots",
                     knots=tuple(knots), derivatives=rows, amplitude=amplitude)


def _numbers(field: str, values) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
        raise validate.fail(field, values, "a list of numbers")
    out = []
    for i, value in enumerate(values):
        value = value.item() if isinstance(value, np.generic) else value
        out.append(float(validate.number(f"{field}[{i}]", value)))
    return tuple(out)
