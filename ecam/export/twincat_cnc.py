"""The ISG kernel's ASCII cam table (TwinCAT CNC, ISG-MCE): linear or the ISG cubic.

From the ISG kernel documentation (isg-stuttgart.de/fileadmin/kernel/kernel-html):

* "The table header" (179258123): the keywords ``Tablename`` ("any name without blanks"),
  ``Tabletype``, ``Table-ID``, ``Functiontype`` (interpolation type), ``Lines`` (number of lines
  holding table values). Other pages' examples write ``Function type``; this export follows the page
  that defines the keywords.
* "Table format" (179240075): master position in column 0, slave in column 1, "each in the unit
  1E-4° or 1E-4 mm"; Tabletype 7 is "the two-column integer format".
* "Characteristics of the tables" (179241611): master positions ascending, "at a minimum distance
  of 0.1° from one another", "the maximum table size is limited to 360 master and slave value
  pairs", "the master and slave axes must be a modulo axis".
* "File format of the cam tables" (179256587): the lines "represent the interpolation points of the
  slave axis over the modulo range of the master axis"; "Table format": "the area between the last
  point of the table and its first point is referred to as the first segment" -- the table wraps.
* "Function types" (179262219): ``1 LINEAR``: "The slave position between two table entries is
  interpolated linearly"; ``2 POLYNOM_3``: "Currently not implemented" as a table's own type.
* "Values at the TableFctType input" (179325835), ``MC_CamIn.TableFctType``: ``HLI_POLYNOM_3``
  (2): "Within the position interval of the master axis s_mi, s_mi+1 a constant tangent cubic Bezier
  spline is interpolated between the four adjacent position entries ... s_si-1, s_si, s_si+1,
  s_si+2" (German: "ein tangentenstetiger, kubischer Bezier-Spline"); the table's own Functiontype
  applies only with ``TABLE_DEFINED`` (6).
* "Behaviour of the slave axis at the modulo limit" (179243147): "If an endlessly rotating slave is
  required, either EndlessPositive or EndlessNegative must be specified in the start mode of the FB
  MC_CamIn."

The cubic, as ecam reads it: at every table point the tangent is parallel to the chord through its
two neighbours, and the Bezier's inner control points lie on those tangents one third of the
interval away (in master). The documentation does not give the handle length nor say whether the
first and last points take their neighbours across the wrap. ecam places cubic tables'
points equidistantly -- then every handle length proportional to the chord or the interval gives
the same polynomial -- and certifies the worse of the two readings at the ends: neighbours taken
across the wrap, or the first and last points' tangents from their one neighbour in the table.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .certify import (
    EXPORT_VERSION, Cam, Hermite, Reading, VendorExport, certify, content_crc, divisors, place_local, positional,
    predicted, unreachable,
)
from .table_files import identifier

NAME = "twincat-cnc"
SUFFIX = ".txt"
LIMIT = 360
MIN_POINTS = 2
MIN_SPACING = 1000  # 0.1 deg (or 0.1 mm) in 1e-4 units
INTERPOLATIONS = ("linear", "cubic")
CARRIES = {"linear": "master, slave (integers, 1e-4 deg or mm)", "cubic": "master, slave (integers, 1e-4 deg or mm)"}
RULE = {"linear": "straight line between neighbouring pairs",
        "cubic": "ISG cubic: Bezier with tangents parallel to the chord through the neighbours"}
FUNCTION_TYPE = {"linear": 1, "cubic": 2}

# the kernel's units: 1e-4 deg or 1e-4 mm; the cam's unit -> (kernel unit, kernel units per cam unit)
UNITS = {
    "deg": ("deg", 1.0), "rev": ("deg", 360.0), "rad": ("deg", 180.0 / math.pi),
    "mm": ("mm", 1.0), "um": ("mm", 1e-3), "m": ("mm", 1000.0), "in": ("mm", 25.4),
}


def _factor(unit: str, which: str) -> tuple[str, float]:
    if unit not in UNITS:
        raise InputError(f"{which}_unit: {unit!r} should be one of {', '.join(UNITS)} "
                         f"(the ISG table holds 1e-4 deg or 1e-4 mm)")
    kernel, per = UNITS[unit]
    return kernel, per * 1e4


def export(cam: Cam, *, tolerance, points, interp, name: str) -> VendorExport:
    if not cam.periodic:
        raise InputError("periodic: false should be true for twincat-cnc: the ISG table describes one modulo "
                         "period of the master and wraps from its last point to its first")
    master_kernel, master_factor = _factor(cam.profile.master_unit, "master")
    slave_kernel, slave_factor = _factor(cam.profile.slave_unit, "slave")
    grid = round(cam.period * master_factor)
    if abs(grid - cam.period * master_factor) > 1e-6 * max(1.0, grid) or grid < 2 * MIN_SPACING:
        raise InputError(f"master_period: {cam.period!r} {cam.profile.master_unit} should be a whole number of "
                         f"1e-4 {master_kernel} of at least 0.2 {master_kernel}")
    net_internal = cam.net_stroke * slave_factor
    if interp == "linear":
        knots = place_local(cam, 1, grid=grid, tolerance=tolerance, points=points, limit=LIMIT,
                            what="twincat-cnc linear", file_points=lambda k: k - 1, min_step=MIN_SPACING,
                            quantum=1.0 / slave_factor)
        table = _table(cam, knots, slave_factor)
        readings = [Reading("linear", _linear(cam, table, grid, master_factor, slave_factor))]
        certificate = certify(cam, readings, tolerance)
    else:
        table, certificate = _cubic(cam, grid, tolerance, points, master_factor, slave_factor)

    ident = identifier(name)
    body = [f"Tablename = {ident}", "Table-ID = 1", "Tabletype = 7", f"Functiontype = {FUNCTION_TYPE[interp]}",
            f"Lines = {len(table)}", "Begintable"]
    body += [f"{m} {s}" for m, s in table]
    body += ["EndTable", ""]
    body_text = "\n".join(body)
    c = certificate
    unit, munit = cam.profile.slave_unit, cam.profile.master_unit
    header = [
        f"# Generated by ecam (vendor export {EXPORT_VERSION}) from cam '{cam.name}'; "
        f"CRC-32 0x{content_crc(body_text):08x} of the lines from Tablename on. Do not edit.",
        f"# ISG kernel cam table, two-column integers: master in 1e-4 {master_kernel}, slave in 1e-4 {slave_kernel}"
        f" ({slave_factor:g} per {unit}).",
        f"# Interpolation: {RULE[interp]}" + (" (MC_CamIn.TableFctType := HLI_POLYNOM_3)." if interp == "cubic"
                                               else "."),
        f"# Certified by ecam under it: max error {c.max_error_units:.6g} {unit} ({c.max_error_counts:.6g} counts "
        f"at {cam.scale:g} counts/{unit}) at master {c.max_error_at_master:.6g} {munit}; predicted bound "
        f"{c.predicted_error_units:.6g} {unit}.",
    ]
    notes = [f"master and slave must be modulo axes; the master's modulo range is {positional(cam.period)} "
             f"{munit} ({grid} x 1e-4 {master_kernel})"]
    if interp == "cubic":
        notes.append("give MC_CamIn TableFctType := HLI_POLYNOM_3 (2): the table header's Functiontype 2 is "
                     "documented as 'currently not implemented' and takes effect only with TABLE_DEFINED")
        notes.append("the ISG documentation does not say whether the first and last points take their "
                     "neighbours across the wrap; both readings are certified, the worse one counts")
    else:
        notes.append("MC_CamIn TableFctType := HLI_LINEAR (1), or TABLE_DEFINED (6) to use the table's "
                     "Functiontype")
    if cam.net_stroke:
        mode = "EndlessPositive" if cam.net_stroke > 0 else "EndlessNegative"
        notes.append(f"net stroke {cam.net_stroke:+.6g} {unit} per period: the slave's modulo range must be "
                     f"{abs(cam.net_stroke):.6g} {unit} ({abs(net_internal):.6g} x 1e-4 {slave_kernel}) and "
                     f"MC_CamIn's start mode {mode}")
        header.append(f"# Net stroke {cam.net_stroke:+.6g} {unit} per period: slave modulo range "
                      f"{abs(cam.net_stroke):.6g} {unit}, MC_CamIn start mode {mode}.")
    content = "\n".join(header) + "\n" + body_text
    master = np.array([m for m, _ in table]) / master_factor
    return VendorExport(NAME, interp, len(table), LIMIT, content, SUFFIX, certificate, master, tuple(notes))


def _table(cam: Cam, knots, slave_factor: float) -> list[tuple[int, int]]:
    """(master, slave) integer pairs: the knots but the last, which is the period's end (the table
    wraps to its first pair there)."""
    knots = np.asarray(knots, dtype=np.int64)
    grid = int(knots[-1])
    y = cam(knots[:-1] * (cam.period / grid), 0, "right")
    slaves = np.round(y * slave_factor)
    if np.abs(slaves).max() > 2**31 - 1:
        raise InputError(f"slave position: {np.abs(y).max():.6g} {cam.profile.slave_unit} should fit the ISG "
                         f"table's 32-bit integers of 1e-4 units")
    slaves = slaves.astype(np.int64)
    return [(int(m), int(s)) for m, s in zip(knots[:-1], slaves)]


def _closed(cam: Cam, table, grid: int, master_factor: float, slave_factor: float):
    """Knots over the whole period in user units, the last being the first point one period on."""
    x = np.array([m for m, _ in table] + [table[0][0] + grid], dtype=float) / master_factor
    y = np.array([s for _, s in table] + [table[0][1]], dtype=float) / slave_factor
    y[-1] += cam.net_stroke  # the modulo slave goes on by the net stroke across the wrap
    return x, y


def _linear(cam: Cam, table, grid: int, master_factor: float, slave_factor: float) -> Hermite:
    x, y = _closed(cam, table, grid, master_factor, slave_factor)
    return Hermite.continuous(x, 1, y)


def _cubic_readings(cam: Cam, table, grid: int, master_factor: float, slave_factor: float) -> list[Reading]:
    x, y = _closed(cam, table, grid, master_factor, slave_factor)
    n = len(table)
    period = x[-1] - x[0]
    # tangent at point i parallel to the chord through points i-1 and i+1 (wrapping: one period on)
    prev_x = np.concatenate([[x[n - 1] - period], x[:n - 1]])
    prev_y = np.concatenate([[y[n - 1] - cam.net_stroke], y[:n - 1]])
    next_x, next_y = x[1:n + 1], y[1:n + 1]
    wrap = (next_y - prev_y) / (next_x - prev_x)
    one_sided = wrap.copy()
    one_sided[0] = (y[1] - y[0]) / (x[1] - x[0])
    one_sided[n - 1] = (y[n - 1] - y[n - 2]) / (x[n - 1] - x[n - 2])
    out = []
    for label, slopes in (("neighbours across the wrap", wrap), ("end points from one neighbour", one_sided)):
        data = np.stack([y, np.concatenate([slopes, slopes[:1]])], axis=1)
        out.append(Reading(label, Hermite.continuous(x, 3, data)))
    return out


def _cubic(cam: Cam, grid: int, tolerance, points, master_factor: float, slave_factor: float):
    """Equidistant points: the fewest (a divisor of the period in 1e-4 units) whose worse reading
    meets the tolerance."""
    allowed = [n for n in divisors(grid) if 4 <= n <= LIMIT and grid // n >= MIN_SPACING]
    if points is not None:
        if points not in allowed:
            nearest = min(allowed, key=lambda n: (abs(n - points), n)) if allowed else None
            raise InputError(f"points: {points} should divide the period into equal whole steps of 1e-4 units, "
                             f"at least {MIN_SPACING} apart (e.g. {nearest})")
        allowed = [points]
    if not allowed:
        raise InputError(f"master_period: {grid} x 1e-4 units has no divisor between 4 and {LIMIT} points")
    best = None
    for n in allowed:
        knots = np.arange(n + 1, dtype=np.int64) * (grid // n)
        table = _table(cam, knots, slave_factor)
        readings = _cubic_readings(cam, table, grid, master_factor, slave_factor)
        if points is not None:
            return table, certify(cam, readings, tolerance)
        worst = max(predicted(cam, r) for r in readings)
        if worst <= tolerance:
            return table, certify(cam, readings, tolerance)
        if best is None or worst < best[0]:
            best = (worst, n)
    raise unreachable("twincat-cnc cubic", tolerance, best[0], LIMIT, cam, best[1])
