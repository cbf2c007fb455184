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


def test_the_slave_range_takes_the_position_reached_at_the_seam():
    """A periodic cam that ends its period higher than it starts (a net stroke left undeclared)
    reaches that end position just before the seam, where the evaluation wraps back to 0: the
    range (what `ecam check` prints as the stroke) is 0 .. 360, not the last sample's 359.98."""
    ramp = CamProfile.from_segments([Segment.from_span(360.0, 360.0, "constant_velocity")])
    assert ramp(360.0) == 0.0 and ramp(360.0, side="left") == 360.0
    assert ramp.slave_range == (0.0, 360.0)
    declared = CamProfile.from_segments([Segment.from_span(360.0, 360.0, "constant_velocity")], net_stroke=360.0)
    assert declared.slave_range == (0.0, 360.0)
    falling = CamProfile.from_segments([Segment.from_span(360.0, -360.0, "constant_velocity")])
    assert falling.slave_range == (-360.0, 0.0)


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


# --- cost in the number of segments (issue 14) ----------------------------------------------------
# Evaluation finds each point's segment by binary search and evaluates every point at once (the
# laws' pieces stacked in a LawTable); these tests hold that without a clock: they count what the
# work touches, which is the same on every machine.
from ecam.compile import compile_table  # noqa: E402
from ecam.laws import LAWS, LawTable, polynomial_from_boundary  # noqa: E402
from ecam.linear import solve_exact  # noqa: E402
from ecam.profile import MAX_SEGMENTS  # noqa: E402


def many_segments(count):
    """A cam of ``count`` segments (a multiple of 4), one master unit each: dwell, a rise, dwell,
    a return; every other rise a poly5 from rest to rest (a law of its own per segment)."""
    segments = []
    for k in range(count // 4):
        rise = (Segment.polynomial(0.0, 1.0, 0.0, 1.0) if k % 2
                else Segment.from_span(1.0, 1.0, "cycloidal"))
        segments += [Segment.from_span(1.0), rise, Segment.from_span(1.0),
                     Segment.from_span(1.0, -1.0, "modified_sine")]
    return CamProfile.from_segments(segments)


def python_calls(work):
    """How many Python-level calls (functions, builtins, numpy entry points) ``work()`` makes: a
    deterministic measure of its cost. A loop over every segment per evaluated point, or per
    joint, shows as calls growing with the square of the segments."""
    import sys

    count = 0

    def tally(frame, event, arg):
        nonlocal count
        if event in ("call", "c_call"):
            count += 1

    previous = sys.getprofile()
    sys.setprofile(tally)
    try:
        work()
    finally:
        sys.setprofile(previous)
    return count


def everything_check_and_compile_do(profile):
    """What `ecam check` and `ecam compile` ask of a profile."""
    profile.check()
    for order in (1, 2, 3):
        profile.peak(order)
    profile.slave_range
    profile(np.linspace(0.0, profile.master_period, 4097), 1)
    segments = len(profile.segments)
    compile_table(profile, interp="cubic", points=4 * segments + 1, master_counts=16 * segments)


def test_check_and_compile_cost_is_linear_in_the_segments():
    """Four times the segments, at most about four times the calls (3.5 measured; the quadratic
    version before issue 14, whose every evaluation looped over all segments, made 9.9 times as
    many)."""
    small = python_calls(lambda: everything_check_and_compile_do(many_segments(64)))
    large = python_calls(lambda: everything_check_and_compile_do(many_segments(256)))
    assert large / small < 4.5, (small, large)


def test_each_point_is_evaluated_once_by_its_own_segment(monkeypatch):
    """N points on M segments: one stacked evaluation of exactly N values, whatever M; check()
    evaluates every break once per order and side."""
    profile = many_segments(400)
    evaluated = []
    original = LawTable.pieces_at

    def counting(self, piece, t, order):
        evaluated.append(np.size(t))
        return original(self, piece, t, order)

    monkeypatch.setattr(LawTable, "pieces_at", counting)
    x = np.linspace(0.0, profile.master_period, 1001)
    profile(x, 2)
    assert evaluated == [1001]
    evaluated.clear()
    report = profile.check()
    breaks = len(profile.breaks())
    assert evaluated == [breaks] * 8  # orders 0..3, left and right: each break once
    assert report.ok and len(report.warnings) > 0


def test_stacked_laws_give_the_laws_own_bits():
    """The LawTable (every law's pieces in arrays) is each law's own evaluation to the last bit,
    at random points, on the breaks and at the ends, from both sides, for derivatives 0..7: the
    golden tables depend on it."""
    rng = np.random.default_rng(14)
    laws = [*LAWS.values(), ecam.law("dwell"), polynomial_from_boundary((0.3, -2.0), (1.5, 4.0)),
            polynomial_from_boundary((0.0, 0.0, 1.0), (2.0, 0.0, -3.0))]
    table = LawTable(laws)
    for which, law in enumerate(laws):
        u = np.concatenate([rng.random(200), law.breaks, [0.0, 1.0], np.nextafter(law.breaks, 0.0)])
        for order in range(8):
            for side in ("right", "left"):
                got = table(np.full(u.size, which), u, order, side == "left")
                want = law(u, order, side)
                assert np.array_equal(got.view(np.int64), want.view(np.int64)), (law.name, order, side)


def test_profile_evaluation_gives_each_segments_own_bits(drrd, msine):
    """profile(x) is the containing segment's own Segment.evaluate, bit for bit, inside every
    segment, on its law's breaks, and one-sided at its ends."""
    for profile in (drrd, msine, many_segments(16)):
        for seg in profile.segments:
            inside = np.concatenate([np.linspace(seg.master_start, seg.master_end, 35)[1:-1],
                                     [seg.master_start + b * seg.span for b in seg.law.breaks]])
            for order in range(6):
                for side in ("right", "left"):
                    got, want = profile(inside, order, side), seg.evaluate(inside, order, side)
                    assert np.array_equal(got.view(np.int64), want.view(np.int64)), (seg.label, order, side)
            ends = [(seg.master_start, "right", 0.0), (seg.master_end, "left", 1.0)]
            for x, side, u in ends:
                if profile.periodic or 0.0 < x < profile.master_period:
                    for order in range(4):
                        assert profile(x, order, side) == seg.at(u, order)


@given(st.lists(st.one_of(st.just(0.0), st.floats(-1e6, 1e6), st.floats(-1e-6, 1e-6)), min_size=4, max_size=6)
       .filter(lambda v: len(v) != 5))
def test_polynomial_coefficients_are_the_exact_solution(values):
    """The closed-form rational solve of a poly5/poly7 gives the bits of a full exact elimination
    (ecam.linear.solve_exact) of the boundary-condition system."""
    import math

    k = len(values) // 2
    start, end = tuple(values[:k]), tuple(values[k:])
    degree = 2 * k + 1
    rows, rhs = [], []
    for u, conditions in ((0.0, (0.0,) + start), (1.0, (1.0,) + end)):
        for order, value in enumerate(conditions):
            rows.append([math.factorial(i) / math.factorial(i - order) * u ** (i - order) if i >= order else 0.0
                         for i in range(degree + 1)])
            rhs.append(value)
    assert polynomial_from_boundary(start, end).pieces[0].poly == tuple(solve_exact(rows, rhs))


def test_more_segments_than_the_limit_is_one_clear_error():
    dwell = Segment.from_span(1.0)
    with pytest.raises(ecam.InputError, match=f"segments: {MAX_SEGMENTS + 1} should be at most {MAX_SEGMENTS}"):
        CamProfile.from_segments([dwell] * (MAX_SEGMENTS + 1))


def test_polyline_draws_each_segment_on_its_own_points(drrd):
    """The plot line: every segment on the positions inside it (its ends included) with its own
    Segment.evaluate values, a NaN after each, nothing outside the period."""
    x = np.concatenate([np.linspace(-10.0, 370.0, 381), drrd.joints()])
    xs, ys = drrd.polyline(x, 2)
    pieces = np.split(np.arange(xs.size), np.nonzero(np.isnan(xs))[0] + 1)
    assert len(pieces) == len(drrd.segments) + 1 and pieces[-1].size == 0
    for seg, piece in zip(drrd.segments, pieces):
        inside = np.sort(x[(x >= seg.master_start) & (x <= seg.master_end)])
        assert np.array_equal(xs[piece[:-1]], inside)
        assert np.array_equal(ys[piece[:-1]], seg.evaluate(inside, 2, "right"))
        assert np.isnan(ys[piece[-1]])
