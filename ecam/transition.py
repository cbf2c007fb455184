"""A transition cam between two cams: A's end state to B's start state over a master span.

VDI 2143 (Bewegungsgesetze fuer Kurvengetriebe, Blatt 1) calls a segment between two motions a
motion-to-motion transition ("Bewegung-Bewegung") and joins it with a polynomial that takes the
neighbours' position, velocity and acceleration at both ends -- jerk too for the 7th order
(:meth:`ecam.Segment.polynomial`, :func:`ecam.polynomial_from_boundary`). Controllers do the same
when they change cams: CODESYS SoftMotion's smooth transition between cams and B&R's cam automat
with its compensation segments insert such a curve between the two tables.

The transition cam T is an ordinary, non-periodic cam file over ``[0, span]``. It is run between A
and B with the master relative (CODESYS: "sets the zero point of the master to ... the position at
the end of the previous cam ... allows the new cam to be connected exactly to the previous one"),
so T starts at A's period end and B starts at T's end (:mod:`ecam.cam_join`). Its slave
coordinates are those of the switches it sits between: absolute, T(0) is A's end position and
T(span) B's start; relative, T starts at 0 (each cam adds to where the slave stands) and its end
position is free (B adds to it), so T takes the stroke its end velocities call for.
``ecam check A --then T --master relative`` and ``ecam check T --then B --master relative`` (with
the same ``--slave``) prove it continuous in position, velocity, acceleration and jerk.
"""

from __future__ import annotations

import math

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .cam_join import COORDINATES
from .errors import InputError
from .linear import solve_exact
from .profile import CamProfile, Segment, check_master_period, dwell

__all__ = ["transition_cam"]

# Where a transition whose two ends sit at the same slave position is split into two 7th-order
# segments (a segment needs a stroke): the first of these fractions of the span whose two parts
# both move the slave.
_SPLITS = (0.5, 0.25, 0.75, 1.0 / 3.0, 2.0 / 3.0)


def transition_cam(first: CamProfile, then: CamProfile, span: float, *, slave: str = "absolute",
                   name: str | None = None) -> CamProfile:
    """The 7th-order transition from ``first``'s period end to ``then``'s start.

    Parameters
    ----------
    first, then : CamProfile
        Cam A (left at its period end) and cam B (entered at its master 0).
    span : float
        Master span of the transition [master units], > 0: the longer, the gentler.
    slave : {"absolute", "relative"}
        The slave coordinates of both switches (PLCopen ``MC_CamTableSelect.SlaveAbsolute``).
        Absolute: T runs from A's end position to B's start position. Relative: from 0 over the
        stroke a cubic velocity through the end velocities and accelerations integrates to,
        ``span (v_A + v_B) / 2 + span^2 (a_A - a_B) / 12``, since B then starts wherever T ends.
    name : str, optional
        The transition cam's name; default ``"<A>_to_<B>"``.

    Returns
    -------
    CamProfile
        Not periodic, over ``[0, span]``: one ``poly7`` segment matching A's end and B's start
        in position, velocity, acceleration and jerk; two when both ends sit at one slave
        position (each part then moves the slave), or a dwell when nothing moves at all.

    Raises
    ------
    InputError
        Cams in different units, a span that is not a positive number, or boundary conditions a
        7th-order segment cannot take over this span (too large once normalized).
    """
    for cam, field in ((first, "cam"), (then, "then")):
        if not isinstance(cam, CamProfile):
            raise validate.fail(field, cam, "a CamProfile")
    validate.choice("slave", slave, COORDINATES)
    for unit in ("master_unit", "slave_unit"):
        if getattr(first, unit) != getattr(then, unit):
            raise validate.fail(f"then.{unit}", getattr(then, unit),
                                f"{validate.show(getattr(first, unit))}, the first cam's")
    span = check_master_period(span, "span")
    last, entered = first.segments[-1], then.segments[0]
    # positions as the segments hold them (a steep law evaluated at its ends may miss by rounding)
    start = [last.slave_end] + [last.at(1.0, order) for order in range(1, 4)]
    end = [entered.slave_start] + [entered.at(0.0, order) for order in range(1, 4)]
    if slave == "relative":
        # T starts where A left the slave (its origin, 0) and B starts where T ends, whatever that
        # is: the end position is free. Take the stroke the end velocities and accelerations call
        # for, the integral of a cubic velocity through them (the trapezoid rule with its end
        # correction): between two cams at one constant speed T is that constant speed.
        start[0] = 0.0
        end[0] = span * (start[1] + end[1]) / 2.0 + span**2 * (start[2] - end[2]) / 12.0
    name = f"{first.name}_to_{then.name}" if name is None else validate.string("name", name)
    segments = _segments(span, start, end)
    return CamProfile(segments, span, periodic=False, name=name, master_unit=first.master_unit,
                      slave_unit=first.slave_unit)


def _segments(span: float, start: list, end: list) -> list[Segment]:
    """One poly7 from ``start`` to ``end`` (position, velocity, acceleration, jerk), or its two
    parts when it has no stroke of its own."""
    if end[0] != start[0]:
        return [_poly7(0.0, span, start, end)]
    polynomial = _poly7_coefficients(span, start, end)
    if not np.any(polynomial[1:]):
        return [dwell(0.0, span, start[0], "transition")]
    best, split = 0.0, None
    for fraction in _SPLITS:
        middle = _state(polynomial, fraction, span)
        stroke = min(abs(middle[0] - start[0]), abs(end[0] - middle[0]))
        if stroke > best:
            best, split = stroke, (fraction * span, middle)
    if split is None:
        raise InputError("span: the transition's two ends sit at one slave position and no split "
                         "of it moves the slave; give another span")
    at, middle = split
    return [_poly7(0.0, at, start, middle), _poly7(at, span, middle, end)]


def _poly7(master_start: float, master_end: float, start: list, end: list) -> Segment:
    return Segment.polynomial(master_start, master_end, start[0], end[0], degree=7, name="transition",
                              start_velocity=start[1], start_acceleration=start[2], start_jerk=start[3],
                              end_velocity=end[1], end_acceleration=end[2], end_jerk=end[3])


def _poly7_coefficients(span: float, start: list, end: list) -> np.ndarray:
    """Coefficients c_k of y(x) = sum c_k (x / span)^k, k = 0..7, taking ``start`` at x = 0 and
    ``end`` at x = span (derivatives scaled by span^order, so the system is well conditioned)."""
    rows, values = [], []
    for order in range(4):
        for at, state in ((0.0, start), (1.0, end)):
            row = [0.0] * 8
            for k in range(order, 8):
                row[k] = math.perm(k, order) * at ** (k - order)
            rows.append(row)
            values.append(state[order] * span**order)
    return np.array(solve_exact(rows, values))  # no LAPACK: the same bits on every CPU


def _state(coefficients: np.ndarray, u: float, span: float) -> list:
    """Position, velocity, acceleration and jerk (per master unit) at ``u = x / span``."""
    return [sum(float(c) * math.perm(k, order) * u ** (k - order) for k, c in enumerate(coefficients)
                if k >= order) / span**order for order in range(4)]
