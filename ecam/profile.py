"""Cam profiles: segments of motion laws over one master period, in user units.

Every rule a cam must obey is checked here, once, where the Python API builds it: a
:class:`Segment` checks its own numbers, law and span, a :class:`CamProfile` the chain (no gap,
no overlap, spans against the period). The cam-file reader (:mod:`ecam.camfile`) maps its
fields onto these and renames the fields in the messages.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .errors import InputError
from .laws import DWELL, LAWS, SIDES, Law, LawTable, law as _law, polynomial_from_boundary
from .spline import SplineLaw
from .tappet import TappetTrack

__all__ = ["Segment", "CamProfile", "Discontinuity", "CheckReport", "ORDER_NAMES", "MAX_SEGMENTS", "check_span",
           "check_master_period", "check_segment_count"]

ORDER_NAMES = ("position", "velocity", "acceleration", "jerk")
MIN_PERIOD, MAX_PERIOD = 1e-9, 1e12  # master units
MIN_SPAN_FRACTION = 1e-9  # of the master period; 1e-6 (a hard case) is well inside
MAX_SLAVE = 1e15  # slave units
# Segments of one cam. Evaluation is linear in them (binary search, every law's pieces stacked),
# but each segment is a Python object built and checked on its own: 100 000 take seconds to
# read and check and tens of seconds to compile. Far beyond a drawn cam (a few to a few hundred).
MAX_SEGMENTS = 100_000
# Boundary conditions of a polynomial segment, in the order they are solved for (user units:
# slave units per master unit^k); the names are the cam file's and Segment.polynomial's.
BOUNDARY_KEYS = ("velocity", "acceleration", "jerk")


def check_master_period(value, field: str = "master_period") -> float:
    """A master period: a number in ``MIN_PERIOD..MAX_PERIOD`` (master units)."""
    return validate.number(field, _plain(value), minimum=MIN_PERIOD, maximum=MAX_PERIOD)


def check_span(span, master_period: float | None = None, field: str = "span") -> float:
    """A segment's span: > 0 and, when the period is known, at least ``MIN_SPAN_FRACTION`` of it
    (derivatives up to the 7th divide by span**7: keep that far from under- and overflow).

    The one rule for spans: :class:`Segment` and :class:`CamProfile` use it, and so does the cam
    file reader on the span as written, before a span too small to move its start position is
    lost in rounding.
    """
    span = validate.positive(field, _plain(span))
    # A span written at the limit is recomputed from its end positions (end - start) with a
    # rounding error of up to an ulp of the period: 1e-6 of the limit absorbs that.
    if master_period is not None and span < MIN_SPAN_FRACTION * master_period * (1 - 1e-6):
        raise validate.fail(field, span, f">= {MIN_SPAN_FRACTION:g} of master_period "
                            f"({MIN_SPAN_FRACTION * master_period:g})")
    return span


def check_tiling(placements, master_period: float) -> None:
    """Segments placed at ``[(master_start, master_end), ...]`` tile ``0..master_period``: each
    starts where the one before ends, spans at least the least span (:func:`check_span`), and the
    last ends at the period. The one rule for placement: :class:`CamProfile` uses it, and so does
    the cam file reader before it solves a polynomial's ``match`` from a neighbour (a neighbour
    that runs far past the period has derivatives that overflow)."""
    position = 0.0
    for i, (start, end) in enumerate(placements):
        if not math.isclose(start, position, rel_tol=0, abs_tol=1e-9 * master_period):
            kind = "a gap" if start > position else "an overlap"
            where = f"where segment[{i - 1}] ends" if i else "the start of the period"
            raise validate.fail(f"segment[{i}].master_start", start,
                                f"{validate.show(position)}, {where} (it leaves {kind})")
        check_span(end - start, master_period, f"segment[{i}].span")
        position = end
    if not math.isclose(position, master_period, rel_tol=1e-12):
        kind = "a gap" if position < master_period else "an overlap"
        raise validate.fail(f"segment[{len(placements) - 1}].master_end", position,
                            f"{validate.show(master_period)}, the master_period (it leaves {kind})")


def check_segment_count(count: int, field: str = "segments") -> int:
    """A number of segments: at most ``MAX_SEGMENTS``."""
    if count > MAX_SEGMENTS:
        raise validate.fail(field, count, f"at most {MAX_SEGMENTS} segments")
    return count


def _plain(value):
    """A numpy scalar as the Python number it holds (validate checks Python types)."""
    return value.item() if isinstance(value, np.generic) else value


@dataclass(frozen=True)
class Segment:
    """A law scaled to a master span and a slave stroke.

    ``y(x) = slave_start + (slave_end - slave_start) * law((x - master_start) / span)``.
    A dwell is a segment with zero stroke (law ``"dwell"``, or any law).

    Parameters
    ----------
    master_start, master_end : float
        Where the segment starts and ends, in master units; ``master_end > master_start``.
    slave_start, slave_end : float
        Slave position at the start and at the end, in slave units, within +-1e15.
    law : Law or str
        The normalized law, or its name (``"dwell"`` included, see :func:`ecam.law`). A dwell
        must have ``slave_end == slave_start``.
    name : str
        For reports and plots; the law's name when empty.
    boundary : tuple, optional
        Set by :meth:`polynomial`: the boundary conditions, in user units, the polynomial law
        was solved from, ``((start velocity, acceleration[, jerk]), (end ...))``; kept so that
        :meth:`CamProfile.to_toml` writes the segment back exactly. None for other laws.

    Raises
    ------
    InputError
        A field is not a finite number, the span is not > 0, the law is unknown, or a dwell
        has a stroke: ``<field>: <value> should be <expected>``.

    See Also
    --------
    from_span : a segment from its span and stroke, for :meth:`CamProfile.from_segments`.
    polynomial : a 5th/7th-order segment from boundary conditions (VDI 2143).
    """

    master_start: float
    master_end: float
    slave_start: float
    slave_end: float
    law: Law
    name: str = ""
    boundary: tuple | None = None

    def __post_init__(self):
        for name in ("master_start", "master_end"):
            object.__setattr__(self, name, validate.number(name, _plain(getattr(self, name))))
        for name in ("slave_start", "slave_end"):
            object.__setattr__(self, name, validate.number(name, _plain(getattr(self, name)),
                                                           minimum=-MAX_SLAVE, maximum=MAX_SLAVE))
        check_span(self.span)
        object.__setattr__(self, "law", _law(self.law))
        validate.text("name", self.name)
        if self.law == DWELL and self.stroke != 0:
            raise validate.fail("stroke", self.stroke, "0 for a dwell (or give a law that moves)")
        if self.boundary is not None:
            self._check_boundary()
        if isinstance(self.law, SplineLaw):
            self._check_spline()

    def _check_spline(self):
        """A spline segment spans its knots and ends where its last piece does."""
        law_ = self.law
        if not math.isclose(self.span, law_.span, rel_tol=1e-12):
            raise validate.fail("master_end", self.master_end, f"master_start + {law_.span!r}, the spline's last knot")
        end = law_.end_position
        if abs(self.stroke - end) > 1e-12 * max(abs(self.slave_start), abs(self.slave_end), law_.amplitude):
            raise validate.fail("slave_end", self.slave_end, f"slave_start + {end!r}, where the spline ends")

    def _check_boundary(self):
        shape = "((start velocity, acceleration[, jerk]), (end velocity, acceleration[, jerk]))"
        boundary = self.boundary
        if not (isinstance(boundary, tuple) and len(boundary) == 2
                and all(isinstance(side, tuple) and len(side) in (2, 3) for side in boundary)
                and len(boundary[0]) == len(boundary[1])):
            raise validate.fail("boundary", boundary, shape)
        for end, values in zip(("start", "end"), boundary):
            for key, value in zip(BOUNDARY_KEYS, values):
                validate.number(f"{end}_{key}", value)
        expected = f"poly{2 * len(boundary[0]) + 1}"
        if self.law.name != expected:
            raise validate.fail("law", self.law.name, f"{expected!r}, the polynomial solved from boundary")

    @classmethod
    def from_span(cls, span, stroke=0.0, law="dwell", name: str = "", *, master_start=0.0,
                  slave_start=0.0) -> "Segment":
        """A segment given by its span and stroke rather than by its end positions.

        Parameters
        ----------
        span : float
            Master span, > 0 (master units).
        stroke : float
            Slave stroke (slave units); negative for a return, 0 for a dwell.
        law : Law or str
            The law, or its name; the default, ``"dwell"``, holds the slave (stroke 0).
        name : str
            For reports and plots.
        master_start, slave_start : float
            Where it starts. :meth:`CamProfile.from_segments` places segments one after
            another, so the defaults (0) serve there.

        Returns
        -------
        Segment
            ``Segment(master_start, master_start + span, slave_start, slave_start + stroke, ...)``.

        Examples
        --------
        >>> rise = Segment.from_span(180.0, 50.0, "modified_sine", "rise")
        >>> (rise.master_end, rise.slave_end)
        (180.0, 50.0)
        """
        span = check_span(span)
        stroke = validate.number("stroke", _plain(stroke))
        master_start = validate.number("master_start", _plain(master_start))
        slave_start = validate.number("slave_start", _plain(slave_start))
        return cls(master_start, master_start + span, slave_start, slave_start + stroke, law, name)

    @classmethod
    def polynomial(cls, master_start, master_end, slave_start, slave_end, *, degree: int | None = None,
                   start_velocity=0.0, start_acceleration=0.0, start_jerk=None,
                   end_velocity=0.0, end_acceleration=0.0, end_jerk=None, name: str = "") -> "Segment":
        """A 5th- or 7th-order polynomial segment solved from its boundary conditions (VDI 2143
        motion-to-motion transitions), in user units.

        Parameters
        ----------
        master_start, master_end, slave_start, slave_end : float
            As for :class:`Segment`; the stroke must not be 0.
        degree : {5, 7}, optional
            5 matches velocity and acceleration at both ends, 7 jerk as well. Default: 7 when a
            jerk is given, else 5.
        start_velocity, end_velocity : float
            Slave units per master unit.
        start_acceleration, end_acceleration : float
            Slave units per master unit^2.
        start_jerk, end_jerk : float, optional
            Slave units per master unit^3; degree 7 only (default 0 there).
        name : str

        Returns
        -------
        Segment
            Its law is named ``"poly5"`` or ``"poly7"``; ``boundary`` keeps the conditions.

        Raises
        ------
        InputError
            A zero stroke, a jerk for degree 5, or a condition that is not finite once
            normalized (``value * span**k / stroke``).
        """
        jerks = (start_jerk, end_jerk)
        if degree is None:
            degree = 5 if jerks == (None, None) else 7
        if isinstance(degree, bool) or _plain(degree) not in (5, 7):
            raise validate.fail("degree", degree, "5 or 7")
        if degree == 5:
            for end, jerk in zip(("start", "end"), jerks):
                if jerk is not None:
                    raise validate.fail(f"{end}_jerk", jerk, "absent for a 5th-order polynomial (poly5); "
                                        "use degree 7 (poly7)")
        count = 2 if degree == 5 else 3
        given = {"start": (start_velocity, start_acceleration, start_jerk),
                 "end": (end_velocity, end_acceleration, end_jerk)}
        boundary = tuple(
            tuple(validate.number(f"{end}_{key}", 0.0 if value is None else _plain(value))
                  for key, value in zip(BOUNDARY_KEYS[:count], given[end]))
            for end in ("start", "end"))
        # The positions and the name, checked as for any segment (constant velocity takes any
        # stroke); the law is solved from them.
        shape = cls(master_start, master_end, slave_start, slave_end, LAWS["constant_velocity"], name)
        span, stroke = shape.span, shape.stroke
        if stroke == 0:
            raise validate.fail("stroke", stroke, f"non-zero for a polynomial segment (poly{degree})")
        normalized = []
        for end, values in zip(("start", "end"), boundary):
            side = []
            for order, (key, value) in enumerate(zip(BOUNDARY_KEYS, values), start=1):
                # user units -> normalized: d^k s/du^k = (d^k y/dx^k) * span^k / stroke
                try:
                    normal = value * span**order / stroke
                except OverflowError:
                    normal = math.inf
                if not (math.isfinite(normal) and abs(normal) <= validate.MAX_MAGNITUDE):
                    raise validate.fail(f"{end}_{key}", value,
                                        f"finite and at most {validate.MAX_MAGNITUDE:g} once normalized "
                                        f"(value * span^{order} / stroke; span {validate.show(span)}, "
                                        f"stroke {validate.show(stroke)})")
                side.append(normal)
            normalized.append(side)
        solved = polynomial_from_boundary(normalized[0], normalized[1], name=f"poly{degree}")
        return replace(shape, law=solved, boundary=boundary)

    def placed_at(self, master_start: float, slave_start: float) -> "Segment":
        """The same span, stroke, law and name, starting at ``master_start``/``slave_start``."""
        master_end, slave_end = master_start + self.span, slave_start + self.stroke
        if self.boundary is None:
            return replace(self, master_start=master_start, master_end=master_end, slave_start=slave_start,
                           slave_end=slave_end)
        conditions = {f"{end}_{key}": value for end, values in zip(("start", "end"), self.boundary)
                      for key, value in zip(BOUNDARY_KEYS, values)}
        return Segment.polynomial(master_start, master_end, slave_start, slave_end, name=self.name,
                                  degree=2 * len(self.boundary[0]) + 1, **conditions)

    @property
    def span(self) -> float:
        """Master length of the segment (end - start)."""
        return self.master_end - self.master_start

    @property
    def stroke(self) -> float:
        """Slave change over the segment (end - start), negative for a return."""
        return self.slave_end - self.slave_start

    @property
    def scale(self) -> float:
        """Slave units per unit of the law's s: the stroke, or a spline's amplitude (a spline may
        end where it starts)."""
        return self.law.amplitude if isinstance(self.law, SplineLaw) else self.stroke

    def evaluate(self, x: np.ndarray, order: int, side: str = "right") -> np.ndarray:
        u = np.clip((x - self.master_start) / self.span, 0.0, 1.0)
        for b in self.law.breaks:  # a break recomputed from a master position may miss by an ulp
            u = np.where(np.abs(u - b) < 1e-12, b, u)
        values = self.scale / self.span**order * self.law(u, order, side=side)
        if order == 0:
            values = values + self.slave_start
        return values

    def at(self, u: float, order: int) -> float:
        """Value of derivative ``order`` at normalized position u (0 = start, 1 = end)."""
        x = self.master_start + u * self.span
        side = "left" if u >= 1.0 else "right"
        return float(self.evaluate(np.array([x]), order, side)[0])

    @property
    def label(self) -> str:
        return self.name or self.law.name


@dataclass(frozen=True)
class Discontinuity:
    """A jump of one derivative at one master position."""

    master: float
    order: int
    left: float
    right: float
    where: str

    @property
    def jump(self) -> float:
        """right - left, in slave units per master unit^order."""
        return self.right - self.left

    @property
    def severity(self) -> str:
        """``"error"`` for position, velocity and acceleration, ``"warning"`` for jerk and up."""
        return "warning" if self.order >= 3 else "error"

    def to_dict(self) -> dict:
        """The JSON object of ``ecam check --json``: master, order, quantity, left, right, jump,
        where, severity."""
        return {
            "master": self.master,
            "order": self.order,
            "quantity": ORDER_NAMES[self.order],
            "left": self.left,
            "right": self.right,
            "jump": self.jump,
            "where": self.where,
            "severity": self.severity,
        }


@dataclass(frozen=True)
class CheckReport:
    """Every discontinuity of a profile: position, velocity, acceleration (errors), jerk (warnings)."""

    discontinuities: tuple[Discontinuity, ...]

    @property
    def errors(self) -> tuple[Discontinuity, ...]:
        """The position, velocity and acceleration jumps: what makes a cam unusable."""
        return tuple(d for d in self.discontinuities if d.severity == "error")

    @property
    def warnings(self) -> tuple[Discontinuity, ...]:
        """The jerk jumps: allowed, but they excite the mechanics."""
        return tuple(d for d in self.discontinuities if d.severity == "warning")

    @property
    def ok(self) -> bool:
        """True when there are no errors (warnings allowed)."""
        return not self.errors

    def continuous(self, order: int) -> bool:
        """True when no derivative up to ``order`` jumps anywhere."""
        return all(d.order > order for d in self.discontinuities)

    def at(self, master: float, order: int | None = None) -> tuple[Discontinuity, ...]:
        """The discontinuities at ``master`` (within 1e-9), of one derivative ``order`` if given."""
        return tuple(
            d
            for d in self.discontinuities
            if math.isclose(d.master, master, abs_tol=1e-9) and (order is None or d.order == order)
        )


@dataclass(frozen=True)
class CamProfile:
    """A cam: segments over one master period, evaluated with ``profile(master, order)``.

    Parameters
    ----------
    segments : sequence of Segment
        Contiguous segments from master 0 to ``master_period`` (kept as a tuple). To give spans
        and strokes instead of positions, see :meth:`from_segments`.
    master_period : float
        Length of one cycle in master units (e.g. 360 degrees), 1e-9..1e12.
    periodic : bool
        Whether the cam repeats: master positions wrap modulo the period. A non-periodic cam is
        defined on [0, master_period] only.
    name, master_unit, slave_unit : str
        For reports and plots.
    table : dict
        Default table format for the compiler (interp, points or tolerance and
        interpolation_tolerance, master_counts, slave_counts_per_unit), from the cam file's
        ``[table]`` section.
    net_stroke : float, optional
        For a periodic cam whose slave advances every period (a rotary knife's drum turns 360
        degrees per cut, an indexing table one station): that advance, in slave units. It must
        equal what the segments add up to (the last segment's end minus the first one's start),
        so a stroke entered wrong still shows as an error instead of being taken for the net
        stroke. The cam is then unrolled: ``profile(x + k * master_period) = profile(x) + k *
        net_stroke``, and the seam is checked like any joint, the position continuing by the
        net stroke. None (the default): the slave returns to its start every period, and a
        position step at the seam is a jump that :meth:`check` reports.
    tappets : sequence of TappetTrack
        Digital cam switches on the master position (:mod:`ecam.tappet`), each within the
        master period; the cam file's ``[[tappet]]`` tables. Kept as a tuple.

    Raises
    ------
    InputError
        ``<field>: <value> should be <expected>``: a segment that does not start where the one
        before it ends (``segment[2].master_start: 170 should be 180, where segment[1] ends (it
        leaves an overlap)``), a span below 1e-9 of the period, segments that do not end at the
        period, a net stroke that the segments do not add up to, or a field of the wrong type.

    See Also
    --------
    ecam.load_cam, ecam.parse_cam : a profile from a cam file; :meth:`to_toml` writes one.
    """

    segments: tuple[Segment, ...]
    master_period: float
    periodic: bool = True
    name: str = ""
    master_unit: str = "deg"
    slave_unit: str = "mm"
    table: dict = field(default_factory=dict)
    net_stroke: float | None = None
    tappets: tuple = ()

    def __post_init__(self):
        segments = self.segments
        if isinstance(segments, (str, bytes, Mapping)) or not hasattr(segments, "__iter__"):
            raise validate.fail("segments", segments, "a sequence of Segment")
        segments = tuple(segments)
        if not segments:
            raise validate.fail("segments", segments, "at least one Segment")
        check_segment_count(len(segments))
        for i, seg in enumerate(segments):
            if not isinstance(seg, Segment):
                raise validate.fail(f"segment[{i}]", seg, "a Segment")
        object.__setattr__(self, "segments", segments)
        period = check_master_period(self.master_period)
        object.__setattr__(self, "master_period", period)
        validate.boolean("periodic", self.periodic)
        validate.text("name", self.name)
        for unit in ("master_unit", "slave_unit"):  # written into exports, plots and messages
            validate.text(unit, getattr(self, unit), maximum=validate.MAX_UNIT_CHARS)
        if not isinstance(self.table, Mapping):
            raise validate.fail("table", self.table, "a mapping of table settings (interp, points, ...)")
        object.__setattr__(self, "table", dict(self.table))
        check_tiling([(seg.master_start, seg.master_end) for seg in segments], period)
        object.__setattr__(self, "_starts", np.array([s.master_start for s in segments]))
        self._check_net_stroke()
        self._check_tappets()

    def _check_tappets(self):
        """Each tappet a TappetTrack within the master period."""
        tappets = self.tappets
        if isinstance(tappets, (str, bytes, Mapping)) or not hasattr(tappets, "__iter__"):
            raise validate.fail("tappets", tappets, "a sequence of TappetTrack")
        tappets = tuple(tappets)
        for i, track in enumerate(tappets):
            if not isinstance(track, TappetTrack):
                raise validate.fail(f"tappet[{i}]", track, "a TappetTrack")
            try:
                track.within(self.master_period)
            except InputError as exc:
                raise validate.renamed(exc, lambda f: f"tappet[{i}].{f}") from None
        object.__setattr__(self, "tappets", tappets)

    def _check_net_stroke(self):
        """The declared net stroke: a periodic cam's only, and what its segments add up to
        (the same 1e-12 relative allowance as a position jump, so float sums of decimal strokes
        pass and any stroke entered wrong does not)."""
        if self.net_stroke is None:
            return
        net = validate.number("net_stroke", _plain(self.net_stroke), minimum=-2 * MAX_SLAVE, maximum=2 * MAX_SLAVE)
        object.__setattr__(self, "net_stroke", net)
        if not self.periodic:
            raise validate.fail("net_stroke", net, "absent for a cam that is not periodic (it does not repeat, "
                                "so it has no advance per period)")
        first, last = self.segments[0], self.segments[-1]
        advance = self.advance
        scale = max(abs(first.slave_start), abs(last.slave_end), abs(net),
                    max(abs(seg.stroke) for seg in self.segments))
        if abs(advance - net) > 1e-12 * scale:
            raise validate.fail("net_stroke", net, f"{advance:+.12g}, what the segments add up to (the slave starts "
                                f"the period at {validate.show(first.slave_start)} and ends it at "
                                f"{validate.show(last.slave_end)}): correct a stroke or the net stroke")

    @property
    def advance(self) -> float:
        """How far the slave ends each period from where it starts it: the last segment's end
        minus the first one's start (slave units). A periodic cam that declares no
        :attr:`net_stroke` should have 0 here, else :meth:`check` reports a jump at the seam."""
        return self.segments[-1].slave_end - self.segments[0].slave_start

    @classmethod
    def from_segments(cls, segments, master_period=None, *, start=0.0, periodic: bool = True, name: str = "",
                      master_unit: str = "deg", slave_unit: str = "mm", table=None,
                      net_stroke=None) -> "CamProfile":
        """A profile from segments placed one after another, from master 0 and slave ``start``.

        Each segment keeps its span, stroke, law and name; where it was placed is ignored.
        A polynomial segment (:meth:`Segment.polynomial`) is solved again where it lands, so its
        boundary conditions hold in user units.

        Parameters
        ----------
        segments : sequence of Segment
            Typically :meth:`Segment.from_span` segments.
        master_period : float, optional
            Master units; default: the sum of the spans. When given, the spans must add up to it.
        start : float
            Slave position at master 0 (slave units).
        periodic, name, master_unit, slave_unit, table
            As for :class:`CamProfile`.
        net_stroke : float, optional
            The slave's advance per period, as for :class:`CamProfile`: it must equal the
            strokes added up.

        Examples
        --------
        >>> cam = CamProfile.from_segments([
        ...     Segment.from_span(60.0),                                   # dwell
        ...     Segment.from_span(120.0, 10.0, "modified_sine", "rise"),
        ...     Segment.from_span(60.0),
        ...     Segment.from_span(120.0, -10.0, "cycloidal", "return"),
        ... ])
        >>> cam.master_period, cam(180.0)
        (360.0, 10.0)

        A rotary knife: the drum turns once per cut, the cut synchronous at 1.2 deg/deg.

        >>> knife = CamProfile.from_segments([
        ...     Segment.from_span(30.0, 36.0, "constant_velocity", "cut"),
        ...     Segment.polynomial(0.0, 300.0, 0.0, 288.0, start_velocity=1.2, end_velocity=1.2,
        ...                        start_jerk=0.0, end_jerk=0.0, name="catch-up"),
        ...     Segment.from_span(30.0, 36.0, "constant_velocity", "cut"),
        ... ], slave_unit="deg", net_stroke=360.0)
        >>> knife(360.0 + 30.0), knife.check().ok
        (396.0, True)
        """
        if isinstance(segments, (str, bytes, Mapping)) or not hasattr(segments, "__iter__"):
            raise validate.fail("segments", segments, "a sequence of Segment")
        if hasattr(segments, "__len__"):
            check_segment_count(len(segments))  # before placing (solving) them one by one
        master = 0.0
        slave = validate.number("start", _plain(start))  # its range is the first segment's to check
        placed = []
        for i, seg in enumerate(segments):
            if not isinstance(seg, Segment):
                raise validate.fail(f"segment[{i}]", seg, "a Segment")
            try:
                placed.append(seg.placed_at(master, slave))
            except InputError as exc:
                raise validate.renamed(exc, lambda f: f"segment[{i}].{f}") from None
            master, slave = placed[-1].master_end, placed[-1].slave_end
        return cls(tuple(placed), master if master_period is None else master_period, periodic, name=name,
                   master_unit=master_unit, slave_unit=slave_unit, table={} if table is None else table,
                   net_stroke=net_stroke)

    def to_toml(self) -> str:
        """The profile as cam-file text (TOML), which :func:`ecam.load_cam` and
        :func:`ecam.parse_cam` read back to an equal profile.

        Every float is written with ``repr``, which reads back to the same float; a segment is
        written by ``span``/``stroke`` where adding them to its start gives its end exactly, else
        by ``end``/``to``, and ``start``/``from`` only where it does not begin where the one before
        it ended. A combination is written as its two solved segments; a polynomial segment as
        ``poly5``/``poly7`` with the boundary conditions it was solved from. The output depends
        on nothing but the profile.

        Returns
        -------
        str

        Raises
        ------
        InputError
            A segment's law has no name a cam file knows (a law built by hand, or
            :func:`~ecam.laws.polynomial_from_boundary` outside :meth:`Segment.polynomial`),
            or a name or table setting cannot be written as TOML.
        """
        lines = [f"name = {_toml_value('name', self.name)}",
                 f"master_unit = {_toml_value('master_unit', self.master_unit)}",
                 f"slave_unit = {_toml_value('slave_unit', self.slave_unit)}",
                 f"master_period = {_toml_value('master_period', self.master_period)}",
                 f"periodic = {_toml_value('periodic', self.periodic)}",
                 f"start = {_toml_value('start', self.segments[0].slave_start)}"]
        if self.net_stroke is not None:
            lines.append(f"net_stroke = {_toml_value('net_stroke', self.net_stroke)}")
        if self.table:
            lines += ["", "[table]"]
            for key in sorted(self.table):
                if not (isinstance(key, str) and key in TABLE_KEYS):
                    raise validate.fail("table", key, f"a table setting ({', '.join(TABLE_KEYS)})")
                value = self.table[key]
                if key == "slave_counts_per_unit" and isinstance(value, int) and not isinstance(value, bool):
                    value = float(value)  # read back as a float: write it as one, for the same text
                lines.append(f"{key} = {_toml_value(f'table.{key}', value)}")
        master, slave = 0.0, self.segments[0].slave_start
        for i, seg in enumerate(self.segments):
            lines += ["", "[[segment]]"]
            if seg.name:
                lines.append(f"name = {_toml_value(f'segment[{i}].name', seg.name)}")
            lines.append(f"law = {_toml_value(f'segment[{i}].law', _law_name(i, seg))}")
            if seg.master_start != master:
                lines.append(f"start = {seg.master_start!r}")
            spline = isinstance(seg.law, SplineLaw)  # its knots and rows give its span and stroke
            if spline:
                pass
            elif seg.master_start + seg.span == seg.master_end:
                lines.append(f"span = {seg.span!r}")
            else:
                lines.append(f"end = {seg.master_end!r}")
            if seg.slave_start != slave:
                lines.append(f"from = {seg.slave_start!r}")
            if spline:
                lines.append("knots = [" + ", ".join(repr(k) for k in seg.law.knots) + "]")
                lines.append("derivatives = [")
                lines += ["  [" + ", ".join(repr(v) for v in row) + "]," for row in seg.law.derivatives]
                lines.append("]")
            elif seg.law != DWELL:
                if seg.slave_start + seg.stroke == seg.slave_end:
                    lines.append(f"stroke = {seg.stroke!r}")
                else:
                    lines.append(f"to = {seg.slave_end!r}")
            for end, values in zip(("start", "end"), seg.boundary or ()):
                for key, value in zip(BOUNDARY_KEYS, values):
                    lines.append(f"{end}_{key} = {value!r}")
            master, slave = seg.master_end, seg.slave_end
        for i, track in enumerate(self.tappets):
            lines += ["", "[[tappet]]"]
            if track.name:
                lines.append(f"name = {_toml_value(f'tappet[{i}].name', track.name)}")
            lines += [f"on = {track.on!r}", f"off = {track.off!r}"]
            if track.direction != "both":
                lines.append(f"direction = {_toml_value(f'tappet[{i}].direction', track.direction)}")
            for key in ("hysteresis", "on_compensation", "off_compensation"):
                if getattr(track, key):
                    lines.append(f"{key} = {getattr(track, key)!r}")
        return "\n".join(lines) + "\n"

    # evaluation --------------------------------------------------------------------------
    def __call__(self, master, order: int = 0, side: str = "right"):
        """Slave position (order 0) or its derivative d^order y / dx^order, in user units.

        Parameters
        ----------
        master : array_like
            Master position(s) in master units, finite. Periodic cams wrap (the position
            continuing by the net stroke per period, when the cam declares one); a non-periodic
            cam raises :class:`~ecam.errors.InputError` outside [0, master_period].
        order : int
            0 position, 1 velocity (slave units per master unit), 2 acceleration, 3 jerk, ...
        side : {'right', 'left'}
            One-sided limit at a joint.
        """
        order = validate.integer("order", _plain(order), minimum=0)
        validate.choice("side", side, SIDES)
        scalar = np.ndim(master) == 0
        try:
            x = np.asarray(master, dtype=float)
        except (TypeError, ValueError):
            raise validate.fail("master", master, "a number or an array of numbers") from None
        if not np.all(np.isfinite(x)):
            raise validate.fail("master", float(x[~np.isfinite(x)].flat[0]), "finite")
        period = self.master_period
        turns = None
        if self.periodic:
            unrolled = order == 0 and bool(self.net_stroke)
            if unrolled:
                turns, x = np.divmod(x, period)
            else:
                x = np.mod(x, period)
            if side == "left":
                wrap = x == 0.0
                x = np.where(wrap, period, x)
                if unrolled:
                    turns = turns - wrap
        elif np.any((x < 0) | (x > period)):
            bad = x[(x < 0) | (x > period)].flat[0]
            raise validate.fail("master", float(bad), f"in [0, {validate.show(period)}], the range of a "
                                "non-periodic cam")
        x = self._snap_to_joints(x)
        # The segment by binary search, then every point at once (O(points log segments)).
        index = np.searchsorted(self._starts, x, side="right" if side == "right" else "left") - 1
        index = np.clip(index, 0, len(self.segments) - 1)
        out = self._arrays.evaluate(index, x, order, side == "left")
        if turns is not None:  # a net stroke per whole period passed
            out = out + turns * self.net_stroke
        return float(out) if scalar else out

    def _snap_to_joints(self, x: np.ndarray) -> np.ndarray:
        """A joint recomputed from counts (e.g. 6000 * 0.01) may miss by an ulp and pick the
        wrong side; move positions within rounding distance onto the joint."""
        if len(self.segments) == 1 or x.size == 0:
            return x
        joints = self._starts[1:]
        i = np.clip(np.searchsorted(joints, x), 1, len(joints)) - 1
        near = np.where(np.abs(joints[i] - x) <= np.abs(joints[np.minimum(i + 1, len(joints) - 1)] - x),
                        joints[i], joints[np.minimum(i + 1, len(joints) - 1)])
        return np.where(np.abs(near - x) <= 1e-12 * self.master_period, near, x)

    @functools.cached_property
    def _arrays(self) -> "_SegmentArrays":
        return _SegmentArrays(self.segments)

    def polyline(self, master, order: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Points that draw derivative ``order`` as one line without bridging a jump.

        Each segment is evaluated on the master positions of ``master`` that fall inside it, its
        own ends included (so a joint appears twice, once with each segment's value), and a NaN
        separates one segment's points from the next, which breaks a plotted line there. The
        cost is linear in the points plus the segments, for cams of many segments.

        Parameters
        ----------
        master : array_like
            Master positions (master units); sorted here, those outside [0, master_period]
            left out.
        order : int
            0 position, 1 velocity, ...

        Returns
        -------
        x, y : ndarray
            Master positions and values (user units), NaN between segments.
        """
        order = validate.integer("order", _plain(order), minimum=0)
        try:
            x = np.sort(np.asarray(master, dtype=float).ravel())
        except (TypeError, ValueError):
            raise validate.fail("master", master, "a number or an array of numbers") from None
        arrays = self._arrays
        low = np.searchsorted(x, arrays.master_start, side="left")
        counts = np.searchsorted(x, arrays.master_end, side="right") - low
        segment = np.repeat(np.arange(len(self.segments)), counts)
        first = np.cumsum(counts) - counts  # where each segment's points begin in the output
        position = np.arange(counts.sum()) - np.repeat(first, counts) + np.repeat(low, counts)
        slots = np.arange(counts.sum()) + segment  # one NaN slot after each segment
        xs = np.full(counts.sum() + len(self.segments), np.nan)
        ys = xs.copy()
        xs[slots] = x[position]
        ys[slots] = arrays.evaluate(segment, x[position], order)
        return xs, ys

    @functools.cached_property
    def slave_range(self) -> tuple[float, float]:
        """Smallest and largest slave position over the period (dense sample + joints + the
        period's end approached from the left: a periodic cam wraps at the period, so its last
        position is reached only there, the step back at the seam when no net stroke is declared)."""
        x = np.concatenate([np.linspace(0, self.master_period, 20001), self.joints()])
        y = np.append(self(x), self(self.master_period, side="left"))
        return float(y.min()), float(y.max())

    def joints(self) -> np.ndarray:
        """Master positions of the segment joints (without 0 and the period)."""
        return np.array([s.master_start for s in self.segments[1:]])

    def breaks(self) -> list[tuple[float, str, tuple[int, ...]]]:
        """Every place a derivative may jump -- joints, inner law breaks, and the seam -- as
        (master position, description, indices of the segments on either side)."""
        out = []
        last = len(self.segments) - 1
        for i, seg in enumerate(self.segments):
            if i > 0:
                prev = self.segments[i - 1]
                out.append((seg.master_start, f"joint {prev.label} -> {seg.label}", (i - 1, i)))
            for u in seg.law.breaks:
                out.append((seg.master_start + u * seg.span, f"inside {seg.label} (law break)", (i,)))
        if self.periodic:
            seam = f"seam {self.segments[-1].label} -> {self.segments[0].label}"
            if self.net_stroke:
                seam += f", position continuing by the net stroke {self.net_stroke:+.6g}"
            out.append((0.0, seam, (last, 0)))
        return out

    # continuity ----------------------------------------------------------------------------
    def local_scale(self, order: int, segments) -> float:
        """Magnitude of derivative ``order`` that the given segments can produce:
        the largest |stroke| / span**order among them."""
        scale = self._arrays.local_scale(order)
        return max(float(scale[i]) for i in segments)

    def jumps(self, max_order: int = 3) -> list[Discontinuity]:
        """Every jump of a derivative up to ``max_order``, at every break.

        A difference counts as a jump when it exceeds float noise: a relative 1e-9 of the
        one-sided values (1e-12 for positions, so a small step high up the int32 range is not
        lost in the absolute position) plus 1e-12 of what the neighbouring segments -- not the
        whole cam -- can produce, so a tiny segment elsewhere hides nothing.

        Every break is evaluated at once per order and side: linear in the segments.
        """
        breaks = self.breaks()
        masters = np.array([master for master, _, _ in breaks])
        first = np.array([neighbours[0] for _, _, neighbours in breaks], dtype=np.int64)
        last = np.array([neighbours[-1] for _, _, neighbours in breaks], dtype=np.int64)
        hits = np.zeros((len(breaks), max_order + 1), dtype=bool)
        sides = {}
        for order in range(max_order + 1):
            left = self(masters, order, side="left")
            right = self(masters, order, side="right")
            relative = 1e-12 if order == 0 else 1e-9
            local = self._arrays.local_scale(order)
            noise = relative * np.maximum(np.abs(left), np.abs(right)) + 1e-12 * np.maximum(local[first], local[last])
            hits[:, order] = np.abs(right - left) > noise
            sides[order] = (left, right)
        found = []
        for k, order in zip(*np.nonzero(hits)):  # break by break, orders rising: the order of the report
            left, right = sides[order]
            found.append(Discontinuity(float(masters[k]), int(order), float(left[k]), float(right[k]), breaks[k][1]))
        return found

    def check(self, max_order: int = 3) -> CheckReport:
        """Report every jump of position, velocity, acceleration (and jerk, as a warning).

        Joints between segments, breaks inside a law (e.g. the acceleration step of the
        parabolic law) and, for periodic cams, the seam where the period wraps are all checked.
        """
        return CheckReport(tuple(self.jumps(max_order)))

    def peak(self, order: int) -> float:
        """Largest |d^order y/dx^order| over the period (user units: slave units per master
        unit^order), sampled densely on each smooth piece, one-sided at its ends: the value a
        summary shows (:meth:`derivative_bound` is the certified upper bound). A derivative that
        jumps (e.g. the velocity of a law that starts from rest with a step) is counted on both
        sides, its jump is not.

        A segment is its law scaled (stroke / span**order, plus its start for positions), so each
        law's pieces are sampled once (1025 points each) and every segment reads its extremes
        from there: the cost is in the laws, not in the segments times the samples.
        """
        order = validate.integer("order", _plain(order), minimum=0)
        arrays = self._arrays
        low, high = arrays.law_ranges(order)
        which = arrays.law_index
        scale = arrays.scale(order)
        ends = np.stack([scale * low[which], scale * high[which]])
        if order == 0:
            ends = ends + arrays.slave_start
        return max(0.0, float(np.abs(ends).max()))

    def derivative_bound(self, order: int, lo: float = 0.0, hi: float | None = None) -> float:
        """Upper bound of |d^order y/dx^order| on [lo, hi] (user units), from dense sampling of
        each smooth piece with a Lipschitz margin from the next derivative.

        Each smooth piece (a segment between its law's breaks) meeting [lo, hi] is sampled at
        257 points; the bound is the largest sample plus half a sample step times the largest
        |d^(order+1) y/dx^(order+1)| there, with a 1 % margin. Every piece of every segment is
        evaluated in one pass (in blocks of bounded size): linear in the segments.
        """
        hi = self.master_period if hi is None else hi
        n = 257
        segment, p0, p1 = self._arrays.smooth_pieces()
        a = np.maximum(lo, self._arrays.master_start[segment])
        b = np.minimum(hi, self._arrays.master_end[segment])
        c, d = np.maximum(a, p0), np.minimum(b, p1)
        keep = (b >= a) & (d >= c)
        segment, p0, p1, c, d = segment[keep], p0[keep], p1[keep], c[keep], d[keep]
        best = 0.0
        rows = max(1, 2**20 // n)  # a bounded working set however many pieces
        for first in range(0, segment.size, rows):
            block = slice(first, first + rows)
            x = _linspace_rows(c[block], d[block], n)
            index = np.repeat(segment[block], n)
            left = (x >= p1[block, None]).ravel()  # the piece's own values at its end: its left limit
            values = np.abs(self._arrays.evaluate(index, x.ravel(), order, left)).reshape(x.shape).max(axis=1)
            slope = np.abs(self._arrays.evaluate(index, x.ravel(), order + 1, left)).reshape(x.shape).max(axis=1)
            bounds = values + slope * (d[block] - c[block]) / (n - 1) / 2 * 1.01
            best = max(best, float(bounds.max()))
        return best


class _SegmentArrays:
    """The segments of a profile as arrays, for evaluating many points on many segments at once
    (:meth:`evaluate` is :meth:`Segment.evaluate` per point, to the last bit).

    The scale factors ``stroke / span**order`` are computed in Python floats, as
    :meth:`Segment.evaluate` computes them, so the products agree bit for bit.
    """

    def __init__(self, segments) -> None:
        self.segments = segments
        self.master_start = np.array([seg.master_start for seg in segments])
        self.master_end = np.array([seg.master_end for seg in segments])
        self.span = np.array([seg.span for seg in segments])
        self.slave_start = np.array([seg.slave_start for seg in segments])
        laws: dict[int, int] = {}  # id(law) -> its row in the law table
        unique = []
        for seg in segments:
            if id(seg.law) not in laws:
                laws[id(seg.law)] = len(unique)
                unique.append(seg.law)
        self.law_index = np.array([laws[id(seg.law)] for seg in segments], dtype=np.int64)
        self.laws = LawTable(unique)
        self._scale: dict[int, np.ndarray] = {}
        self._local: dict[int, np.ndarray] = {}

    def scale(self, order: int) -> np.ndarray:
        """``stroke / span**order`` of each segment."""
        if order not in self._scale:
            self._scale[order] = np.array([seg.scale / seg.span**order for seg in self.segments])
        return self._scale[order]

    def local_scale(self, order: int) -> np.ndarray:
        """``|stroke| / span**order`` of each segment (see :meth:`CamProfile.local_scale`)."""
        if order not in self._local:
            self._local[order] = np.array([seg.law.local_scale(order) if isinstance(seg.law, SplineLaw)
                                           else abs(seg.stroke) / seg.span**order for seg in self.segments])
        return self._local[order]

    def evaluate(self, index: np.ndarray, x: np.ndarray, order: int, left=False) -> np.ndarray:
        """Segment ``index[k]`` at master ``x[k]``: :meth:`Segment.evaluate` with side "left"
        where ``left`` (a bool, or one per point)."""
        shape = np.shape(x)
        index, x = np.ravel(index), np.ravel(x)
        left = left if np.ndim(left) == 0 else np.ravel(left)
        u = np.clip((x - self.master_start[index]) / self.span[index], 0.0, 1.0)
        values = self.scale(order)[index] * self.laws(self.law_index[index], u, order, left, snap=True)
        if order == 0:
            values = values + self.slave_start[index]
        return values.reshape(shape)

    def law_ranges(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Smallest and largest d^order s/du^order of each law over its pieces (sampled)."""
        low, high = self.laws.piece_ranges(order)
        return (np.minimum.reduceat(low, self.laws.first_piece),
                np.maximum.reduceat(high, self.laws.first_piece))

    def smooth_pieces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every smooth piece of every segment, between its start, its law's breaks and its end,
        in master units: (segment index, start, end), pieces of zero length left out."""
        # Each segment's edges -- its start, its law's breaks scaled, its end -- flattened, sorted
        # within the segment: linear in the pieces (a spline segment has thousands).
        count = self.laws.break_count[self.law_index] + 2
        segment = np.repeat(np.arange(len(self.segments)), count)
        rank = np.arange(segment.size) - np.repeat(np.cumsum(count) - count, count)  # 0 .. count - 1
        inner = (rank > 0) & (rank < count[segment] - 1)
        index = self.laws.break_first[self.law_index][segment[inner]] + rank[inner] - 1
        edges = np.where(rank == 0, self.master_start[segment], self.master_end[segment])
        edges[inner] = self.master_start[segment[inner]] + self.laws.break_values[index] * self.span[segment[inner]]
        edges = edges[np.lexsort((edges, segment))]
        last = np.cumsum(count) - 1  # each segment's last edge: no piece starts there
        start = np.ones(segment.size, dtype=bool)
        start[last] = False
        p0, p1 = edges[start], edges[np.flatnonzero(start) + 1]
        real = p0 < p1  # false for breaks that round onto each other
        return segment[start][real], p0[real], p1[real]


def _linspace_rows(start: np.ndarray, stop: np.ndarray, num: int) -> np.ndarray:
    """``np.linspace(start[i], stop[i], num)`` as row i, with numpy's own arithmetic (k * step +
    start, the last point set to ``stop``)."""
    step = (stop - start) / (num - 1)
    rows = np.arange(num, dtype=float)[None, :] * step[:, None] + start[:, None]
    flat = step == 0  # numpy's branch for a step that underflows: k / div * delta
    if flat.any():
        rows[flat] = (np.arange(num, dtype=float) / (num - 1))[None, :] * (stop - start)[flat, None] + start[flat, None]
    rows[:, -1] = stop
    return rows


# The settings of a cam file's [table] (ecam.table_spec.TableSpec checks their values).
TABLE_KEYS = ("horner_bits", "interp", "interpolation_tolerance", "master_counts", "points", "slave_counts_per_unit",
              "tolerance")
# TOML basic strings: these characters are escaped, every other control character as \uXXXX.
_TOML_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def _law_name(i: int, seg: Segment) -> str:
    """The name a cam file gives the law of segment ``i``."""
    if seg.boundary is not None:
        return seg.law.name  # poly5 / poly7, with its boundary conditions
    if isinstance(seg.law, SplineLaw):
        return "spline"  # with its knots and derivatives
    if seg.law == DWELL or LAWS.get(seg.law.name) == seg.law:
        return seg.law.name
    raise validate.fail(f"segment[{i}].law", seg.law.name, "a law of ecam.LAWS, 'dwell' or a polynomial "
                        "from Segment.polynomial, to be written to a cam file")


def _toml_value(field: str, value) -> str:
    """``value`` as a TOML value that reads back equal."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # inf / -inf / nan are TOML too
    if isinstance(value, str):
        out = []
        for char in value:
            if char in _TOML_ESCAPES:
                out.append(_TOML_ESCAPES[char])
            elif ord(char) < 0x20 or ord(char) == 0x7F:
                out.append(f"\\u{ord(char):04X}")
            elif 0xD800 <= ord(char) <= 0xDFFF:
                raise validate.fail(field, value, "text without lone surrogates (TOML is UTF-8)")
            else:
                out.append(char)
        return '"' + "".join(out) + '"'
    raise validate.fail(field, value, "a string, a number or true/false (a TOML value)")


def dwell(master_start: float, master_end: float, slave: float, name: str = "dwell") -> Segment:
    """A segment that holds the slave at ``slave`` (law ``"dwell"``)."""
    return Segment(master_start, master_end, slave, slave, DWELL, name)
