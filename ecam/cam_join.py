"""Continuity across a cam switch: cam A runs to the end of its period, cam B takes over there.

A controller that switches tables at a period end (CODESYS places a newly selected cam exactly
at the end of the previous one; TwinCAT's activation "next cam cycle"; Rockwell's pending cam)
joins A's end state to B's start state; whether the slave jumps there depends on how B's
coordinates are placed, which PLCopen defines per axis:

* PLCopen, Function Blocks for Motion Control, Part 1 (v2.0), ``MC_CamTableSelect``:
  ``MasterAbsolute`` / ``SlaveAbsolute``: TRUE, the cam table is absolute in that axis; FALSE,
  relative to the axis's position when the table is started. CODESYS SoftMotion's help
  ("Function Blocks: MC_CamTableSelect and MC_CamIn") spells it out for a switch:
  ``MasterAbsolute = FALSE`` "sets the zero point of the master to ... the position at the end
  of the previous cam", which "allows the new cam to be connected exactly to the previous one";
  with ``MasterAbsolute = TRUE`` the cam "is started at the current master position" (B is
  entered at the master axis position where A ends, within B's own master range).
* ``MC_CamIn.StartMode`` (same page): "absolute: ... the cam is evaluated independent of the
  current position of the slave. This can lead to jumps ..."; "relative: ... The position that
  the slave has after the end of the previous cycle is added as a slave offset to the new
  evaluations of the cam. Jumps can also occur if the slave position at the master start
  position is not 0." Beckhoff (TwinCAT NC Camming, ``MC_StartMode``) says the same of
  relative: "the origin of the cam plate coordinate system is at the axis position ... at the
  time of coupling or cam plate switching".

The switch happens at a master position ``at`` (by default A's first period end, its
master_period). The join compares A's left limit there with B's right limit at its entry X,
offset by A's position there when the slave is relative. The master relative enters B at X = 0.
The master absolute evaluates B at the absolute master position itself, X = ``at`` (PLCopen
MasterAbsolute: the cam's master coordinate is the axis's), and a periodic cam there is what it
is everywhere in ecam: wrapped into its period, its position continuing by its net stroke per
period, so a cam with a net stroke at X includes floor(X / period) net strokes; A's left limit at
its N-th period end includes N - 1 of its own. That is what the firmware's table lookup does
(FORMAT.md, step 7: :class:`ecam.table_pair.SwitchPair`, ``ecam_switch_pair``) and what the rig's
``[[event]]`` switches do (:mod:`hil_sim.events`), so the join checked here is the join they make:
the rotary knife switched to itself at its period end with master and slave absolute changes
nothing; with the master relative it restarts at 0 (a jump of minus its position).

Position, velocity and acceleration jumps are errors, a jerk jump a warning, as
:meth:`ecam.CamProfile.check` reports a joint. Both cams must use the same master and slave units
(derivatives are per master unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .errors import InputError
from .profile import ORDER_NAMES, CamProfile, CheckReport, Discontinuity

__all__ = ["COORDINATES", "Join", "join_cams"]

#: How a cam's coordinates are placed on an axis when it is switched in (PLCopen).
COORDINATES = ("absolute", "relative")


@dataclass(frozen=True)
class Join:
    """Where and how cam B takes over from cam A, and what jumps there.

    Attributes
    ----------
    master : float
        The master axis position of the join (``at``; by default A's period end) [master units].
    entry : float
        Where B is entered, in B's own master coordinate X [master units]: 0 with the master
        relative, the master position itself with it absolute (not wrapped: a periodic B is
        evaluated there with the net strokes of the periods before).
    slave_offset : float
        What is added to B's positions: A's position at the join when the slave is relative,
        else 0.
    master_coordinates, slave_coordinates : {"absolute", "relative"}
    left, right : tuple of float
        A's end and B's entry (offset applied): position, velocity, acceleration, jerk (slave
        units per master unit^k).
    report : CheckReport
        The jumps at the join, as :meth:`ecam.CamProfile.check` reports them.
    """

    master: float
    entry: float
    slave_offset: float
    master_coordinates: str
    slave_coordinates: str
    left: tuple
    right: tuple
    report: CheckReport

    @property
    def where(self) -> str:
        """The join in words, for the report's lines."""
        return (f"join, master {self.master_coordinates} (entered at {self.entry:.6g}), "
                f"slave {self.slave_coordinates}"
                + (f" (offset {self.slave_offset:+.6g})" if self.slave_coordinates == "relative" else ""))


def join_cams(first: CamProfile, then: CamProfile, *, master: str = "absolute",
              slave: str = "absolute", at: float | None = None) -> Join:
    """The join of ``first`` to ``then`` at master ``at`` (see the module docstring).

    Parameters
    ----------
    first, then : CamProfile
        Cam A, running when the switch is made, and cam B, switched in at ``at``.
    master, slave : {"absolute", "relative"}
        PLCopen ``MC_CamTableSelect.MasterAbsolute`` / ``SlaveAbsolute`` (absolute: TRUE).
        The default, absolute, is CODESYS's initial value of both inputs.
    at : float, optional
        The master position of the switch [master units]: A's left limit and B's entry are taken
        there. Default: A's first period end (``first.master_period``); ``N x master_period`` is
        the end of A's N-th period, where a switch queued for the period end happens. Within
        A's master range for an A that does not repeat.

    Returns
    -------
    Join

    Raises
    ------
    InputError
        A mode other than absolute or relative; cams in different master or slave units; an
        absolute master that enters a cam which is not periodic outside its master range
        (CODESYS reports SMC_CI_MASTER_OUT_OF_SCALE there); ``at`` outside the master range of
        an A that does not repeat.
    """
    for cam, field in ((first, "cam"), (then, "then")):
        if not isinstance(cam, CamProfile):
            raise validate.fail(field, cam, "a CamProfile")
    validate.choice("master", master, COORDINATES)
    validate.choice("slave", slave, COORDINATES)
    for unit in ("master_unit", "slave_unit"):
        if getattr(first, unit) != getattr(then, unit):
            raise validate.fail(f"then.{unit}", getattr(then, unit),
                                f"{validate.show(getattr(first, unit))}, the first cam's (derivatives "
                                "are compared per master unit)")
    if at is None:
        at = first.master_period
    at = validate.number("at", validate.plain(at))
    if not first.periodic and not 0.0 < at <= first.master_period:
        raise validate.fail("at", at, f"within {first.name or 'the first cam'}'s master range "
                            f"(0, {first.master_period:g}] (it does not repeat)")
    left = _left_limit(first, at)
    if master == "relative":
        entry = 0.0
    elif then.periodic or 0.0 <= at <= then.master_period:
        entry = at
    else:
        raise InputError(f"master: 'absolute' should be 'relative' here: the join at master "
                         f"{at:g} lies outside {then.name or 'then'}'s master range "
                         f"0..{then.master_period:g}, which does not repeat")
    # a non-periodic B entered at its very end has nothing to its right: take its left limit
    side = "left" if (not then.periodic and entry == then.master_period) else "right"
    values = [float(then(np.array([entry]), order, side=side)[0]) for order in range(len(ORDER_NAMES))]
    offset = left[0] if slave == "relative" else 0.0
    values[0] += offset
    right = tuple(values)
    scale = _local_scale(_segment_at(first, at, "left"), then, entry)
    found = []
    for order in range(len(ORDER_NAMES)):
        a, b = left[order], right[order]
        relative = 1e-12 if order == 0 else 1e-9
        noise = relative * max(abs(a), abs(b)) + 1e-12 * scale[order]
        if abs(b - a) > noise:
            found.append((order, a, b))
    join = Join(at, entry, offset, master, slave, left, right, CheckReport(()))
    return replace(join, report=CheckReport(tuple(Discontinuity(at, order, a, b, join.where)
                                                  for order, a, b in found)))


def _left_limit(first: CamProfile, at: float) -> tuple:
    """A's left limit at ``at``: position (with the net strokes of the periods before),
    velocity, acceleration, jerk per master unit^k."""
    period = first.master_period
    if (at % period == 0.0) if first.periodic else at == period:
        # a period end: a segment ends at its slave_end by definition (its law evaluated there
        # may miss by the rounding of a steep polynomial), the periods before add their strokes
        last = first.segments[-1]
        turns = round(at / period) if first.periodic else 1
        return (last.slave_end + (turns - 1) * (first.net_stroke or 0.0),
                *(last.at(1.0, order) for order in range(1, len(ORDER_NAMES))))
    return tuple(float(first(np.array([at]), order, side="left")[0]) for order in range(len(ORDER_NAMES)))


def _segment_at(cam: CamProfile, x: float, side: str):
    """The segment of ``cam`` that holds master x (wrapped into a periodic cam's period), the one
    before a joint on the left side."""
    if cam.periodic:
        x = x % cam.master_period
        if side == "left" and x == 0.0:
            return cam.segments[-1]
    starts = [segment.master_start for segment in cam.segments]
    index = int(np.searchsorted(starts, x, side="left" if side == "left" else "right")) - 1
    return cam.segments[max(0, min(index, len(cam.segments) - 1))]


def _local_scale(last, then: CamProfile, entry: float) -> list[float]:
    """What the two segments at the join can produce per derivative: their largest
    |stroke| / span**order times the law's peak (Cv, Ca, Cj where finite): the size float noise
    is measured against, as :meth:`CamProfile.jumps` measures it against the neighbours."""
    entered = _segment_at(then, entry, "right")
    out = []
    for order in range(len(ORDER_NAMES)):
        peaks = []
        for segment in (last, entered):
            law = segment.law
            peak = (1.0, law.cv, law.ca, law.cj)[order]
            peak = peak if math.isfinite(peak) else 1.0
            peaks.append(abs(segment.stroke) / segment.span**order * max(1.0, peak))
        out.append(max(peaks))
    return out
