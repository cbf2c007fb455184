"""The golden vendor exports in firmware_tables/exports/, read back as each controller reads them.

Every reader here is written from the vendor's documentation (quoted in ecam/export/<format>.py),
not from ecam's writers: it parses the file as the controller would, interpolates as the
documentation says (with scipy where a textbook routine exists), and measures the error against the
analytic cam. The measurement must stay within the certificate's predicted bound and agree with
the certificate's measured maximum (which also searches each interval's extremum, so it may only be
slightly larger than a reader's dense sampling; on consumers that see whole master counts the two
are the same numbers). The net-stroke cam (rotary_knife) is read over two periods, the second one
continued the way the vendor's documentation says a slave that does not return is run.
"""

import json
import math
import re

import numpy as np
import pytest
from scipy.interpolate import BPoly, CubicSpline

import ecam
from conftest import CAMS, ROOT

EXPORTS = ROOT / "firmware_tables" / "exports"
SEEDS = ("combination_drrd", "modified_sine")
NET = "rotary_knife"  # +360 deg per period
SAMPLES = 400  # per interval, for consumers that evaluate at any master position


def certificates(stem):
    document = json.loads((EXPORTS / f"{stem}.certificates.json").read_text())
    return {entry["file"].split("/")[-1]: entry for entry in document["exports"] if "file" in entry}


def cam(stem):
    return ecam.load_cam(CAMS / f"{stem}.toml")


def exact(profile, master):
    """The cam at master positions; a net-stroke cam unrolled (one net stroke per period passed), a
    returning one at P the value the period ends with."""
    master = np.asarray(master, dtype=float)
    if profile.net_stroke:
        return profile(master)
    values = profile(np.minimum(master, profile.master_period))
    end = master >= profile.master_period
    return np.where(end, profile(profile.master_period, side="left"), values)


def dense(knots):
    """SAMPLES points in every interval between the knots, both ends included."""
    t = np.linspace(0.0, 1.0, SAMPLES + 1)
    return np.unique((knots[:-1, None] + t[None, :] * np.diff(knots)[:, None]).ravel())


def agrees(measured_units, entry, exhaustive=False):
    """The reader's measurement against the certificate."""
    assert measured_units <= entry["predicted_error_units"] * (1 + 1e-9), (measured_units, entry)
    if exhaustive:
        assert math.isclose(measured_units, entry["max_error_units"], rel_tol=1e-9, abs_tol=1e-12)
    else:
        assert measured_units <= entry["max_error_units"] * (1 + 1e-6) + 1e-12
        assert measured_units >= entry["max_error_units"] * 0.98
    if "tolerance_units" in entry:
        assert entry["predicted_error_units"] <= entry["tolerance_units"]


def wrapped(difference, modulo):
    """A difference of positions on a modulo axis, in [-modulo/2, modulo/2)."""
    return np.mod(np.asarray(difference) + modulo / 2, modulo) - modulo / 2


# -- CODESYS: SMC_CAMXYVA points, one fifth-degree polynomial per interval through X, Y, V, A ------------
def read_codesys(text):
    points = [tuple(float(v) for v in m) for m in re.findall(
        r"\(dX := ([-\d.]+), dY := ([-\d.]+), dV := ([-\d.]+), dA := ([-\d.]+)\)", text)]
    ref = re.search(r"MC_CAM_REF := \((.*)\);", text).group(1)
    fields = dict(item.split(" := ") for item in ref.split(", "))
    assert fields["byType"] == "3"  # SMC_CAM_TYPE.XYVA
    assert int(fields["nElements"]) == len(points)
    declared = re.search(r"ARRAY\[0\.\.(\d+)\] OF SMC_CAMXYVA", text)
    assert int(declared.group(1)) == len(points) - 1
    x = np.array([p[0] for p in points])
    assert float(fields["xStart"]) == x[0] and float(fields["xEnd"]) == x[-1]
    return np.array(points)


def xyva_polynomials(points):
    """For each interval the coefficients of y(x - x0) = sum c_k (x - x0)^k, k = 0..5, solved from
    Y, V = dY/dX and A = d2Y/dX2 at both ends."""
    out = []
    for (x0, y0, v0, a0), (x1, y1, v1, a1) in zip(points[:-1], points[1:]):
        h = x1 - x0
        rows = [[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 2, 0, 0, 0],
                [1, h, h**2, h**3, h**4, h**5],
                [0, 1, 2 * h, 3 * h**2, 4 * h**3, 5 * h**4],
                [0, 0, 2, 6 * h, 12 * h**2, 20 * h**3]]
        out.append(np.linalg.solve(np.array(rows, dtype=float), [y0, v0, a0, y1, v1, a1]))
    return np.array(out)


@pytest.mark.parametrize("stem", SEEDS)
def test_codesys_xyva_read_back(stem):
    name = f"{stem}.codesys.st"
    points = read_codesys((EXPORTS / name).read_text())
    coefficients = xyva_polynomials(points)
    x = dense(points[:, 0])
    i = np.clip(np.searchsorted(points[:, 0], x, side="right") - 1, 0, len(points) - 2)
    y = np.polynomial.polynomial.polyval(x - points[i, 0], coefficients[i].T, tensor=False)
    error = np.abs(y - exact(cam(stem), x)).max()
    agrees(error, certificates(stem)[name])


def codesys_relative(points, x):
    """MC_CamIn.StartMode relative on a periodic cam: "The position of the slave after the end of the
    previous cycle is added as a slave offset to the new evaluation of the cam" (CODESYS help,
    Function Blocks: MC_CamTableSelect and MC_CamIn), the slave starting at 0."""
    coefficients = xyva_polynomials(points)
    period = points[-1, 0] - points[0, 0]
    cycle, local = np.divmod(x - points[0, 0], period)
    local = local + points[0, 0]
    i = np.clip(np.searchsorted(points[:, 0], local, side="right") - 1, 0, len(points) - 2)
    y = np.polynomial.polynomial.polyval(local - points[i, 0], coefficients[i].T, tensor=False)
    return y + cycle * points[-1, 1]  # each cycle ends where the cam's last point is


def test_codesys_net_stroke_runs_on_in_relative_mode_and_on_a_modulo_slave():
    name = f"{NET}.codesys.st"
    points = read_codesys((EXPORTS / name).read_text())
    profile = cam(NET)
    assert points[0, 1] == 0.0  # starts at dY = 0, so relative mode runs on without a jump
    assert points[-1, 1] - points[0, 1] == profile.net_stroke
    x = np.concatenate([dense(points[:, 0]), profile.master_period + dense(points[:, 0])[1:]])
    relative = np.abs(codesys_relative(points, x) - exact(profile, x)).max()
    entry = certificates(NET)[name]
    agrees(relative, entry)
    # StartMode absolute: each period evaluates the cam anew; on a slave whose modulo period is the
    # net stroke that is the same position
    coefficients = xyva_polynomials(points)
    local = np.mod(x, profile.master_period)
    i = np.clip(np.searchsorted(points[:, 0], local, side="right") - 1, 0, len(points) - 2)
    absolute = np.polynomial.polynomial.polyval(local - points[i, 0], coefficients[i].T, tensor=False)
    error = np.abs(wrapped(absolute - exact(profile, x), profile.net_stroke)).max()
    assert error <= entry["predicted_error_units"] and math.isclose(error, relative, rel_tol=1e-6, abs_tol=1e-9)


# -- ISG kernel: interpolation point table, one column, equidistant over the master's modulo range ---------
def read_isg(text):
    """Header keywords and the slave entries (1e-4 units) of a TABLE_ONE_COLUMN_SGN32 table."""
    header, values, inside = {}, [], False
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()  # the pages' examples comment after '#'
        if not line:
            continue
        if line == "Begintable":
            inside = True
        elif line == "EndTable":
            inside = False
        elif inside:
            values.append(int(line))
        else:
            key, value = (part.strip() for part in line.split("=", 1))
            header[key.replace(" ", "").lower()] = value
    assert header["tabletype"] == "2"  # TABLE_ONE_COLUMN_SGN32
    assert " " not in header["tablename"]
    assert int(header["lines"]) == len(values) <= 360
    assert all(-(2**31) <= v < 2**31 for v in values)
    return header, np.array(values, dtype=float)


def isg_points(entries, modulo_range, endless_range):
    """The entries with their master positions, the modulo range split into equal sections, and
    one neighbour beyond each end taken from the neighbouring modulo ranges, "corrected by one
    modulo range" of the slave when it rotates endlessly (0 when it does not)."""
    n = len(entries)
    master = np.arange(-1, n + 2) * (modulo_range / n)
    slave = np.concatenate([[entries[-1] - endless_range], entries, entries[:2] + endless_range])
    return master, slave


def isg_linear(master, slave, x):
    return np.interp(x, master, slave)


def isg_polynom_3(master, slave, x):
    """HLI_POLYNOM_3: a cubic Bezier on each interval whose tangent at every entry is parallel to the
    straight line through its two neighbouring entries, inner control points a third of the interval
    away in master. Evaluated by de Casteljau, the curve parameter found by bisection on master."""
    i = np.clip(np.searchsorted(master, x, side="right") - 1, 1, len(master) - 3)
    h = master[i + 1] - master[i]
    p0 = np.stack([master[i], slave[i]])
    p3 = np.stack([master[i + 1], slave[i + 1]])
    left = np.stack([master[i + 1] - master[i - 1], slave[i + 1] - slave[i - 1]])
    right = np.stack([master[i + 2] - master[i], slave[i + 2] - slave[i]])
    p1 = p0 + left * (h / 3) / left[0]
    p2 = p3 - right * (h / 3) / right[0]
    lo, hi = np.zeros_like(x), np.ones_like(x)
    for _ in range(60):
        t = (lo + hi) / 2
        a, b, c = p0 + t * (p1 - p0), p1 + t * (p2 - p1), p2 + t * (p3 - p2)
        d, e = a + t * (b - a), b + t * (c - b)
        point = d + t * (e - d)
        below = point[0] < x
        lo, hi = np.where(below, t, lo), np.where(below, hi, t)
    return point[1]


ISG_FCT = {"linear": ("1", isg_linear), "cubic": ("2", isg_polynom_3)}


@pytest.mark.parametrize("interp", ["linear", "cubic"])
@pytest.mark.parametrize("stem", (*SEEDS, NET))
def test_twincat_cnc_table_read_back(stem, interp):
    name = f"{stem}.twincat-cnc-{interp}.txt"
    header, entries = read_isg((EXPORTS / name).read_text())
    profile = cam(stem)
    functiontype, interpolate = ISG_FCT[interp]
    assert header["functiontype"] == functiontype
    entry = certificates(stem)[name]
    assert any(f"TableFctType := {('HLI_LINEAR', 'HLI_POLYNOM_3')[interp == 'cubic']}" in n for n in entry["notes"])
    per_unit = {"in": 254000.0, "mm": 1e4, "deg": 1e4}[profile.slave_unit]  # 1e-4 mm or 1e-4 deg
    modulo_range = profile.master_period * 1e4  # the master axis, 1e-4 deg
    assert modulo_range % len(entries) == 0 and modulo_range / len(entries) >= 1000  # 0.1 deg apart
    endless = (profile.net_stroke or 0.0) * per_unit  # the slave's modulo range, HLI_CI_ENDLESS_POSITIVE
    if endless:
        assert any("HLI_CI_ENDLESS_POSITIVE" in n for n in entry["notes"])
    master, slave = isg_points(entries, modulo_range, endless)
    periods = 2 if endless else 1
    x = np.concatenate([k * modulo_range + dense(master[1:-1]) for k in range(periods)])
    local = np.mod(x, modulo_range)
    local[(x > 0) & (local == 0)] = modulo_range  # the end of a period belongs to it
    y = interpolate(master, slave, local) + np.floor_divide(x - local, modulo_range) * endless
    error = np.abs(y / per_unit - exact(profile, x / 1e4)).max()
    agrees(error, entry)


# -- Kollmorgen KAS CSV: normalised to the maxima, cubic spline through the points ---------------------
def read_kas(text):
    lines = text.splitlines()
    assert lines[0] in ("CYCLIC;YES;", "CYCLIC;NO;") and lines[1] == "TABLE_BEGIN;;"
    end = lines.index("TABLE_END;;")
    rows = [line.split(";") for line in lines[2:end]]
    assert all(r[2] == "SPLINE" and "e" not in r[0].lower() + r[1].lower() for r in rows)
    assert len(rows) >= 5, "at least 4 spline segments"
    assert len(rows) <= 1000
    return lines[0] == "CYCLIC;YES;", np.array([[float(r[0]), float(r[1])] for r in rows])


@pytest.mark.parametrize("stem", SEEDS)
def test_kollmorgen_csv_read_back(stem):
    name = f"{stem}.kollmorgen.csv"
    cyclic, rows = read_kas((EXPORTS / name).read_text())
    entry = certificates(stem)[name]
    # KAS: values normalised to the file's maxima, then scaled and offset as set in the profile;
    # the export's notes give the scale and offsets to set.
    scales = re.findall(r"scale ([-\d.]+)", entry["notes"][0])
    offsets = re.findall(r"offset ([-\d.]+)", entry["notes"][0])
    master = rows[:, 0] / rows[:, 0].max() * float(scales[0]) + float(offsets[0])
    slave = rows[:, 1] / rows[:, 1].max() * float(scales[1]) + float(offsets[1])
    profile = cam(stem)
    x = dense(master)
    worst = 0.0
    for condition in (["periodic", "natural", "not-a-knot"] if cyclic else ["natural", "not-a-knot"]):
        spline = CubicSpline(master, slave, bc_type=condition)
        error = np.abs(spline(x) - exact(profile, x)).max()
        reading = next(r for r in entry["readings"] if r["reading"] == f"{condition} spline")
        assert error <= reading["predicted_error_units"] * (1 + 1e-6) + 1e-12
        worst = max(worst, error)
    agrees(worst, entry)


# -- Elmo: ET[] entries, EM[] settings, IET = FR[3] * (aux - EM[3]), linear interpolation ------------------
def read_elmo(text):
    table, settings = {}, {}
    for command in text.split(";"):
        command = command.strip()
        if not command:
            continue
        match = re.fullmatch(r"(ET|EM|FR)\[(\d+)\]=(-?\d+)", command)
        assert match, command
        kind, index, value = match.group(1), int(match.group(2)), int(match.group(3))
        (table if kind == "ET" else settings)[(kind, index) if kind != "ET" else index] = value
    return table, settings


def elmo_output(table, settings, aux, rounding):
    first, last, step, start, shorten = (settings[("EM", 5)], settings[("EM", 2)], settings[("EM", 4)],
                                         settings[("EM", 3)], settings[("EM", 7)])
    iet_max = (last - first) * step - shorten
    iet = settings[("FR", 3)] * (aux - start)
    if settings[("EM", 1)] == 2:  # cyclical
        iet = np.mod(iet, iet_max)
    entries = np.array([table[k] for k in range(first, last + 1)], dtype=np.int64)
    i = np.minimum(iet // step, len(entries) - 2)
    num = entries[i] * step + (entries[i + 1] - entries[i]) * (iet - i * step)
    if rounding == "nearest":
        return np.floor_divide(2 * num + step, 2 * step)
    if rounding == "floor":
        return np.floor_divide(num, step)
    return np.sign(num) * (np.abs(num) // step)


@pytest.mark.parametrize("stem", (*SEEDS, NET))
def test_elmo_table_read_back(stem):
    name = f"{stem}.elmo.txt"
    table, settings = read_elmo((EXPORTS / name).read_text())
    assert settings[("EM", 2)] <= 1024 and settings[("EM", 7)] == 0
    profile = cam(stem)
    spec = profile.table
    period = spec["master_counts"]
    assert (settings[("EM", 2)] - settings[("EM", 5)]) * settings[("EM", 4)] == period
    entry = certificates(stem)[name]
    # "If the output of the ECAM table is out of the position sensor range, it is interpreted modulo
    # the position sensor range": the export names the range (XM) that makes the net stroke no move
    sensor = [int(m) for n in entry["notes"] for m in re.findall(r"\(XM\[1\], XM\[2\]\) to (\d+) counts", n)]
    assert len(sensor) == (1 if profile.net_stroke else 0)
    aux = np.arange((2 if sensor else 1) * period, dtype=np.int64)  # a net stroke: across the wrap too
    reference = exact(profile, aux * profile.master_period / period) * spec["slave_counts_per_unit"]
    worst = 0.0
    for rounding in ("nearest", "floor", "toward zero"):
        difference = elmo_output(table, settings, aux, rounding) - reference
        worst = max(worst, np.abs(wrapped(difference, sensor[0]) if sensor else difference).max())
    agrees(worst / spec["slave_counts_per_unit"], entry, exhaustive=True)


# -- Technosoft: two integer columns, X from 0 in power-of-two steps up to 128, at most 8192 points -------
@pytest.mark.parametrize("stem", SEEDS)
def test_technosoft_table_read_back(stem):
    name = f"{stem}.technosoft.txt"
    rows = np.array([[int(v) for v in line.split()] for line in (EXPORTS / name).read_text().splitlines()])
    x, y = rows[:, 0], rows[:, 1]
    step = int(x[1] - x[0])
    assert x[0] >= 0 and np.all(np.diff(x) == step) and step in (1, 2, 4, 8, 16, 32, 64, 128)
    assert len(rows) <= 8192 and np.abs(y).max() < 2**31
    profile = cam(stem)
    spec = profile.table
    counts = np.arange(x[-1], dtype=np.int64)  # one period: the table's end is the next period's start
    i = np.minimum((counts - x[0]) // step, len(x) - 2)
    num = y[i] * step + (y[i + 1] - y[i]) * (counts - x[i])
    outputs = [np.floor_divide(2 * num + step, 2 * step), num // step, np.sign(num) * (np.abs(num) // step)]
    reference = exact(profile, counts * profile.master_period / x[-1]) * spec["slave_counts_per_unit"]
    worst = max(np.abs(out - reference).max() for out in outputs)
    agrees(worst / spec["slave_counts_per_unit"], certificates(stem)[name], exhaustive=True)


# -- CSV: the interpolation named in the header ------------------------------------------------------
@pytest.mark.parametrize("interp", ["linear", "cubic", "quintic"])
@pytest.mark.parametrize("stem", (*SEEDS, NET))
def test_csv_points_read_back(stem, interp):
    name = f"{stem}.csv-{interp}.csv"
    lines = (EXPORTS / name).read_text().splitlines()
    comments = [line for line in lines if line.startswith("#")]
    declared = next(line for line in comments if line.startswith("# interpolation:")).split()[2]
    assert declared == interp
    fields = dict(item.split(": ") for line in comments if line.startswith("# master_unit:")
                  for item in line[2:].split("; "))
    period, net_stroke = float(fields["master_period"]), float(fields["net_stroke"])
    data = np.array([[float(v) for v in line.split(",")] for line in lines[len(comments) + 1:]])
    x = data[:, 0]
    assert x[-1] - x[0] == period and data[-1, 1] - data[0, 1] == net_stroke
    if interp == "linear":
        def curve(points):
            return np.interp(points, x, data[:, 1])
    else:
        curve = BPoly.from_derivatives(x, data[:, 1:])
    # the header's rule for repeating the table: every period adds the net stroke
    periods = 2 if net_stroke else 1
    grid = np.concatenate([k * period + dense(x) for k in range(periods)])
    cycle = np.minimum(np.floor_divide(grid - x[0], period), periods - 1)
    error = np.abs(curve(grid - cycle * period) + cycle * net_stroke - exact(cam(stem), grid)).max()
    agrees(error, certificates(stem)[name])


@pytest.mark.parametrize("fmt, reason", [("kollmorgen", "KAS"), ("technosoft", "EasyMotion Studio")])
def test_formats_that_cannot_carry_a_net_stroke_record_the_refusal_and_write_no_file(fmt, reason):
    document = json.loads((EXPORTS / f"{NET}.certificates.json").read_text())
    refused = [entry for entry in document["exports"] if entry["format"] == fmt]
    assert len(refused) == 1 and "file" not in refused[0]
    assert refused[0]["refused"].startswith(f"net stroke: +360 deg per period should be 0 for {fmt}: ")
    assert reason in refused[0]["refused"] and "\n" not in refused[0]["refused"]
    assert not list(EXPORTS.glob(f"{NET}.{fmt}*"))
