"""Technosoft (iPOS / EasyMotion Studio): the two-column integer cam table text.

From the EasyMotion Studio help, "CAM Tables Edit" (technosoftmotion.com/ESM-um-html/
help_cam_tables_view.htm):

* "The cam tables are arrays of X, Y points, where X is the cam input i.e. the master position and
  Y is the cam output i.e. the slave position. The X points are expressed in the master internal
  position units, while the Y points are expressed in the slave internal position units. Both X and
  Y points 32-bit long integer values."
* "The X points must be positive (including 0) and equally spaced at: 1, 2, 4, 8, 16, 32, 64 or 128
  i.e. having the interpolation step a power of 2 between 0 and 7. The maximum number of points for
  one cam table is 8192."
* "Press the Import... button to import the cam table points from a simple text file (.txt), with 2
  columns, first the X points and the column with Y points. A tab or a space must separate the
  columns."

The page names the spacing the "interpolation step" but does not write out the formula between
points. ecam reads it as the straight line between neighbouring points -- the only rule the table's
X and Y alone determine -- with the division by the power-of-two step rounded to nearest, floored
(a shift) or truncated toward zero: all three are certified on every master count, the worst counts.

The table covers one master period, its end included. Nothing on the page says how a table whose
last Y differs from its first continues, so a net-stroke cam is refused.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .certify import Cam, VendorExport, certify
from .elmo import choose

NAME = "technosoft"
SUFFIX = ".txt"
LIMIT = 8192
MIN_POINTS = 2
INTERPOLATIONS = ("linear",)
CARRIES = "master, slave (int32 internal units; master step a power of 2 up to 128)"
RULE = "straight line between neighbouring points, output in whole counts"
STEPS = tuple(2**k for k in range(7, -1, -1))  # largest step (fewest points) first


def export(cam: Cam, *, tolerance, points, interp, name: str) -> VendorExport:
    if cam.net_stroke:
        raise InputError(
            f"net stroke: {cam.net_stroke:+.6g} {cam.profile.slave_unit} per period should be 0 for technosoft: "
            f"the EasyMotion Studio page describes absolute slave positions over the table's master range and no "
            f"way for the slave to continue from a different end position; use codesys, twincat-cnc, elmo or csv")
    allowed = [cam.master_counts // step for step in STEPS
               if cam.master_counts % step == 0 and cam.master_counts // step + 1 <= LIMIT]
    if not allowed:
        raise InputError(f"master_counts: {cam.master_counts} should be a multiple of a power of two up to 128 "
                         f"with at most {LIMIT} points (the Technosoft master step)")
    intervals, entries, readings = choose(cam, tolerance, points, LIMIT, allowed, "technosoft (linear)",
                                          steps="master steps of 1, 2, 4, ... or 128 counts")
    step = cam.master_counts // intervals
    certificate = certify(cam, readings, tolerance)
    rows = [f"{k * step}\t{int(v)}" for k, v in enumerate(entries)]
    content = "\n".join(rows) + "\n"
    unit = cam.profile.slave_unit
    notes = [
        f"master start 0, interpolation step {step} master counts (2^{step.bit_length() - 1}); the table covers "
        f"one master period of {cam.master_counts} counts, its end included; Y in slave counts "
        f"({cam.scale:g} counts/{unit})",
        "the page does not write out the interpolation between points: straight lines with the output "
        "rounded to nearest, floored or truncated are certified, the worst counts",
    ]
    if cam.periodic:
        notes.append(f"the master position must wrap every {cam.master_counts} counts for the cam to repeat")
    master = np.arange(entries.size) * (step * cam.period / cam.master_counts)
    return VendorExport(NAME, "linear", int(entries.size), LIMIT, content, SUFFIX, certificate, master,
                        tuple(notes))
