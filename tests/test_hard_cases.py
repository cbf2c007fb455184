"""Numerical stability on hard cases: every case works or fails with a clear error -- never a
wrong number, a NaN or a hang."""
import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

import ecam
from ecam import compile_table
from ecam.laws import polynomial_from_boundary
from ecam.profile import CamProfile, Segment


def test_tiny_segment_next_to_huge_ones():
    """A 1e-6-of-the-period dwell between two long rises: checked, compiled, certified."""
    period = 360.0
    tiny = 1e-6 * period
    cyc = ecam.law("cycloidal")
    segs = (
        Segment(0.0, 180.0, 0.0, 10.0, cyc),
        Segment(180.0, 180.0 + tiny, 10.0, 10.0, ecam.law("constant_velocity"), "tiny dwell"),
        Segment(180.0 + tiny, period, 10.0, 0.0, cyc),
    )
    profile = CamProfile(segs, period, True)
    assert profile.check().ok
    for kind in ("linear", "cubic", "quintic"):
        table = compile_table(profile, interp=kind, points=1025, master_counts=2**16, slave_counts_per_unit=1e4)
        r = table.report
        assert math.isfinite(r["max_error_counts"]) and r["max_error_counts"] <= r["predicted_error_counts"]


def test_tiny_segment_with_a_stroke_fails_clearly_for_a_tolerance():
    """A rise over 1e-6 of the period has an enormous acceleration: no table within the point
    limit meets a tight tolerance, and the error says so instead of producing a bad table."""
    period = 360.0
    tiny = 1e-6 * period
    cyc = ecam.law("cycloidal")
    segs = (Segment(0.0, tiny, 0.0, 1.0, cyc), Segment(tiny, period, 1.0, 0.0, cyc))
    profile = CamProfile(segs, period, True)
    with pytest.raises(ecam.TableFormatError, match="cannot be met within"):
        compile_table(profile, interp="auto", tolerance="2 counts", master_counts=2**16, slave_counts_per_unit=1e4)
    # a fixed point count still compiles, and its certificate tells the (large) truth
    table = compile_table(profile, interp="cubic", points=257, master_counts=2**16, slave_counts_per_unit=1e4)
    r = table.report
    assert r["max_error_counts"] <= r["predicted_error_counts"] and r["max_error_counts"] > 100


@given(
    v=st.lists(st.floats(-200, 200), min_size=2, max_size=2),
    a=st.lists(st.floats(-5e4, 5e4), min_size=2, max_size=2),
    j=st.lists(st.floats(-1e6, 1e6), min_size=2, max_size=2),
    seven=st.booleans(),
)
def test_extreme_boundary_polynomials(v, a, j, seven):
    """5th/7th-order segments with extreme boundary conditions stay finite and certified, or are
    rejected with a clear error."""
    start = (v[0], a[0], j[0]) if seven else (v[0], a[0])
    end = (v[1], a[1], j[1]) if seven else (v[1], a[1])
    law = polynomial_from_boundary(start, end)
    profile = CamProfile((Segment(0.0, 100.0, 0.0, 1.0, law),), 100.0, periodic=False)
    try:
        table = compile_table(profile, interp="quintic", points=257, master_counts=2**14, slave_counts_per_unit=1e3)
    except ecam.EcamError as exc:
        assert "overflow" in str(exc) or "int32" in str(exc)
        return
    r = table.report
    assert np.isfinite(r["max_error_counts"]) and r["max_error_counts"] <= r["predicted_error_counts"]


@pytest.mark.slow
@given(st.integers(-(2**63), 2**63 - 1))
def test_any_int64_master_position(m):
    profile = CamProfile((Segment(0.0, 360.0, 0.0, 0.0, ecam.law("constant_velocity")),), 360.0)
    msine = ecam.design.modified_sine_cam(50.0)
    table = compile_table(msine, interp="cubic", points=257, master_counts=65536, slave_counts_per_unit=1000)
    assert table.lookup(m) == table.lookup(m % 65536)
    assert 0 <= table.lookup(m) <= 50000
    del profile


def test_master_that_reverses_jitters_and_stops_inside_a_segment(drrd):
    """The lookup is a pure function of master position: a master that reverses, jitters and
    stops inside a segment gets the same answer at the same position, with no drift."""
    table = compile_table(drrd, interp="quintic", points=18 * 16 + 1)
    m = table.master_counts
    inside = int(m * 75 / 360)  # inside the C1 piece of the rise
    rng = np.random.default_rng(3)
    path = np.concatenate([
        np.arange(inside - 500, inside + 500),          # forward
        np.arange(inside + 500, inside - 500, -1),      # reverse
        inside + rng.integers(-3, 4, 2000),             # jitter
        np.full(1000, inside),                          # stop
    ]).astype(np.int64)
    values = table.lookup(path)
    again = table.lookup(path)
    np.testing.assert_array_equal(values, again)
    np.testing.assert_array_equal(values[path == inside], table.lookup(inside))
    # and the position follows the profile within the certificate everywhere on the path
    exact = drrd(path * 360.0 / m) * 1e5
    assert np.abs(values - exact).max() <= table.report["predicted_error_counts"]


def test_non_integer_and_non_finite_queries_are_rejected(msine):
    table = compile_table(msine, interp="cubic", points=257)
    with pytest.raises(ecam.InputError, match="should be integers"):
        table.lookup(np.array([1.5]))
    with pytest.raises(ecam.InputError):
        table.lookup(np.array([np.nan]))
    with pytest.raises(ecam.InputError):
        table.lookup(2**64)


def test_prime_master_period_has_no_hang():
    """2^31 - 1 is prime: the only step dividing it is 1 count (too many points) or the whole
    period; the compiler answers at once either way."""
    msine = ecam.design.modified_sine_cam(50.0)
    with pytest.raises(ecam.TableFormatError, match="step 2147483647 counts .* should be <= 1073741824"):
        compile_table(msine, interp="quintic", points=2, master_counts=2**31 - 1, slave_counts_per_unit=10)
    with pytest.raises(ecam.InputError, match="cannot be met within"):
        compile_table(msine, interp="auto", tolerance=0.01, master_counts=2**31 - 1, slave_counts_per_unit=10)
    with pytest.raises(ecam.InputError, match="do not divide"):
        compile_table(msine, interp="cubic", points=1025, master_counts=2**31 - 1, slave_counts_per_unit=10)


@pytest.mark.parametrize("stroke_counts", [2**24, -(2**27), 2**30 - 2**16, -(2**30) + 2**16])
def test_any_net_stroke_up_to_2_30_counts_meets_one_count(stroke_counts):
    """Issue 27: a periodic cam advancing up to 2^30 counts per period (either way) meets a 1-count
    tolerance, stored relative to its ramp (format version 3) once absolute positions would keep
    fewer than 10 fraction bits, and its certificate holds across the wrap."""
    stroke = 45.0 if stroke_counts > 0 else -45.0
    profile = CamProfile.from_segments([Segment.from_span(240.0, stroke, "modified_sine"), Segment.from_span(120.0)],
                                       net_stroke=stroke)
    table = compile_table(profile, interp="auto", tolerance="1 counts", master_counts=2**18,
                          slave_counts_per_unit=abs(stroke_counts) / 45.0)
    r = table.report
    assert table.net_stroke == stroke_counts and table.format_version == 3
    assert table.format.ramp_slope == stroke_counts // 2**18 and table.format.position_bits >= 2
    assert r["max_error_counts"] <= r["predicted_error_counts"] <= 1.0
    assert r["wrap_max_error_counts"] <= r["predicted_error_counts"]
