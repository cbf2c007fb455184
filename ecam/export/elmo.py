"""Elmo (SimplIQ / Harmonica drives): the electronic cam table ET[] and the EM[] settings it needs,
as interpreter commands.

From the SimplIQ Software Manual (MAN-SIMSW Ver. 1.4, section 11.2.2 "ECAM", page 11-33, table
11-10 "ECAM-related Commands") and the HARmonica Software Manual (HARSFEN0602, section 12.2.1):

* ``EM[2]``: "The last valid index of the ECAM table. The maximum for EM[2] is 1024." (HARmonica).
  ``EM[5]``: "First valid index of ECAM table. The EM[2] setting goes into effect at next setting
  of EM[5] or next MO=1" (SimplIQ), so EM[5] is written after EM[2].
* ``EM[3]``: starting position; ``EM[4]``: "Table difference": the master step between entries.
  ``EM[7]``: "Last interval shortening. EM[7] allows the ECAM table length (ECAM cycle in the
  EM[1]=2 cyclical mode) not to be an integer multiple of EM[4]".
* "The input to the ECAM table (IET) is FR[3] * (auxiliary encoder - EM[3]). The ECAM table
  defines the external position reference for IET values between 0 and IETmax = (EM[2] - EM[5]) *
  EM[4] - EM[7]."
* 11.2.2.1: "Linear ECAM is selected by EM[1]=1 ... If 0 < IET < IETmax, the external position
  command will be derived by linear interpolation of the ECAM table"; ``EM[1]=2`` is the cyclical
  mode (the EM[7] entry above: "ECAM cycle in the EM[1]=2 cyclical mode"), in which the table repeats
  every IETmax.
* "If the output of the ECAM table is out of the position sensor range, it is interpreted modulo the
  position sensor range."

So entries are slave positions in counts at equidistant master counts, joined by straight lines.
ecam makes the master step divide the cam's master period in counts (``EM[7] = 0``: how a shortened
last interval is interpolated is not spelled out). Not documented: how the drive rounds the
interpolated position to whole counts -- ecam certifies the worst of rounding to nearest, flooring
and truncating toward zero, on every master count of the period.

A net stroke works where the slave position wraps: with the position sensor range (XM[1], XM[2])
equal to the net stroke in counts (or a whole fraction of it), the cyclic table's jump back from
its last entry to its first is no move at all. So the net stroke must be a whole number of counts.

The file holds commands only, one per line (``EM[1]=0;``): the stored manual pages do not show the
user-program comment syntax, and a wrong guess would stop the drive at the first line.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .certify import Cam, Hermite, Reading, VendorExport, certify, divisors, predicted, unreachable

NAME = "elmo"
SUFFIX = ".txt"
LIMIT = 1024  # ET[1..1024]
MIN_POINTS = 2
INTERPOLATIONS = ("linear",)
CARRIES = "slave position, counts (ET[] entries; master step EM[4] in counts)"
RULE = "straight line between neighbouring entries, output in whole counts"
_INT32 = 2**31 - 1

ROUNDINGS = {
    "rounded to nearest": lambda num, den: np.floor_divide(2 * num + den, 2 * den),
    "floored": lambda num, den: np.floor_divide(num, den),
    "truncated toward zero": lambda num, den: np.sign(num) * np.floor_divide(np.abs(num), den),
}
ROUNDING_BOUND = {"rounded to nearest": 0.5, "floored": 1.0, "truncated toward zero": 1.0}


def linear_readings(cam: Cam, entries: np.ndarray, step: int) -> list[Reading]:
    """The consumer's straight lines through integer ``entries`` every ``step`` master counts, with
    each plausible rounding of the output to whole counts."""
    intervals = entries.size - 1
    x = np.arange(entries.size) * (step * cam.period / cam.master_counts)
    hermite = Hermite.continuous(x, 1, entries / cam.scale)
    out = []
    for name, rounding in ROUNDINGS.items():
        def output(counts, rounding=rounding):
            i = np.minimum(counts // step, intervals - 1)
            offset = counts - i * step
            num = entries[i] * step + (entries[i + 1] - entries[i]) * offset
            return rounding(num, step).astype(float)

        out.append(Reading(f"linear, {name}", hermite, output, ROUNDING_BOUND[name]))
    return out


def entries_for(cam: Cam, intervals: int) -> np.ndarray:
    step = cam.master_counts // intervals
    y = cam(np.arange(intervals + 1) * (step * cam.period / cam.master_counts), 0, "right")
    y[-1] = cam(np.array([cam.period]))[0]
    values = np.round(y * cam.scale)
    if np.abs(values).max() > _INT32:
        raise InputError(f"slave_counts_per_unit: {cam.scale:g} should keep every table entry within int32 "
                         f"(largest {np.abs(values).max():.0f} counts)")
    return values.astype(np.int64)


def choose(cam: Cam, tolerance, points, limit: int, allowed: list[int], what: str,
           steps: str = "equal whole master steps"):
    """The fewest intervals among ``allowed`` (ascending) whose worst reading meets the tolerance,
    or the given number of points. Returns (intervals, entries, readings)."""
    if points is not None:
        if points - 1 not in allowed:
            nearest = min(allowed, key=lambda n: (abs(n + 1 - points), n)) + 1 if allowed else None
            raise InputError(f"points: {points} should be one more than a number of {steps} in "
                             f"{cam.master_counts} counts (e.g. {nearest})")
        allowed = [points - 1]
    best = None
    for intervals in allowed:
        entries = entries_for(cam, intervals)
        readings = linear_readings(cam, entries, cam.master_counts // intervals)
        if points is not None:
            return intervals, entries, readings
        worst = max(predicted(cam, r) for r in readings)
        if worst <= tolerance:
            return intervals, entries, readings
        if best is None or worst < best[0]:
            best = (worst, intervals + 1)
    if best is None:
        raise InputError(f"master_counts: {cam.master_counts} should have a divisor giving at most {limit} points")
    raise unreachable(what, tolerance, best[0], limit, cam, best[1])


def export(cam: Cam, *, tolerance, points, interp, name: str) -> VendorExport:
    net_counts = cam.net_stroke * cam.scale
    if cam.net_stroke and abs(net_counts - round(net_counts)) > 1e-6:
        raise InputError(
            f"net stroke: {cam.net_stroke:+.6g} {cam.profile.slave_unit} per period ({net_counts:.6g} counts) should "
            f"be a whole number of counts for elmo: the table carries a net stroke only through the position "
            f"sensor's modulo range (XM), in whole counts; choose slave_counts_per_unit accordingly")
    allowed = [n for n in divisors(cam.master_counts) if n + 1 <= LIMIT]
    intervals, entries, readings = choose(cam, tolerance, points, LIMIT, allowed, "elmo (ET[], linear)")
    step = cam.master_counts // intervals
    certificate = certify(cam, readings, tolerance)
    mode = 2 if cam.periodic else 1
    lines = ["EM[1]=0;"]
    lines += [f"ET[{k + 1}]={int(v)};" for k, v in enumerate(entries)]
    lines += [f"EM[2]={entries.size};", "EM[3]=0;", f"EM[4]={step};", "EM[7]=0;", "EM[5]=1;", "FR[3]=1;",
              f"EM[1]={mode};", ""]
    unit = cam.profile.slave_unit
    notes = [
        f"ET[1..{entries.size}] slave counts ({cam.scale:g} counts/{unit}) every EM[4]={step} master counts of "
        f"the auxiliary encoder (master period {cam.master_counts} counts), EM[1]={mode} "
        f"({'cyclical' if mode == 2 else 'linear'} ECAM)",
        "the manual does not say how the interpolated position is rounded to whole counts: rounding to "
        "nearest, flooring and truncating toward zero are certified, the worst counts",
    ]
    if cam.net_stroke:
        notes.append(f"net stroke {cam.net_stroke:+.6g} {unit} = {round(net_counts):+d} counts per period: set the "
                     f"position sensor's modulo range (XM[1], XM[2]) to {abs(round(net_counts))} counts or a whole "
                     f"fraction of it, so the table's wrap from ET[{entries.size}] to ET[1] is no move")
    master = np.arange(entries.size) * (step * cam.period / cam.master_counts)
    return VendorExport(NAME, "linear", int(entries.size), LIMIT, "\n".join(lines), SUFFIX, certificate, master,
                        tuple(notes))
