"""The interpolation tolerance (issue 27 item 1): with a tolerance of a count or so, most of which
is the 1/2 count of the final rounding to whole counts, it bounds what the table adds to that
rounding. Without it every table is what it was (the golden tables test the bytes); the drums of
26 to 30 bits are in tests/test_large_drum.py."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import ecam
from ecam.camfile import parse_cam
from ecam.errors import CamFileError, InputError, TableFormatError
from ecam.table_spec import TableSpec

ROOT = Path(__file__).resolve().parents[1]
KNIFE = ROOT / "firmware_tables" / "cams" / "rotary_knife.toml"


@pytest.fixture(scope="module")
def knife():
    return ecam.load_cam(KNIFE)


def test_it_holds_the_table_to_its_share_above_the_rounding(knife):
    """The knife at its own scale (1000 counts per deg, 36000 master counts), 1 count: 13 quintic
    points, whose bound leaves 0.079 counts to the table; 0.05 counts above the rounding takes 25.
    The same tolerance in the slave unit (5e-5 deg) gives the same table."""
    plain = ecam.compile_table(knife, tolerance="1 counts")
    assert plain.points == 13 and plain.certificate.predicted_error_counts - 0.5 > 0.05
    held = ecam.compile_table(knife, tolerance="1 counts", interpolation_tolerance="0.05 counts")
    r = held.report
    assert held.points == 25 and r["predicted_above_rounding_counts"] <= 0.05
    assert r["max_error_counts"] <= r["predicted_error_counts"] <= 0.55
    assert r["interpolation_tolerance_units"] == pytest.approx(5e-5)
    in_units = ecam.compile_table(knife, tolerance="1 counts", interpolation_tolerance=5e-5, certify=False)
    assert in_units.to_bytes() == held.to_bytes()
    # the tolerance still binds where it is the tighter of the two
    assert ecam.compile_table(knife, tolerance="0.51 counts", interpolation_tolerance="0.3 counts",
                              certify=False).certificate.predicted_error_counts <= 0.51


def test_it_needs_a_tolerance_and_a_positive_value():
    with pytest.raises(InputError, match=r"^interpolation_tolerance: '0.05 counts' should be absent when points"):
        TableSpec(points=13, interpolation_tolerance="0.05 counts")
    with pytest.raises(InputError, match=r"^interpolation_tolerance: -1 should be a number > 0"):
        TableSpec(tolerance="1 counts", interpolation_tolerance=-1)
    with pytest.raises(InputError, match=r"^interpolation_tolerance: '0.05 in' should be in the cam's slave unit"):
        TableSpec(tolerance="1 counts", interpolation_tolerance="0.05 in").interpolation_tolerance_counts("deg")


def test_it_travels_with_the_cam_files_tolerance():
    """A cam file's interpolation tolerance refines its tolerance: kept while that tolerance
    applies, dropped with it when points or a tolerance are given explicitly."""
    file = {"tolerance": "1 counts", "interpolation_tolerance": "0.05 counts"}
    assert TableSpec.resolve(file).interpolation_tolerance == "0.05 counts"
    assert TableSpec.resolve(file, master_counts=2**20).interpolation_tolerance == "0.05 counts"
    assert TableSpec.resolve(file, tolerance="2 counts").interpolation_tolerance is None
    assert TableSpec.resolve(file, points=13).interpolation_tolerance is None
    assert TableSpec.resolve(file, interpolation_tolerance="0.1 counts").interpolation_tolerance == "0.1 counts"
    assert TableSpec.resolve({"tolerance": "1 counts"}, tolerance="1 counts",
                             interpolation_tolerance="0.1 counts").interpolation_tolerance == "0.1 counts"


def test_a_cam_files_table_sets_it():
    cam = {"master_period": 360.0, "slave_unit": "deg",
           "table": {"interp": "quintic", "tolerance": "1 counts", "interpolation_tolerance": "0.05 counts"},
           "segment": [{"law": "cycloidal", "span": 180.0, "stroke": 10.0},
                       {"law": "cycloidal", "span": 180.0, "stroke": -10.0}]}
    profile = parse_cam(cam, source="cam.toml")
    assert ecam.compile_table(profile, certify=False).report["interpolation_tolerance_counts"] == 0.05
    assert 'interpolation_tolerance = "0.05 counts"' in profile.to_toml()
    assert parse_cam(tomllib.loads(profile.to_toml()), source="cam.toml").table == profile.table
    del cam["table"]["tolerance"]
    with pytest.raises(CamFileError, match=r"table\.interpolation_tolerance: '0.05 counts' should be given with a "
                                           r"tolerance"):
        parse_cam(cam, source="cam.toml")
    cam["table"].update(tolerance="1 counts", interpolation_tolerance="0.05 mm")
    with pytest.raises(CamFileError, match=r"table\.interpolation_tolerance: '0.05 mm' should be in the cam's "
                                           r"slave unit \(deg\)"):
        parse_cam(cam, source="cam.toml")


def test_ecam_compile_takes_it(tmp_path):
    out = subprocess.run([sys.executable, "-m", "ecam.app", "compile", str(KNIFE), "--tolerance", "1 counts",
                          "--interpolation-tolerance", "0.05 counts", "--json", "-o", str(tmp_path)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["points"] == 25 and summary["interpolation_tolerance_counts"] == 0.05
    assert summary["final_rounding_counts"] + summary["predicted_above_rounding_counts"] == pytest.approx(
        summary["predicted_error_counts"])


def test_ecam_compile_notes_the_share_above_the_rounding_where_the_tolerance_is_a_count(knife):
    from ecam.app.compile_notes import rounding_hint

    note = rounding_hint(ecam.compile_table(knife, tolerance="1 counts", certify=False))
    assert note is not None and "adds up to 0.0793 more; --interpolation-tolerance" in note
    assert rounding_hint(ecam.compile_table(knife, tolerance="1 counts", interpolation_tolerance="0.05 counts",
                                            certify=False)) is None
    assert rounding_hint(ecam.compile_table(knife, certify=False)) is None  # the file's 2 counts
    assert rounding_hint(ecam.compile_table(knife, points=13, interp="quintic", certify=False)) is None
    # 1 count given in the slave unit on a scale that is not whole counts per unit (the 26-bit
    # drum, 2^26 / 360 counts per deg): its float conversion comes back 1.000000000000001 counts
    drum = 2**26 / 360
    table = ecam.compile_table(knife, tolerance=(1.0 / drum) * (1 + 1e-15), interp="quintic", master_counts=2**20,
                               slave_counts_per_unit=drum, certify=False)
    assert table.report["tolerance_counts"] > 1.0 and rounding_hint(table) is not None


def test_a_refusal_says_whether_its_best_bound_is_a_built_tables_or_a_prediction(knife):
    """The drum (2^26 counts per turn) at 2^12 master counts: no size's prediction meets 1e-6
    counts above the rounding, so the figure named is the interpolation's prediction alone, a
    lower bound (the 4097-point table, built, certifies 1e-3 counts above it); at 0.5009 counts
    in 32-bit words the sizes predicted below it were built, and the figure is their bound."""
    drum = dict(interp="quintic", master_counts=2**12, slave_counts_per_unit=2**26 / 360, certify=False)
    with pytest.raises(TableFormatError, match=r"best bound found is 3\.46\d*e-06 counts above the final "
                                               r"rounding's 1/2 count, at least \(the interpolation's prediction"):
        ecam.compile_table(knife, tolerance="1 counts", interpolation_tolerance="1e-6 counts", **drum)
    with pytest.raises(TableFormatError, match=r"best bound found is 0\.511\d* counts \(the final rounding to whole "
                                               r"counts alone costs 1/2 count\)$"):
        ecam.compile_table(knife, tolerance="0.5009 counts", horner_bits=32, **drum)


def test_ecam_export_says_the_key_is_not_for_vendor_exports(tmp_path):
    text = KNIFE.read_text().replace('tolerance = "2 counts"',
                                     'tolerance = "1 counts"\ninterpolation_tolerance = "0.05 counts"')
    cam = tmp_path / "knife.toml"
    cam.write_text(text)
    run = [sys.executable, "-m", "ecam.app", "export", str(cam), "--to", "csv", "--interp", "cubic"]
    out = subprocess.run([*run, "-o", str(tmp_path / "with.csv")], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "interpolation_tolerance applies to `ecam compile`'s tables, not to vendor exports" in out.stdout
    out = subprocess.run([*run[:4], str(KNIFE), *run[5:], "-o", str(tmp_path / "without.csv")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "interpolation_tolerance" not in out.stdout
