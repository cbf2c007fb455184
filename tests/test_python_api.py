"""The Python API: the dwell law, segments by span and stroke, profiles written back as cam files,
and one message shape for every bad value, whoever hands it in."""

import functools
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, strategies as st

import ecam
from ecam import CamProfile, Segment
from ecam.camfile import parse_cam
from ecam.laws import LAWS

# Any text a name may be (ecam.validate.text: no control character but the tab, no line or
# paragraph separator, no bidirectional control; issue 28).
NAMES = functools.partial(st.text, st.characters(
    blacklist_categories=("Cc", "Cs", "Zl", "Zp"),
    blacklist_characters="\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069") | st.just("\t"))

ROOT = Path(__file__).resolve().parent.parent
BUILT_IN = [*sorted((ROOT / "ecam" / "cams").glob("*.toml")),
            *sorted((ROOT / "firmware_tables" / "cams").glob("*.toml"))]
# <field>: <value> should be <expected>, on one line
SHAPE = re.compile(r"^[\w\[\]\.]+: .+ should be .+$")


def round_trip(profile: CamProfile) -> CamProfile:
    text = profile.to_toml()
    back = parse_cam(tomllib.loads(text), source="round-trip")
    assert back.to_toml() == text  # deterministic: the text is a fixed point
    return back


# --- the dwell law ------------------------------------------------------------------------------


def test_dwell_is_a_law():
    dwell = ecam.law("dwell")
    assert dwell is ecam.DWELL and ecam.law(dwell) is dwell and "dwell" in ecam.LAW_NAMES
    assert "dwell" not in LAWS  # LAWS stays the registry of rise laws (`ecam laws`)
    u = np.linspace(0, 1, 11)
    for order in range(4):
        assert np.array_equal(dwell(u, order), np.zeros_like(u))
    assert (dwell.cv, dwell.ca, dwell.cj) == (0.0, 0.0, 0.0)


def test_dwell_is_accepted_wherever_laws_are():
    assert Segment(0.0, 60.0, 5.0, 5.0, "dwell").law is ecam.DWELL
    assert Segment.from_span(60.0).law is ecam.DWELL  # the default
    cam = parse_cam({"master_period": 360.0, "segment": [{"law": "dwell", "span": 360.0}]})
    assert cam.segments[0].law is ecam.DWELL and cam.segments[0].label == "dwell"
    drrd = ecam.design.dwell_rise_return_dwell(stroke=5.0, dwell_before=60.0, rise=120.0, ret=120.0, dwell_after=60.0)
    assert [s.law.name for s in drrd.segments] == ["dwell", "cycloidal", "cycloidal", "dwell"]
    with pytest.raises(ecam.InputError, match=r"^stroke: 5 should be 0 for a dwell"):
        Segment(0.0, 60.0, 0.0, 5.0, "dwell")


# --- segments by span and stroke ----------------------------------------------------------------


def test_from_segments_places_spans_and_strokes_from_zero():
    cam = CamProfile.from_segments([
        Segment.from_span(60.0),
        Segment.from_span(span=120.0, stroke=10.0, law="modified_sine", name="rise"),
        Segment.from_span(60.0),
        Segment.from_span(span=120.0, stroke=-10.0, law="cycloidal", name="return"),
    ], name="knife", start=2.0)
    assert cam.master_period == 360.0
    assert [(s.master_start, s.master_end) for s in cam.segments] == [(0, 60), (60, 180), (180, 240), (240, 360)]
    assert [(s.slave_start, s.slave_end) for s in cam.segments] == [(2, 2), (2, 12), (12, 12), (12, 2)]
    explicit = CamProfile((Segment(0, 60, 2, 2, "dwell"), Segment(60, 180, 2, 12, ecam.law("modified_sine"), "rise"),
                           Segment(180, 240, 12, 12, "dwell"), Segment(240, 360, 12, 2, "cycloidal", "return")),
                          360.0, name="knife")
    assert cam == explicit
    assert cam.check().continuous(2) and cam(180.0) == 12.0


def test_from_segments_takes_a_net_stroke():
    """An indexing table: one station (45 deg) per cycle, the slave never coming back."""
    index = CamProfile.from_segments([Segment.from_span(240.0, 45.0, "modified_sine", "index"),
                                      Segment.from_span(120.0)], slave_unit="deg", net_stroke=45.0)
    assert index.net_stroke == 45.0 and index.check().ok  # the modified sine's jerk steps are warnings
    assert index(360.0) == 45.0 and index(8 * 360.0 + 240.0) == 9 * 45.0 and index(-120.0) == 0.0
    assert CamProfile.from_segments([Segment.from_span(240.0, 45.0, "modified_sine")]).check().errors[0].order == 0


def test_from_segments_ignores_where_a_segment_was_and_checks_the_period():
    moved = Segment(1000.0, 1090.0, 7.0, 17.0, "cycloidal")
    cam = CamProfile.from_segments([moved, Segment.from_span(90.0, -10.0, "cycloidal")], 180.0)
    assert cam.segments[0] == Segment(0.0, 90.0, 0.0, 10.0, "cycloidal")
    with pytest.raises(ecam.InputError, match=r"^segment\[1\]\.master_end: 180 should be 360, the master_period "
                                              r"\(it leaves a gap\)$"):
        CamProfile.from_segments([moved, Segment.from_span(90.0, -10.0, "cycloidal")], 360.0)
    with pytest.raises(ecam.InputError, match=r"^segment\[1\]\.slave_end: 1\.8e\+15 should be <= 1e\+15$"):
        CamProfile.from_segments([Segment.from_span(1.0, 9e14, "cycloidal")] * 2)


def test_a_polynomial_segment_is_solved_again_where_it_lands():
    """VDI 2143 motion to motion: a poly5 from the velocity of a constant-velocity segment to rest."""
    poly = Segment.polynomial(0.0, 100.0, 0.0, 50.0, start_velocity=1.0)
    assert poly.law.name == "poly5" and poly.boundary == ((1.0, 0.0), (0.0, 0.0))
    cam = CamProfile.from_segments([Segment.from_span(100.0, 100.0, "constant_velocity"), poly,
                                    Segment.from_span(100.0)], periodic=False)
    assert cam(100.0, 1, side="right") == pytest.approx(1.0, rel=1e-12)
    assert cam(200.0, 1, side="left") == pytest.approx(0.0, abs=1e-12)
    assert cam.check().continuous(1)
    seven = Segment.polynomial(0.0, 10.0, 0.0, 1.0, end_jerk=0.01)
    assert seven.law.name == "poly7" and seven.boundary == ((0.0, 0.0, 0.0), (0.0, 0.0, 0.01))
    assert seven.law(1.0, 3) == pytest.approx(0.01 * 10.0**3 / 1.0)


# --- to_toml ------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", BUILT_IN, ids=lambda p: f"{p.parent.parent.name}/{p.name}")
def test_built_in_cams_round_trip(path):
    cam = ecam.load_cam(path)
    assert round_trip(cam) == cam


KNIFE = {  # a rotary knife: poly5 transitions matched to the constant-velocity cut
    "name": "knife", "master_unit": "deg", "slave_unit": "deg", "master_period": 360.0,
    "table": {"master_counts": 36000, "slave_counts_per_unit": 1000, "interp": "auto", "tolerance": "2 counts"},
    "segment": [
        {"law": "constant_velocity", "span": 60.0, "stroke": 72.0, "name": "cut"},
        {"law": "poly5", "span": 240.0, "stroke": 216.0, "start_velocity": "match", "end_velocity": "match"},
        {"law": "constant_velocity", "span": 60.0, "stroke": 72.0},
    ],
}
POLY7 = {
    "master_period": 300.0, "periodic": False, "start": -3.25,
    "segment": [
        {"law": "constant_velocity", "span": 100.1, "stroke": 100.3},
        {"law": "poly7", "end": 200.2, "to": 150.7, "start_velocity": "match", "end_velocity": "match",
         "start_acceleration": 0.01, "end_jerk": -1e-4},
        {"law": "constant_velocity", "span": 99.8, "from": 160.0, "stroke": 20.0},
    ],
}
COMBINATION = {
    "name": 'odd "name" \\ with\ttabs', "master_period": 1.0, "slave_unit": "rad",
    "segment": [
        {"combination": ["half_cycloid_start", "half_harmonic_end"], "accel_ratio": 2.0, "span": 0.3, "stroke": 0.1},
        {"law": "dwell", "span": 0.2},
        {"combination": ["half_harmonic_start", "half_cycloid_end"], "accel_ratio": 0.5, "span": 0.5, "stroke": -0.1},
    ],
}


@pytest.mark.parametrize("data", [KNIFE, POLY7, COMBINATION], ids=["poly5-match", "poly7-end-to-from", "combination"])
def test_polynomial_and_combination_cams_round_trip(data):
    cam = parse_cam(data, source="x.toml")
    back = round_trip(cam)
    assert back == cam
    x = np.linspace(0, cam.master_period, 1001)
    for order in range(4):
        assert np.array_equal(back(x, order), cam(x, order))


def test_to_toml_writes_what_a_reader_expects():
    cam = parse_cam(POLY7, source="p7.toml")
    doc = tomllib.loads(cam.to_toml())
    assert doc["name"] == "p7" and doc["start"] == -3.25 and doc["periodic"] is False
    second = doc["segment"][1]
    assert second["law"] == "poly7" and second["start_acceleration"] == 0.01 and second["end_jerk"] == -1e-4
    assert doc["segment"][2]["from"] == 160.0  # the position jump is kept
    assert "from" not in doc["segment"][1] and "start" not in doc["segment"][1]


def test_to_toml_refuses_a_law_no_cam_file_can_name():
    law = ecam.polynomial_from_boundary((1.0, 0.0), (0.0, 0.0))
    cam = CamProfile((Segment(0.0, 10.0, 0.0, 1.0, law),), 10.0)
    with pytest.raises(ecam.InputError, match=r"^segment\[0\]\.law: 'polynomial' should be a law of ecam\.LAWS"):
        cam.to_toml()


RISE_LAWS = sorted(LAWS)


@st.composite
def profiles(draw):
    count = draw(st.integers(1, 6))
    master = draw(st.sampled_from([0.0, 0.1, 1e-3]))  # odd starts: span + start is not always exact
    slave = draw(st.floats(-1e3, 1e3))
    start = slave
    segments = []
    for i in range(count):
        span = draw(st.floats(0.01, 1000.0))
        kind = draw(st.sampled_from(["law", "law", "dwell", "poly5", "poly7"]))
        if i and draw(st.booleans()):
            slave += draw(st.floats(-10.0, 10.0))  # a position jump: `from` in the file
        stroke = 0.0 if kind == "dwell" else draw(st.floats(-100.0, 100.0).filter(lambda v: abs(v) > 1e-3))
        first = master if i else 0.0
        end = first + span
        if kind == "law":
            law, name = draw(st.sampled_from(RISE_LAWS)), draw(NAMES(max_size=8))
            seg = Segment(first, end, slave, slave + stroke, law, name)
        elif kind == "dwell":
            seg = Segment(first, end, slave, slave, "dwell")
        else:
            values = st.floats(-2.0, 2.0)
            conditions = {"start_velocity": draw(values), "end_velocity": draw(values),
                          "start_acceleration": draw(values), "end_acceleration": draw(values)}
            if kind == "poly7":
                conditions.update(start_jerk=draw(values), end_jerk=draw(values))
            seg = Segment.polynomial(first, end, slave, slave + stroke, degree=int(kind[-1]), **conditions)
        segments.append(seg)
        master, slave = seg.master_end, seg.slave_end
    table = draw(st.sampled_from([{}, {"interp": "cubic", "points": 257},
                                  {"interp": "auto", "tolerance": "2 counts", "master_counts": 2**16,
                                   "slave_counts_per_unit": 1000.0},
                                  {"tolerance": 0.01}]))
    periodic = draw(st.booleans())
    # a periodic cam may declare its advance per period as its net stroke (0 included)
    net_stroke = segments[-1].slave_end - start if periodic and draw(st.booleans()) else None
    return CamProfile(tuple(segments), master, periodic, name=draw(NAMES(max_size=12)),
                      master_unit=draw(st.sampled_from(["deg", "rad", "mm"])), slave_unit="mm", table=table,
                      net_stroke=net_stroke), start


@given(profiles())
def test_any_profile_round_trips(drawn):
    cam, start = drawn
    back = round_trip(cam)
    assert back == cam and back.segments[0].slave_start == start


# --- one validation path ------------------------------------------------------------------------


@pytest.mark.parametrize("build, message", [
    (lambda: Segment(0, 10, 0, "x", "cycloidal"), "slave_end: 'x' should be a number"),
    (lambda: Segment(0, 10, 0, 1, "cycloid"), "law: 'cycloid' should be one of " + ", ".join(ecam.LAW_NAMES)),
    (lambda: Segment(10, 0, 0, 1, "cycloidal"), "span: -10 should be > 0"),
    (lambda: Segment(0, 10, 0, math.inf, "cycloidal"), "slave_end: inf should be finite"),
    (lambda: Segment(0, 10, 0, 1, "cycloidal", name=5), "name: 5 should be a string"),
    (lambda: Segment.from_span(10, 5), "stroke: 5 should be 0 for a dwell (or give a law that moves)"),
    (lambda: Segment.from_span(0.0, 1.0, "cycloidal"), "span: 0 should be > 0"),
    (lambda: Segment.polynomial(0, 10, 1, 1), "stroke: 0 should be non-zero for a polynomial segment (poly5)"),
    (lambda: Segment.polynomial(0, 10, 0, 1, degree=5, end_jerk=1.0),
     "end_jerk: 1 should be absent for a 5th-order polynomial (poly5); use degree 7 (poly7)"),
    (lambda: Segment.polynomial(0, 10, 0, 1, degree=6), "degree: 6 should be 5 or 7"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), "10"), "master_period: '10' should be a number"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), 10.0, periodic="yes"),
     "periodic: 'yes' should be true or false"),
    (lambda: CamProfile((), 10.0), "segments: () should be at least one Segment"),
    (lambda: CamProfile(("rise",), 10.0), "segment[0]: 'rise' should be a Segment"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"), Segment(11, 20, 1, 0, "cycloidal")), 20.0),
     "segment[1].master_start: 11 should be 10, where segment[0] ends (it leaves a gap)"),
    (lambda: CamProfile((Segment(0, 1e-12, 0, 1, "cycloidal"), Segment(1e-12, 20, 1, 0, "cycloidal")), 20.0),
     "segment[0].span: 1e-12 should be >= 1e-09 of master_period (2e-08)"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), 10.0, net_stroke=2.0),
     "net_stroke: 2 should be +1, what the segments add up to (the slave starts the period at 0 and ends it at 1): "
     "correct a stroke or the net stroke"),
    (lambda: CamProfile((Segment(0, 10, 0, 1, "cycloidal"),), 10.0, False, net_stroke=1.0),
     "net_stroke: 1 should be absent for a cam that is not periodic (it does not repeat, so it has no advance per "
     "period)"),
    (lambda: ecam.design.modified_sine_cam(50.0)(1.0, order=-1), "order: -1 should be an integer >= 0"),
    (lambda: ecam.design.modified_sine_cam(50.0)(1.0, side="middle"), "side: 'middle' should be one of right, left"),
    (lambda: ecam.design.modified_sine_cam(50.0)([1.0, math.nan]), "master: nan should be finite"),
    (lambda: ecam.law("cycloidal")(0.5, order=1.5), "order: 1.5 should be an integer"),
    (lambda: ecam.design.combination("half_cycloid_start", "half_harmonic_end", span=1.0, stroke=1.0, accel_ratio=0),
     "accel_ratio: 0 should be >= 1e-06"),
    (lambda: ecam.design.combination("half_cycloid_start", "half_harmonic_end", span=1.0, stroke=0.0, accel_ratio=1),
     "stroke: 0 should be non-zero for a combination"),
    (lambda: ecam.design.dwell_rise_return_dwell(stroke=1.0, dwell_before=-1, rise=1, ret=1, dwell_after=0),
     "dwell_before: -1 should be >= 0"),
    (lambda: ecam.design.dwell_rise_return_dwell(stroke=1.0, dwell_before=0, rise=0, ret=1, dwell_after=0),
     "rise: 0 should be > 0"),
    (lambda: ecam.design.smallest_peak_law(0), "order: 0 should be an integer >= 1"),
])
def test_every_bad_value_is_one_line_of_one_shape(build, message):
    with pytest.raises(ecam.InputError) as info:
        build()
    text = str(info.value)
    assert text == message
    assert isinstance(info.value, ValueError) and SHAPE.match(text)


@pytest.mark.parametrize("build, message", [
    (lambda: ecam.TableSpec(interp="spline", points=3),
     "interp: 'spline' should be one of " + ", ".join(ecam.INTERPOLATIONS)),
    (lambda: ecam.TableSpec(points=3, master_counts=1), "master_counts: 1 should be an integer in 2..2147483648"),
    (lambda: ecam.TableSpec(points=1), "points: 1 should be an integer in 2..4194305"),
    (lambda: ecam.TableSpec(points=3, slave_counts_per_unit=0), "slave_counts_per_unit: 0 should be >= 1e-06"),
    (lambda: ecam.TableSpec(points=65, tolerance=0.01),
     "points: 65 should be absent when a tolerance is given: give either points or tolerance, not both"),
    (lambda: ecam.TableSpec(interp="auto", points=65),
     "interp: 'auto' should be given a tolerance, not points (it picks the point count)"),
    (lambda: ecam.Mechanics(motor_inertia=-1.0), "motor_inertia: -1 should be > 0"),
    (lambda: ecam.Mechanics(motor_inertia=1.0, gear_efficiency=2.0), "gear_efficiency: 2 should be <= 1"),
    (lambda: ecam.Mechanics(motor_inertia=1.0, coupling_stiffness=1e4),
     "load_inertia: 0 should be > 0 when coupling_stiffness is given"),
    (lambda: ecam.mechanics.torsional_harmonic(100.0, 0.0), "cycle_hz: 0 should be > 0"),
    (lambda: ecam.mechanics.peak_torque_check([], 10.0), "torque: [] should be a 1-D series of at least one number"),
    (lambda: ecam.mechanics.residual_vibration(40.0, 0.1, "cycloid"),
     "law: 'cycloid' should be one of " + ", ".join(ecam.LAW_NAMES)),
    (lambda: _small_table().lookup(np.array([1.5, 2.0])), "master_counts: 1.5 should be integers (int64 counts), "
                                                          "not float64"),
    (lambda: _small_table().lookup(2.5), "master_counts: 2.5 should be an integer (int64 counts), not float64"),
    (lambda: _small_table().lookup(True), "master_counts: True should be an integer (int64 counts)"),
    (lambda: _small_table().lookup(2**70), "master_counts: 1.18059e+21 should be in -2^63..2^63-1 (int64 counts)"),
    (lambda: _small_table().lookup([3, 2**70]),
     "master_counts: 1.18059e+21 should be in -2^63..2^63-1 (int64 counts)"),
    (lambda: _small_table().lookup([3, "4"]), "master_counts: '3' should be integers (int64 counts), not <U21"),
    (lambda: _small_table().lookup(np.array([2**64 - 1], dtype=np.uint64)),
     "master_counts: 1.84467e+19 should be in -2^63..2^63-1 (int64 counts)"),
])
def test_tables_and_mechanics_speak_the_same_shape(build, message):
    with pytest.raises(ecam.InputError) as info:
        build()
    assert str(info.value) == message and SHAPE.match(message)


@functools.cache
def _small_table():
    return ecam.compile_table(ecam.design.modified_sine_cam(50.0), points=65)


def _stiff():
    import hil_sim

    return hil_sim.SCENES_DIR / "stiff_coupling.toml"


@pytest.mark.parametrize("build, message", [
    (lambda hil_sim: hil_sim.load_scene(_stiff(), cam="x"), "cam: 'x' should be an ecam.CamProfile"),
    (lambda hil_sim: hil_sim.load_scene(42), "path: 42 should be a scene file path (str or Path)"),
    (lambda hil_sim: hil_sim.run_scene(42), "path: 42 should be a scene file path (str or Path)"),
    (lambda hil_sim: hil_sim.find_max_speed(42), "path: 42 should be a scene file path (str or Path)"),
    # the arguments are checked before the first trial runs
    (lambda hil_sim: hil_sim.find_max_speed(_stiff(), tolerance=1), "tolerance: 1 should be < 1 (a share of "
                                                                    "the passing speed)"),
    (lambda hil_sim: hil_sim.find_max_speed(_stiff(), tolerance=0.0), "tolerance: 0 should be > 0"),
    (lambda hil_sim: hil_sim.find_max_speed(_stiff(), max_runs=0), "max_runs: 0 should be an integer in 4..10000"),
    (lambda hil_sim: hil_sim.find_max_speed(_stiff(), max_runs="x"), "max_runs: 'x' should be an integer"),
    (lambda hil_sim: hil_sim.VirtualDrive(node_id=0), "node_id: 0 should be an integer in 1..127"),
    (lambda hil_sim: hil_sim.VirtualDrive(node_id=True), "node_id: True should be an integer"),
])
def test_the_rig_entry_points_speak_the_same_shape(build, message):
    import hil_sim

    with pytest.raises(ecam.InputError) as info:
        build(hil_sim)
    assert str(info.value) == message and SHAPE.match(message)


def test_a_cam_file_error_names_the_file_and_its_own_field():
    data = {"master_period": 360.0, "segment": [{"law": "cycloidal", "span": 180.0, "to": 1e20},
                                                {"law": "cycloidal", "span": 180.0, "to": 0.0}]}
    with pytest.raises(ecam.CamFileError) as info:
        parse_cam(data, source="knife.toml")
    # the API's slave_end is the file's `to`
    assert str(info.value) == "cam knife.toml: segment[0].to: 1e+20 should be <= 1e+15"


def test_interpolation_kinds_come_from_the_table_module():
    """The kind names are listed once, in ecam.table; the cam-file reader takes them from there."""
    from ecam.table import INTERPOLATIONS

    for kind in INTERPOLATIONS:
        assert parse_cam({"master_period": 1.0, "table": {"interp": kind}, "segment": [{"law": "dwell", "span": 1.0}]}
                         ).table["interp"] == kind
    expected = r"table\.interp: 'spline' should be one of " + ", ".join(INTERPOLATIONS)
    with pytest.raises(ecam.CamFileError, match=expected):
        parse_cam({"master_period": 1.0, "table": {"interp": "spline"}, "segment": [{"law": "dwell", "span": 1.0}]})
    for module in ("camfile", "profile", "laws", "design", "validate"):
        assert '"quintic"' not in (ROOT / "ecam" / f"{module}.py").read_text(), module
