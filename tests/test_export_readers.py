"""The golden vendor exports in firmware_tables/exports/, read back as each controller reads them.

Every reader here is written from the vendor's documentation (quoted in ecam/export/<format>.py),
not from ecam's writers: it parses the file as the controller would, interpolates as the
documentation says (with scipy where a textbook routine exists), and measures the error against the
analytic cam. The measurement must stay within the certificate's predicted bound and agree with
the certificate's measured maximum (which also searches each interval's extremum, so it may only be
slightly larger than a reader's dense sampling; on consumers that see whole master counts the two
are the same numbers).
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
SAMPLES = 400  # per interval, for consumers that evaluate at any master position


def certificates(stem):
    document = json.loads((EXPORTS / f"{stem}.certificates.json").read_text())
    return {entry["file"].split("/")[-1]: entry for entry in document["exports"]}


def cam(stem):
    return ecam.load_cam(CAMS / f"{stem}.toml")


def exact(profile, master):
    """The cam at master positions in [0, P]; at P the value the period ends with."""
    master = np.asarray(master, dtype=float)
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


# -- ISG kernel table: header keywords, integers in 1e-4 units, wraps from the last pair to the first ----
def read_isg(text):
    header, pairs, inside = {}, [], False
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if line == "Begintable":
            inside = True
        elif line == "EndTable":
            inside = False
        elif inside:
            master, slave = line.split()
            pairs.append((int(master), int(slave)))
        else:
            key, value = (part.strip() for part in line.split("=", 1))
            header[key.replace(" ", "").lower()] = value
    assert int(header["lines"]) == len(pairs)
    assert header["tabletype"] == "7"  # two-column integers
    master = np.array([p[0] for p in pairs])
    assert np.all(np.diff(master) >= 1000), "master positions at least 0.1 deg apart"
    assert len(pairs) <= 360
    return header, np.array(pairs, dtype=float)


def isg_closed(pairs, period_units):
    """The table over one modulo period: the last pair runs on to the first, one period later."""
    master = np.append(pairs[:, 0], pairs[0, 0] + period_units)
    slave = np.append(pairs[:, 1], pairs[0, 1])
    return master, slave


def bezier_isg(master, slave, x):
    """The ISG cubic: a cubic Bezier per interval whose tangent at every point is parallel to the
    chord through its two neighbours (wrapping), inner control points a third of the interval away.
    Evaluated by de Casteljau, the curve parameter found by bisection on its master coordinate."""
    n = len(master) - 1
    period = master[-1] - master[0]
    prev_m = np.concatenate([[master[n - 1] - period], master[:n - 1]])
    prev_s = np.concatenate([[slave[n - 1]], slave[:n - 1]])
    direction = np.stack([master[1:] - prev_m, slave[1:] - prev_s], axis=1)
    direction = np.vstack([direction, direction[:1]])
    out = np.empty_like(x)
    for k, xk in enumerate(x):
        i = min(max(np.searchsorted(master, xk, side="right") - 1, 0), n - 1)
        h = master[i + 1] - master[i]
        p0 = np.array([master[i], slave[i]])
        p3 = np.array([master[i + 1], slave[i + 1]])
        p1 = p0 + direction[i] * (h / 3) / direction[i][0]
        p2 = p3 - direction[i + 1] * (h / 3) / direction[i + 1][0]
        lo, hi = 0.0, 1.0
        for _ in range(60):
            t = (lo + hi) / 2
            a, b, c = p0 + t * (p1 - p0), p1 + t * (p2 - p1), p2 + t * (p3 - p2)
            d, e = a + t * (b - a), b + t * (c - b)
            point = d + t * (e - d)
            lo, hi = (t, hi) if point[0] < xk else (lo, t)
        out[k] = point[1]
    return out


@pytest.mark.parametrize("interp", ["linear", "cubic"])
@pytest.mark.parametrize("stem", SEEDS)
def test_twincat_cnc_table_read_back(stem, interp):
    name = f"{stem}.twincat-cnc-{interp}.txt"
    header, pairs = read_isg((EXPORTS / name).read_text())
    profile = cam(stem)
    assert header["functiontype"] == {"linear": "1", "cubic": "2"}[interp]
    master_per_unit = 1e4  # 1e-4 deg
    slave_per_unit = {"in": 254000.0, "mm": 1e4}[profile.slave_unit]  # 1e-4 mm
    master, slave = isg_closed(pairs, profile.master_period * master_per_unit)
    x_units = dense(master) if interp == "linear" else dense(master)[::7]
    if interp == "linear":
        y_units = np.interp(x_units, master, slave)
    else:
        y_units = bezier_isg(master, slave, x_units)
    error = np.abs(y_units / slave_per_unit - exact(profile, x_units / master_per_unit)).max()
    entry = certificates(stem)[name]
    assert error <= entry["predicted_error_units"]
    if interp == "linear":
        agrees(error, entry)
    else:  # the reading across the wrap; the certificate holds the worse of two readings
        wrap = next(r for r in entry["readings"] if r["reading"] == "neighbours across the wrap")
        assert error <= wrap["max_error_units"] * (1 + 1e-6) and error >= wrap["max_error_units"] * 0.9


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


@pytest.mark.parametrize("stem", SEEDS)
def test_elmo_table_read_back(stem):
    name = f"{stem}.elmo.txt"
    table, settings = read_elmo((EXPORTS / name).read_text())
    assert settings[("EM", 2)] <= 1024 and settings[("EM", 7)] == 0
    profile = cam(stem)
    spec = profile.table
    period = spec["master_counts"]
    assert (settings[("EM", 2)] - settings[("EM", 5)]) * settings[("EM", 4)] == period
    aux = np.arange(period, dtype=np.int64)
    reference = exact(profile, aux * profile.master_period / period) * spec["slave_counts_per_unit"]
    worst = max(np.abs(elmo_output(table, settings, aux, r) - reference).max()
                for r in ("nearest", "floor", "toward zero"))
    agrees(worst / spec["slave_counts_per_unit"], certificates(stem)[name], exhaustive=True)


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
@pytest.mark.parametrize("stem", SEEDS)
def test_csv_points_read_back(stem, interp):
    name = f"{stem}.csv-{interp}.csv"
    lines = (EXPORTS / name).read_text().splitlines()
    comments = [line for line in lines if line.startswith("#")]
    declared = next(line for line in comments if line.startswith("# interpolation:")).split()[2]
    assert declared == interp
    data = np.array([[float(v) for v in line.split(",")] for line in lines[len(comments) + 1:]])
    x = data[:, 0]
    if interp == "linear":
        def curve(points):
            return np.interp(points, x, data[:, 1])
    else:
        curve = BPoly.from_derivatives(x, data[:, 1:])
    grid = dense(x)
    error = np.abs(curve(grid) - exact(cam(stem), grid)).max()
    agrees(error, certificates(stem)[name])
