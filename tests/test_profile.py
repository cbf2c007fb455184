"""Cam profiles: evaluation, wrapping, and check() on random chains of segments."""
import numpy as np
import pytest
from hypothesis import given, strategies as st

import ecam
from ecam.profile import CamProfile, Segment

REST_LAWS = ["cycloidal", "poly345", "poly4567", "modified_sine", "modified_trapezoid", "harmonic", "cubic",
             "constant_acceleration"]


def chain(spec, periodic=True):
    """spec: list of (law name, span, stroke)."""
    x = y = 0.0
    segments = []
    for name, span, stroke in spec:
        segments.append(Segment(x, x + span, y, y + stroke, ecam.law(name), name))
        x += span
        y += stroke
    return CamProfile(tuple(segments), x, periodic)


def significant(left, right, order, neighbours):
    """Float noise: 1e-9 relative (1e-12 for positions) plus 1e-12 of the neighbours' scale."""
    local = max(abs(s.stroke) / s.span**order for s in neighbours)
    relative = 1e-12 if order == 0 else 1e-9
    return abs(right - left) > relative * max(abs(left), abs(right)) + 1e-12 * local


def expected_jumps(profile):
    """Independent oracle: compare one-sided derivatives of neighbours directly from the laws."""
    out = set()
    segs = profile.segments
    pairs = [(segs[i - 1], segs[i], segs[i].master_start) for i in range(1, len(segs))]
    if profile.periodic:
        pairs.append((segs[-1], segs[0], 0.0))
    for left, right, at in pairs:
        for order in range(4):
            lv = left.slave_end if order == 0 else left.stroke / left.span**order * left.law(1.0, order, side="left")
            rv = right.slave_start if order == 0 else right.stroke / right.span**order * right.law(0.0, order)
            if significant(lv, rv, order, (left, right)):
                out.add((round(at, 9), order))
    for seg in segs:
        for u in seg.law.breaks:
            for order in range(4):
                lv = seg.stroke / seg.span**order * seg.law(u, order, side="left")
                rv = seg.stroke / seg.span**order * seg.law(u, order, side="right")
                if order == 0:
                    lv, rv = lv + seg.slave_start, rv + seg.slave_start
                if significant(lv, rv, order, (seg,)):
                    out.add((round(seg.master_start + u * seg.span, 9), order))
    return out


segment = st.tuples(
    st.sampled_from(REST_LAWS + ["constant_velocity", "half_cycloid_start", "half_harmonic_end"]),
    st.floats(0.5, 100.0),
    st.one_of(st.just(0.0), st.floats(-50.0, 50.0).filter(lambda v: abs(v) > 1e-3)),
)


@given(st.lists(segment, min_size=1, max_size=7), st.booleans())
def test_check_finds_exactly_the_jumps(spec, periodic):
    profile = chain(spec, periodic)
    found = {(round(d.master, 9), d.order) for d in profile.check().discontinuities}
    assert found == expected_jumps(profile)


@given(st.lists(st.tuples(st.sampled_from(REST_LAWS), st.floats(1, 90), st.floats(-10, 10)), min_size=1, max_size=6))
def test_rest_to_rest_chains_are_velocity_continuous(spec):
    """Laws that start and end at rest never jump in velocity, whatever the strokes."""
    profile = chain(spec + [("cycloidal", 10.0, -sum(s for _, _, s in spec))])
    report = profile.check()
    assert report.continuous(0) and report.continuous(1)


def test_periodic_evaluation_wraps(drrd):
    x = np.array([10.0, 75.0, 200.0])
    np.testing.assert_allclose(drrd(x + 360.0 * 7), drrd(x), atol=1e-12)
    np.testing.assert_allclose(drrd(x - 720.0), drrd(x), atol=1e-12)


def test_non_periodic_range_is_checked():
    profile = chain([("cycloidal", 90.0, 10.0)], periodic=False)
    assert profile(90.0) == pytest.approx(10.0)
    with pytest.raises(ecam.InputError, match=r"master: 91 should be in \[0, 90\], the range of a non-periodic cam"):
        profile(91.0)


def test_seam_position_jump_is_reported():
    profile = chain([("cycloidal", 90.0, 10.0), ("dwell" if False else "constant_velocity", 90.0, 0.0)])
    seam = profile.check().at(0.0, 0)
    assert len(seam) == 1 and seam[0].jump == pytest.approx(-10.0)
    assert "seam" in seam[0].where


def test_a_declared_net_stroke_makes_the_seam_a_joint():
    segments = chain([("cycloidal", 90.0, 10.0), ("constant_velocity", 90.0, 0.0)]).segments
    profile = CamProfile(segments, 180.0, net_stroke=10.0)
    assert not profile.check().at(0.0, 0)  # the position continues by the net stroke
    assert [d.order for d in profile.check().at(0.0)] == [d.order for d in chain(
        [("cycloidal", 90.0, 10.0), ("constant_velocity", 90.0, 0.0)]).check().at(0.0) if d.order > 0]
    assert profile(180.0) == 10.0 and profile(180.0 + 45.0) == pytest.approx(15.0)
    assert profile(-90.0) == -10.0 + 10.0 and profile(-135.0) == pytest.approx(-5.0)


def test_constant_acceleration_break_inside_the_law():
    profile = chain([("constant_acceleration", 100.0, 10.0), ("constant_velocity", 100.0, -10.0)])
    inner = profile.check().at(50.0, 2)
    assert len(inner) == 1 and inner[0].jump == pytest.approx(-8 * 10.0 / 100.0**2)


def test_gaps_and_overlaps_are_rejected():
    law = ecam.law("cycloidal")
    with pytest.raises(ecam.InputError, match="gap"):
        CamProfile((Segment(0, 10, 0, 1, law), Segment(11, 20, 1, 0, law)), 20.0)
    with pytest.raises(ecam.InputError, match="overlap"):
        CamProfile((Segment(0, 10, 0, 1, law), Segment(9, 20, 1, 0, law)), 20.0)
    with pytest.raises(ecam.InputError, match="master_period"):
        CamProfile((Segment(0, 10, 0, 1, law),), 20.0)


def test_derivative_bound_is_an_upper_bound(drrd):
    x = np.linspace(0, 360, 100001)
    for order in range(6):
        assert drrd.derivative_bound(order) >= np.abs(drrd(x, order)).max()
        assert drrd.derivative_bound(order) <= 1.05 * np.abs(drrd(x, order)).max() + 1e-300


def test_small_position_step_high_up_the_range_is_found():
    """A 1.9-unit step at 2.1e9 is a jump, not float noise of the absolute position."""
    dwell = ecam.law("constant_velocity")
    profile = CamProfile((Segment(0, 100.5, 2.1e9, 2.1e9, dwell), Segment(100.5, 360, 2.1e9 + 1.9, 2.1e9 + 1.9, dwell)),
                         360.0, periodic=False)
    found = profile.check().at(100.5, 0)
    assert len(found) == 1 and found[0].jump == pytest.approx(1.9)


def test_a_tiny_segment_hides_no_jump_elsewhere():
    """The noise threshold is local: a segment 1e-6 of the period long (with its enormous
    acceleration) does not mask the harmonic law's acceleration jumps at the other joints."""
    tiny = 3.6e-4
    profile = chain([("constant_velocity", 60.0, 0.0), ("harmonic", 120.0, 1.0), ("constant_velocity", 60.0, 0.0),
                     ("harmonic", 120.0 - tiny, -0.5), ("cycloidal", tiny, -0.5)])
    accel = {round(d.master, 6) for d in profile.check().errors if d.order == 2}
    assert {60.0, 180.0, 240.0, round(360.0 - tiny, 6)} <= accel
