"""Cams from points (ecam.fit_points, ecam fit): the quintic smoothing spline, its certificate, the
spline segment in cam files, and the hard cases of issue 24.

Oracles: the laws' own values (a modified sine's peak acceleration Ca * stroke / span^2), scipy's
B-splines for the basis, scipy's make_smoothing_spline (a cubic, C2) as the reference the quintic
must beat in continuity and never lose to in deviation, and the vendor exports' certificates.
"""

import json
import subprocess
import sys
import tomllib

import numpy as np
import pytest
from scipy.interpolate import BSpline, make_smoothing_spline

import ecam
from conftest import CAMS, ROOT
from ecam.errors import InputError
from ecam.fit import _bsplines, _Factor, fit_points
from ecam.points import MAX_POINTS_BYTES, parse_points
from ecam.profile import CamProfile, Segment

EXPORTS = ROOT / "firmware_tables" / "exports"
MS = ecam.law("modified_sine")
STROKE, SPAN = 10.0, 180.0


def rise_return(x, order=0):
    """A modified-sine rise over 180 deg and its mirrored return: the cam the points measure."""
    x = np.asarray(x, dtype=float)
    out = np.zeros_like(x)
    rise = x < SPAN
    out[rise] = STROKE / SPAN**order * MS(x[rise] / SPAN, order)
    back = ~rise
    out[back] = (STROKE if order == 0 else 0.0) - STROKE / SPAN**order * MS((x[back] - SPAN) / SPAN, order)
    return out


def noisy(count=1441, seed=7, share=1e-4):
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 360.0, count)
    return x, rise_return(x) + share * STROKE * rng.standard_normal(x.size)


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "ecam.app", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


# -- the basis and the solver, against independent implementations ---------------------------------------
@pytest.mark.parametrize("nu", range(6))
def test_the_b_spline_values_and_derivatives_are_scipys(nu):
    rng = np.random.default_rng(1)
    tau = np.unique(np.concatenate([[0.0, 1.0], rng.random(12)]))
    t = np.concatenate([np.zeros(5), tau, np.ones(5)])
    x = rng.random(200)
    interval = np.clip(np.searchsorted(tau, x, side="right") - 1, 0, tau.size - 2)
    ours = _bsplines(t, interval + 5, x, nu)
    for k in range(6):
        coefficients = np.zeros(t.size - 6)
        expected = np.empty(x.size)
        for p, (i, xp) in enumerate(zip(interval, x)):
            coefficients[:] = 0.0
            coefficients[i + k] = 1.0
            expected[p] = BSpline(t, coefficients, 5)(xp, nu)
        assert np.allclose(ours[:, k], expected, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize("periodic", [False, True])
def test_the_banded_cholesky_solves_as_numpy_does(periodic):
    rng = np.random.default_rng(2)
    n, p = 30, 5
    a = 0.1 * np.eye(n)
    for i in range(n):  # a sum of banded (cyclic) rank-one terms: positive definite, B^T B shaped
        cols = [(i + k) % n for k in range(p + 1)] if periodic else [i + k for k in range(p + 1) if i + k < n]
        v = rng.standard_normal(len(cols))
        a[np.ix_(cols, cols)] += np.outer(v, v)
    factor = _Factor(a, p, periodic)
    b = rng.standard_normal(n)
    assert np.allclose(factor.solve(b), np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)
    z = factor.inverse_factor()
    assert np.allclose(z.T @ z, np.linalg.inv(a), rtol=1e-9, atol=1e-12)


# -- the fit ------------------------------------------------------------------------------------------
def test_noisy_measurements_of_a_modified_sine_recover_its_peak_acceleration():
    x, y = noisy()
    result = fit_points(x, y, periodic=True)
    assert result.smoothing == "gcv"
    law_peak = STROKE * MS.ca / SPAN**2  # Ca = 5.528 (the law's own)
    assert abs(result.profile.peak(2) / law_peak - 1) < 0.05
    # the raw points' second differences are noise: two orders of magnitude off
    assert result.certificate["peaks"]["acceleration"]["points"] > 10 * law_peak


@pytest.mark.parametrize("seed", [0, 3])
def test_gcv_smooths_noisy_points_that_are_not_periodic_instead_of_interpolating_them(seed):
    # Knots at the points (181 <= 600): as the fit nears interpolation, tr H nears n and the GCV
    # score's numerator and denominator become rounding noise; it once picked lambda ~ 1e-12 (181
    # effective parameters, the noise interpolated). scipy's make_smoothing_spline (GCV, cubic) is
    # the peer: its error against the law is about 0.2-0.3 sigma here.
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, SPAN, 181)
    sigma = 1e-3 * STROKE
    y = rise_return(x) + sigma * rng.standard_normal(x.size)
    result = fit_points(x, y)
    assert result.smoothing == "gcv"
    assert result.certificate["effective_parameters"] < x.size / 4
    assert 0.7 * sigma < result.rms_deviation < 1.3 * sigma  # it leaves the noise in the residuals
    grid = np.linspace(0.0, SPAN, 5001)
    error = np.sqrt(np.mean((result.profile(grid) - rise_return(grid)) ** 2))
    cubic = np.sqrt(np.mean((make_smoothing_spline(x, y)(grid) - rise_return(grid)) ** 2))
    assert error < 0.5 * sigma
    assert error < 1.25 * cubic


def test_the_quintic_beats_scipys_cubic_in_continuity_and_never_loses_in_deviation():
    x, y = noisy()
    ours = fit_points(x, y, periodic=True)
    cubic = make_smoothing_spline(x, y)  # GCV too; C2, its jerk steps at every point
    grid = np.linspace(0.0, 360.0, 20001)
    ours_error = ours.profile(grid) - rise_return(grid)
    cubic_error = cubic(grid) - rise_return(grid)
    assert np.sqrt(np.mean(ours_error**2)) <= np.sqrt(np.mean(cubic_error**2))
    assert np.abs(ours_error).max() <= np.abs(cubic_error).max()
    # continuity: the cubic's jerk jumps at its knots, the quintic's jerk is continuous (check()
    # finds no jump of order <= 3, the seam included)
    knots = x[1:-1]
    eps = 1e-7
    cubic_jumps = np.abs(cubic(knots + eps, 3) - cubic(knots - eps, 3))
    assert cubic_jumps.max() > 1e-3 * np.abs(cubic(grid, 3)).max()
    assert ours.profile.check().continuous(3)
    # and with the cubic's own largest deviation from the points as the tolerance, the quintic
    # keeps within it
    within = fit_points(x, y, periodic=True, tolerance=float(np.abs(cubic(x) - y).max()))
    assert within.max_deviation <= np.abs(cubic(x) - y).max()


def test_a_tolerance_is_met_at_every_point_and_the_certificate_is_the_cams():
    x, y = noisy(count=721)
    tolerance = 4e-3
    result = fit_points(x, y, periodic=True, tolerance=tolerance)
    assert result.smoothing == "tolerance"
    deviation = np.abs(result.profile(x) - y)
    assert deviation.max() <= tolerance * (1 + 1e-9)
    assert result.max_deviation == pytest.approx(deviation.max(), rel=1e-12)
    k = int(np.argmax(deviation))
    assert result.certificate["max_deviation_at"] == x[k]
    # a looser tolerance gives a smoother fit
    looser = fit_points(x, y, periodic=True, tolerance=4 * tolerance)
    assert looser.profile.peak(3) < result.profile.peak(3)


def test_unevenly_spaced_points_not_periodic():
    rng = np.random.default_rng(3)
    x = np.sort(np.concatenate([[0.0, 360.0], rng.random(400) * 360]))
    y = rise_return(x)
    result = fit_points(x, y, tolerance=1e-4)
    assert result.max_deviation <= 1e-4
    assert not result.profile.periodic
    assert result.profile.master_period == 360.0
    assert result.profile.check().continuous(3)


def test_a_periodic_table_whose_last_point_repeats_the_first_is_continuous_across_the_seam():
    x = np.linspace(0.0, 360.0, 181)
    result = fit_points(x, rise_return(x), periodic=True, tolerance=1e-5)
    assert result.profile.master_period == 360.0
    assert result.certificate["duplicates_averaged"] == 1  # the last row, one period on, is the first
    for order in range(4):
        left = result.profile(360.0, order, side="left")
        right = result.profile(0.0, order)
        assert left == pytest.approx(right, abs=1e-9 * max(1.0, abs(right)))
    assert result.profile.check().continuous(3)


def test_a_net_stroke_cam_continues_by_its_net_stroke():
    x = np.linspace(0.0, 360.0, 361)
    y = 360.0 * x / 360.0 + 5.0 * np.sin(np.radians(2 * x))  # a feed roll: +360 per period
    result = fit_points(x, y, net_stroke=360.0, tolerance=1e-6)
    profile = result.profile
    assert profile.net_stroke == 360.0 and profile.periodic
    assert profile(360.0 + 90.0) == pytest.approx(360.0 + profile(90.0), abs=1e-9)
    assert profile.check().continuous(3)
    assert result.max_deviation <= 1e-6


def test_duplicate_master_positions_are_averaged_and_said_so():
    x = np.linspace(0.0, 100.0, 101)
    y = (x / 100.0) ** 3
    xs = np.insert(x, 50, x[50])
    ys = np.insert(y, 50, y[50] + 2e-4)
    result = fit_points(xs, ys, tolerance=5e-4)
    assert result.certificate["duplicates_averaged"] == 1
    assert result.certificate["points"] == 101
    assert np.abs(result.profile(xs) - ys).max() <= 5e-4  # every given point, both duplicates


def test_duplicates_far_apart_are_a_step_and_refused():
    x = np.array([0.0, 1, 2, 3, 3, 4, 5, 6, 7])
    y = np.array([0.0, 0, 0, 0, 1, 1, 1, 1, 1])
    with pytest.raises(InputError, match=r"at the same master 3 "):
        fit_points(x, y)


def test_a_step_in_the_points_is_refused_in_one_line_naming_where():
    x = np.linspace(0.0, 10.0, 101)
    y = np.where(x < 5.05, 0.0, 1.0) + 0.01 * x
    with pytest.raises(InputError) as caught:
        fit_points(x, y)
    message = str(caught.value)
    assert "\n" not in message
    assert "between master 5 and 5.1" in message and "step" in message


@pytest.mark.parametrize("master, slave, expected", [
    ([0, 1, 2, np.nan, 4, 5, 6], [0, 1, 2, 3, 4, 5, 6], r"master\[3\]: nan should be a finite number"),
    ([0, 1, 2, 3, 2, 5, 6], [0, 1, 2, 3, 4, 5, 6], r"master\[4\]: 2 should be >= master\[3\]"),
    ([0, 1, 2], [0, 1, 2], r"points: 3 should be at least 6"),
    ([0, 1, 2, 3, 4, 5], [0, 1, 2], r"slave: '3 values' should be 6 values"),
])
def test_bad_points_are_one_line_errors(master, slave, expected):
    with pytest.raises(InputError, match=expected):
        fit_points(master, slave)


# -- the cam: file, check, compile, export ------------------------------------------------------------
@pytest.fixture(scope="module")
def fitted():
    x, y = noisy(count=721)
    return fit_points(x, y, periodic=True, tolerance=4e-3, name="measured")


def test_the_fit_reads_back_equal_from_its_cam_file(fitted):
    text = fitted.profile.to_toml()
    assert 'law = "spline"' in text and "knots = [" in text and "derivatives = [" in text
    back = ecam.parse_cam(tomllib.loads(text))
    assert back == fitted.profile
    assert back.to_toml() == text


def test_the_spline_segment_compiles_with_a_certified_error(fitted):
    table = ecam.compile_table(fitted.profile, interp="quintic", tolerance="2 counts", master_counts=36000,
                               slave_counts_per_unit=1000.0)
    c = table.certificate
    assert c.max_error_counts <= c.predicted_error_counts <= 2.0
    table = ecam.compile_table(fitted.profile, interp="cubic", tolerance="2 counts", master_counts=36000,
                               slave_counts_per_unit=1000.0)
    assert table.certificate.max_error_counts <= table.certificate.predicted_error_counts <= 2.0


@pytest.mark.parametrize("fmt", ["codesys", "twincat-cnc", "kollmorgen", "elmo", "technosoft", "csv"])
def test_the_spline_segment_exports_to_every_vendor_format(fitted, fmt):
    from ecam.export import export_cam

    result = export_cam(fitted.profile, fmt, tolerance=0.01, master_counts=36000, slave_counts_per_unit=1000.0)
    c = result.certificate
    assert c.max_error_units <= c.predicted_error_units <= 0.01


def test_a_cam_mixes_spline_and_law_segments_with_its_joints_checked():
    x = np.linspace(0.0, 120.0, 121)
    rise = fit_points(x, 10.0 * MS(x / 120.0), tolerance=1e-6)
    spline = rise.profile.segments[0]
    cam = CamProfile([spline, Segment(120.0, 360.0, spline.slave_end, 0.0, "cycloidal", "return")], 360.0)
    report = cam.check()
    joint = report.at(120.0)
    # the spline ends at rest to 1e-6 but is not exactly a dwell: the joint's jumps, if any, are tiny
    assert all(abs(d.jump) < 1e-3 for d in joint)
    assert ecam.parse_cam(tomllib.loads(cam.to_toml())) == cam
    text = cam.to_toml().replace("knots = [0.0, 1.0,", "knots = [0.0, 1.5,", 1)
    broken = ecam.parse_cam(tomllib.loads(text))
    assert not broken.check().continuous(3)  # a hand-edited knot shows as a jump


def test_cam_file_spline_fields_are_checked():
    base = {"master_period": 1.0, "segment": [{"law": "spline", "knots": [0.0, 1.0],
                                               "derivatives": [[0.0, 0, 0, 0, 0, 0]]}]}
    assert ecam.parse_cam(base).segments[0].stroke == 0.0
    bad = json.loads(json.dumps(base))
    bad["segment"][0]["derivatives"] = [[0.0, 1.0]]
    with pytest.raises(ecam.CamFileError, match=r"segment\[0\]\.derivatives\[0\]: .* should be 6 numbers"):
        ecam.parse_cam(bad)
    bad = json.loads(json.dumps(base))
    bad["segment"][0]["span"] = 1.0
    with pytest.raises(ecam.CamFileError, match=r"segment\[0\]\.span: 1 should be absent"):
        ecam.parse_cam(bad)
    bad = json.loads(json.dumps(base))
    bad["segment"][0]["knots"] = [0.0, 0.5, 0.4, 1.0]
    bad["segment"][0]["derivatives"] = [[0.0] * 6] * 3
    with pytest.raises(ecam.CamFileError, match=r"knots\[2\]: 0.4 should be greater than knots\[1\]"):
        ecam.parse_cam(bad)
    bad = {"master_period": 1.0, "segment": [{"law": "dwell", "span": 1.0, "knots": [0.0, 1.0]}]}
    with pytest.raises(ecam.CamFileError, match=r"knots: should be absent"):
        ecam.parse_cam(bad)


# -- reading tables: text, ecam's CSV, CODESYS ----------------------------------------------------------
def test_a_text_table_with_comments_a_header_and_weights():
    text = "# measured lift\nmaster; slave; weight\n0;0;1\n1 ;1;2 # a comment\n\n2;4;1\n"
    table = parse_points(text)
    assert table.kind == "table"
    assert table.master.tolist() == [0.0, 1.0, 2.0] and table.weights.tolist() == [1.0, 2.0, 1.0]
    assert table.lines.tolist() == [3, 4, 6]


@pytest.mark.parametrize("text, expected", [
    ("", "no rows of numbers"),
    ("1\n2\n3\n", "line 1: 1 columns should be 2 or 3"),
    ("0 0\n1 x\n", r"line 2: 'x' should be a number"),
    ("0 0\n1 1 1\n", "line 2: 3 columns should be 2"),
    ("0 0\n1 nan\n", "line 2: nan should be a finite number"),
])
def test_bad_tables_are_one_line_errors(text, expected):
    with pytest.raises(InputError, match=expected):
        parse_points(text, source="t.txt")


@pytest.mark.parametrize("stem", ["modified_sine", "combination_drrd"])
def test_the_seed_cam_goes_round_codesys_and_back_within_the_exports_certificate(stem, tmp_path):
    certificate = next(entry for entry in json.loads((EXPORTS / f"{stem}.certificates.json").read_text())["exports"]
                       if entry.get("file", "").endswith(".codesys.st"))
    cam = ecam.load_cam(CAMS / f"{stem}.toml")
    tolerance = 0.1 * certificate["predicted_error_units"]
    done = run("fit", EXPORTS / f"{stem}.codesys.st", "--periodic", "--tolerance", tolerance, "--slave-unit",
               cam.slave_unit, "-o", tmp_path / "back.toml", "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["source"]["kind"] == "codesys-xyva"
    back = ecam.load_cam(tmp_path / "back.toml")
    grid = np.linspace(0.0, 360.0, 36001)
    assert np.abs(back(grid) - cam(grid)).max() <= certificate["predicted_error_units"]
    assert back.check().continuous(3)


def test_ecams_csv_export_says_its_period_and_net_stroke(tmp_path):
    stem = "rotary_knife"
    cam = ecam.load_cam(CAMS / f"{stem}.toml")
    done = run("fit", EXPORTS / f"{stem}.csv-quintic.csv", "--tolerance", 1e-4, "-o", tmp_path / "back.toml",
               "--json")
    assert done.returncode == 0, done.stderr
    back = ecam.load_cam(tmp_path / "back.toml")
    assert back.net_stroke == cam.net_stroke and back.slave_unit == cam.slave_unit
    assert back.check().continuous(3)


# -- the command line ------------------------------------------------------------------------------------
def test_ecam_fit_writes_the_cam_the_certificate_and_the_plot(tmp_path):
    x, y = noisy(count=361)
    points = tmp_path / "lift.csv"
    points.write_text("# CMM lift table\nmaster_deg,lift_mm\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(x, y)))
    done = run("fit", points, "--periodic", "-o", tmp_path / "lift.toml", "--plot", tmp_path / "lift.png")
    assert done.returncode == 0, done.stderr
    assert "generalized cross-validation" in done.stdout and "max deviation" in done.stdout
    assert (tmp_path / "lift.png").stat().st_size > 0
    assert run("check", tmp_path / "lift.toml").returncode == 0
    again = run("fit", points, "--periodic", "--json")
    report = json.loads(again.stdout)
    for key in ("max_deviation", "max_deviation_at", "rms_deviation", "peaks", "smoothing", "lambda", "knots"):
        assert key in report
    assert report["smoothing"] == "gcv"
    assert set(report["peaks"]) == {"velocity", "acceleration", "jerk"}
    assert run("fit", points, "--periodic", "--json").stdout == again.stdout  # deterministic


@pytest.mark.parametrize("content, expected", [
    ("0,0\n1,1\n2,nan\n", "should be a finite number"),
    ("0\n1\n2\n", "columns should be 2 or 3"),
    ("", "no rows of numbers"),
    ("0 0\n1 1\n2 2\n1 3\n4 4\n5 5\n6 6\n", r"should be >= master"),
])
def test_bad_point_files_exit_2_with_one_line(tmp_path, content, expected):
    points = tmp_path / "bad.txt"
    points.write_text(content)
    done = run("fit", points)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("ecam: error: ")
    assert expected in done.stderr or __import__("re").search(expected, done.stderr)


def test_huge_and_irregular_point_files_are_refused_before_reading(tmp_path):
    huge = tmp_path / "huge.txt"
    with open(huge, "wb") as handle:
        handle.truncate(MAX_POINTS_BYTES + 1)  # sparse: no disk used
    done = run("fit", huge)
    assert done.returncode == 2 and "should be at most" in done.stderr
    done = run("fit", "/dev/zero")
    assert done.returncode == 2 and "regular file" in done.stderr


@pytest.mark.slow
def test_a_hundred_thousand_points():
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 360.0, 100_001)
    y = rise_return(x) + 1e-4 * STROKE * rng.standard_normal(x.size)
    result = fit_points(x, y, periodic=True)
    assert result.certificate["knots"] <= 1600
    law_peak = STROKE * MS.ca / SPAN**2
    assert abs(result.profile.peak(2) / law_peak - 1) < 0.05
    assert result.profile.check().continuous(3)


def test_a_declared_step_splits_the_fit_and_the_check_reports_it():
    x = np.linspace(0.0, 10.0, 101)
    y = np.where(x < 5.0, 0.0, 1.0) + 0.01 * x**2
    xs = np.insert(x, 50, 5.0)  # the table steps at 5: two rows there, 0.25 and 1.25
    ys = np.insert(y, 50, 0.25)
    result = fit_points(xs, ys, steps=[5.0], tolerance=1e-6)
    profile = result.profile
    assert len(profile.segments) == 2 and result.certificate["steps"] == [5.0]
    assert profile(5.0, side="left") == pytest.approx(0.25, abs=1e-6)
    assert profile(5.0) == pytest.approx(1.25, abs=1e-6)
    jumps = profile.check().at(5.0, 0)
    assert len(jumps) == 1 and jumps[0].jump == pytest.approx(1.0, abs=1e-5)
    assert np.abs(profile(xs[:50]) - ys[:50]).max() <= 1e-6
    assert ecam.parse_cam(tomllib.loads(profile.to_toml())) == profile
    with pytest.raises(InputError, match=r"steps\[0\]: 12 should be inside the points' master range"):
        fit_points(xs, ys, steps=[12.0])


def test_the_fitted_seed_cam_runs_on_the_rig_as_the_seed_does(tmp_path):
    import hil_sim
    from hil_sim import SCENES_DIR
    from hil_sim.scene import load_scene

    done = run("fit", EXPORTS / "combination_drrd.codesys.st", "--periodic", "--slave-unit", "in", "--tolerance",
               1e-5, "-o", tmp_path / "drrd.toml")
    assert done.returncode == 0, done.stderr
    fitted = hil_sim.run_scene(load_scene(SCENES_DIR / "stiff_coupling.toml", cam=ecam.load_cam(tmp_path / "drrd.toml")))
    seed = hil_sim.run_scene(load_scene(SCENES_DIR / "stiff_coupling.toml"))
    assert fitted.passed and seed.passed
    by_name = {check.name: check.value for check in seed.checks}
    for check in fitted.checks:
        if check.name in ("coupling_peak_torque", "coupling_rms_torque", "tracking_error"):
            assert check.value == pytest.approx(by_name[check.name], rel=0.05), check.name


def test_a_tolerance_below_the_scatter_of_many_points_is_refused_with_the_reachable_deviation():
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, 100.0, 2001)  # more points than knots: the spline cannot follow the noise
    y = np.sin(x / 10) + 1e-2 * rng.standard_normal(x.size)
    with pytest.raises(InputError, match=r"^tolerance: 0.001 should be at least [0-9.]+ mm, the smallest largest "
                                         r"deviation a quintic spline on \d+ knot intervals reaches here$"):
        fit_points(x, y, tolerance=1e-3)


def test_weights_pull_the_fit_and_a_zero_weight_leaves_a_row_out(tmp_path):
    x, y = noisy(count=361)
    y = y.copy()
    y[100] += 0.05  # an outlier
    heavy = np.ones(x.size)
    heavy[100] = 100.0
    plain = fit_points(x, y, periodic=True)
    pulled = fit_points(x, y, heavy, periodic=True)
    assert abs(pulled.residuals[100]) < abs(plain.residuals[100])
    left_out = np.ones(x.size)
    left_out[100] = 0.0
    without = fit_points(x, y, left_out, periodic=True)
    assert without.certificate["points_read"] == x.size - 1
    assert abs(without.profile(x[100]) - rise_return(x[100:101])[0]) < 0.005
    points = tmp_path / "weighted.txt"
    points.write_text("".join(f"{float(a)!r} {float(b)!r} {float(c)!r}\n" for a, b, c in zip(x, y, left_out)))
    done = run("fit", points, "--periodic", "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["max_deviation"] == pytest.approx(without.max_deviation, rel=1e-12)
