"""Digital cam switches (tappets): an output that is on over a window of master positions.

The behaviour follows PLCopen's digital cam switch (Motion Control Part 1, ``MC_DigitalCamSwitch``
with its switch and track structures), as the vendors document those structures:

* the window: ``FirstOnPosition`` "the first position where the switch is on", ``LastOnPosition``
  "the last" (CODESYS SM3_Basic ``MC_CAMSWITCH_TR``); a last position below the first "results in
  an 'inverted' switch" (the window wraps through the period end);
* ``AxisDirection``: "0 = the output is switched in two directions, 1 = only in positive
  direction, 2 = only in negative direction" (same structure): :data:`DIRECTIONS`;
* the track (Beckhoff ``TRACK_REF`` / ``MC_TRACK_REF``, PLCopen's track structure):
  ``OnCompensation`` / ``OffCompensation`` "compensation time [s] ... For negative values the
  switching time is brought forward, otherwise it is delayed" -- an actuator's dead time T is
  compensated with -T; ``Hysteresis``: "the axis must have moved away from the switching point
  by this distance before reaching of the switching point is evaluated again".

A compensation time c moves an edge by the distance the master covers in it: the output at a
master position x moving at speed v is the window's value at x - v c, so an edge programmed at p
happens at p + v c. A direction-limited switch is off while the master moves the other way;
standing still keeps the last direction.

Two forms: :class:`TappetTrack` in user units (master units, seconds), as the cam file holds it
(``[[tappet]]``), and :class:`TappetCounts`, integers for firmware (master counts, microseconds),
whose :meth:`TappetCounts.step` is what ``firmware_tables/ecam_tappet.c`` computes bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__

__all__ = ["DIRECTIONS", "MAX_COMPENSATION_S", "TAPPET_KEYS", "Edge", "TappetCounts", "TappetState",
           "TappetTrack", "evaluate"]

#: PLCopen AxisDirection 0, 1, 2.
DIRECTIONS = ("both", "positive", "negative")
#: The largest |compensation| [s]: far beyond any valve or camera (milliseconds), and small enough
#: that speed (int32 counts/s) x compensation (microseconds) stays inside int64 in firmware.
MAX_COMPENSATION_S = 100.0
#: The fields of a ``[[tappet]]`` table in a cam file, in the order to_toml writes them.
TAPPET_KEYS = ("name", "on", "off", "direction", "hysteresis", "on_compensation", "off_compensation")
_MICROSECONDS = 1_000_000


@dataclass(frozen=True)
class TappetTrack:
    """One output switched on over a window of master positions (see the module docstring).

    Parameters
    ----------
    on, off : float
        First and last master position where the output is on [master units], within the cam's
        period (checked by :class:`ecam.CamProfile`); ``off < on`` wraps through the period end.
    direction : {"both", "positive", "negative"}
        The master's direction of motion in which the output switches (PLCopen AxisDirection).
    hysteresis : float
        Master distance [master units], >= 0, to move away from a switching point before the
        output switches again.
    on_compensation, off_compensation : float
        Compensation times [s], |c| <= 100: negative brings the edge forward (an actuator's dead
        time T: -T), positive delays it.
    name : str
        For reports and exports.
    """

    on: float
    off: float
    direction: str = "both"
    hysteresis: float = 0.0
    on_compensation: float = 0.0
    off_compensation: float = 0.0
    name: str = ""

    def __post_init__(self):
        for field in ("on", "off"):
            object.__setattr__(self, field, validate.number(field, _plain(getattr(self, field))))
        validate.choice("direction", self.direction, DIRECTIONS)
        object.__setattr__(self, "hysteresis", validate.number("hysteresis", _plain(self.hysteresis),
                                                               minimum=0.0))
        for field in ("on_compensation", "off_compensation"):
            object.__setattr__(self, field, validate.number(field, _plain(getattr(self, field)),
                                                            minimum=-MAX_COMPENSATION_S,
                                                            maximum=MAX_COMPENSATION_S))
        validate.text("name", self.name)  # goes into exports and plots (issue 28)

    def within(self, master_period: float) -> "TappetTrack":
        """The track, checked against a cam's master period: on, off in [0, period], hysteresis
        below half of it (a switch point cannot be left by more)."""
        for field in ("on", "off"):
            value = getattr(self, field)
            if not 0.0 <= value <= master_period:
                raise validate.fail(field, value, f"within the master period 0..{master_period:g}")
        if self.hysteresis >= 0.5 * master_period:
            raise validate.fail("hysteresis", self.hysteresis,
                                f"< half the master period ({0.5 * master_period:g})")
        return self

    def to_counts(self, master_period: float, master_counts: int) -> "TappetCounts":
        """The integer form for a master of ``master_counts`` per ``master_period``: positions
        rounded to the nearest count (modulo the period), compensations to microseconds."""
        period = validate.positive("master_period", master_period)
        counts = validate.integer("master_counts", master_counts, minimum=2, maximum=2**31)
        per_unit = counts / period

        def position(value):
            return math.floor(value * per_unit + 0.5) % counts

        return TappetCounts(
            period_counts=counts, on_counts=position(self.on), off_counts=position(self.off),
            hysteresis_counts=min(math.floor(self.hysteresis * per_unit + 0.5), counts // 2),
            on_compensation_us=_round_half_away(self.on_compensation * _MICROSECONDS),
            off_compensation_us=_round_half_away(self.off_compensation * _MICROSECONDS),
            direction=DIRECTIONS.index(self.direction))

@dataclass(frozen=True)
class TappetState:
    """What a track remembers between samples: its output (0/1), the master's last direction of
    motion (+1, -1; 0 before it first moves), whether a switch may happen (hysteresis), and
    the master position of the last switch [counts, 0..period-1]."""

    output: int = 0
    direction: int = 0
    armed: int = 1
    last_switch_counts: int = 0


@dataclass(frozen=True)
class Edge:
    """An output change: the sample it happened at, the master position there [counts, as
    given], rising or falling, and the switch point it belongs to: programmed and compensated
    at the sample's speed [counts, within the period]."""

    index: int
    master_counts: int
    rising: bool
    programmed_counts: int
    compensated_counts: int


@dataclass(frozen=True)
class TappetCounts:
    """A track in integers, for firmware (``ecam_tappet_track`` in ``firmware_tables``).

    Attributes
    ----------
    period_counts : int
        Master counts per period, 2..2^31.
    on_counts, off_counts : int
        First and last on position [counts], 0..period-1.
    hysteresis_counts : int
        0..period/2.
    on_compensation_us, off_compensation_us : int
        Microseconds, |c| <= 1e8.
    direction : int
        0 both, 1 positive, 2 negative (PLCopen AxisDirection).
    """

    period_counts: int
    on_counts: int
    off_counts: int
    hysteresis_counts: int = 0
    on_compensation_us: int = 0
    off_compensation_us: int = 0
    direction: int = 0

    def __post_init__(self):
        period = validate.integer("period_counts", self.period_counts, minimum=2, maximum=2**31)
        for field in ("on_counts", "off_counts"):
            validate.integer(field, getattr(self, field), minimum=0, maximum=period - 1)
        validate.integer("hysteresis_counts", self.hysteresis_counts, minimum=0, maximum=period // 2)
        limit = int(MAX_COMPENSATION_S * _MICROSECONDS)
        for field in ("on_compensation_us", "off_compensation_us"):
            validate.integer(field, getattr(self, field), minimum=-limit, maximum=limit)
        validate.integer("direction", self.direction, minimum=0, maximum=2)

    def step(self, state: TappetState, master_counts: int, speed_counts_per_s: int) -> TappetState:
        """The state after one sample of the master: position [counts, any int64] and speed
        [counts/s, int32]. Integer arithmetic only, in the order the C function does it."""
        period = self.period_counts
        position = master_counts % period
        direction = 1 if speed_counts_per_s > 0 else -1 if speed_counts_per_s < 0 else state.direction
        on, length = self._window(speed_counts_per_s)
        if length < 0:
            inside = False
        elif length >= period:
            inside = True
        else:
            inside = (position - on) % period <= length
        allowed = (self.direction == 0 or (self.direction == 1 and direction == 1)
                   or (self.direction == 2 and direction == -1))
        wanted = 1 if inside and allowed else 0
        armed, last = state.armed, state.last_switch_counts
        if not armed and _distance(position, last, period) >= self.hysteresis_counts:
            armed = 1
        output = state.output
        if wanted != output and armed:
            output, last = wanted, position
            armed = 1 if self.hysteresis_counts == 0 else 0
        return TappetState(output, direction, armed, last)

    def _window(self, speed: int) -> tuple[int, int]:
        """The compensated window at ``speed``: its first on position (0..period-1) and its
        length in counts (may be < 0: empty, or >= period: always on)."""
        period = self.period_counts
        shift_on = _divide_rounding(speed * self.on_compensation_us, _MICROSECONDS)
        shift_off = _divide_rounding(speed * self.off_compensation_us, _MICROSECONDS)
        length = (self.off_counts - self.on_counts) % period + shift_off - shift_on
        return (self.on_counts + shift_on) % period, length

    def switch_points(self, speed_counts_per_s: int) -> tuple[int, int]:
        """(on, off) positions [counts, within the period] where the edges fall at a speed."""
        on, length = self._window(speed_counts_per_s)
        return on, (on + length) % self.period_counts


def evaluate(track: TappetCounts, master_counts, speeds_counts_per_s,
             state: TappetState | None = None) -> tuple[list[int], list[Edge], TappetState]:
    """Run a track over a sequence of master samples.

    Parameters
    ----------
    track : TappetCounts
    master_counts : sequence of int
        Master positions [counts] (int64; wrapped into the period by the track).
    speeds_counts_per_s : sequence of int
        The master's speed at each sample [counts/s] (int32), as firmware knows it.
    state : TappetState, optional
        Where to start from; default: output off, no direction yet.

    Returns
    -------
    outputs : list of int
        The output (0/1) after each sample.
    edges : list of Edge
        Every change, with the master position it happened at and the switch point it belongs
        to (rising: the on point when moving forward, the off point backward).
    state : TappetState
        The state after the last sample.
    """
    if not isinstance(track, TappetCounts):
        raise validate.fail("track", track, "a TappetCounts")
    masters, speeds = list(master_counts), list(speeds_counts_per_s)
    if len(masters) != len(speeds):
        raise validate.fail("speeds_counts_per_s", f"{len(speeds)} samples",
                            f"{len(masters)}, as many as master_counts")
    state = TappetState() if state is None else state
    outputs, edges = [], []
    for k, (master, speed) in enumerate(zip(masters, speeds)):
        master = validate.integer(f"master_counts[{k}]", _plain(master), minimum=-2**63, maximum=2**63 - 1)
        speed = validate.integer(f"speeds_counts_per_s[{k}]", _plain(speed), minimum=-2**31,
                                 maximum=2**31 - 1)
        after = track.step(state, master, speed)
        if after.output != state.output:
            rising = after.output == 1
            forward = after.direction >= 0
            on, off = track.switch_points(speed)
            use_on = rising == forward
            edges.append(Edge(k, master, rising, track.on_counts if use_on else track.off_counts,
                              on if use_on else off))
        outputs.append(after.output)
        state = after
    return outputs, edges, state


def _distance(a: int, b: int, period: int) -> int:
    """Distance of two positions on the circle of ``period`` counts."""
    d = (a - b) % period
    return min(d, period - d)


def _divide_rounding(numerator: int, denominator: int) -> int:
    """numerator / denominator (> 0) rounded half away from zero, as the C function does it."""
    half = denominator // 2
    if numerator >= 0:
        return (numerator + half) // denominator
    return -((-numerator + half) // denominator)


def _round_half_away(value: float) -> int:
    return int(math.copysign(math.floor(abs(value) + 0.5), value))


def _plain(value):
    """A numpy scalar as the Python number it holds (validate checks Python types)."""
    return value.item() if hasattr(value, "item") and not isinstance(value, (int, float)) else value
