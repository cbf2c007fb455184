"""The ISG kernel's cam table (TwinCAT CNC, ISG-MCE): an interpolation point table, linear or the
ISG cubic.

The ISG kernel documentation (isg-stuttgart.de/fileadmin/kernel/kernel-html/en-GB/<page>.html,
republished by Beckhoff for TwinCAT CNC at infosys.beckhoff.com/content/1033/tccncmcplatform_fb/)
describes two kinds of cam table, and only one of them is interpolated linearly or cubically:

* "Cam description by interpolation point tables" (179211019; Beckhoff 15306123915): "The entries
  (= lines in the cam table) in the interpolation point tables are represented by equidistant
  interpolation points of the slave axis across the modulo range of the master axis. This is why no
  master positions are kept in this table type." The form is "only suitable for use with closed
  scanning because ... the slave position at the end of the cam is implicitly assumed as being equal
  to the slave position at the start of the cam."  The other kind, "tables with alternating
  LINE/POLY5 motion sections", holds master/slave pairs (Tabletype 7, Functiontype 4 or 5) joined by
  straight lines and fifth-order blends; ecam does not write that kind.
* "Online interpolation of interpolation point tables" (179215243; Beckhoff 15306126987):
  ``MC_CamIn.TableFctType`` chooses the interpolation: ``HLI_LINEAR`` (1) "a linear interpolation is
  placed between the slave position entries s_si, s_si+1"; ``HLI_POLYNOM_3`` (2) "a constant tangent
  cubic Bezier spline is interpolated between the four adjacent slave position entries s_si-1, s_si,
  s_si+1, s_si+2. Polynomial coefficient calculation takes place online. ... at every interpolation
  point, the tangent is a parallel line to the straight line that passes through the two
  neighbouring interpolation points", and "the slave positions from the 'neighbouring' modulo
  ranges are also used to compute ... the pitch": the first and last entries take their neighbours
  across the wrap.
* "Closed processing for an endlessly rotating slave axis" (Beckhoff 15306128523): with HLI_LINEAR or
  HLI_POLYNOM_3 "the table interpolation points that are used to calculate the interpolation must be
  corrected by one modulo range at the cam's definition limits", in the direction given by
  ``HLI_CI_ENDLESS_POSITIVE`` (16#20) or ``HLI_CI_ENDLESS_NEGATIVE`` (16#40) ORed into
  ``MC_CamIn.StartMode``. So a net stroke per period is exactly one slave modulo range.
* "The table header" (179258123): keywords ``Tablename`` ("any name without blanks"), ``Tabletype``,
  ``Table-ID``, ``Functiontype``, ``Lines`` ("number of lines which contain the table values"),
  then ``Begintable`` ... ``EndTable``; the examples put comments after ``#`` at the end of a line.
  "Table types" (Beckhoff 15306153099): 2 = TABLE_ONE_COLUMN_SGN32. "Table format" (Beckhoff
  15306136203): "Contrary to the interpolation point tables, in the case of these [LINE/POLY5] tables
  the ... interpolation type can be specified in the 'Functiontype' token": for this table the
  interpolation is the one MC_CamIn commands. "Function types" (179262219): 1 LINEAR, 2 POLYNOM_3
  "currently not implemented" (as a table's own type).

What ecam reads into it, and why:

* Positions are whole 1e-4 deg or 1e-4 mm, the unit the pages give for the kernel's tables (179211019).
* The cubic's polynomial: "polynomial coefficient calculation" means the slave is a cubic
  polynomial of the master on each interval, so the Bezier's inner control points lie on those
  tangents a third of the interval away in master; with equidistant entries that is the cubic
  Hermite polynomial whose slope at an entry is the chord slope through its neighbours.
* Limits: the pages give 360 pairs and 0.1 deg (0.1 mm) spacing for the master/slave tables
  ("Characteristics of the tables", 179241611; ID 60260/60261 in the diagnosis manual tie both to
  LINE/POLY5 tables) and none for interpolation point tables. ecam keeps to them here as well, and
  to entry spacings that are whole 1e-4 units (it cannot know how the kernel rounds the master
  split otherwise): the number of entries divides the master's modulo range in 1e-4 units.
* Cams can only be "an absolute coupling between two endlessly rotating axes" (179206283): a cam
  that is not periodic is refused.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .certify import (
    EXPORT_VERSION, Cam, Hermite, Reading, VendorExport, certify, content_crc, positional, predicted,
    unreachable,
)
from .escape import line_comment
from .table_files import identifier

NAME = "twincat-cnc"
SUFFIX = ".txt"
LIMIT = 360
MIN_POINTS = 2
MIN_SPACING = 1000  # 0.1 deg (or 0.1 mm) in 1e-4 units
TABLETYPE = 2  # TABLE_ONE_COLUMN_SGN32
INTERPOLATIONS = ("linear", "cubic")
CARRIES = {"linear": "slave position (integer, 1e-4 deg or mm), equidistant in master",
           "cubic": "slave position (integer, 1e-4 deg or mm), equidistant in master"}
RULE = {"linear": "straight line between neighbouring entries (MC_CamIn.TableFctType HLI_LINEAR)",
        "cubic": "ISG cubic: tangent at an entry parallel to the chord through its neighbours "
                 "(MC_CamIn.TableFctType HLI_POLYNOM_3)"}
# (the name MC_CamIn knows the interpolation by, its TableFctType, the header's Functiontype)
TABLE_FCT_TYPE = {"linear": ("HLI_LINEAR", 1), "cubic": ("HLI_POLYNOM_3", 2)}
ENDLESS = {1: ("HLI_CI_ENDLESS_POSITIVE", "16#20"), -1: ("HLI_CI_ENDLESS_NEGATIVE", "16#40")}

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


def entry_counts(grid: int) -> list[int]:
    """Entry counts the table may have, ascending: divisors of the master's modulo range in 1e-4
    units from MIN_POINTS to LIMIT whose spacing is at least MIN_SPACING.

    Only those LIMIT - 1 candidates are tried: listing every divisor of a range of up to 10^16
    units would take 10^8 trial divisions."""
    return [n for n in range(MIN_POINTS, LIMIT + 1) if grid % n == 0 and grid // n >= MIN_SPACING]


def entries_for(cam: Cam, count: int, slave_factor: float) -> np.ndarray:
    """The table: the slave at master k * P / count, k = 0 .. count - 1, in whole 1e-4 units."""
    y = cam(np.arange(count) * (cam.period / count), 0, "right")
    values = np.round(y * slave_factor)
    if np.abs(values).max() > 2**31 - 1:
        raise InputError(f"slave position: {np.abs(y).max():.6g} {cam.profile.slave_unit} should fit the ISG "
                         f"table's 32-bit integers of 1e-4 units")
    return values.astype(np.int64)


def interpolant(cam: Cam, entries: np.ndarray, interp: str, slave_factor: float) -> Hermite:
    """The kernel's interpolant over one period, in the cam's units: knots at the entries and one
    period on, where the first entry returns corrected by one modulo range (the net stroke)."""
    n = entries.size
    x = np.arange(n + 1) * (cam.period / n)
    y = np.append(entries, entries[0]) / slave_factor
    y[-1] += cam.net_stroke
    if interp == "linear":
        return Hermite.continuous(x, 1, y)
    # tangent at entry i parallel to the chord through entries i-1 and i+1, across the wrap
    previous = np.concatenate([[y[n - 1] - cam.net_stroke], y[:n - 1]])
    following = y[1:n + 1]
    slopes = (following - previous) / (2 * cam.period / n)
    return Hermite.continuous(x, 3, np.stack([y, np.append(slopes, slopes[0])], axis=1))


def export(cam: Cam, *, tolerance, points, interp, name: str) -> VendorExport:
    if not cam.periodic:
        raise InputError("periodic: false should be true for twincat-cnc: ISG cams couple two endlessly "
                         "rotating axes over the master's whole modulo range, the last entry running on to the "
                         "first")
    master_kernel, master_factor = _factor(cam.profile.master_unit, "master")
    slave_kernel, slave_factor = _factor(cam.profile.slave_unit, "slave")
    grid = round(cam.period * master_factor)
    if abs(grid - cam.period * master_factor) > 1e-6 * max(1.0, grid) or grid < MIN_POINTS * MIN_SPACING:
        raise InputError(f"master_period: {cam.period!r} {cam.profile.master_unit} should be a whole number of "
                         f"1e-4 {master_kernel} of at least 0.2 {master_kernel}")
    allowed = entry_counts(grid)
    if not allowed:
        raise InputError(f"master_period: {grid} x 1e-4 {master_kernel} should split into {MIN_POINTS} to {LIMIT} "
                         f"equal whole steps of at least 0.1 {master_kernel}")
    if points is not None:
        if points not in allowed:
            nearest = min(allowed, key=lambda n: (abs(n - points), n))
            raise InputError(f"points: {points} should divide the master period ({grid} x 1e-4 {master_kernel}) "
                             f"into equal whole steps of at least 0.1 {master_kernel} (e.g. {nearest})")
        allowed = [points]

    def reading(count):
        entries = entries_for(cam, count, slave_factor)
        return entries, Reading(f"{interp}, {TABLE_FCT_TYPE[interp][0]}",
                                interpolant(cam, entries, interp, slave_factor))

    best = None
    for count in allowed:  # ascending: the first that meets the tolerance has the fewest entries
        entries, chosen = reading(count)
        if points is not None:
            break
        bound = predicted(cam, chosen)
        if bound <= tolerance:
            break
        if best is None or bound < best[0]:
            best = (bound, count)
    else:
        raise unreachable(f"twincat-cnc {interp}", tolerance, best[0], LIMIT, cam, best[1])
    certificate = certify(cam, [chosen], tolerance)
    count = entries.size
    step = cam.period / count
    function, fct_value = TABLE_FCT_TYPE[interp]
    unit, munit = cam.profile.slave_unit, cam.profile.master_unit
    values = "".join(f"{int(v)}\n" for v in entries)
    c = certificate
    lines = [
        f"Tablename = {identifier(name)}  # ecam vendor export {EXPORT_VERSION} of cam '{line_comment(cam.name)}'; CRC-32 "
        f"0x{content_crc(values):08x} of the {count} value lines",
        "Table-ID = 1  # any ID no other table on the controller uses",
        f"Tabletype = {TABLETYPE}  # TABLE_ONE_COLUMN_SGN32: slave positions in 1e-4 {slave_kernel} "
        f"({slave_factor:g} per {unit}), equidistant over the master's modulo range",
        f"Functiontype = {fct_value}  # {function[4:]}; MC_CamIn.TableFctType := {function} ({fct_value}) decides",
        f"Lines = {count}  # entry k at master k x {positional(step)} {munit}; master modulo range "
        f"{positional(cam.period)} {munit}",
        "Begintable",
        values.rstrip("\n"),
        f"EndTable  # certified by ecam under {function}: max error {c.max_error_units:.6g} {unit} "
        f"({c.max_error_counts:.6g} counts) at master {c.max_error_at_master:.6g} {munit}, bound "
        f"{c.predicted_error_units:.6g} {unit}",
        "",
    ]
    notes = [f"interpolation point table: the master's modulo range must be {positional(cam.period)} {munit} "
             f"({grid} x 1e-4 {master_kernel}), the slave a modulo axis; MC_CamIn.TableFctType := {function} "
             f"({fct_value})"]
    if cam.net_stroke:
        mode, value = ENDLESS[1 if cam.net_stroke > 0 else -1]
        notes.append(f"net stroke {cam.net_stroke:+.6g} {unit} per period: the slave's modulo range must be "
                     f"{abs(cam.net_stroke):.6g} {unit} ({abs(cam.net_stroke) * slave_factor:.10g} x 1e-4 "
                     f"{slave_kernel}), with {mode} ({value}) ORed into MC_CamIn.StartMode")
    if interp == "cubic":
        notes.append("the header's Functiontype 2 (POLYNOM_3) is documented as 'currently not implemented' as a "
                     "table's own type; the interpolation is MC_CamIn.TableFctType's, so do not pass TABLE_DEFINED")
    master = np.arange(count) * step
    return VendorExport(NAME, interp, count, LIMIT, "\n".join(lines), SUFFIX, certificate, master, tuple(notes))
