"""The table compiler: certified error, accuracy targets, wrapping, blobs, overflow, bad input."""
import json
import math
import subprocess
import sys
import zlib

import numpy as np
import pytest
from hypothesis import given, strategies as st

import ecam
from ecam import CamTable, TableFormatError, compile_table
from ecam.laws import LAWS
from ecam.profile import CamProfile, Segment

KINDS = ["linear", "cubic", "quintic"]


def rise_return(name, stroke=10.0, period=360.0):
    law = ecam.law(name)
    half = period / 2
    return CamProfile((Segment(0, half, 0, stroke, law, "rise"), Segment(half, period, stroke, 0, law, "return")),
                      period, True, slave_unit="mm")


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", sorted(LAWS))
def test_measured_error_never_exceeds_the_certified_bound(name, kind):
    profile = rise_return(name)
    for intervals, counts in ((16, 4096), (64, 65536), (100, 36000)):  # 36000/100: non-power-of-two step
        table = compile_table(profile, interp=kind, points=intervals + 1, master_counts=counts,
                              slave_counts_per_unit=1000.0)
        r = table.report
        assert r["evaluated"] == "every master count"
        assert r["max_error_counts"] <= r["predicted_error_counts"], (name, kind, intervals, r)
        assert r["interpolation_error_counts"] <= r["predicted_interpolation_counts"] + 1e-6


@given(
    laws=st.lists(st.sampled_from(sorted(LAWS)), min_size=1, max_size=4),
    spans=st.lists(st.integers(1, 8), min_size=4, max_size=4),
    strokes=st.lists(st.floats(-30, 30), min_size=4, max_size=4),
    kind=st.sampled_from(KINDS),
    log_intervals=st.integers(2, 8),
    offset=st.integers(0, 1),
)
def test_certificate_holds_on_random_cams(laws, spans, strokes, kind, log_intervals, offset):
    """Random chains, with joints on or off the table points (offset), any law."""
    x = y = 0.0
    segments = []
    for name, span, stroke in zip(laws, spans, strokes):
        span = span * 45.0 + offset * 7.3
        segments.append(Segment(x, x + span, y, y + stroke, ecam.law(name)))
        x, y = x + span, y + stroke
    profile = CamProfile(tuple(segments), x, periodic=bool(offset))
    table = compile_table(profile, interp=kind, points=2**log_intervals + 1, master_counts=2**14,
                          slave_counts_per_unit=100.0)
    r = table.report
    assert r["max_error_counts"] <= r["predicted_error_counts"]


def test_cubic_error_attains_the_h4_bound_on_the_harmonic_law():
    """Before quantization, cubic Hermite on the simple harmonic law is within 10% of
    h^4/384 max|f''''| (the bound is nearly attained there, so a looser interpolator shows)."""
    profile = rise_return("harmonic", stroke=100.0)
    m, intervals, s = 2**16, 64, 1000.0
    table = compile_table(profile, interp="cubic", points=intervals + 1, master_counts=m, slave_counts_per_unit=s)
    h = m / intervals
    # f(m) = S * stroke * s(m / (M/2)) on the rise: f'''' = S stroke (2/M)^4 s''''
    f4 = s * 100.0 * (2 / m) ** 4 * (math.pi**4 / 2)
    bound = h**4 / 384 * f4
    measured = table.report["interpolation_error_counts"]
    assert 0.9 * bound <= measured <= bound * (1 + 1e-9)
    assert table.report["predicted_interpolation_counts"] == pytest.approx(bound, rel=0.02)


@pytest.mark.parametrize("kind", KINDS)
def test_enough_points_give_at_most_one_count(kind, drrd):
    table = compile_table(drrd, interp=kind, points=18 * 2**(9 if kind == "linear" else 4) + 1)
    assert table.report["max_error_counts"] <= 1.0
    assert table.report["max_error_counts"] >= 0.45  # the quantization floor is 1/2 count


def test_points_at_table_points_are_within_half_a_count(msine):
    table = compile_table(msine, interp="cubic", points=257)
    counts = np.arange(257, dtype=np.int64) * table.format.step_counts
    exact = msine(counts * 360.0 / table.master_counts) * 1000.0
    assert np.abs(table.lookup(counts) - exact).max() <= 0.5


@pytest.mark.parametrize("kind", KINDS)
def test_wrapping_negative_and_huge_master_counts(kind, drrd):
    table = compile_table(drrd, interp=kind, points=18 * 8 + 1)
    m = table.master_counts
    rng = np.random.default_rng(1)
    base = rng.integers(0, m, 5000)
    expected = table.lookup(base)
    for shift in (m, -m, 7 * m, -(2**31 // m + 3) * m, (2**32 // m + 1) * m, (2**62 // m) * m, -(2**62 // m) * m):
        np.testing.assert_array_equal(table.lookup(base + shift), expected)
    assert table.lookup(2**63 - 1) == table.lookup((2**63 - 1) % m)
    assert table.lookup(-(2**63)) == table.lookup((-(2**63)) % m)


def test_billion_cycles_without_drift(drrd):
    """A master running a billion cycles lands on exactly the same slave counts."""
    table = compile_table(drrd, interp="cubic", points=18 * 16 + 1)
    m = table.master_counts
    phases = np.arange(0, m, 97, dtype=np.int64)
    for cycles in (10**9, 10**9 + 1, 3 * 10**9 + 17):
        np.testing.assert_array_equal(table.lookup(phases + cycles * m), table.lookup(phases))


def test_non_periodic_holds_the_end_positions():
    law = ecam.law("cycloidal")
    profile = CamProfile((Segment(0, 90, 0, 10, law),), 90.0, periodic=False)
    table = compile_table(profile, interp="cubic", points=65, master_counts=2**12, slave_counts_per_unit=1000)
    assert table.lookup(-5) == 0 and table.lookup(2**12) == 10000 and table.lookup(2**40) == 10000
    assert table.slope(-1) == 0 and table.slope(2**12 + 3) == 0


def test_slope_tracks_the_velocity(msine):
    table = compile_table(msine, interp="quintic", points=257)
    counts = np.arange(0, table.master_counts, 17, dtype=np.int64)
    exact = msine(counts * 360.0 / table.master_counts, 1) * 1000.0 * 360.0 / table.master_counts
    assert np.abs(table.slope(counts) / 2**16 - exact).max() < 1e-4 * np.abs(exact).max()


def test_blob_roundtrip_and_determinism(drrd):
    a = compile_table(drrd, interp="quintic", points=18 * 4 + 1)
    b = compile_table(drrd, interp="quintic", points=18 * 4 + 1)
    assert a.to_bytes() == b.to_bytes()
    loaded = CamTable.from_bytes(a.to_bytes())
    q = np.arange(-100000, 100000, 7, dtype=np.int64)
    np.testing.assert_array_equal(loaded.lookup(q), a.lookup(q))
    np.testing.assert_array_equal(loaded.slope(q), a.slope(q))
    assert not loaded.positions.flags.writeable


def test_every_single_byte_change_and_truncation_is_rejected(drrd):
    blob = compile_table(drrd, interp="cubic", points=19).to_bytes()
    for i in range(len(blob)):
        for flip in (0x01, 0xFF):
            bad = bytearray(blob)
            bad[i] ^= flip
            with pytest.raises(TableFormatError):
                CamTable.from_bytes(bytes(bad))
    for n in range(len(blob)):
        with pytest.raises(TableFormatError):
            CamTable.from_bytes(blob[:n])
    with pytest.raises(TableFormatError, match="length"):
        CamTable.from_bytes(blob + b"\0")


def test_inconsistent_blob_with_valid_crcs_is_rejected(drrd):
    """A header whose CRCs are right but whose fields disagree is still refused."""
    blob = bytearray(compile_table(drrd, interp="cubic", points=19).to_bytes())
    blob[20:24] = (12345).to_bytes(4, "little")  # master_counts no longer points-1 times step
    blob[60:64] = zlib.crc32(bytes(blob[:60])).to_bytes(4, "little")
    with pytest.raises(TableFormatError, match="step_counts"):
        CamTable.from_bytes(bytes(blob))


def test_the_certificate_holds_python_numbers(drrd):
    """The compiler works in numpy; the certificate it hands out holds Python floats and ints
    (plain repr, plain equality), with the same values."""
    import dataclasses

    for settings in (dict(interp="linear", points=129), dict(interp="cubic", tolerance="2 counts")):
        table = compile_table(drrd, master_counts=2**16, **settings)  # (the first one held numpy scalars)
        certificate = table.certificate
        for part in (certificate, certificate.measurement):
            for field in dataclasses.fields(part):
                value = getattr(part, field.name)
                if field.name in ("measurement", "joints_off_points") or value is None or isinstance(value, str):
                    continue
                assert type(value) in (float, int), (settings, field.name, type(value))
                assert (type(value) is float) == ("float" in str(field.type)), field.name
        assert all(type(x) is float for x in certificate.joints_off_points)
        assert "np." not in repr(certificate) and "numpy" not in repr(certificate)
        again = ecam.Certificate(**{f.name: getattr(certificate, f.name) for f in dataclasses.fields(certificate)})
        assert again == certificate and again.report(table) == table.report


# Where each TableFormat field sits in the blob header (FORMAT.md), as struct codes.
HEADER_FIELDS = {
    "degree": (8, "B"), "step_shift": (10, "b"), "tau_bits": (11, "B"), "work_bits": (12, "B"),
    "slope_bits": (13, "B"), "curvature_bits": (14, "B"), "slope_preshift": (15, "B"), "points": (16, "I"),
    "master_counts": (20, "I"), "step_counts": (24, "I"), "position_bits": (28, "B"), "tau_recip": (32, "Q"),
}


def test_the_format_and_the_loader_state_each_field_rule_once(drrd):
    """TableFormat.validate and the loader take their rules from one table (ecam.table.FIELD_RULES):
    a header field changed in a blob (CRCs fixed) and the same field changed in the format are
    refused by the same rule, with the same words and the same C status."""
    import dataclasses
    import struct

    from ecam.table import FIELD_RULES

    seen = set()
    format_rules = {rule.status for rule in FIELD_RULES if not rule.blob_only}
    periodic = CamProfile.from_segments([Segment.from_span(240.0, 45.0, "modified_sine"), Segment.from_span(120.0)],
                                        net_stroke=45.0)
    tables = [compile_table(drrd, interp=interp, points=points, master_counts=counts)
              for interp, points, counts in [("linear", 9, 2**12), ("cubic", 19, 36000), ("quintic", 65, 2**16)]]
    tables.append(compile_table(periodic, interp="cubic", points=25, master_counts=36000))
    for table in tables:
        blob, f = table.to_bytes(), table.format
        changes = [(name, offset, code, value) for name, (offset, code) in HEADER_FIELDS.items()
                   for value in {0, 1, 2, 7, 30, 31, 41, 64, 127, getattr(f, name) - 1, getattr(f, name) + 1}
                   if 0 <= value < 2 ** (8 * struct.calcsize(code) - (code == "b"))]
        changes += [("net", 48, "qI", value) for value in [(45000, 2), (f.net_stroke_num, 0), (2**40, 1)]]
        changes += [("ramp", 48, "qI", (0, 1))]  # version 3 without a net stroke
        for name, offset, code, value in changes:
            header = bytearray(blob[:64])
            struct.pack_into("<" + code, header, offset, *(value if name in ("net", "ramp") else (value,)))
            if name in ("net", "ramp"):
                struct.pack_into("<H", header, 4, 2 if name == "net" else 3)  # versions 2 and 3 store it
            struct.pack_into("<I", header, 60, zlib.crc32(bytes(header[:60])))
            try:
                CamTable.from_bytes(bytes(header) + blob[64:])
            except TableFormatError as exc:
                loader = exc
            else:
                continue
            if loader.status not in format_rules:
                continue  # a rule about the blob's own bytes (payload size), or the overflow proof
            fields = dict(net_stroke_num=value[0], net_stroke_den=value[1]) if name in ("net", "ramp") else {name: value}
            if name == "ramp":
                fields["ramp"] = True
            with pytest.raises(TableFormatError) as info:
                dataclasses.replace(f, **fields).validate()
            assert (info.value.status, f"blob {info.value} ({info.value.status})") == (loader.status, str(loader))
            seen.add(loader.status)
    assert seen == format_rules


def test_non_power_of_two_steps_use_the_reciprocal(drrd):
    table = compile_table(drrd, interp="cubic", points=361, master_counts=36000, slave_counts_per_unit=1e5)
    assert table.format.step_shift == -1 and table.format.step_counts == 100
    r = table.report
    assert r["max_error_counts"] <= r["predicted_error_counts"] and r["max_error_counts"] < 1.5


def test_strokes_near_the_int32_limit():
    """Either a correct table or a clear error -- never a wrapped number."""
    big = 2**31 - 1000
    profile = rise_return("cycloidal", stroke=1.0)
    table = compile_table(profile, interp="quintic", points=1025, master_counts=2**20, slave_counts_per_unit=big)
    r = table.report
    assert r["max_error_counts"] <= r["predicted_error_counts"]
    assert table.lookup(2**19) == big
    with pytest.raises(ecam.InputError, match="overflows int32"):
        compile_table(profile, interp="cubic", points=65, master_counts=2**16, slave_counts_per_unit=2.0**31)


def test_auto_meets_the_tolerance_with_the_fewest_bytes(drrd):
    tol = 1e-5 * 3
    auto = compile_table(drrd, interp="auto", tolerance=tol)
    assert auto.report["max_error_units"] <= auto.report["predicted_error_units"] <= tol
    for kind in KINDS:
        fixed = compile_table(drrd, interp=kind, tolerance=tol)
        assert fixed.report["predicted_error_units"] <= tol
        assert auto.nbytes <= fixed.nbytes


@pytest.mark.slow
def test_large_period_is_sampled_not_skipped():
    profile = rise_return("poly345", stroke=10.0)
    table = compile_table(profile, interp="cubic", points=1025, master_counts=2**30, slave_counts_per_unit=1e6)
    r = table.report
    assert "sample" in r["evaluated"] and r["evaluated_counts"] >= 2**22
    assert r["max_error_counts"] <= r["predicted_error_counts"]


@pytest.mark.slow
def test_table_of_2_20_points():
    profile = rise_return("cycloidal", stroke=100.0)
    table = compile_table(profile, interp="linear", points=2**20 + 1, master_counts=2**22,
                          slave_counts_per_unit=1e4)
    assert table.points == 2**20 + 1
    assert table.report["max_error_counts"] <= table.report["predicted_error_counts"]


BAD = [
    (dict(points=1), "points: 1 should be an integer in 2..4194305"),
    (dict(points=1000), "points 1000 gives 999 intervals, which do not divide master_counts 65536"),
    (dict(tolerance=1e-9), "cannot be met within"),
    (dict(points=65, slave_counts_per_unit=1e12), "overflows int32"),
    (dict(points=65, master_counts=2**31 + 1), "master_counts: 2147483649 should be an integer in 2..2147483648"),
    (dict(points=65, slave_counts_per_unit=-1.0), "slave_counts_per_unit: -1 should be >= 1e-06"),
    (dict(points=65, interp="spline"), "interp: 'spline' should be one of linear, cubic, quintic, auto"),
    (dict(tolerance="3 furlongs"), "tolerance: '3 furlongs' should be in the cam's slave unit"),
    (dict(tolerance="three counts"), "tolerance: 'three counts' should be a number > 0"),
    (dict(tolerance="-2 counts"), "tolerance: '-2 counts' should be a number > 0"),
    (dict(points=65, tolerance=0.01), "give either points or tolerance, not both"),
    (dict(points=65, master_counts=True), "master_counts: True should be an integer"),
    (dict(points=65, slave_counts_per_unit=float("nan")), "slave_counts_per_unit: nan should be finite"),
]


@pytest.mark.parametrize("kwargs,message", BAD)
def test_bad_input(kwargs, message, msine):
    kwargs = {"interp": "cubic", "master_counts": 65536, **kwargs}
    with pytest.raises(ecam.InputError) as info:
        compile_table(msine, **kwargs)
    assert message in str(info.value)


def test_compile_cli_json_contract(tmp_path):
    from conftest import CAMS

    run = subprocess.run([sys.executable, "-m", "ecam.app", "compile", str(CAMS / "modified_sine.toml"),
                          "--interp", "cubic", "--points", "257", "-o", str(tmp_path), "--format", "c,bin,csv,json",
                          "--json"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    for key in ("interp", "points", "bytes", "crc32", "max_error_counts", "max_error_units",
                "predicted_error_units", "files"):
        assert key in out
    assert out["interp"] == "cubic" and out["points"] == 257 and len(out["files"]) == 4
    blob = (tmp_path / "modified_sine.bin").read_bytes()
    assert len(blob) == out["bytes"] and CamTable.from_bytes(blob).crc32 == out["crc32"]
    header = (tmp_path / "modified_sine.h").read_text()
    assert f"0x{out['crc32']:08x}" in header and "modified_sine_blob" in header


@pytest.mark.parametrize("args,message", [
    (["--points", "1"], "points: 1 should be an integer in 2..4194305"),
    (["--points", "1000"], "do not divide master_counts"),
    (["--tolerance", "1e-12"], "cannot be met"),
    (["--points", "65", "--slave-counts-per-unit", "1e12"], "overflows int32"),
    (["--points", "65", "--format", "pdf"], "--format 'pdf'"),
    (["--points", "x"], "invalid int value"),
])
def test_compile_cli_bad_input_is_one_line(args, message, tmp_path):
    from conftest import CAMS

    run = subprocess.run([sys.executable, "-m", "ecam.app", "compile", str(CAMS / "modified_sine.toml"),
                          "-o", str(tmp_path), *args], capture_output=True, text=True)
    assert run.returncode == 2
    assert len(run.stderr.strip().splitlines()) == 1 and message in run.stderr, run.stderr


@pytest.mark.slow
def test_generated_firmware_tables_are_reproducible():
    """Regenerate firmware_tables/ and compare byte for byte with the committed files."""
    from conftest import ROOT
    from ecam.app.firmware import generate

    files = generate(ROOT / "firmware_tables" / "cams")
    assert files
    for relative, content in files.items():
        path = ROOT / "firmware_tables" / relative
        assert path.exists(), f"{relative} is not committed; run python3 -m ecam.app.firmware"
        assert path.read_bytes() == content, f"{relative} differs; run python3 -m ecam.app.firmware"


@pytest.mark.parametrize("kind", KINDS)
def test_scalar_path_matches_the_vectorized_lookup(kind, drrd):
    """Single master positions take a pure-integer path; it must give the very same bits."""
    for periodic_table in (compile_table(drrd, interp=kind, points=18 * 8 + 1),
                           compile_table(drrd, interp=kind, points=361, master_counts=36000),
                           compile_table(CamProfile((Segment(0, 90, 0, 10, ecam.law("cycloidal")),), 90.0, False),
                                         interp=kind, points=65, master_counts=2**12, slave_counts_per_unit=1e3)):
        rng = np.random.default_rng(5)
        m = periodic_table.master_counts
        queries = np.concatenate([rng.integers(-3 * m, 3 * m, 300), [0, m - 1, m, -1, 2**63 - 1, -(2**63)]])
        position, slope = periodic_table.lookup(queries, with_slope=True)
        for q, p, s in zip(queries.tolist(), position.tolist(), slope.tolist()):
            assert periodic_table.lookup(q, with_slope=True) == (p, s)
            assert periodic_table.lookup(np.int64(q)) == p


def test_tolerance_just_above_the_half_count_floor(msine):
    """The search's lower bound is the 1/2-count final rounding, so 0.6 counts is reachable and
    0.5 counts (the floor itself) is refused with the best bound in the message."""
    table = compile_table(msine, interp="auto", tolerance="0.6 counts")
    assert table.report["max_error_counts"] <= table.report["predicted_error_counts"] <= 0.6
    with pytest.raises(TableFormatError, match="best bound found is 0.5"):
        compile_table(msine, interp="auto", tolerance="0.5 counts")


def test_a_tolerance_in_the_cams_slave_unit_equals_the_plain_number(msine):
    unit = msine.slave_unit
    worded = compile_table(msine, interp="cubic", tolerance=f"0.001 {unit}", certify=False)
    plain_number = compile_table(msine, interp="cubic", tolerance=0.001, certify=False)
    assert worded.to_bytes() == plain_number.to_bytes()
    assert worded.report["tolerance_units"] == 0.001


def test_a_tolerance_in_another_unit_is_refused_naming_the_cams_unit(msine):
    with pytest.raises(ecam.InputError) as info:
        compile_table(msine, interp="cubic", tolerance="0.001 furlong")
    assert str(info.value) == (f"tolerance: '0.001 furlong' should be in the cam's slave unit "
                               f"({msine.slave_unit}) or in counts")
