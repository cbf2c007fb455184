"""Digital cam switches (issue 23, item 4, core): the tappet track in user units and in integers,
its evaluation against PLCopen's documented behaviour, the cam file's [[tappet]] tables, and the C
function of firmware_tables/ecam_tappet.c bit for bit against Python on shared vectors."""

import math
import os
import shutil
import subprocess
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ecam import load_cam, parse_cam
from ecam.errors import CamFileError, InputError
from ecam.tappet import TappetCounts, TappetState, TappetTrack, evaluate

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "firmware_tables"
DRRD = ROOT / "ecam" / "cams" / "combination_drrd.toml"
COUNTS = 36000  # 100 counts per degree


def sweep(track, speed_deg_s=360.0, start=0.0, stop=360.0, step=0.01):
    """The master moving at a constant speed: outputs and edges of the integer track."""
    counts = track.to_counts(360.0, COUNTS)
    masters = [round(x * 100) for x in np.arange(start, stop, step if speed_deg_s > 0 else -step)]
    speed = round(speed_deg_s * 100)
    return evaluate(counts, masters, [speed] * len(masters))


def test_the_output_is_on_from_the_first_to_the_last_on_position():
    outputs, edges, _ = sweep(TappetTrack(60.0, 180.0))
    assert [(e.rising, e.master_counts) for e in edges] == [(True, 6000), (False, 18001)]
    assert sum(outputs) == 18000 - 6000 + 1  # FirstOnPosition .. LastOnPosition, both on


def test_a_last_position_below_the_first_wraps_through_the_period_end():
    """MC_CAMSWITCH_TR: LastOnPosition < FirstOnPosition "results in an 'inverted' switch"."""
    outputs, edges, _ = sweep(TappetTrack(350.0, 10.0))
    assert outputs[0] == 1 and outputs[1000] == 1 and outputs[1001] == 0 and outputs[35000] == 1
    assert [(e.rising, e.master_counts) for e in edges] == [(True, 0), (False, 1001), (True, 35000)]


def test_a_direction_limited_switch_is_off_the_other_way():
    forward = sweep(TappetTrack(60.0, 180.0, direction="positive"))[0]
    backward = sweep(TappetTrack(60.0, 180.0, direction="positive"), speed_deg_s=-360.0, start=359.99, stop=0.0)[0]
    assert sum(forward) == 12001 and sum(backward) == 0
    assert sum(sweep(TappetTrack(60.0, 180.0, direction="negative"), speed_deg_s=-360.0, start=359.99,
                     stop=0.0)[0]) == 12001


def test_a_negative_on_compensation_brings_the_edge_forward_by_speed_times_time():
    """A valve with 20 ms dead time, master at 360 deg/s: OnCompensation -0.02 s switches the
    output 360 x 0.02 = 7.2 deg early, at 52.8 deg, so the valve opens at 60."""
    _, edges, _ = sweep(TappetTrack(60.0, 180.0, on_compensation=-0.02, off_compensation=0.01))
    assert [(e.rising, e.master_counts, e.compensated_counts, e.programmed_counts) for e in edges] == [
        (True, 5280, 5280, 6000), (False, 18361, 18360, 18000)]
    # the same track at twice the speed: twice the lead
    assert sweep(TappetTrack(60.0, 180.0, on_compensation=-0.02), speed_deg_s=720.0)[1][0].master_counts == 4560


def test_compensation_can_empty_a_short_window_or_fill_the_period():
    empty = TappetCounts(36000, 6000, 6100, on_compensation_us=10_000, off_compensation_us=-10_000)
    assert evaluate(empty, range(0, 36000, 7), [36000] * len(range(0, 36000, 7)))[0].count(1) == 0
    full = TappetCounts(36000, 6000, 5000, on_compensation_us=-100_000, off_compensation_us=100_000)
    assert set(evaluate(full, range(0, 36000, 7), [36000] * len(range(0, 36000, 7)))[0]) == {1}


def test_hysteresis_stops_an_output_chattering_on_a_jittering_master():
    """Track Hysteresis: "the axis must have moved away from the switching point by this distance
    before reaching of the switching point is evaluated again"."""
    rng = np.random.default_rng(4)
    masters = [6000 + int(v) for v in rng.integers(-20, 21, 400)]  # +-0.2 deg around the on point
    speeds = [int(np.sign(b - a)) * 100 for a, b in zip([masters[0]] + masters, masters)]
    plain = evaluate(TappetTrack(60.0, 180.0).to_counts(360.0, COUNTS), masters, speeds)[1]
    held = evaluate(TappetTrack(60.0, 180.0, hysteresis=0.5).to_counts(360.0, COUNTS), masters, speeds)[1]
    assert len(plain) > 20 and len(held) == 1


def test_to_counts_rounds_positions_and_compensations():
    counts = TappetTrack(0.004999, 359.996, hysteresis=1e-3, on_compensation=-1.5e-6,
                         off_compensation=2.5e-6).to_counts(360.0, COUNTS)
    assert counts == TappetCounts(36000, 0, 0, 0, -2, 3, 0)  # 359.996 deg is 35999.6 -> 36000 -> 0


@pytest.mark.parametrize("kwargs,message", [
    (dict(on=1.0, off=2.0, direction="up"), "direction: 'up' should be one of"),
    (dict(on=1.0, off=2.0, hysteresis=-1.0), "hysteresis: -1 should be >= 0"),
    (dict(on=1.0, off=2.0, on_compensation=200.0), "on_compensation: 200 should be <= 100"),
    (dict(on=math.nan, off=2.0), "on: nan should be finite"),
])
def test_bad_tracks_are_one_line(kwargs, message):
    with pytest.raises(InputError, match=message):
        TappetTrack(**kwargs)


# ------------------------------------------------------------------------------- cam files

def test_tappets_live_in_the_cam_file_and_read_back_equal():
    cam = load_cam(DRRD)
    tracks = (TappetTrack(60.0, 180.0, name='glue "A"', on_compensation=-0.02, hysteresis=0.5),
              TappetTrack(350.0, 10.0, direction="negative", off_compensation=0.001))
    with_tappets = replace(cam, tappets=tracks)
    text = with_tappets.to_toml()
    assert text.count("[[tappet]]") == 2
    again = parse_cam(tomllib.loads(text))
    assert again == with_tappets and again.tappets == tracks
    assert again.to_toml() == text


@pytest.mark.parametrize("table,message", [
    ('on = 10.0', "tappet[0].off: missing; expected a number"),
    ('on = 10.0\noff = 400.0', "tappet[0].off: 400 should be within the master period 0..360"),
    ('on = 10.0\noff = 20.0\ndirection = "up"', "tappet[0].direction: 'up' should be one of"),
    ('on = 10.0\noff = 20.0\nwhen = 3', "tappet[0]"),
    ('on = 10.0\noff = 20.0\nhysteresis = 200.0', "tappet[0].hysteresis: 200 should be < half the master period"),
])
def test_bad_tappet_tables_name_their_field(table, message):
    text = DRRD.read_text() + "\n[[tappet]]\n" + table + "\n"
    with pytest.raises(CamFileError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_cam(tomllib.loads(text), source="c.toml")


# ------------------------------------------------------------------------------- firmware

DRIVER = r"""
#include <inttypes.h>
#include <stdio.h>
#include "ecam_tappet.h"
/* stdin: a track line "period on off hysteresis on_us off_us direction count", then count lines
   "master speed"; repeated. stdout: per sample "output direction armed last". */
int main(void)
{
    ecam_tappet_track t;
    unsigned period, on, off, hyst, dir;
    long on_us, off_us, count, k;
    while (scanf("%u %u %u %u %ld %ld %u %ld", &period, &on, &off, &hyst, &on_us, &off_us, &dir, &count) == 8) {
        ecam_tappet_state s;
        t.period_counts = period; t.on_counts = on; t.off_counts = off; t.hysteresis_counts = hyst;
        t.on_compensation_us = (int32_t)on_us; t.off_compensation_us = (int32_t)off_us; t.direction = (uint8_t)dir;
        ecam_tappet_init(&s);
        for (k = 0; k < count; k++) {
            int64_t master; long speed; int out;
            if (scanf("%" SCNd64 " %ld", &master, &speed) != 2) return 2;
            out = ecam_tappet_step(&t, &s, master, (int32_t)speed);
            printf("%d %d %u %" PRIu32 "\n", out, (int)s.direction, (unsigned)s.armed, s.last_switch_counts);
        }
    }
    return 0;
}
"""


def _compiler():
    for name in (os.environ.get("CC", "cc"), "cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _random_cases(rng, tracks=300, samples=60):
    cases = []
    for _ in range(tracks):
        period = int(rng.choice([2, 3, 360, 36000, 2**20, 2**31]))
        on, off = (int(v) for v in rng.integers(0, period, 2))
        hysteresis = int(rng.choice([0, 0, rng.integers(0, period // 2 + 1)]))
        on_us, off_us = (int(rng.choice([0, v])) for v in rng.integers(-10**8, 10**8 + 1, 2))
        track = TappetCounts(period, on, off, hysteresis, on_us, off_us, int(rng.integers(0, 3)))
        start = int(rng.integers(-2**62, 2**62))
        steps = rng.integers(-period, period + 1, samples)
        masters = [start + int(v) for v in np.cumsum(steps)]
        speeds = [int(v) for v in rng.integers(-2**31, 2**31, samples)]
        speeds = [0 if rng.random() < 0.1 else v for v in speeds]
        cases.append((track, masters, speeds))
    return cases


def test_the_c_function_is_the_python_track_bit_for_bit(tmp_path):
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    (tmp_path / "driver.c").write_text(DRIVER)
    exe = tmp_path / "tappet"
    cmd = [cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-I", str(FIRMWARE), "-o", str(exe),
           str(tmp_path / "driver.c"), str(FIRMWARE / "ecam_tappet.c")]
    build = subprocess.run(cmd, capture_output=True, text=True)
    assert build.returncode == 0 and build.stderr == "", build.stderr
    cases = _random_cases(np.random.default_rng(20261127))
    cases.append((TappetTrack(60.0, 180.0, on_compensation=-0.02, hysteresis=0.5).to_counts(360.0, COUNTS),
                  list(range(0, 36000, 7)), [36000] * len(range(0, 36000, 7))))
    lines, expected = [], []
    for track, masters, speeds in cases:
        lines.append(f"{track.period_counts} {track.on_counts} {track.off_counts} {track.hysteresis_counts} "
                     f"{track.on_compensation_us} {track.off_compensation_us} {track.direction} {len(masters)}")
        state = TappetState()
        for master, speed in zip(masters, speeds):
            lines.append(f"{master} {speed}")
            state = track.step(state, master, speed)
            expected.append(f"{state.output} {state.direction} {state.armed} {state.last_switch_counts}")
    # a track out of range (on at the period, a direction 3): a negative code, the state untouched
    lines += ["10 10 0 0 0 0 0 1", "5 1", "10 0 0 0 0 0 3 1", "5 1"]
    run = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    got = run.stdout.splitlines()
    assert got[-2:] == ["-2 0 1 0", "-2 0 1 0"]
    got = got[:-2]
    assert len(got) == len(expected) > 18000
    assert got == expected
    outputs = {line.split()[0] for line in got}
    assert outputs == {"0", "1"}  # both states reached: the vectors exercise the switch


# ------------------------------------------------------------------------------- CODESYS

def test_the_codesys_export_writes_the_tappets_into_mc_cam_ref():
    """MC_CAM_REF.nTappets "Number of tappet switch actions" and .pt (CODESYS SM3_Basic): two
    actions per track, at its on and off positions, passes as the module's table says; the same
    tracks as MC_CAMSWITCH_TR switches (TrackNumber, First/LastOnPosition, AxisDirection)."""
    import re

    from ecam.export import export_cam

    cam = replace(load_cam(DRRD), tappets=(
        TappetTrack(60.0, 180.0, name="glue *) (*", on_compensation=-0.02),
        TappetTrack(350.0, 10.0, direction="positive"), TappetTrack(90.0, 95.5, direction="negative")))
    text = export_cam(cam, "codesys").content
    ref = re.search(r"combination_drrd : MC_CAM_REF := \((.*)\);", text).group(1)
    assert "nTappets := 6" in ref and "pt := ADR(combination_drrd_tappets)" in ref
    actions = re.findall(r"\(iGroupID := (\d+), x := ([\d.]+), ctaPositive := (\w+), ctaNegative := (\w+)\)", text)
    assert actions == [
        ("1", "60.0", "TAPPETACTION_ON", "TAPPETACTION_OFF"), ("1", "180.0", "TAPPETACTION_OFF", "TAPPETACTION_ON"),
        ("2", "350.0", "TAPPETACTION_ON", "TAPPETACTION_OFF"), ("2", "10.0", "TAPPETACTION_OFF", "TAPPETACTION_NON"),
        ("3", "90.0", "TAPPETACTION_NON", "TAPPETACTION_OFF"), ("3", "95.5", "TAPPETACTION_OFF", "TAPPETACTION_ON")]
    assert "ARRAY[0..5] OF SMC_CAMTappet" in text and "ARRAY[1..3] OF MC_CAMSWITCH_TR" in text
    assert ("(TrackNumber := 2, FirstOnPosition := 350.0, LastOnPosition := 10.0, AxisDirection := 1, "
            "CamSwitchMode := 0, Duration := T#0MS)") in text
    assert "OnCompensation -0.02 s" in text
    assert text.count("*)") == text.count("(*") == 2  # the name cannot end the comment
    plain = export_cam(load_cam(DRRD), "codesys").content  # no tappets: as before
    assert "nTappets := 0" in plain and "pt :=" not in plain and "SMC_CAMTappet" not in plain
