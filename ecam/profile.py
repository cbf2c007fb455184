"""Cam profiles: segments of motion laws over one master period, in user units."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .laws import Law, law as _law

__all__ = ["Segment", "CamProfile", "Discontinuity", "CheckReport", "ORDER_NAMES"]

ORDER_NAMES = ("position", "velocity", "acceleration", "jerk")
MIN_PERIOD, MAX_PERIOD = 1e-9, 1e12  # master units
MIN_SPAN_FRACTION = 1e-9  # of the master period; 1e-6 (a hard case) is well inside
MAX_SLAVE = 1e15  # slave units


@dataclass(frozen=True)
class Segment:
    """A law scaled to a master span and a slave stroke.

    ``y(x) = slave_start + (slave_end - slave_start) * law((x - master_start) / span)``.
    A dwell is a segment with zero stroke.
    """

    master_start: float
    master_end: float
    slave_start: float
    slave_end: float
    law: Law
    name: str = ""

    @property
    def span(self) -> float:
        return self.master_end - self.master_start

    @property
    def stroke(self) -> float:
        return self.slave_end - self.slave_start

    def evaluate(self, x: np.ndarray, order: int, side: str = "right") -> np.ndarray:
        u = np.clip((x - self.master_start) / self.span, 0.0, 1.0)
        for b in self.law.breaks:  # a break recomputed from a master position may miss by an ulp
            u = np.where(np.abs(u - b) < 1e-12, b, u)
        values = self.stroke / self.span**order * self.law(u, order, side=side)
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
        return self.right - self.left

    @property
    def severity(self) -> str:
        return "warning" if self.order >= 3 else "error"

    def to_dict(self) -> dict:
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
        return tuple(d for d in self.discontinuities if d.severity == "error")

    @property
    def warnings(self) -> tuple[Discontinuity, ...]:
        return tuple(d for d in self.discontinuities if d.severity == "warning")

    @property
    def ok(self) -> bool:
        return not self.errors

    def continuous(self, order: int) -> bool:
        """True when no derivative up to ``order`` jumps anywhere."""
        return all(d.order > order for d in self.discontinuities)

    def at(self, master: float, order: int | None = None) -> tuple[Discontinuity, ...]:
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
    segments : tuple of Segment
        Contiguous segments from master 0 to ``master_period``.
    master_period : float
        Length of one cycle in master units (e.g. 360 degrees).
    periodic : bool
        Whether the cam repeats: master positions wrap modulo the period. A non-periodic cam is
        defined on [0, master_period] only.
    name, master_unit, slave_unit : str
        For reports and plots.
    table : dict
        Default table format for the compiler (interp, points or tolerance, master_counts,
        slave_counts_per_unit), from the cam file's ``[table]`` section.
    """

    segments: tuple[Segment, ...]
    master_period: float
    periodic: bool = True
    name: str = ""
    master_unit: str = "deg"
    slave_unit: str = "mm"
    table: dict = field(default_factory=dict)

    def __post_init__(self):
        if not self.segments:
            raise InputError("segments [] should hold at least one segment")
        if not (math.isfinite(self.master_period) and MIN_PERIOD <= self.master_period <= MAX_PERIOD):
            raise InputError(f"master_period {self.master_period!r} should be in {MIN_PERIOD:g}..{MAX_PERIOD:g}")
        position = 0.0
        for i, seg in enumerate(self.segments):
            if not math.isclose(seg.master_start, position, rel_tol=0, abs_tol=1e-9 * self.master_period):
                kind = "gap" if seg.master_start > position else "overlap"
                raise InputError(
                    f"segment[{i}].start {seg.master_start!r} leaves a {kind}: "
                    f"the previous segment ends at {position!r}"
                )
            if not seg.span > 0:
                raise InputError(f"segment[{i}].span {seg.span!r} should be > 0")
            # derivatives up to the 7th divide by span**7: keep that far from under/overflow
            if seg.span < MIN_SPAN_FRACTION * self.master_period:
                raise InputError(f"segment[{i}].span {seg.span!r} should be >= {MIN_SPAN_FRACTION:g} of "
                                 f"master_period ({MIN_SPAN_FRACTION * self.master_period:g})")
            for name, value in (("from", seg.slave_start), ("to", seg.slave_end)):
                if not (math.isfinite(value) and abs(value) <= MAX_SLAVE):
                    raise InputError(f"segment[{i}] slave position ({name}) {value!r} should be finite "
                                     f"and within +-{MAX_SLAVE:g}")
            position = seg.master_end
        if not math.isclose(position, self.master_period, rel_tol=1e-12):
            kind = "gap" if position < self.master_period else "overlap"
            raise InputError(
                f"segments end at {position!r}, which leaves a {kind} against "
                f"master_period {self.master_period!r}"
            )
        object.__setattr__(self, "_starts", np.array([s.master_start for s in self.segments]))

    # evaluation --------------------------------------------------------------------------
    def __call__(self, master, order: int = 0, side: str = "right"):
        """Slave position (order 0) or its derivative d^order y / dx^order, in user units.

        Parameters
        ----------
        master : array_like
            Master position(s) in master units. Periodic cams wrap; a non-periodic cam raises
            :class:`~ecam.errors.InputError` outside [0, master_period].
        order : int
            0 position, 1 velocity (slave units per master unit), 2 acceleration, 3 jerk, ...
        side : {'right', 'left'}
            One-sided limit at a joint.
        """
        scalar = np.ndim(master) == 0
        x = np.asarray(master, dtype=float)
        if not np.all(np.isfinite(x)):
            raise InputError("master position should be finite")
        period = self.master_period
        if self.periodic:
            x = np.mod(x, period)
            if side == "left":
                x = np.where(x == 0.0, period, x)
        elif np.any((x < 0) | (x > period)):
            bad = x[(x < 0) | (x > period)].flat[0]
            raise InputError(
                f"master position {bad!r} is outside the non-periodic cam's range [0, {period!r}]"
            )
        x = self._snap_to_joints(x)
        index = np.searchsorted(self._starts, x, side="right" if side == "right" else "left") - 1
        index = np.clip(index, 0, len(self.segments) - 1)
        out = np.empty_like(x)
        for i, seg in enumerate(self.segments):
            mask = index == i
            if mask.any():
                out[mask] = seg.evaluate(x[mask], order, side)
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
    def slave_range(self) -> tuple[float, float]:
        """Smallest and largest slave position over the period (dense sample + joints)."""
        x = np.concatenate([np.linspace(0, self.master_period, 20001), self.joints()])
        y = self(x)
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
            out.append((0.0, f"seam {self.segments[-1].label} -> {self.segments[0].label}", (last, 0)))
        return out

    # continuity ----------------------------------------------------------------------------
    def local_scale(self, order: int, segments) -> float:
        """Magnitude of derivative ``order`` that the given segments can produce:
        the largest |stroke| / span**order among them."""
        return max(abs(self.segments[i].stroke) / self.segments[i].span ** order for i in segments)

    def jumps(self, max_order: int = 3) -> list[Discontinuity]:
        """Every jump of a derivative up to ``max_order``, at every break.

        A difference counts as a jump when it exceeds float noise: a relative 1e-9 of the
        one-sided values (1e-12 for positions, so a small step high up the int32 range is not
        lost in the absolute position) plus 1e-12 of what the neighbouring segments -- not the
        whole cam -- can produce, so a tiny segment elsewhere hides nothing.
        """
        found = []
        for master, where, neighbours in self.breaks():
            for order in range(max_order + 1):
                left = float(self(master, order, side="left"))
                right = float(self(master, order, side="right"))
                relative = 1e-12 if order == 0 else 1e-9
                noise = relative * max(abs(left), abs(right)) + 1e-12 * self.local_scale(order, neighbours)
                if abs(right - left) > noise:
                    found.append(Discontinuity(float(master), order, left, right, where))
        return found

    def check(self, max_order: int = 3) -> CheckReport:
        """Report every jump of position, velocity, acceleration (and jerk, as a warning).

        Joints between segments, breaks inside a law (e.g. the acceleration step of the
        parabolic law) and, for periodic cams, the seam where the period wraps are all checked.
        """
        return CheckReport(tuple(self.jumps(max_order)))

    def derivative_bound(self, order: int, lo: float = 0.0, hi: float | None = None) -> float:
        """Upper bound of |d^order y/dx^order| on [lo, hi] (user units), from dense sampling of
        each smooth piece with a Lipschitz margin from the next derivative."""
        hi = self.master_period if hi is None else hi
        best = 0.0
        for seg in self.segments:
            a, b = max(lo, seg.master_start), min(hi, seg.master_end)
            if b < a:
                continue
            edges = [seg.master_start] + [seg.master_start + u * seg.span for u in seg.law.breaks]
            edges = sorted(set(edges + [seg.master_end]))
            for p0, p1 in zip(edges[:-1], edges[1:]):
                c, d = max(a, p0), min(b, p1)
                if d < c:
                    continue
                n = 257
                x = np.linspace(c, d, n)
                values = np.abs(_piece_values(seg, x, order, p0, p1))
                slope = np.abs(_piece_values(seg, x, order + 1, p0, p1)).max()
                best = max(best, float(values.max()) + slope * (d - c) / (n - 1) / 2 * 1.01)
        return best


def _piece_values(seg: Segment, x: np.ndarray, order: int, p0: float, p1: float) -> np.ndarray:
    """Derivative values of one smooth piece of a segment, one-sided at its own ends."""
    out = np.empty_like(x)
    inner = (x > p0) & (x < p1)
    out[inner] = seg.evaluate(x[inner], order, "right")
    at_start = x <= p0
    at_end = x >= p1
    if at_start.any():
        out[at_start] = seg.evaluate(x[at_start], order, "right")
    if at_end.any():
        out[at_end] = seg.evaluate(x[at_end], order, "left")
    return out


def dwell(master_start: float, master_end: float, slave: float, name: str = "dwell") -> Segment:
    """A segment that holds the slave at ``slave``."""
    return Segment(master_start, master_end, slave, slave, _law("constant_velocity"), name)
