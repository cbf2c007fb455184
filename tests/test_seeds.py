"""The seeds' numbers, derived by ecam.design and checked against the textbook pages."""
import math

import numpy as np
import pytest

import ecam
from ecam.design import combination, modified_sine_cam


def test_combination_rise_is_solved_not_typed():
    first, second = combination("half_cycloid_start", "half_harmonic_end",
                                span=math.radians(120), stroke=1.75, accel_ratio=2.0)
    assert first.stroke == pytest.approx(0.4934, abs=5e-5)
    assert second.stroke == pytest.approx(1.2566, abs=5e-5)
    assert math.degrees(first.span) == pytest.approx(40.0, abs=1e-9)
    assert math.degrees(second.span) == pytest.approx(80.0, abs=1e-9)
    # the seed's four equations hold
    h1, h2, b1, b2 = first.stroke, second.stroke, first.span, second.span
    assert 4 * h1 / (math.pi * h2) == pytest.approx(b1 / b2)
    assert math.pi * h1 / b1**2 == pytest.approx(2 * math.pi**2 * h2 / (4 * b2**2))


def test_combination_cam_file(drrd):
    rise = [s for s in drrd.segments if s.name.startswith("rise")]
    ret = [s for s in drrd.segments if s.name.startswith("return")]
    assert [s.law.name for s in rise] == ["half_cycloid_start", "half_harmonic_end"]
    assert [s.law.name for s in ret] == ["half_harmonic_start", "half_cycloid_end"]
    assert rise[0].stroke == pytest.approx(0.4934, abs=5e-5) and rise[0].span == pytest.approx(40.0)
    assert rise[1].stroke == pytest.approx(1.2566, abs=5e-5) and rise[1].span == pytest.approx(80.0)
    assert ret[0].stroke == pytest.approx(-1.2566, abs=5e-5) and ret[1].span == pytest.approx(40.0)
    # solution (b) of the seed: 15 degrees into C1, y = h1 (theta/b1 - sin(pi theta/b1)/pi), which
    # the page prints as 0.0400 in (it rounds theta and b1 to 0.262 and 0.698 rad first)
    y15 = drrd(rise[0].master_start + 15.0)
    h1 = rise[0].stroke
    assert y15 == pytest.approx(h1 * (15 / 40 - math.sin(math.pi * 15 / 40) / math.pi), rel=1e-12)
    assert y15 == pytest.approx(0.0400, abs=1e-4)
    # C1's peak acceleration is twice H2's
    x1 = np.linspace(rise[0].master_start, rise[0].master_end, 2001)
    x2 = np.linspace(rise[1].master_start, rise[1].master_end, 2001)
    assert np.abs(drrd(x1, 2)).max() == pytest.approx(2 * np.abs(drrd(x2, 2)).max(), rel=1e-6)


def test_combination_acceleration_continuous_where_rise_meets_return(drrd):
    top = [s for s in drrd.segments if s.name.startswith("return")][0].master_start
    report = drrd.check()
    assert not report.at(top, 2) and not report.at(top, 1) and not report.at(top, 0)
    assert report.ok  # position, velocity, acceleration continuous everywhere
    assert drrd(top, 2, side="left") == pytest.approx(drrd(top, 2, side="right"), rel=1e-12)
    assert drrd(top, 2) < 0  # decelerating over the top, not a dwell


def test_modified_sine_cam_matches_eq_3_140(msine):
    """Eq 3.140: Cam1 = A_o rise/(4 pi) (theta - rise/(4 pi) sin(4 pi theta / rise)) on [0, rise/8]."""
    rise = math.pi  # half a revolution, in radians
    stroke = 50.0
    a_o = stroke * ecam.law("modified_sine").ca / rise**2
    theta = np.linspace(0, rise / 8, 50)
    seed = a_o * rise / (4 * math.pi) * (theta - rise / (4 * math.pi) * np.sin(4 * math.pi * theta / rise))
    np.testing.assert_allclose(msine(np.degrees(theta)), seed, atol=1e-9)


def test_modified_sine_cam_mirror_and_continuity(msine):
    x = np.linspace(0, 180, 181)
    np.testing.assert_allclose(msine(360 - x), msine(x), atol=1e-9)  # Cam(2 rise - theta) = Cam(theta)
    report = msine.check()
    assert report.continuous(2)
    assert modified_sine_cam(50.0).check().continuous(2)


def test_smallest_peak_law_picks_by_characteristic_value():
    """Among rest-to-rest laws: the parabolic law has the smallest finite Ca (4), the cycloidal
    the smallest finite Cj (4 pi^2 < 52.5 of 4-5-6-7)."""
    from ecam.design import smallest_peak_law

    assert smallest_peak_law(2).name == "constant_acceleration"
    assert smallest_peak_law(3).name == "cycloidal"
    assert smallest_peak_law(2, ["cycloidal", "modified_sine", "modified_trapezoid"]).name == "modified_trapezoid"


def test_dwell_rise_return_dwell_builder():
    from ecam.design import dwell_rise_return_dwell

    cam = dwell_rise_return_dwell(stroke=20.0, dwell_before=90, rise=90, ret=120, dwell_after=60,
                                  rise_law="cycloidal", return_law="modified_sine")
    assert cam.master_period == 360.0 and [s.label for s in cam.segments] == ["dwell", "rise", "return", "dwell"]
    assert cam(180.0) == pytest.approx(20.0) and cam(45.0) == 0.0 and cam(330.0) == pytest.approx(0.0, abs=1e-12)
    assert cam.check().continuous(2)  # both laws start and end at rest
