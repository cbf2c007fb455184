"""Vendor exports from Python: tolerance met with the fewest points, the certificate's bound holds
over a population of cams, net-stroke cams exported or refused with the reason, one-line errors,
deterministic bytes."""

import math

import numpy as np
import pytest

import ecam
from ecam import InputError, TableFormatError
from ecam.camfile import parse_cam
from ecam.export import VENDOR_FORMATS, export_cam, vendor_format
from ecam.profile import CamProfile, Segment

COMBINATIONS = [("codesys", None), ("twincat-cnc", "linear"), ("twincat-cnc", "cubic"), ("kollmorgen", None),
                ("elmo", None), ("technosoft", None), ("csv", "linear"), ("csv", "cubic"), ("csv", "quintic")]

KNIFE = {  # a rotary knife: the drum turns 360 deg per cut, 1.2 deg per master deg through the cut
    "name": "knife", "master_unit": "deg", "slave_unit": "deg", "master_period": 360.0, "periodic": True,
    "net_stroke": 360.0,
    "table": {"master_counts": 36000, "slave_counts_per_unit": 1000.0},
    "segment": [
        {"law": "constant_velocity", "span": 60.0, "stroke": 72.0},
        {"law": "poly5", "span": 240.0, "stroke": 216.0, "start_velocity": "match", "end_velocity": "match"},
        {"law": "constant_velocity", "span": 60.0, "stroke": 72.0},
    ],
}


def test_the_old_exporters_are_still_importable_from_ecam_export():
    from ecam import export
    from ecam.export import EXPORTERS, identifier

    for name in ("to_c_header", "to_blob", "to_csv", "to_json", "json_safe", "export_cam", "VENDOR_FORMATS"):
        assert callable(getattr(export, name)) or isinstance(getattr(export, name), dict)
    assert set(EXPORTERS) == {"c", "bin", "csv", "json"}
    assert identifier("9 lives") == "cam_9_lives"


def test_the_vendor_certificate_does_not_shadow_the_tables(drrd):
    """ecam.Certificate certifies ecam's own table; the vendor one is ExportCertificate, and a
    star import of ecam.export after ecam's keeps ecam's."""
    from ecam import export

    assert export.ExportCertificate is not ecam.Certificate
    assert "ExportCertificate" in export.__all__ and "Certificate" not in export.__all__
    assert export.Certificate is export.ExportCertificate  # the deprecated alias still imports
    names: dict = {}
    exec("from ecam import *\nfrom ecam.export import *", names)
    assert names["Certificate"] is ecam.Certificate
    assert isinstance(export_cam(drrd, "csv", points=37).certificate, export.ExportCertificate)


def test_the_vendor_path_reads_the_counts_through_table_spec(drrd):
    """The counts a vendor export uses are the TableSpec's: same defaults from the cam file's
    [table], same limits, same messages."""
    from ecam.export.certify import Cam

    cam, spec = Cam(drrd), ecam.TableSpec.resolve(drrd.table, points=3)
    assert (cam.master_counts, cam.scale) == (spec.master_counts, spec.slave_counts_per_unit)
    given = Cam(drrd, master_counts=np.int64(7200), slave_counts_per_unit=250)
    assert (given.master_counts, given.scale) == (7200, 250.0) and type(given.master_counts) is int
    for counts, message in [(dict(master_counts=1), "master_counts: 1 should be an integer in 2..2147483648"),
                            (dict(master_counts=2.5), "master_counts: 2.5 should be an integer"),
                            (dict(slave_counts_per_unit=1e13), "slave_counts_per_unit: 1e+13 should be <= 1e+12")]:
        with pytest.raises(InputError) as vendor:
            export_cam(drrd, "csv", points=10, **counts)
        with pytest.raises(InputError) as own:
            ecam.TableSpec(points=3, **counts)
        assert str(vendor.value) == str(own.value) == message


# Equidistant straight lines on at most 360 entries cannot reach 5 counts on this cam (12.3 at best).
IN_COUNTS = {("twincat-cnc", "linear"): 15}


@pytest.mark.parametrize("fmt, interp", COMBINATIONS)
@pytest.mark.parametrize("in_counts", [True, False])
def test_tolerance_is_met_and_the_bound_holds(drrd, fmt, interp, in_counts):
    counts = IN_COUNTS.get((fmt, interp), 5)
    tolerance = f"{counts} counts" if in_counts else 4e-4
    result = export_cam(drrd, fmt, tolerance=tolerance, interp=interp)
    c = result.certificate
    limit_units = counts / 100000 if in_counts else tolerance
    assert c.predicted_error_units <= limit_units
    assert c.max_error_units <= c.predicted_error_units
    assert math.isclose(c.max_error_counts, c.max_error_units * 100000)
    assert 2 <= result.points <= result.limit
    assert 0 <= c.max_error_at_master <= drrd.master_period


def next_smaller(fmt, result, profile):
    """The largest point count below ``result.points`` that the format allows for this cam, worked
    out from the vendors' rules (None when there is none)."""
    points = result.points
    if fmt in ("codesys", "csv", "kollmorgen"):  # any count (Kollmorgen: at least 4 spline segments)
        return points - 1 if points - 1 >= (5 if fmt == "kollmorgen" else 2) else None
    if fmt == "twincat-cnc":  # equal whole steps of 1e-4 deg, at least 0.1 deg apart
        grid = round(profile.master_period * 1e4)
        smaller = [n for n in range(2, points) if grid % n == 0 and grid // n >= 1000]
        return smaller[-1] if smaller else None
    master_counts = profile.table["master_counts"]
    if fmt == "elmo":  # EM[4] divides the master period in counts
        smaller = [d for d in range(1, points - 1) if master_counts % d == 0]
        return smaller[-1] + 1 if smaller else None
    step = master_counts // (points - 1)  # technosoft: the next power-of-two step up to 128
    return master_counts // (2 * step) + 1 if 2 * step <= 128 and master_counts % (2 * step) == 0 else None


FEWEST = [(stem, fmt, interp) for stem in ("combination_drrd", "modified_sine", "rotary_knife")
          for fmt, interp in COMBINATIONS
          if not (stem == "rotary_knife" and fmt in ("kollmorgen", "technosoft"))]


@pytest.mark.parametrize("stem, fmt, interp", FEWEST)
def test_one_point_fewer_misses_the_tolerance(stem, fmt, interp):
    """The fewest points within the vendor's rules: the next smaller count the format allows (placed
    by the error where placement is free) has a predicted bound above the tolerance. The greedy
    placement is optimal for a bound that grows with the interval, the equidistant formats try every
    allowed count in turn, and the spline's search ends on a count whose predecessor failed."""
    profile = ecam.load_cam(ecam.camfile.CAMS_DIR / f"{stem}.toml")
    low, high = profile.slave_range
    # Technosoft's coarsest step (128 counts) already meets 3e-4 of the stroke on both cams
    tolerance = 2 / profile.table["slave_counts_per_unit"] if fmt == "technosoft" else 3e-4 * (high - low)
    best = export_cam(profile, fmt, tolerance=tolerance, interp=interp)
    assert best.certificate.predicted_error_units <= tolerance
    smaller = next_smaller(fmt, best, profile)
    assert smaller is not None, (fmt, best.points)
    other = export_cam(profile, fmt, points=smaller, interp=interp)
    assert other.points == smaller
    assert other.certificate.predicted_error_units > tolerance


def rise_return(law_name, stroke, period):
    law = ecam.law(law_name)
    half = period / 2
    return CamProfile((Segment(0, half, 0, stroke, law, "rise"), Segment(half, period, stroke, 0, law, "return")),
                      period, True, master_unit="deg", slave_unit="mm",
                      table={"master_counts": 2**14, "slave_counts_per_unit": 1000.0})


POINTS = {("codesys", None): 12, ("twincat-cnc", "linear"): 60, ("twincat-cnc", "cubic"): 60,
          ("kollmorgen", None): 30, ("elmo", None): 129, ("technosoft", None): 129, ("csv", "linear"): 40,
          ("csv", "cubic"): 20, ("csv", "quintic"): 12}


@pytest.mark.parametrize("law_name", ["cycloidal", "modified_trapezoid", "harmonic", "poly345", "poly4567",
                                      "modified_sine", "constant_acceleration", "cubic"])
def test_measured_never_exceeds_the_bound_over_a_population(law_name):
    """A fixed-seed population of rise-return cams (law, stroke, period) in every format: the
    measured error stays within the predicted bound, every reading."""
    rng = np.random.default_rng(sum(map(ord, law_name)))
    stroke = float(rng.uniform(0.5, 80.0))
    period = float(rng.choice([360.0, 90.0, 720.0]))
    profile = rise_return(law_name, stroke, period)
    for (fmt, interp), points in POINTS.items():
        result = export_cam(profile, fmt, points=points, interp=interp)
        c = result.certificate
        assert result.points == points, (fmt, interp)
        assert c.max_error_units <= c.predicted_error_units, (law_name, fmt, interp, c)
        for name, bound, measured in c.readings:
            assert measured <= bound, (law_name, fmt, interp, name)


def test_an_unreachable_tolerance_is_one_line_with_the_best_error_and_the_limit(drrd):
    with pytest.raises(TableFormatError) as info:
        export_cam(drrd, "twincat-cnc", tolerance="0.5 counts")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("tolerance: 5e-06 in (0.5 counts) should be at least ")
    assert "within its limit of 360 points" in message
    best = float(message.split("should be at least ")[1].split()[0])
    reached = export_cam(drrd, "twincat-cnc", points=360)
    assert best >= reached.certificate.predicted_error_units * (1 - 1e-3)
    with pytest.raises(TableFormatError, match="within its limit of 1024 points"):
        export_cam(drrd, "elmo", tolerance="1 counts")
    with pytest.raises(TableFormatError, match="within its limit of 8192 points"):
        export_cam(drrd, "technosoft", tolerance="0.5 counts")


@pytest.mark.parametrize("master_counts, limit", [(72, 60), (144, 120), (360, 300)])
def test_the_best_error_is_a_number_when_the_limit_exceeds_what_the_grid_holds_where_it_is_needed(
        drrd, monkeypatch, master_counts, limit):
    """CODESYS allows 32767 points, more than a rise of combination_drrd holds in whole master counts
    (36864 per period): the points cannot all go where the error wants them. The best reachable error
    is then that of the most points that do fit (it said 'at least inf'). A small limit on a coarse
    grid is the same situation at a test's cost."""
    monkeypatch.setattr(vendor_format("codesys"), "LIMIT", limit)
    with pytest.raises(TableFormatError) as info:
        export_cam(drrd, "codesys", tolerance=1e-15, master_counts=master_counts)
    message = str(info.value)
    assert "\n" not in message and f"within its limit of {limit} points (at " in message
    best = float(message.split("should be at least ")[1].split()[0])
    at = int(message.split("(at ")[1].split()[0])
    assert math.isfinite(best) and 2 <= at <= limit
    # the error named is reached: that many points give it, and a tolerance just above it is met
    reached = export_cam(drrd, "codesys", points=at, master_counts=master_counts)
    assert math.isclose(reached.certificate.predicted_error_units, best, rel_tol=1e-3)
    met = export_cam(drrd, "codesys", tolerance=best * 1.001, master_counts=master_counts)
    assert met.points <= limit and met.certificate.predicted_error_units <= best * 1.001


@pytest.mark.parametrize("kwargs, message", [
    ({"format": "siemens", "points": 10}, "format: 'siemens' should be one of codesys, twincat-cnc"),
    ({"format": "csv", "interp": "spline", "points": 10}, "interp: 'spline' should be one of linear, cubic"),
    ({"format": "twincat-cnc", "points": 400}, "points: 400 should be an integer in 2..360"),
    ({"format": "kollmorgen", "points": 4}, "points: 4 should be an integer in 5..1000"),
    ({"format": "csv", "points": 10, "tolerance": 1e-3}, "points: 10 should be given without a tolerance"),
    ({"format": "csv", "tolerance": -1.0}, "tolerance: -1 should be a number > 0"),
    ({"format": "csv", "tolerance": "3 mm"}, "tolerance: '3 mm' should be in the cam's slave unit (in) or in counts"),
    ({"format": "elmo", "points": 100}, "points: 100 should be one more than a number of equal whole master"),
    ({"format": "csv", "points": 10, "slave_counts_per_unit": 0.0}, "slave_counts_per_unit: 0 should be"),
])
def test_bad_arguments_name_the_field_the_value_and_the_expectation(drrd, kwargs, message):
    kwargs = dict(kwargs)
    fmt = kwargs.pop("format")
    with pytest.raises(InputError) as info:
        export_cam(drrd, fmt, **kwargs)
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)


def test_a_tolerance_in_the_cams_slave_unit_is_the_plain_number(drrd):
    in_unit = export_cam(drrd, "codesys", tolerance="2e-4 in")
    assert in_unit.certificate.tolerance_units == 2e-4
    assert in_unit.content == export_cam(drrd, "codesys", tolerance=2e-4).content


def test_without_points_or_tolerance_the_cam_files_tolerance_applies(msine):
    result = export_cam(msine, "csv")
    assert result.certificate.tolerance_units == pytest.approx(0.002)
    bare = CamProfile(msine.segments, msine.master_period, True, slave_unit="mm")
    with pytest.raises(InputError, match="^tolerance: missing"):
        export_cam(bare, "csv")


@pytest.mark.parametrize("fmt, interp", COMBINATIONS)
def test_the_same_cam_gives_the_same_bytes(msine, fmt, interp):
    first = export_cam(msine, fmt, tolerance=5e-3, interp=interp)
    second = export_cam(ecam.load_cam(ecam.camfile.CAMS_DIR / "modified_sine.toml"), fmt, tolerance=5e-3,
                        interp=interp)
    assert first.content == second.content and first.crc32 == second.crc32
    assert "20" not in first.content.split("\n", 1)[0] or "Generated by ecam" in first.content  # no dates


@pytest.mark.parametrize("fmt, interp", [("codesys", None), ("twincat-cnc", "linear"), ("twincat-cnc", "cubic"),
                                         ("elmo", None), ("csv", "quintic")])
def test_a_net_stroke_cam_exports_where_the_format_can_carry_it(fmt, interp):
    knife = parse_cam(KNIFE)
    result = export_cam(knife, fmt, tolerance=0.01, interp=interp)
    c = result.certificate
    assert c.max_error_units <= c.predicted_error_units <= 0.01
    assert any("net stroke +360 deg" in note for note in result.notes)
    if fmt == "codesys":
        rows = [line for line in result.content.splitlines() if "(dX := " in line]
        assert "(dX := 0.0, dY := 0.0," in rows[0] and "(dX := 360.0, dY := 360.0," in rows[-1]
    if fmt == "twincat-cnc":  # the kernel corrects the wrap by one slave modulo range in that direction
        assert any("modulo range must be 360 deg" in note and "HLI_CI_ENDLESS_POSITIVE (16#20)" in note
                   for note in result.notes)
    if fmt == "elmo":
        lines = result.content.splitlines()
        entries = [int(line.split("=")[1].rstrip(";")) for line in lines if line.startswith("ET[")]
        assert entries[-1] - entries[0] == 360000
    if fmt == "csv":
        assert "net_stroke: 360.0" in result.content


@pytest.mark.parametrize("fmt, reason", [("kollmorgen", "KAS"), ("technosoft", "EasyMotion Studio")])
def test_a_net_stroke_cam_is_refused_with_the_reason_where_the_format_cannot(fmt, reason):
    with pytest.raises(InputError) as info:
        export_cam(parse_cam(KNIFE), fmt, tolerance=0.01)
    message = str(info.value)
    assert message.startswith(f"net stroke: +360 deg per period should be 0 for {fmt}: ") and reason in message
    assert "use codesys, twincat-cnc, elmo or csv" in message


def test_elmo_refuses_a_net_stroke_of_a_fractional_number_of_counts():
    with pytest.raises(InputError, match="should be a whole number of counts for elmo"):
        export_cam(parse_cam(KNIFE), "elmo", tolerance=0.01, slave_counts_per_unit=1000.0001)


def test_a_non_periodic_cam_has_no_isg_table_but_the_others_export():
    segment = Segment(0.0, 90.0, 0.0, 25.0, ecam.law("cycloidal"), "rise")
    profile = CamProfile((segment,), 90.0, False, slave_unit="mm", table={"master_counts": 9000})
    with pytest.raises(InputError, match="^periodic: false should be true for twincat-cnc"):
        export_cam(profile, "twincat-cnc", points=40)
    for fmt in ("codesys", "kollmorgen", "elmo", "technosoft", "csv"):
        points = {"elmo": 91, "technosoft": 9001}.get(fmt, 20)
        if fmt == "technosoft":
            points = 9000 // 8 + 1
        result = export_cam(profile, fmt, points=points)
        assert result.certificate.max_error_units <= result.certificate.predicted_error_units
    assert "CYCLIC;NO;" in export_cam(profile, "kollmorgen", points=20).content
    assert "EM[1]=1;" in export_cam(profile, "elmo", points=91).content


def test_every_format_documents_its_point_and_its_rule():
    for name in VENDOR_FORMATS:
        module = vendor_format(name)
        assert module.NAME == name and module.LIMIT >= 2 and module.INTERPOLATIONS
        assert module.__doc__ and len(module.__doc__) > 200


def test_a_drum_turning_backwards_runs_endless_negative():
    backwards = dict(KNIFE, net_stroke=-360.0, segment=[dict(s, stroke=-s["stroke"]) for s in KNIFE["segment"]])
    result = export_cam(parse_cam(backwards), "twincat-cnc", tolerance=0.01)
    assert any("net stroke -360 deg" in note and "HLI_CI_ENDLESS_NEGATIVE (16#40)" in note for note in result.notes)
    assert result.certificate.max_error_units <= result.certificate.predicted_error_units <= 0.01


@pytest.mark.slow
def test_tiny_segments_next_to_huge_ones():
    """A 1e-6-of-the-period dwell exports in every format; a rise over 1e-6 of the period has an
    enormous acceleration and fails in one line instead of giving a bad table."""
    period, tiny = 360.0, 360e-6
    cyc = ecam.law("cycloidal")
    table = {"master_counts": 2**16, "slave_counts_per_unit": 1000.0}
    dwell = CamProfile((Segment(0, 180, 0, 10, cyc), Segment(180, 180 + tiny, 10, 10, ecam.law("constant_velocity")),
                        Segment(180 + tiny, period, 10, 0, cyc)), period, True, slave_unit="mm", table=table)
    for fmt, interp in COMBINATIONS:
        c = export_cam(dwell, fmt, tolerance=0.01, interp=interp).certificate
        assert math.isfinite(c.max_error_units) and c.max_error_units <= c.predicted_error_units <= 0.01
    rise = CamProfile((Segment(0, tiny, 0, 1, cyc), Segment(tiny, period, 1, 0, cyc)), period, True,
                      slave_unit="mm", table=table)
    for fmt, interp in [("codesys", None), ("elmo", None), ("twincat-cnc", "linear")]:
        with pytest.raises(TableFormatError, match="^tolerance: 0.002 mm .* should be at least .* within its limit"):
            export_cam(rise, fmt, tolerance="2 counts", interp=interp)


def test_an_undeclared_jump_at_the_seam_is_refused_like_ecam_check_does():
    """A periodic cam whose slave ends 360 deg above its start without saying so has a gap at the
    seam (issue 9): no controller table is exported for it, in any format."""
    undeclared = {key: value for key, value in KNIFE.items() if key != "net_stroke"}
    for fmt, interp in COMBINATIONS:
        with pytest.raises(InputError) as info:
            export_cam(parse_cam(undeclared), fmt, tolerance=0.01, interp=interp)
        message = str(info.value)
        assert message.startswith("position: jumps by -360 deg at the seam (master 360 -> 0)"), message
        assert "net_stroke = 360.0" in message and "\n" not in message


def test_codesys_names_both_ways_to_run_a_net_stroke_and_when_relative_mode_jumps():
    """CODESYS MC_CamIn.StartMode: absolute needs a modulo slave; relative adds the previous end
    position, which is seamless only for a cam that starts at dY = 0."""
    notes = " ".join(export_cam(parse_cam(KNIFE), "codesys", tolerance=0.01).notes)
    assert "StartMode absolute with a modulo slave axis whose period divides 360 deg" in notes
    assert "MC_CamIn.StartMode := relative" in notes and "would jump" not in notes
    shifted = dict(KNIFE, start=10.0)
    notes = " ".join(export_cam(parse_cam(shifted), "codesys", tolerance=0.01).notes)
    assert "this cam starts at dY = 10 deg, so relative mode would jump by that much every period" in notes


def fewest_by_dynamic_programming(bound, grid, forced, budget):
    """The fewest knots on 0..grid (forced ones kept) whose every interval's bound is within budget,
    by trying every interval: the reference the greedy placement must match."""
    best = [math.inf] * (grid + 1)
    best[0] = 1
    for j in range(1, grid + 1):
        start = max(f for f in forced if f < j)  # no interval may step over a forced knot
        for i in range(start, j):
            if best[i] + 1 < best[j] and bound(i, j) <= budget:
                best[j] = best[i] + 1
    return best[grid]


@pytest.mark.parametrize("stem, degree, share", [("modified_sine", 1, 1e-3), ("combination_drrd", 3, 3e-5),
                                                 ("rotary_knife", 5, 1e-5)])
def test_the_greedy_placement_is_the_fewest_any_placement_reaches(stem, degree, share):
    """On a coarse grid every placement can be tried (dynamic programming over all intervals): the
    greedy search of the free-placement formats finds that minimum under the same bound."""
    from ecam.export.certify import Cam, Hermite, greedy_knots, interval_bounds, knot_data

    grid = 120
    cam = Cam(ecam.load_cam(ecam.camfile.CAMS_DIR / f"{stem}.toml"), master_counts=grid)
    r = (degree + 1) // 2
    low, high = cam.profile.slave_range

    data = [knot_data(cam, np.array([k * cam.period / grid]), r, sides=True) for k in range(grid + 1)]

    def bound(i, j):
        (left, right, _), (stored, _, end) = data[i], data[j]
        hermite = Hermite(np.array([i, j]) * (cam.period / grid), degree, left, stored)
        return float(interval_bounds(cam, hermite, inside=(right, end))[0])

    forced = sorted({int(round(x / cam.period * grid)) for x in cam.breaks(degree)})
    budget = share * (high - low)
    greedy = greedy_knots(bound, grid, forced, budget)
    assert greedy is not None
    assert len(greedy) == fewest_by_dynamic_programming(bound, grid, forced, budget)
