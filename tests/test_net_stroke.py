"""Cams with a net stroke per period (issue 9, core): declared and checked, unrolled by the profile,
accumulated exactly by the table lookup for any int64 master, stored in the version-2 blob header,
certified across the seam and at far periods.

Hard cases: a fractional net stroke over a billion periods, a negative net stroke (a drum turning
backwards), a net stroke on a master period that is not a power of two, slave positions passing
2^31 counts, a cut zone that spans the seam.
"""

import json
import struct
import subprocess
import sys
import zlib
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import ecam
from ecam import CamProfile, CamTable, Segment, compile_table
from ecam.camfile import parse_cam
from ecam.compile import net_stroke_fraction
from ecam.table import FORMAT_VERSION, FORMAT_VERSIONS, net_stroke_term

ROOT = Path(__file__).resolve().parent.parent
KNIFE = ROOT / "ecam" / "cams" / "rotary_knife.toml"
MODES = ("linear", "cubic", "quintic")


def knife(sign=1, net=360.0, *, master_counts=36000, slave_counts_per_unit=1000.0, catch_up=288.0):
    """The rotary knife of ecam/cams, built with the Python API (sign -1: the drum turns backwards)."""
    return CamProfile.from_segments([
        Segment.from_span(30.0, sign * 36.0, "constant_velocity", "cut"),
        Segment.polynomial(0.0, 300.0, 0.0, sign * catch_up, start_velocity=sign * 1.2, end_velocity=sign * 1.2,
                           start_jerk=0.0, end_jerk=0.0, name="catch-up"),
        Segment.from_span(30.0, sign * 36.0, "constant_velocity", "cut"),
    ], name="knife", slave_unit="deg", net_stroke=sign * net,
        table={"master_counts": master_counts, "slave_counts_per_unit": slave_counts_per_unit})


def ecam_cli(*args):
    return subprocess.run([sys.executable, "-m", "ecam.app", *map(str, args)], capture_output=True, text=True)


def exact_net(k, table):
    """floor(k N/D + 1/2), with Python integers."""
    net = table.net_stroke
    return (k * net.numerator + net.denominator // 2) // net.denominator


def wrap64(value: int) -> int:
    return ((value + 2**63) % 2**64) - 2**63


# --- declared and checked -----------------------------------------------------------------------


def test_the_shipped_rotary_knife_checks_clean():
    profile = ecam.load_cam(KNIFE)
    assert profile.net_stroke == 360.0 and profile.advance == 360.0
    report = profile.check()
    assert report.ok and not report.discontinuities  # the seam included: position to jerk
    x = np.linspace(-360.0, 720.0, 1081)
    for order in range(4):  # the file says what the Python API below says
        assert np.allclose(profile(x, order), knife()(x, order), rtol=0, atol=1e-9)
    run = ecam_cli("check", KNIFE)
    assert run.returncode == 0, run.stderr
    assert "rotary_knife: 3 segments over 360 deg (periodic, net stroke +360 deg per period)" in run.stdout
    assert "stroke 360 deg (0 .. 360); peak per deg: velocity 1.2 deg/deg" in run.stdout


def test_the_profile_is_unrolled_by_the_net_stroke():
    profile = knife()
    x = np.linspace(0.0, 360.0, 721)
    for k in (-3, -1, 1, 2, 1000):
        assert np.allclose(profile(x + 360.0 * k), profile(x) + 360.0 * k, rtol=0, atol=1e-9)
        assert np.array_equal(profile(x + 360.0 * k, 1), profile(x, 1))  # derivatives stay periodic
    # the seam: both one-sided limits meet, the position continuing by the net stroke
    assert profile(0.0, side="left") == 0.0 == profile(0.0) and profile(360.0, side="left") == 360.0
    assert profile(720.0, side="left") == 720.0 == profile(720.0)
    assert profile(-360.0, side="left") == -360.0
    assert profile.slave_range == (0.0, 360.0)


def test_a_cut_zone_across_the_seam_is_synchronous_on_both_sides():
    profile = knife()
    for x in (-30.0, -10.0, 0.0, 10.0, 30.0, 330.0, 360.0):
        for side in ("left", "right"):
            assert profile(x, 1, side=side) == pytest.approx(1.2, abs=1e-12)
            assert profile(x, 2, side=side) == pytest.approx(0.0, abs=1e-12)
    table = compile_table(profile, interp="quintic", tolerance="2 counts")
    m = table.master_counts
    for k in (0, 1, -1, 10**6, -(10**9)):
        masters = k * m + np.arange(-3000, 3000)  # the cut zone, 330..30 deg, around each seam
        position, slope = table.lookup(masters, with_slope=True)
        assert np.all(np.abs(np.diff(position) - 12) <= 1)  # 1.2 deg/deg = 12 counts per count
        assert np.all(np.abs(slope - 12 * 2**16) <= 2)


def test_a_stroke_entered_wrong_is_still_an_error_at_the_seam(tmp_path):
    text = KNIFE.read_text().replace("stroke = 288.0", "stroke = 278.0")
    path = tmp_path / "knife.toml"
    path.write_text(text)
    with pytest.raises(ecam.CamFileError) as info:
        ecam.load_cam(path)
    assert str(info.value) == (
        f"cam {path}: net_stroke: 360 should be +350, what the segments add up to (the slave starts the period at 0 "
        "and ends it at 350): correct a stroke or the net stroke")
    run = ecam_cli("check", path)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and "net_stroke: 360" in run.stderr


def test_without_the_declaration_the_seam_is_a_jump_with_a_hint(tmp_path):
    path = tmp_path / "knife.toml"
    path.write_text(KNIFE.read_text().replace("net_stroke = 360.0", ""))
    profile = ecam.load_cam(path)
    assert profile.net_stroke is None and profile(360.0) == 0.0  # wraps, as before
    assert [(d.order, d.jump) for d in profile.check().errors] == [(0, -360.0)]
    run = ecam_cli("check", path)
    assert run.returncode == 1
    assert "ERROR   position     jumps by -360 at 0 deg (seam" in run.stdout
    assert "say so in the cam file: net_stroke = 360.0" in run.stdout


def test_a_velocity_step_at_the_seam_is_found_with_a_net_stroke():
    profile = CamProfile.from_segments([
        Segment.from_span(180.0, 100.0, "constant_velocity"),
        Segment.from_span(180.0, 200.0, "constant_velocity"),
    ], net_stroke=300.0)
    seam = profile.check().at(0.0)
    assert [d.order for d in seam] == [1] and seam[0].jump == pytest.approx(100 / 180 - 200 / 180)
    assert "position continuing by the net stroke +300" in seam[0].where


@pytest.mark.parametrize("build, message", [
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), 10.0, False, net_stroke=1.0),
     "net_stroke: 1 should be absent for a cam that is not periodic (it does not repeat, so it has no advance "
     "per period)"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), 10.0, net_stroke="1"), "net_stroke: '1' should be "
                                                                                      "a number"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), 10.0, net_stroke=-1.0),
     "net_stroke: -1 should be +1, what the segments add up to (the slave starts the period at 0 and ends it at 1): "
     "correct a stroke or the net stroke"),
    (lambda: CamProfile.from_segments([Segment.from_span(10.0, 1.0, "cycloidal")], net_stroke=float("nan")),
     "net_stroke: nan should be finite"),
])
def test_bad_net_strokes_are_one_line(build, message):
    with pytest.raises(ecam.InputError) as info:
        build()
    assert str(info.value) == message


def test_decimal_strokes_add_up_to_the_net_stroke():
    """0.1 + 0.2 is not 0.3 in floats: the allowance is relative 1e-12, as for a position jump."""
    profile = CamProfile.from_segments([Segment.from_span(1.0, 0.1, "cycloidal"),
                                        Segment.from_span(1.0, 0.2, "cycloidal")], net_stroke=0.3)
    assert profile.check().ok and profile.advance != 0.3


def test_net_stroke_round_trips_through_to_toml():
    profile = knife()
    text = profile.to_toml()
    assert "\nnet_stroke = 360.0\n" in text
    import tomllib

    back = parse_cam(tomllib.loads(text), source="knife")
    assert back == profile and back.to_toml() == text
    assert "net_stroke" not in ecam.load_cam(ROOT / "ecam" / "cams" / "modified_sine.toml").to_toml()


@pytest.mark.slow
def test_check_prints_peaks_per_master_unit_and_at_a_speed():
    run = ecam_cli("check", KNIFE, "--speed", "120 periods/min")
    assert run.returncode == 0, run.stderr
    assert "at 720 deg/s (120 periods/min): velocity 864 deg/s" in run.stdout
    for speed in ("720", "720 deg/s", "43200 deg/min", "120 rpm", "120 cuts/min"):
        run = ecam_cli("check", KNIFE, "--speed", speed, "--json")
        document = json.loads(run.stdout)
        assert document["speed"]["master_units_per_second"] == pytest.approx(720.0), speed
        assert document["speed"]["velocity"] == pytest.approx(864.0, rel=1e-9)
    assert document["ok"] and document["net_stroke"] == 360.0 and document["stroke"] == 360.0
    assert document["peaks_per_master_unit"]["velocity"] == pytest.approx(1.2, rel=1e-12)
    peaks = document["peaks_per_master_unit"]
    assert document["speed"]["acceleration"] == pytest.approx(peaks["acceleration"] * 720**2)


@pytest.mark.parametrize("speed, message", [
    ("fast", "--speed: 'fast' should be a number > 0 (master deg per second)"),
    ("-5", "--speed: '-5' should be a number > 0"),
    ("5 mm/s", "--speed: '5 mm/s' should be a number > 0"),
])
def test_a_bad_speed_is_one_line(speed, message):
    run = ecam_cli("check", KNIFE, "--speed", speed)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and message in run.stderr, run.stderr


def test_a_stroke_in_the_wrong_unit_shows_in_the_summary(tmp_path):
    """50 mm entered as 50 m: the check is clean, but the summary's peaks say 1000 times too much."""
    good = ecam.load_cam(ROOT / "ecam" / "cams" / "modified_sine.toml")
    wrong = CamProfile.from_segments([Segment.from_span(180.0, 50000.0, "modified_sine"),
                                      Segment.from_span(180.0, -50000.0, "modified_sine")], slave_unit="mm")
    for order in (1, 2, 3):
        assert wrong.peak(order) == pytest.approx(1000 * good.peak(order), rel=1e-9)
    assert good.peak(1) == pytest.approx(50 / 180 * 1.7596, rel=1e-3)  # Cv of the modified sine


# --- the lookup accumulates ---------------------------------------------------------------------


@pytest.mark.parametrize("kind", MODES)
def test_the_lookup_adds_one_net_stroke_per_period(kind):
    table = compile_table(knife(), interp=kind, tolerance="2 counts")
    m = table.master_counts
    assert table.net_stroke == 360000 and table.format_version == 2
    local = np.arange(0, m, 7)
    base, slope = table.lookup(local, with_slope=True)
    for k in (1, -1, 2, -7, 10**6, -(10**9), (2**63 - m) // m, -(2**63 // m)):
        position, slope_k = table.lookup(k * m + local, with_slope=True)
        expected = (base.astype(object) + 360000 * k + 2**63) % 2**64 - 2**63  # modulo 2^64 at the extremes
        assert position.tolist() == expected.tolist() and np.array_equal(slope_k, slope)
    # across the wrap: the position goes on, the slope is continuous
    edge = np.arange(-5, 5) + m
    assert np.all(np.diff(table.lookup(edge)) > 0)
    assert np.ptp(table.slope(edge)) <= 8


def test_the_scalar_path_is_the_vector_path_for_any_int64():
    table = compile_table(knife(slave_counts_per_unit=1000.0001), interp="cubic", tolerance="3 counts")
    rng = np.random.default_rng(9)
    m = table.master_counts
    queries = np.concatenate([rng.integers(-(2**63), 2**63 - 1, 400, dtype=np.int64), rng.integers(-5 * m, 5 * m, 200),
                              [0, -1, m - 1, m, 2**63 - 1, -(2**63), 2**62, -(2**62)]])
    position, slope = table.lookup(queries, with_slope=True)
    for q, p, s in zip(queries.tolist(), position.tolist(), slope.tolist()):
        assert table.lookup(q, with_slope=True) == (p, s)
        k, local = divmod(q, m)
        assert p == wrap64(table.lookup(local) + exact_net(k, table))  # modulo 2^64 beyond int64


def test_net_stroke_term_is_exact_in_64_bit_words():
    rng = np.random.default_rng(3)
    turns = np.concatenate([rng.integers(-(2**62), 2**62, 2000), [0, 1, -1, 2**62 - 1, -(2**62)]])
    for num, den in [(1, 1), (-7, 1), (90000009, 250), (-90000009, 250), (1, 3), (2**31 * 3 - 1, 3),
                     (-(2**31) * (2**32 - 1) + 1, 2**32 - 1), (12345, 2**32 - 1)]:
        got = net_stroke_term(turns, num, den)
        want = [wrap64((int(k) * num + den // 2) // den) for k in turns]
        assert got.tolist() == want, (num, den)


def test_a_fractional_net_stroke_does_not_drift_over_a_billion_periods():
    """360 deg x 1000.0001 counts/deg = 360000.036 counts per cut: stored as 90000009/250 exactly."""
    profile = knife(slave_counts_per_unit=1000.0001)
    table = compile_table(profile, interp="quintic", tolerance="3 counts")
    assert table.net_stroke == Fraction(90000009, 250)
    r = table.report
    assert r["net_stroke_fraction"] == [90000009, 250] and r["net_stroke_exact"]
    m = table.master_counts
    local = np.arange(0, m, 11)
    base = table.lookup(local)
    exact = profile(local * 0.01) * 1000.0001
    for k in (10**9, -(10**9), 10**9 + 1, 123456789):
        position = table.lookup(k * m + local)
        # exactly the rational expectation: round(k N / D), ties up
        assert np.array_equal(position - base, np.full(local.shape, exact_net(k, table)))
        # and within the certified bound of the cam itself, a billion cuts on
        whole, rest = divmod(k * 90000009, 250)
        error = np.abs((position - whole) - rest / 250 - exact)
        assert error.max() <= r["predicted_error_counts"]
    # a net stroke in float32, or rounded to Q16 counts, would be off by thousands of counts there
    assert abs(float(np.float32(360000.036)) - 360000.036) * 1e9 > 1000
    assert abs(round(360000.036 * 2**16) / 2**16 - 360000.036) * 1e9 > 1000


def test_a_net_stroke_no_32_bit_fraction_holds_is_reported_with_its_residual():
    n, residual = net_stroke_fraction(45.0, 1000 / 3)  # 333.3333333333333 counts/deg
    assert n == 15000 and 0 < residual < 1e-11
    assert net_stroke_fraction(0.3333333333333333, 1.0) == (Fraction(1, 3), pytest.approx(3.3e-17, rel=0.1))
    assert net_stroke_fraction(360.0, 1000.0001) == (Fraction(90000009, 250), 0.0)
    assert net_stroke_fraction(-360.0, 1000.0) == (Fraction(-360000), 0.0)
    index = CamProfile.from_segments([Segment.from_span(300.0, 45.0, "modified_sine", "index"),
                                      Segment.from_span(60.0)], net_stroke=45.0, slave_unit="deg")
    table = compile_table(index, interp="cubic", tolerance="2 counts", slave_counts_per_unit=1000 / 3)
    r = table.report
    assert r["net_stroke_fraction"] == [15000, 1] and not r["net_stroke_exact"]
    assert 0 < r["net_stroke_residual_counts"] < 1e-11


@pytest.mark.parametrize("kind", MODES)
def test_a_negative_net_stroke_turns_the_drum_backwards(kind):
    profile = knife(-1)
    assert profile.check().ok and profile(720.0) == -720.0
    table = compile_table(profile, interp=kind, tolerance="2 counts")
    assert table.net_stroke == -360000
    m = table.master_counts
    local = np.arange(0, m, 13)
    base = table.lookup(local)
    for k in (1, -1, 10**6, -(10**6), 10**9):
        assert np.array_equal(table.lookup(k * m + local), base - 360000 * k)
    assert np.all(np.diff(table.lookup(np.arange(-50, 50) + 5 * m)) < 0)
    r = table.report
    assert r["max_error_counts"] <= r["predicted_error_counts"] <= 2


@pytest.mark.parametrize("master_counts, scale", [(36000, 1000.0), (3 * 5 * 7 * 11 * 13 * 4, 7.0),
                                                  (36000, 1000.0001), (360 * 999, 2.5)])
def test_a_net_stroke_on_a_period_that_is_not_a_power_of_two(master_counts, scale):
    profile = knife(master_counts=master_counts, slave_counts_per_unit=scale)
    for kind in MODES:
        table = compile_table(profile, interp=kind, tolerance="3 counts")
        f = table.format
        assert f.master_counts == master_counts and f.master_counts & (f.master_counts - 1)
        r = table.report
        assert r["max_error_counts"] <= r["predicted_error_counts"] <= 3
        assert r["wrap_max_error_counts"] <= r["predicted_error_counts"]
        rng = np.random.default_rng(master_counts)
        queries = rng.integers(-(10**12), 10**12, 3000)
        turns, local = np.divmod(queries, master_counts)
        expected = table.lookup(local) + np.array([exact_net(int(k), table) for k in turns])
        assert np.array_equal(table.lookup(queries), expected)


def test_slave_positions_pass_2_to_the_31_counts():
    """6000 cuts of 360000 counts: 2.16e9 counts, past int32. The int64 lookup goes on exactly; its
    low 32 bits are what a CiA 402 drive sees, rolling over, and their differences stay right."""
    table = compile_table(knife(), interp="quintic", tolerance="2 counts")
    m = table.master_counts
    start = (2**31 // 360000) * m  # the period in which the position passes 2^31
    masters = np.arange(start - 2 * m, start + 2 * m, 3)
    position = table.lookup(masters)
    assert position.min() < 2**31 < position.max()
    assert np.array_equal(position, table.lookup(masters % m) + 360000 * (masters // m))
    bus = position.astype(np.int32)  # two's-complement wrap, as 0x6064 rolls over
    assert bus.min() < 0 < bus.max() and np.array_equal(bus.astype(np.int64) % 2**32, position % 2**32)
    steps = np.diff(bus.astype(np.int64))
    steps = (steps + 2**31) % 2**32 - 2**31  # a drive's wrap-aware difference
    assert np.array_equal(steps, np.diff(position))
    assert table.lookup(int(masters[-1])) == int(position[-1]) > 2**31


# --- the blob -----------------------------------------------------------------------------------


def test_version_2_stores_the_net_stroke_in_the_header():
    table = compile_table(knife(slave_counts_per_unit=1000.0001), interp="cubic", tolerance="3 counts")
    blob = table.to_bytes()
    assert FORMAT_VERSION == 3 and FORMAT_VERSIONS == (1, 2, 3)
    assert struct.unpack_from("<H", blob, 4)[0] == 2
    assert struct.unpack_from("<qI", blob, 48) == (90000009, 250)
    back = CamTable.from_bytes(blob)
    assert back.net_stroke == table.net_stroke and back.to_bytes() == blob
    queries = np.array([0, 1, -1, 10**15, -(10**15), 2**63 - 1, -(2**63)])
    assert np.array_equal(back.lookup(queries), table.lookup(queries))


def test_a_table_without_net_stroke_is_still_version_1(msine):
    table = compile_table(msine)
    blob = table.to_bytes()
    assert table.format_version == 1 and struct.unpack_from("<H", blob, 4)[0] == 1 and blob[48:60] == bytes(12)
    assert "net_stroke_counts" not in table.report and "wrap_evaluated" not in table.report
    for path in sorted((ROOT / "firmware_tables").glob("*/*.bin")):
        data = path.read_bytes()
        if struct.unpack_from("<H", data, 4)[0] == 1:
            loaded = CamTable.from_bytes(data)
            assert loaded.net_stroke == 0 and loaded.to_bytes() == data


@pytest.mark.parametrize("num, den, status", [
    (360000, 0, "ECAM_E_NET_STROKE"),           # no denominator
    (720000, 2, "ECAM_E_NET_STROKE"),           # not reduced
    (0, 5, "ECAM_E_NET_STROKE"),                # zero is 0/1
    (2**31, 1, "ECAM_E_NET_STROKE"),            # 2^31 counts per period
    (-(2**31), 1, "ECAM_E_NET_STROKE"),
    (2**31 - 1, 1, None),
    (0, 1, None),                               # version 2 without a net stroke: loads
    (-7, 3, None),
])
def test_the_loader_checks_the_net_stroke(num, den, status):
    blob = compile_table(knife(), interp="linear", points=13).to_bytes()
    header = bytearray(blob[:64])
    struct.pack_into("<qI", header, 48, num, den)
    struct.pack_into("<I", header, 60, zlib.crc32(bytes(header[:60])))
    mutated = bytes(header) + blob[64:]
    if status is None:
        assert CamTable.from_bytes(mutated).net_stroke == Fraction(num, den)
    else:
        with pytest.raises(ecam.TableFormatError) as info:
            CamTable.from_bytes(mutated)
        assert info.value.status == status and str(info.value).endswith(f"({status})")


def test_the_loader_refuses_a_net_stroke_on_a_table_that_is_not_periodic_and_unknown_versions():
    profile = CamProfile((Segment(0, 90, 0, 10, "cycloidal"),), 90.0, False)
    blob = compile_table(profile, interp="linear", points=9, master_counts=2**12).to_bytes()
    for version, net, status in [(2, (5, 1), "ECAM_E_NET_STROKE"), (2, (0, 1), None), (4, (0, 0), "ECAM_E_VERSION"),
                                 (1, (5, 1), "ECAM_E_RESERVED"), (3, (5, 1), "ECAM_E_NET_STROKE"),
                                 (3, (0, 1), "ECAM_E_RAMP")]:
        header = bytearray(blob[:64])
        struct.pack_into("<H", header, 4, version)
        struct.pack_into("<qI", header, 48, *net)
        struct.pack_into("<I", header, 60, zlib.crc32(bytes(header[:60])))
        if status is None:
            assert CamTable.from_bytes(bytes(header) + blob[64:]).net_stroke == 0
            continue
        with pytest.raises(ecam.TableFormatError) as info:
            CamTable.from_bytes(bytes(header) + blob[64:])
        assert info.value.status == status


# --- the certificate covers the wrap ------------------------------------------------------------


def test_the_certificate_measures_across_the_seam_and_at_far_periods(tmp_path):
    table = compile_table(knife(), interp="auto", tolerance="2 counts")
    r = table.report
    assert r["wrap_evaluated_counts"] > 100000
    text = r["wrap_evaluated"]
    assert "periods +-1, +-2, +-1e+06, +-1e+09" in text and "inside int64" in text
    assert r["wrap_max_error_counts"] <= r["max_error_counts"] <= r["predicted_error_counts"] <= 2
    assert r["net_stroke_units"] == 360.0 and r["net_stroke_counts"] == 360000.0 and r["format_version"] == 2
    run = ecam_cli("compile", KNIFE, "-o", tmp_path, "--format", "json", "--json")
    summary = json.loads(run.stdout)
    assert summary["net_stroke_fraction"] == [360000, 1] and summary["wrap_max_error_counts"] <= 2


def test_a_fractional_net_stroke_adds_half_a_count_to_the_bound():
    whole = compile_table(knife(), interp="cubic", points=13)
    fraction = compile_table(knife(slave_counts_per_unit=1000.0001), interp="cubic", points=13)
    assert fraction.report["quantization_counts"] == pytest.approx(whole.report["quantization_counts"] + 0.5,
                                                                   abs=1e-3)
    r = fraction.report
    assert r["max_error_counts"] <= r["predicted_error_counts"]


def test_a_net_stroke_of_2_to_the_31_counts_per_period_is_refused():
    profile = CamProfile.from_segments([Segment.from_span(360.0, 4.2e6, "cycloidal")], start=-2.1e6,
                                       net_stroke=4.2e6)
    with pytest.raises(ecam.InputError) as info:
        compile_table(profile, interp="cubic", points=257, slave_counts_per_unit=1000.0)
    assert str(info.value) == ("net stroke +4.2e+06 mm x slave_counts_per_unit 1000 = 4.2e+09 counts per period "
                               "should be below 2^31 counts")
