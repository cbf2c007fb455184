"""Kollmorgen Automation Suite (KAS): the cam profile CSV the KAS IDE imports.

From the KAS documentation (webhelp.kollmorgen.com/kas, "Import Cam Profile"):

* Row syntax: ``CYCLIC;YES;`` then ``TABLE_BEGIN;;``, then one ``X;Y;SPLINE`` row per point, then
  ``TABLE_END;;``. "The X and Y coordinates can be specified as floating-point values with
  sufficient digits after the decimal point (example: 995.2514255)." -- so this export writes plain
  decimals, never an exponent. "To be valid, a CSV file must have at least 4 spline segments."
  "Splines are the only segment type that is currently supported when importing CSV data."
* Normalisation: "When a CSV file is imported the X, Y values are normalized with respect to
  maximum X, Y values present in the CSV file. The normalized X, Y values are scaled with respect
  to Master/Input scale and Slave/Output scale. They are added with Master/Input Offset and Slave
  /Output Offset." So the profile KAS runs is ``scale * value / max + offset``: with the scale set
  to the file's maximum and the offset to the shift ecam applies, it is the cam itself. ecam writes
  the slave shifted to start its range at 0 (so that "maximum" cannot be read as the largest
  magnitude of a negative value) and reports the scale and offsets to enter.
* "CAM Profile Segments" (webhelp.kollmorgen.com/kas, Cam-Profile/CAM-Profile-Segments.htm): the
  spline segment type interpolates with a "3rd order polynomial: f(x) = Ax3 + Bx2 + Cx + D",
  continuous in velocity and acceleration, and "only positions are specified"; "Cam Profile Editor's
  Cam Table": for a cyclic profile "the first and last element must have the same Vel and Accel
  values".

Not documented: the spline's end conditions. ecam certifies the worst of the plausible readings:
for a cyclic profile the periodic spline (what "same Vel and Accel" at both ends asks for), the
natural spline (zero acceleration at both ends) and the not-a-knot spline; for a non-cyclic one the
natural and the not-a-knot spline. The normalisation scales master and slave, which changes none
of these splines. The point limit, 1000, is AKD BASIC's ("Overview of Camming in AKD-Basic",
kdn.kollmorgen.com: "You can define up to 1000 data points for the cam profile"); the KAS pages
state none.

A net stroke cannot be expressed: nothing in these pages says how a cyclic KAS profile whose end
position differs from its start continues, so ecam refuses rather than guess.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..linear import solve_sparse
from .certify import (
    Cam, Hermite, Reading, VendorExport, certify, fewest, positional, predicted, spread_knots, unreachable,
)

NAME = "kollmorgen"
SUFFIX = ".csv"
LIMIT = 1000
MIN_POINTS = 5  # at least 4 spline segments
INTERPOLATIONS = ("spline",)
CARRIES = "X, Y (floating point; normalised by KAS to their maxima)"
RULE = "cubic spline through all points (end conditions not documented)"
# A spline is not local: a long interval next to short ones (a dwell spanned at once) lets an end
# condition's error spread. Points are placed by the 4th derivative plus this share of its mean, and
# the first and last stretches between joints get two intervals at least (a not-a-knot spline runs
# one cubic through the first two).
SPREAD = 0.25


def spline_slopes(x: np.ndarray, y: np.ndarray, condition: str) -> np.ndarray:
    """First derivatives at the knots of the C2 cubic spline through (x, y) with the end
    ``condition``: 'periodic' (slope and curvature equal at both ends; y[-1] must equal y[0]),
    'natural' (zero curvature at both ends) or 'not-a-knot' (third derivative continuous at the
    second and second-to-last knots)."""
    n = x.size - 1
    h = np.diff(x).tolist()
    d = (np.diff(y) / np.diff(x)).tolist()
    rows: list[dict] = [{} for _ in range(n + 1)]
    rhs = [0.0] * (n + 1)
    for i in range(1, n):  # curvature continuous at inner knots
        rows[i] = {i - 1: 1 / h[i - 1], i: 2 * (1 / h[i - 1] + 1 / h[i]), i + 1: 1 / h[i]}
        rhs[i] = 3 * (d[i - 1] / h[i - 1] + d[i] / h[i])
    if condition == "natural":
        rows[0], rhs[0] = {0: 2.0, 1: 1.0}, 3 * d[0]
        rows[n], rhs[n] = {n - 1: 1.0, n: 2.0}, 3 * d[n - 1]
    elif condition == "not-a-knot":
        # (m0 + m1 - 2 d0) / h0^2 = (m1 + m2 - 2 d1) / h1^2, and the same at the other end
        rows[0] = {0: 1 / h[0] ** 2, 1: 1 / h[0] ** 2 - 1 / h[1] ** 2, 2: -1 / h[1] ** 2}
        rhs[0] = 2 * d[0] / h[0] ** 2 - 2 * d[1] / h[1] ** 2
        rows[n] = {n - 2: 1 / h[n - 2] ** 2, n - 1: 1 / h[n - 2] ** 2 - 1 / h[n - 1] ** 2, n: -1 / h[n - 1] ** 2}
        rhs[n] = 2 * d[n - 2] / h[n - 2] ** 2 - 2 * d[n - 1] / h[n - 1] ** 2
    elif condition == "periodic":
        # m0 = mn; the curvature leaving knot 0, (6 d0 - 4 m0 - 2 m1) / h0, equals the curvature
        # arriving at knot n, (-6 d_{n-1} + 2 m_{n-1} + 4 mn) / h_{n-1}
        rows[0] = {0: 1.0, n: -1.0}
        rows[n] = {0: 4 / h[0], 1: 2 / h[0], n - 1: 2 / h[n - 1], n: 4 / h[n - 1]}
        rhs[n] = 6 * d[0] / h[0] + 6 * d[n - 1] / h[n - 1]
    else:
        raise ValueError(condition)
    return solve_sparse(rows, rhs)  # the same bits on every machine (ecam.linear)


def _conditions(cam: Cam) -> tuple[str, ...]:
    return ("periodic", "natural", "not-a-knot") if cam.periodic else ("natural", "not-a-knot")


def _readings(cam: Cam, x: np.ndarray, y: np.ndarray, offset: float) -> list[Reading]:
    out = []
    for condition in _conditions(cam):
        slopes = spline_slopes(x, y, condition)
        data = np.stack([y + offset, slopes], axis=1)
        out.append(Reading(f"{condition} spline", Hermite.continuous(x, 3, data)))
    return out


def _rows(cam: Cam, knots: np.ndarray, grid: int, offset: float):
    x = knots * (cam.period / grid)
    y = cam(x, 0, "right") - offset
    y[-1] = cam(np.array([cam.period]))[0] - offset
    text = [(positional(a), positional(b)) for a, b in zip(x, y)]
    return text, np.array([float(a) for a, _ in text]), np.array([float(b) for _, b in text])


def export(cam: Cam, *, tolerance, points, interp, name: str) -> VendorExport:
    if cam.net_stroke:
        raise InputError(
            f"net stroke: {cam.net_stroke:+.6g} {cam.profile.slave_unit} per period should be 0 for kollmorgen: "
            f"the KAS pages describe a cyclic profile's matching velocity and acceleration at its ends, not a "
            f"slave that continues from a different end position; use codesys, twincat-cnc, elmo or csv")
    low, high = cam.profile.slave_range
    offset = min(0.0, low)  # written values start at >= 0: KAS divides by their maximum
    if high - offset <= 0:
        raise InputError("slave position: 0 everywhere should leave 0 somewhere for kollmorgen: KAS divides the "
                         "CSV by its largest slave value")
    grid = cam.master_counts
    forced = cam.breaks(3)

    def attempt(count):
        knots = spread_knots(cam, count, 4, forced, grid, floor=SPREAD, end_intervals=2)
        text, x, y = _rows(cam, knots, grid, offset)
        return text, x, _readings(cam, x, y, offset)

    if points is None:
        def ok(count):
            try:
                readings = attempt(count)[2]
            except InputError:  # fewer points than the joints that must be points
                return False
            return max(predicted(cam, r) for r in readings) <= tolerance

        points = fewest(range(MIN_POINTS, LIMIT + 1), ok)
        if points is None:
            _, _, readings = attempt(LIMIT)
            best = max(predicted(cam, r) for r in readings)
            raise unreachable("kollmorgen (spline)", tolerance, best, LIMIT, cam, LIMIT)
    text, x, readings = attempt(points)
    certificate = certify(cam, readings, tolerance)
    lines = ["CYCLIC;YES;" if cam.periodic else "CYCLIC;NO;", "TABLE_BEGIN;;"]
    lines += [f"{a};{b};SPLINE" for a, b in text]
    lines += ["TABLE_END;;", ""]
    content = "\n".join(lines)
    max_x = max(float(a) for a, _ in text)
    max_y = max(float(b) for _, b in text)
    unit, munit = cam.profile.slave_unit, cam.profile.master_unit
    notes = [
        f"in the KAS cam profile set Master/Input scale {positional(max_x)} {munit}, offset 0; "
        f"Slave/Output scale {positional(max_y)} {unit}, offset {positional(offset)} {unit} "
        f"(KAS divides the CSV by its largest X and Y)",
        "the KAS pages do not give the spline's end conditions: the "
        + ", ".join(_conditions(cam)) + " splines are certified, the worst counts",
    ]
    return VendorExport(NAME, "spline", len(text), LIMIT, content, SUFFIX, certificate, x, tuple(notes))
