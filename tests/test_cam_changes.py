"""Changing cams while the machine runs (issue 23, core): continuity across a switch at a period
end under PLCopen's absolute/relative coordinates (`ecam check A --then B`), and the 7th-order
transition cam that joins two cams (`ecam transition`)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ecam import CamProfile, Segment, load_cam, parse_cam
from ecam.cam_join import join_cams
from ecam.errors import InputError
from ecam.transition import transition_cam

ROOT = Path(__file__).resolve().parent.parent
CAMS = ROOT / "ecam" / "cams"
DRRD = CAMS / "combination_drrd.toml"
KNIFE = CAMS / "rotary_knife.toml"


def ecam_cli(*args):
    return subprocess.run([sys.executable, "-m", "ecam.app", *map(str, args)], capture_output=True, text=True)


def moving(stroke=2.0, end_velocity=0.01, name="feed", period=360.0, start=0.0):
    """A cam that starts at rest at ``start`` and ends moving at ``end_velocity`` (in/deg)."""
    return CamProfile.from_segments([
        Segment.from_span(period / 3),
        Segment.polynomial(0.0, 2 * period / 3, 0.0, stroke, start_velocity=0.0, end_velocity=end_velocity,
                           start_jerk=0.0, end_jerk=0.0, name="ramp"),
    ], name=name, slave_unit="in", periodic=False, start=start)


# ------------------------------------------------------------------------------ the join

def test_a_cam_that_returns_to_its_start_joins_itself_in_every_coordinate():
    cam = load_cam(DRRD)
    for master in ("absolute", "relative"):
        for slave in ("absolute", "relative"):
            join = join_cams(cam, cam, master=master, slave=slave)
            assert join.report.ok and not join.report.discontinuities, (master, slave)
            assert join.master == 360.0 and join.entry == (360.0 if master == "absolute" else 0.0)


def test_a_net_stroke_cam_is_entered_with_the_net_strokes_of_the_periods_before():
    """PLCopen MasterAbsolute: the cam is evaluated at the absolute master position, and a
    periodic cam with a net stroke there includes floor(x / period) net strokes (as the table
    lookup and the rig evaluate it). The knife switched to itself at the end of its N-th period:
    master and slave absolute change nothing; master relative restarts the table at 0 (a jump of
    -N x 360); slave relative adds the slave's position to B's own (+N x 360 absolute, nothing
    relative)."""
    knife = load_cam(KNIFE)
    for turns in (1, 3):
        at = turns * knife.master_period
        jumps = {}
        for master in ("absolute", "relative"):
            for slave in ("absolute", "relative"):
                join = join_cams(knife, knife, master=master, slave=slave, at=at)
                assert join.left[0] == pytest.approx(turns * knife.net_stroke, abs=1e-9)
                assert all(d.order == 0 for d in join.report.discontinuities)
                jumps[master, slave] = sum(d.jump for d in join.report.errors)
        net = turns * knife.net_stroke
        assert jumps == {("absolute", "absolute"): 0, ("relative", "relative"): 0,
                         ("relative", "absolute"): pytest.approx(-net, abs=1e-9),
                         ("absolute", "relative"): pytest.approx(net, abs=1e-9)}, turns
        assert join_cams(knife, knife, at=at).entry == at  # not wrapped: its own coordinate


def test_a_switch_inside_a_period_joins_the_left_and_right_limits_there():
    """At 100 deg, inside the knife's catch-up (and two periods later), the knife switched to
    itself absolutely changes nothing; a cam that does not repeat is joined within its range."""
    knife = load_cam(KNIFE)
    assert join_cams(knife, knife, at=100.0).report.ok
    assert join_cams(knife, knife, at=100.0 + 2 * 360.0).report.ok
    assert not join_cams(knife, knife, at=100.0, master="relative").report.ok
    once = moving(period=180.0)
    with pytest.raises(InputError, match=r"at: 200 should be within feed's master range \(0, 180\]"):
        join_cams(once, once, at=200.0, master="relative")
    join = join_cams(once, moving(name="next"), at=150.0, master="relative")
    assert join.left == pytest.approx(tuple(float(once(150.0, k, side="left")) for k in range(4)))


def test_an_absolute_master_enters_the_next_cam_where_the_master_stands():
    """A period of 360 switched to a periodic cam of 240: absolutely, B is evaluated at the
    master position 360, 120 into its second period (CODESYS: "the cam is started at the current
    master position"); relatively at 0."""
    first = load_cam(DRRD)
    short = CamProfile.from_segments([Segment.from_span(80.0), Segment.from_span(80.0, 1.0, "cycloidal"),
                                      Segment.from_span(80.0, -1.0, "cycloidal")], slave_unit="in", name="short")
    join = join_cams(first, short)
    assert join.entry == 360.0  # B's own coordinate: 120 into its second period
    assert join.right[0] == pytest.approx(float(short(120.0)))
    assert join.right[1] == pytest.approx(float(short(120.0, 1)))
    assert not join.report.ok and {d.order for d in join.report.errors} >= {0, 1}
    assert join_cams(first, short, master="relative").report.ok  # both at rest at 0


def test_a_cam_that_does_not_repeat_is_refused_outside_its_range():
    once = moving(period=180.0)
    with pytest.raises(InputError, match=r"master: 'absolute' should be 'relative' here: the join at master "
                                         r"360 lies outside feed's master range 0..180"):
        join_cams(load_cam(DRRD), once)
    with pytest.raises(InputError, match="then.slave_unit: 'mm' should be 'in'"):
        join_cams(load_cam(DRRD), load_cam(CAMS / "modified_sine.toml"))
    with pytest.raises(InputError, match="master: 'sideways' should be"):
        join_cams(load_cam(DRRD), load_cam(DRRD), master="sideways")


def test_each_derivative_jump_is_reported_with_its_size():
    first = moving(end_velocity=0.01)  # ends at 2 in moving at 0.01 in/deg, acceleration 0
    then = moving(stroke=1.0, end_velocity=0.0, name="next")  # starts at rest at 0
    join = join_cams(first, then, master="relative")
    by_order = {d.order: d for d in join.report.discontinuities}
    assert by_order[0].jump == pytest.approx(-2.0) and by_order[1].jump == pytest.approx(-0.01)
    assert 2 not in by_order  # both accelerations are 0 there
    assert all(d.severity == "error" for d in join.report.errors)


# ------------------------------------------------------------------------- the transition

def continuous(first, transition, then, slave):
    for a, b in ((first, transition), (transition, then)):
        report = join_cams(a, b, master="relative", slave=slave).report
        assert not report.discontinuities, report.discontinuities


@pytest.mark.parametrize("slave", ["absolute", "relative"])
def test_a_transition_joins_a_moving_end_to_another_cams_start(slave):
    first = moving(stroke=2.0, end_velocity=0.01)
    then = load_cam(DRRD)
    transition = transition_cam(first, then, 90.0, slave=slave)
    assert not transition.periodic and transition.master_period == 90.0
    assert [s.law.name for s in transition.segments] == ["poly7"]
    continuous(first, transition, then, slave)
    # VDI 2143 7th order: the boundary conditions it was solved from are the neighbours' states
    start, end = transition.segments[0].boundary
    assert start == pytest.approx((0.01, 0.0, 0.0), abs=1e-12) and end == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    if slave == "absolute":
        assert transition(0.0) == pytest.approx(2.0) and transition(90.0) == pytest.approx(0.0, abs=1e-12)
    else:  # the stroke a cubic velocity from 0.01 to 0 integrates to over 90 deg: 0.45 in
        assert transition(90.0) - transition(0.0) == pytest.approx(90.0 * 0.01 / 2)
    assert parse_cam(__import__("tomllib").loads(transition.to_toml())) == transition


def test_a_transition_between_equal_positions_is_split_so_each_part_moves():
    first = moving(stroke=0.0 + 1.0, end_velocity=0.004)  # ends at 1 in, moving
    then = moving(stroke=1.0, end_velocity=0.0, name="next", start=1.0)  # starts at rest at 1 in
    transition = transition_cam(first, then, 60.0)
    assert len(transition.segments) == 2 and all(s.stroke != 0 for s in transition.segments)
    continuous(first, transition, then, "absolute")
    # the two parts are one 7th-order polynomial: the jerk is continuous inside too
    assert transition.check().ok and not transition.check().warnings


def test_a_transition_between_two_cams_at_one_speed_is_that_speed():
    knife = load_cam(KNIFE)
    transition = transition_cam(knife, knife, 30.0, slave="relative")
    x = np.linspace(0.0, 30.0, 61)
    np.testing.assert_allclose(transition(x, 1), 1.2, rtol=1e-12)
    assert transition(30.0) == pytest.approx(36.0)


@settings(max_examples=100, deadline=None)
@given(v0=st.floats(-0.05, 0.05), a0=st.floats(-1e-3, 1e-3), j0=st.floats(-1e-4, 1e-4),
       stroke=st.floats(-3.0, 3.0), span=st.floats(5.0, 200.0), slave=st.sampled_from(["absolute", "relative"]))
def test_transitions_are_continuous_in_all_four_derivatives(v0, a0, j0, stroke, span, slave):
    """Any end state of A (velocity, acceleration, jerk) into the seed cam, over any span."""
    first = CamProfile.from_segments([
        Segment.from_span(100.0),
        Segment.polynomial(0.0, 260.0, 0.0, 1.0 + stroke if stroke != -1.0 else 2.0, start_velocity=0.0,
                           end_velocity=v0, end_acceleration=a0, start_jerk=0.0, end_jerk=j0),
    ], slave_unit="in", periodic=False, name="a")
    then = load_cam(DRRD)
    try:
        transition = transition_cam(first, then, span, slave=slave)
    except InputError as exc:  # a condition too steep for the span once normalized: said so, in one line
        assert "should be" in str(exc)
        return
    continuous(first, transition, then, slave)


def test_transition_input_is_checked():
    cam = load_cam(DRRD)
    with pytest.raises(InputError, match="span: 0 should be"):
        transition_cam(cam, cam, 0.0)
    with pytest.raises(InputError, match="slave: 'both' should be"):
        transition_cam(cam, cam, 10.0, slave="both")


# ------------------------------------------------------------------------------ the CLI

def test_check_then_reports_the_join_like_check(tmp_path):
    run = ecam_cli("check", KNIFE, "--then", KNIFE, "--master", "relative", "--at-period", 2, "--json")
    assert run.returncode == 1, run.stderr
    data = json.loads(run.stdout)
    assert {"cam", "then", "ok", "errors", "warnings", "discontinuities", "join"} <= set(data)
    assert data["ok"] is False and data["discontinuities"][0]["quantity"] == "position"
    assert data["discontinuities"][0]["jump"] == pytest.approx(-720.0)  # restarted at 0 from 720
    assert data["join"]["entry"] == 0.0 and data["join"]["master"] == 720.0
    assert data["join"]["master_coordinates"] == "relative"
    run = ecam_cli("check", KNIFE, "--then", KNIFE)
    assert run.returncode == 0 and "continuous in position, velocity, acceleration and jerk" in run.stdout
    assert "entered at 360 deg, with 1 x its net stroke +360 deg" in run.stdout
    run = ecam_cli("check", DRRD, "--master", "relative")
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and "--then" in run.stderr


def test_transition_cli_writes_a_cam_that_check_then_proves(tmp_path):
    out = tmp_path / "t.toml"
    run = ecam_cli("transition", KNIFE, KNIFE, "--span", 45, "--slave", "relative", "-o", out, "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["continuous"] is True
    for a, b in ((KNIFE, out), (out, KNIFE)):
        check = ecam_cli("check", a, "--then", b, "--master", "relative", "--slave", "relative")
        assert check.returncode == 0 and "0 errors, 0 warnings" in check.stdout, check.stdout
    run = ecam_cli("transition", KNIFE, DRRD, "--span", 45, "-o", out)
    assert run.returncode == 2 and "ecam: error: then.slave_unit" in run.stderr


@pytest.mark.parametrize("at,message", [
    (float("nan"), "--at: nan should be finite"),
    (0.0, "--at: 0 should be within combination_drrd_to_product_b's master range (0, 90]"),
])
def test_check_then_names_the_at_option_in_its_errors(at, message):
    """The API's parameter is `at`; on the command line the user typed --at (in process: the
    CLI turns the InputError into `ecam: error: ...`, exit 2)."""
    from argparse import Namespace

    from ecam.app.join_command import cmd_check

    transition = Path(__file__).resolve().parents[1] / "hil_sim" / "scenes" / "cams" / "a_to_b.toml"
    args = Namespace(cam=transition, then=transition.with_name("product_b.toml"), master="relative",
                     slave=None, at=at, at_period=None, json=True)
    with pytest.raises(InputError) as raised:
        cmd_check(args)
    assert str(raised.value).startswith(message)
