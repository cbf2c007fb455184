"""The rig in a user's CI: several scenes per call, JUnit XML, the HTML report (opened in headless
Chromium), the plots over the master position, and the pytest plugin (tested with pytest's own
``pytester``)."""

from __future__ import annotations

import base64
import html
import json
import re
import shutil
import subprocess
import sys
from dataclasses import replace
from importlib.metadata import entry_points
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from ecam.app.html_report import html_report
from ecam.app.junit import junit_xml
from ecam.app.multi import (SceneCrashed, exit_status, is_scene_file, run_scenes, scene_files,
                            scene_labels, summary_table)
from ecam.errors import CamFileError, InputError, SimulationError
from hil_sim.report import Report, check
from hil_sim.rig.plot import (MAX_OVERLAID_PERIODS, figure_bytes, master_period, period_index,
                              plot_report, report_figure)

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "hil_sim" / "scenes"
CAMS = ROOT / "firmware_tables" / "cams"
CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists()
                                        else None)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _short_scene(name: str, cycles: int = 300, passing: bool = False) -> str:
    """A shipped scene's TOML with its cam path made absolute and a short duration.

    These tests are about the plumbing (reports, files, exit codes), not the physics, so the
    verdicts are made certain: ``passing`` widens every limit and rating a hundredfold, and
    the rig runs the ideal model where it has a choice (fast, and the shipped soft coupling
    fails it by several times its limits).
    """
    from hil_sim.scene import Scene

    text = (SCENES / f"{name}.toml").read_text()
    text = re.sub(r'file = "[^"]*/([^/"]+\.toml)"',
                  lambda m: f'file = "{(CAMS / m.group(1)).as_posix()}"', text)
    text = re.sub(r"\[duration\][^\[]*$", f"[duration]\ncycles = {cycles}\n", text, flags=re.S)
    if "fidelity" in Scene.__dataclass_fields__:
        text = f'fidelity = "ideal"\n{text}'
    if passing:
        text = re.sub(r"^(tracking_error|wind_up_deg|coupling_rated_torque|coupling_max_torque)"
                      r" = ([\d.e+-]+)", lambda m: f"{m.group(1)} = {float(m.group(2)) * 100}",
                      text, flags=re.M)
        text = text.replace("[limits]\n", "[limits]\nmotor_saturation_percent = 100.0\n"
                            "resonance_excitation_percent = 100.0\n")
        # the coupling's default inertia scales with its rating (hil_sim.effects): keep the
        # shipped coupling's, or the hundredfold rating makes a 0.6 kg m^2 coupling the drive is
        # tuned for and the ideal model leaves out
        text = text.replace("[mechanics]\n", "[mechanics]\ncoupling_inertia = 2.3e-4\n")
    return text


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """A passing and a failing scene (short runs) beside a cam file, which is not a scene."""
    path = tmp_path_factory.mktemp("scenes")
    (path / "a_stiff.toml").write_text(_short_scene("stiff_coupling", passing=True))
    (path / "b_soft.toml").write_text(_short_scene("soft_coupling"))
    shutil.copy(CAMS / "combination_drrd.toml", path / "cam.toml")
    return path


@pytest.fixture(scope="module")
def results(scene_dir):
    return run_scenes([scene_dir])


@pytest.fixture(scope="module")
def broken(tmp_path_factory, scene_dir):
    """Two files that cannot run beside the good scenes: a bad field, and not TOML at all."""
    path = tmp_path_factory.mktemp("broken")
    (path / "bad_field.toml").write_text(_short_scene("stiff_coupling").replace(
        "tracking_error = 0.002", "tracking_error = -1.0"))
    (path / "not_toml.toml").write_text("[master\nspeed_rpm = 60\n")
    lines = []
    out = run_scenes([scene_dir, path], progress=lines.append)
    return out, lines


@pytest.fixture(scope="module")
def page(results):
    """The HTML page of the two scenes (each page draws its plots: done once here)."""
    return html_report(results)


@pytest.fixture(scope="module")
def broken_page(broken):
    return html_report(broken[0])


def _no_plots(report):
    """The report without its series: the page then has no plot to draw (fast)."""
    return replace(report, series={})


def _fake_report(periods: float = 2.0, per_period: int = 400, twist: bool = True,
                 spike_period: int | None = None, saturate: bool = False,
                 fault_s: float | None = None) -> Report:
    """A report with made-up series (a master at constant speed, 360 deg per period): the
    figure's geometry tested without running the rig."""
    n = int(round(periods * per_period))
    k = np.arange(n)
    travel = (k + 1) * 360.0 / per_period
    position = travel % 360.0
    index = (travel // 360.0).astype(int)
    phase = np.radians(position)
    tracking = 0.001 * np.sin(phase) * (1 + 0.1 * index)
    if spike_period is not None:
        tracking = tracking + 0.004 * ((index == spike_period) & (np.abs(position - 200) < 5))
    torque = 20 * np.abs(np.sin(2 * phase))
    motor = np.minimum(6.0 if saturate else 3.0, 7 * np.abs(np.sin(phase)))
    following = 100 * np.cos(phase)
    series = {"time_s": (k + 1) * 0.001, "master_position": position,
              "tracking_error": tracking, "coupling_torque": torque,
              "peak_coupling_torque": torque, "peak_motor_torque": motor,
              "following_error": following}
    if twist:
        series["peak_twist"] = np.radians(torque / 300.0)
    checks = [check("following_error", np.max(np.abs(following)), 20000, "counts"),
              check("tracking_error", np.max(np.abs(tracking)), 0.002, "in"),
              check("coupling_peak_torque", np.max(torque), 120, "N m"),
              check("wind_up", np.max(torque) / 300.0, 0.05, "deg"),
              check("motor_saturation", 100 * np.mean(motor >= 6.0), 0.0, "%")]
    summary = {"units": {"master": "deg", "slave": "in"},
               "master": {"speed": 360.0 * 1000 / per_period,
                          "cam_frequency_hz": 1000.0 / per_period},
               "mechanics": {"coupling_rated_torque": 60.0, "coupling_max_torque": 120.0,
                             "motor_torque_limit": 6.0},
               "faults": [{"time_s": fault_s, "code": "0x8611"}] if fault_s else []}
    return Report(scene="fake", model="two_mass" if twist else "rigid", model_reason="made up",
                  cycles=n, checks=checks, summary=summary, series=series)


# ------------------------------------------------------------------------------------------
# Several scenes

def test_directory_holds_scenes_and_a_cam_file(scene_dir):
    assert is_scene_file(scene_dir / "a_stiff.toml")
    assert not is_scene_file(scene_dir / "cam.toml")
    assert [p.name for p in scene_files([scene_dir])] == ["a_stiff.toml", "b_soft.toml"]


def test_a_scene_that_cannot_run_is_an_error_and_the_others_run(broken, scene_dir):
    out, lines = broken
    assert [p.name for p, _, _ in out] == ["a_stiff.toml", "b_soft.toml", "bad_field.toml",
                                           "not_toml.toml"]
    (_, stiff, _), (_, soft, _), (_, bad, _), (_, toml, _) = out
    assert stiff.passed and not soft.passed  # the good scenes ran in full
    assert isinstance(bad, CamFileError) and "limits.tracking_error: -1 should be > 0" in str(bad)
    assert isinstance(toml, CamFileError) and "not_toml.toml" in str(toml)
    assert len(lines) == 4
    assert sum("ERROR" in line for line in lines) == 2
    assert exit_status(out) == 2  # could not run outranks a failed check
    table = summary_table(out)
    assert re.search(r"^bad_field\s+ERROR .*limits\.tracking_error", table, re.M)
    assert table.splitlines()[-1] == "1 of 4 scenes passed, 2 could not run"
    # A mistake on the command line still stops the call before anything runs.
    with pytest.raises(InputError, match="does not exist"):
        run_scenes([scene_dir, scene_dir / "missing.toml"])
    with pytest.raises(InputError, match="jobs: 0"):
        run_scenes([scene_dir], jobs=0)


def test_a_crash_inside_the_rig_is_that_scenes_error(monkeypatch, scene_dir):
    import hil_sim.rig

    real = hil_sim.rig.run_scene

    def flaky(scene):
        if scene.path.name == "b_soft.toml":
            return {}["a key the rig forgot"]
        return real(scene)

    monkeypatch.setattr(hil_sim.rig, "run_scene", flaky)
    out = run_scenes([scene_dir / "b_soft.toml", scene_dir / "a_stiff.toml"])
    (_, crash, _), (_, stiff, _) = out
    assert isinstance(stiff, Report)  # the other scene ran
    assert isinstance(crash, SceneCrashed) and "KeyError" in str(crash)
    assert "Traceback" in crash.details and "a key the rig forgot" in crash.details
    import pickle  # a worker process sends it back pickled

    again = pickle.loads(pickle.dumps(crash))
    assert (str(again), again.details) == (str(crash), crash.details)
    error = ET.fromstring(junit_xml(out)).find("testsuite/testcase/error")
    assert error.get("type") == "SceneCrashed" and "Traceback" in error.text
    assert exit_status(out) == 2


@pytest.mark.slow
def test_serial_and_parallel_runs_give_the_same_reports(scene_dir, results, page):
    lines = []
    paths = [scene_dir / "a_stiff.toml", scene_dir / "b_soft.toml"]
    given = paths[::-1]  # the failing scene first: it also finishes first
    parallel = run_scenes(given, jobs=2, progress=lines.append)
    assert [p for p, _, _ in parallel] == given  # the input order, not the finishing order
    parallel.reverse()
    for (_, one, _), (_, other, _) in zip(results, parallel):
        assert one.to_json() == other.to_json()
    # The files a CI keeps are the same bytes too (JUnit but for its wall times).
    assert html_report(parallel) == page
    strip = re.compile(r' time="[^"]*"')
    assert strip.sub("", junit_xml(parallel)) == strip.sub("", junit_xml(results))
    assert len(lines) == 2 and all(re.match(r"\[\d/2\] \S+\.toml: (PASSED|FAILED)", x)
                                   for x in lines)
    assert any("b_soft.toml: FAILED tracking_error x" in x for x in lines)


def test_summary_table_and_exit_status(results):
    (_, stiff, _), (_, soft, _) = results
    assert stiff.passed and not soft.passed  # the premise of the two scenes
    table = summary_table(results)
    rows = table.splitlines()
    assert rows[0].split()[:5] == ["scene", "verdict", "model", "cycles", "wall"]
    assert rows[2].startswith("a_stiff ") and " PASS " in rows[2]
    assert rows[3].startswith("b_soft ") and " FAIL " in rows[3]
    assert rows[3].endswith(", ".join(f"{c.name} x{c.ratio:.3g}" if c.ratio is not None
                                      else c.name for c in soft.failed))
    nearest = max((c for c in stiff.checks if c.ratio is not None), key=lambda c: c.ratio)
    assert rows[2].endswith(f"{nearest.name} at {100 * nearest.ratio:.3g} % of its limit")
    assert rows[-1] == "1 of 2 scenes passed"
    assert exit_status(results) == 1
    assert exit_status(results[:1]) == 0
    assert exit_status([]) == 2
    assert exit_status([(results[0][0], SimulationError("bus gone"), 0.1)]) == 2


def test_scene_labels_are_distinct():
    paths = [Path("line_a/knife.toml"), Path("line_b/knife.toml"), Path("x/feed.toml"),
             Path("x/feed.toml")]
    assert scene_labels(paths) == ["line_a/knife", "line_b/knife", "feed (1)", "feed (2)"]
    assert scene_labels([Path("a/b/c.toml"), Path("d/b/c.toml"), Path("e.toml")]) == \
        ["a/b/c", "d/b/c", "e"]


# ------------------------------------------------------------------------------------------
# JUnit XML

# junit-10.xsd of Jenkins' xUnit plugin (what Jenkins validates against; GitLab and GitHub
# Actions read the same elements): allowed children and attributes, required attributes.
_SCHEMA = {
    "testsuites": ({"testsuite"}, {"name", "time", "tests", "failures", "errors"}, set()),
    "testsuite": ({"testsuite", "properties", "testcase", "system-out", "system-err"},
                  {"name", "tests", "failures", "errors", "group", "time", "skipped",
                   "timestamp", "hostname", "id", "package", "file", "log", "url"},
                  {"name", "tests", "failures", "errors"}),
    "testcase": ({"skipped", "error", "failure", "system-out", "system-err"},
                 {"name", "time", "classname", "group"}, {"name"}),
    "failure": (set(), {"type", "message"}, set()),
    "error": (set(), {"type", "message"}, set()),
    "system-out": (set(), set(), set()),
}
_SUREFIRE_TIME = re.compile(r"(([0-9]{0,3},)*[0-9]{3}|[0-9]{0,3})*(\.[0-9]*)?")


def _validate(element) -> None:
    children, allowed, required = _SCHEMA[element.tag]
    assert set(element.attrib) <= allowed, (element.tag, element.attrib)
    assert required <= set(element.attrib), (element.tag, element.attrib)
    if "time" in element.attrib and element.tag in ("testsuites", "testsuite"):
        assert _SUREFIRE_TIME.fullmatch(element.attrib["time"]), element.attrib["time"]
    for child in element:
        assert child.tag in children, (element.tag, child.tag)
        _validate(child)


def test_junit_one_suite_per_scene_one_case_per_check(results):
    text = junit_xml(results)
    root = ET.fromstring(text)
    _validate(root)
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == ["a_stiff", "b_soft"]
    for suite, (path, report, seconds) in zip(suites, results):
        cases = suite.findall("testcase")
        assert [c.get("name") for c in cases] == [c.name for c in report.checks]
        assert {c.get("classname") for c in cases} == {f"ecam.sim.{suite.get('name')}"}
        assert int(suite.get("tests")) == len(cases)
        failures = [c.find("failure") for c in cases if c.find("failure") is not None]
        assert int(suite.get("failures")) == len(failures) == len(report.failed)
        assert suite.get("errors") == "0" and suite.get("file") == str(path)
        assert [f.get("message") for f in failures] == [c.line() for c in report.failed]
        assert [f.text for f in failures] == [c.line() for c in report.failed]
        assert float(suite.get("time")) == pytest.approx(seconds, abs=1e-3)
        out = suite.find("system-out").text
        assert report.model_reason in out and "bus: " in out and "faults: " in out
        for case in cases:  # GitLab shows a failed case's own output, not the suite's
            assert (case.find("system-out") is not None) == (case.find("failure") is not None)
            if case.find("system-out") is not None:
                assert case.find("system-out").text == out
    assert int(root.get("tests")) == sum(len(r.checks) for _, r, _ in results)
    assert int(root.get("failures")) == sum(len(r.failed) for _, r, _ in results) > 0
    assert root.get("errors") == "0"
    message = suites[1].find("testcase/failure").get("message")
    assert re.search(r"FAIL  \w+: [-\d.e]+ \S+, limit [\d.e-]+ .*\(exceeded by .* %, x[\d.]+\); "
                     r"\S", message)


def test_junit_deterministic_except_times_and_reports_errors(results, broken):
    again = [(p, r, s + 1.234) for p, r, s in results]
    strip = re.compile(r' time="[^"]*"')
    assert strip.sub("", junit_xml(results)) == strip.sub("", junit_xml(again))
    assert junit_xml(results) != junit_xml(again)  # the times are there
    out, _ = broken
    root = ET.fromstring(junit_xml(out))
    _validate(root)
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == ["a_stiff", "b_soft", "bad_field", "not_toml"]
    for suite, (_, error, _) in zip(suites[2:], out[2:]):
        assert (suite.get("tests"), suite.get("errors"), suite.get("failures")) == ("1", "1", "0")
        case = suite.find("testcase")
        assert case.get("name") == "run"
        assert case.find("error").get("message") == str(error)
        assert case.find("error").get("type") == "CamFileError"
    assert root.get("errors") == "2"
    assert int(root.get("tests")) == sum(len(r.checks) for _, r, _ in results) + 2


def test_effects_listed_when_the_report_has_them(results):
    _, report, seconds = results[1]
    effects = [{"name": "gear_backlash", "included": True, "change": "wind_up +45 %",
                "why": "moves wind_up by 45 % of its limit"},
               {"name": "encoder_resolution", "included": False, "change": 0.02,
                "why": "moves no check by more than 2 % of its limit"}]
    with_effects = replace(_no_plots(report), summary={**report.summary, "effects": effects})
    out = ET.fromstring(junit_xml([("s.toml", with_effects, seconds)])).find(
        "testsuite/system-out").text
    assert "effect gear_backlash: included; moves wind_up by 45 % of its limit" in out
    assert "effect encoder_resolution: left out; moves no check by more than 2 %" in out
    valued = replace(with_effects, summary={**with_effects.summary, "effects": [
        {"name": "encoder", "included": True, "value": "1.049e+06 counts/rev",
         "why": "moves tracking_error by 6 %"}, {"name": "current_loop", "included": False}]})
    out = ET.fromstring(junit_xml([("s.toml", valued, seconds)])).find(
        "testsuite/system-out").text
    assert "effect encoder: included, 1.049e+06 counts/rev; moves tracking_error by 6 %" in out
    assert "effect current_loop: left out\n" in out
    page = html_report([("s.toml", with_effects, seconds)])
    table = page[page.index('<table class="effects">'):]
    table = table[:table.index("</table>")]
    assert re.findall(r"<th>([^<]*)</th>", table) == ["name", "included", "change", "why"]
    assert ('<td><code>gear_backlash</code></td><td><span class="badge pass">included</span>'
            "</td><td>wind_up +45 %</td>") in table
    assert '<td><code>encoder_resolution</code></td><td><span class="badge info">left out' in table
    # A proof whose run moved no check has no check to name: the page says nothing of it.
    proved = replace(with_effects, summary={**with_effects.summary, "fidelity": "auto",
                                            "fidelity_proof": {"runs": 10, "check": None,
                                                               "same_verdicts": True}})
    assert ('<span class="note">proof: 10 bus-free runs; the same verdicts</span>'
            in html_report([("s.toml", proved, seconds)]))
    _, stiff, _ = results[0]
    without = replace(stiff, summary={k: v for k, v in stiff.summary.items()
                                      if k not in ("effects", "fidelity")}, series={})
    assert "lists no effects" in html_report([("s.toml", without, seconds)])


# ------------------------------------------------------------------------------------------
# Plots over the master position

def test_period_index_counts_wraps_both_ways():
    position = np.array([350.0, 355.0, 2.0, 8.0, 359.0, 3.0, 10.0])  # reverses over the seam
    assert period_index(position, 360.0).tolist() == [0, 0, 1, 1, 0, 1, 1]
    # A master at constant speed over many periods, any phase: floor(travel / period).
    travel = 17.0 + np.arange(20000) * 0.9
    index = period_index(travel % 360.0, 360.0)
    assert (index == (travel // 360.0).astype(int) - 0).all()
    assert period_index(np.zeros(0), 360.0).size == 0


def test_figure_is_over_the_master_position_with_the_periods_overlaid():
    report = _fake_report(periods=3.0)
    fig = report_figure(report)
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == 5  # tracking, following, coupling torque, wind-up, motor torque
    for ax in panels:
        assert "master position in the cam period [deg]" in ax.get_xlabel()
        assert ax.get_xlim() == (0.0, 360.0)
        # one line per period, each within one period and reaching its end
        lines = [line for line in ax.get_lines() if len(line.get_xdata()) > 50]
        assert len(lines) == 3
        for line in lines:
            x = np.asarray(line.get_xdata(), dtype=float)
            assert np.nanmin(x) >= 0 and np.nanmax(x) == pytest.approx(360.0, abs=1.0)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["period 1", "period 2", "period 3"]
    assert master_period(report) == pytest.approx(360.0)


def test_the_failed_checks_sample_is_marked_where_it_is():
    report = _fake_report(periods=3.0, spike_period=1)
    tracking = report.check("tracking_error")
    assert not tracking.passed
    fig = report_figure(report)
    ax = next(a for a in fig.axes if a.get_title(loc="left").startswith("Tracking error"))
    assert ax.get_title(loc="left").startswith(
        f"Tracking error: FAIL {tracking.value:.3g} in, x{tracking.ratio:.3g} the limit")
    worst = int(np.argmax(np.abs(report.series["tracking_error"])))
    rings = [line for line in ax.get_lines() if line.get_marker() == "o"]
    assert len(rings) == 1
    x, y = rings[0].get_xdata()[0], rings[0].get_ydata()[0]
    assert x == report.series["master_position"][worst] and abs(y) == tracking.value
    assert rings[0].get_label() == f"worst, at {x:.4g} deg, period 2"
    assert f"worst, at {x:.4g} deg, period 2" in [t.get_text() for t in ax.get_legend().texts]
    # The limit lines are drawn at +-limit.
    levels = sorted(line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--")
    assert levels == [-tracking.limit, tracking.limit]


def test_many_periods_are_a_band_with_the_worst_and_the_last_period():
    report = _fake_report(periods=MAX_OVERLAID_PERIODS + 14.5, per_period=200, spike_period=7,
                          saturate=True, fault_s=1.25)
    fig = report_figure(report)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend[0] == "all 21 periods (min to max)"
    assert "period 8" in legend and "period 21" in legend
    ax = next(a for a in fig.axes if a.get_title(loc="left").startswith("Tracking error"))
    assert len(ax.collections) == 1  # the band
    band = ax.collections[0].get_paths()[0].vertices
    assert band[:, 1].max() == pytest.approx(report.check("tracking_error").value)
    labels = ax.get_legend_handles_labels()[1]
    assert "EMCY 0x8611 (period 7)" in labels  # 1.25 s at 0.2 s per period
    assert "worst, at 196.2 deg, period 8" in labels
    motor = next(a for a in fig.axes if a.get_title(loc="left").startswith("Motor torque"))
    assert "torque clamped" in motor.get_legend_handles_labels()[1]


def test_master_positions_outside_a_checks_window_are_greyed():
    from hil_sim.report import Check

    class Windowed(Check):  # the form a check gives its window in: master [start, end]
        def to_dict(self):
            return {**super().to_dict(), "window": {"master": [330.0, 30.0]}}

    report = _fake_report(periods=1.0, twist=False)
    tracking = report.check("tracking_error")
    windowed = Windowed(*(getattr(tracking, f) for f in ("name", "value", "limit", "passed",
                                                          "unit", "detail")))
    report = replace(report, checks=[windowed if c is tracking else c for c in report.checks])
    fig = report_figure(report)
    ax = next(a for a in fig.axes if a.get_title(loc="left").startswith("Tracking error"))
    spans = [p.get_path().transformed(p.get_patch_transform()).vertices[:, 0]
             for p in ax.patches]
    labels = ax.get_legend_handles_labels()[1]
    assert len(spans) == 1 and "outside it: not checked" in labels
    assert "tracking window 330..30 deg" in labels  # the window (a knife's cut zone) is named
    assert (spans[0].min(), spans[0].max()) == (30.0, 330.0)  # the window spans the seam
    for other in fig.axes:  # its edges on every panel, so the cut zone shows on the torques too
        if other.get_visible():
            edges = sorted(line.get_xdata()[0] for line in other.lines if line.get_linestyle() == "--"
                           and line.get_color() == "#8250df")
            assert edges == [30.0, 330.0], other.get_title(loc="left")


@pytest.mark.slow
def test_figure_bytes_are_deterministic_small_and_without_metadata(tmp_path):
    report = _fake_report(periods=2.0, per_period=90)
    png = figure_bytes(report)
    assert png[:8] == PNG_MAGIC and png == figure_bytes(report)
    assert len(png) < 150_000
    assert b"tEXt" not in png and b"iTXt" not in png  # no Software, no date
    import matplotlib.image

    (tmp_path / "f.png").write_bytes(png)
    image = matplotlib.image.imread(tmp_path / "f.png")
    assert image.shape[1] == 1100  # 11 in at 100 dpi
    assert (image[2, 2, :3] == 1.0).all()  # the background is white, exactly
    # The vector formats `ecam sim --plot` writes, on one panel (drawing text is slow there).
    one = replace(report, series={k: report.series[k] for k in ("time_s", "master_position",
                                                                 "tracking_error")})
    svg = figure_bytes(one, fmt="svg")
    assert svg == figure_bytes(one, fmt="svg") and b"<dc:date>" not in svg
    plot_report(one, tmp_path / "plot.pdf")
    first = (tmp_path / "plot.pdf").read_bytes()
    plot_report(one, tmp_path / "plot.pdf")
    assert (tmp_path / "plot.pdf").read_bytes() == first and b"CreationDate" not in first
    with pytest.raises(InputError, match="no recorded samples"):
        figure_bytes(replace(report, series={}))


def test_the_rig_reports_figure_marks_the_checks_worst_samples(results):
    _, soft, _ = results[1]
    fig = report_figure(soft)
    titles = {ax.get_title(loc="left").split(":")[0]: ax for ax in fig.axes if ax.get_visible()}
    for panel, name in (("Tracking error", "tracking_error"),
                        ("Following error", "following_error"),
                        ("Coupling torque", "coupling_peak_torque")):
        ring = [line for line in titles[panel].get_lines() if line.get_marker() == "o"]
        assert abs(ring[0].get_ydata()[0]) == pytest.approx(soft.check(name).value, rel=1e-12)
        # the check's own 'at master X deg' is where the ring is
        at = re.search(r"at master ([-\d.e]+)", soft.check(name).detail)
        assert ring[0].get_xdata()[0] == pytest.approx(float(at.group(1)), rel=1e-5)


# ------------------------------------------------------------------------------------------
# HTML report

_EXTERNAL = re.compile(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//""", re.I)


def test_html_report_content(results, scene_dir, page):
    assert not _EXTERNAL.search(page) and "<script" not in page.lower()
    assert "@import" not in page and "url(" not in page
    body = page[page.index("<body>"):]
    # The verdict comes first, with the failed checks' lines.
    first = body.index("FAILED: 1 of 2 scenes passed")
    _, soft, _ = results[1]
    for check_ in soft.failed:
        assert body.index(html.escape(check_.line())) > first
    assert first < body.index("<h3>Checks</h3>")
    assert body.index('id="scene-b_soft"') < body.index('id="scene-a_stiff"')  # failed first
    for _, report, _ in results:
        for check_ in report.checks:
            assert f"<code>{check_.name}</code>" in body
        assert html.escape(report.model_reason) in body
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) == 4  # each scene's figure and its open-loop Bode plot (issue 20)
    assert all(base64.b64decode(data)[:8] == PNG_MAGIC for data in images)
    assert "Over the master position [deg]" in body
    assert html.escape((scene_dir / "b_soft.toml").read_text().splitlines()[0]) in body
    assert "Scene as run: every field, defaults filled in" in body
    assert "% left (" in body and "% used)" in body and "% over" in body
    assert "drive faults (EMCY):</b> none" in body and "bitrate" in body
    assert " s wall" not in body and "<th class=\"num\">wall</th>" not in body
    timed = html_report([(p, _no_plots(r), t) for p, r, t in results], timing=True)
    assert " s wall" in timed and "<th class=\"num\">wall</th>" in timed


def test_html_figures_carry_their_units(results):
    # Bus, master, table and mechanics figures once stood bare ("coupling rated torque 60",
    # "peak percent 43" beside "peak bits 430"): each number now says its unit.
    _, report, seconds = results[1]
    data = report.to_dict()
    page = html_report([("s.toml", _no_plots(report), seconds)])
    rows = dict(re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td></tr>", page))
    assert rows["bitrate"] == f"{data['bus']['bitrate']} bit/s"
    assert rows["peak load"] == f"{data['bus']['peak_percent']:.6g} %"
    assert rows["peak per cycle"] == f"{data['bus']['peak_bits']} bits"
    assert rows["motor torque limit"] == f"{data['mechanics']['motor_torque_limit']:.6g} N m"
    assert rows["speed"] == f"{data['master']['speed']:.6g} {data['master']['speed_unit']}"
    assert rows["max error"].endswith(f" {data['units']['slave']}")
    assert rows["excitation"].endswith(" Hz") and "speed unit" not in rows


def test_the_same_scene_gives_the_same_html_bytes(scene_dir, results):
    again = run_scenes([scene_dir / "a_stiff.toml"])
    assert again[0][1] is not results[0][1]
    assert html_report(again) == html_report(results[:1])


def test_html_entry_for_a_scene_that_could_not_run(broken, broken_page):
    out, _ = broken
    body = broken_page[broken_page.index("<body>"):]
    assert "FAILED: 1 of 4 scenes passed, 2 could not run" in body
    _, bad, _ = out[2]
    # In the verdict, in the overview, and a section of its own with the file, line-numbered.
    assert body.index(html.escape(str(bad))) < body.index("<h3>Scenes</h3>")
    section = body[body.index('id="scene-bad_field"'):]
    section = section[:section.index("</section>")]
    assert '<span class="badge error">ERROR</span>' in section
    assert "could not run (CamFileError)" in section
    # The line of the field the message names is marked, and only that line.
    assert re.findall(r'<span class="hl"><span class="ln">\d+</span>([^<]*)</span>', section) \
        == ["tracking_error = -1.0         # in"]
    # Broken scenes come first, then failed, then passed.
    order = [body.index(f'id="scene-{n}"') for n in ("bad_field", "not_toml", "b_soft",
                                                      "a_stiff")]
    assert order == sorted(order)


def test_html_report_of_a_scene_object(results):
    from hil_sim.scene import load_scene

    scene = load_scene(SCENES / "stiff_coupling.toml")
    page = html_report([(scene, _no_plots(results[0][1]), 0.1)])
    assert "<code>mechanics.coupling_stiffness</code>" in page and "2e+06" in page
    assert "stiff_coupling.toml</code>" in page  # its file, too
    assert html_report([]).count("NO SCENE RAN") == 2  # title and verdict


def test_check_fields_a_newer_report_adds_are_shown(results):
    _, report, seconds = results[0]
    from hil_sim.report import Check

    class Windowed(Check):
        def to_dict(self):
            return {**super().to_dict(), "window": {"from": 60.0, "to": 120.0}}

    first = report.checks[0]
    windowed = Windowed(first.name, first.value, first.limit, first.passed, first.unit,
                        first.detail)
    page = html_report([("s.toml", replace(_no_plots(report),
                                           checks=[windowed, *report.checks[1:]]), seconds)])
    assert '<span class="note">window: from 60, to 120</span>' in page


def _chromium(page: Path, tmp_path: Path, screenshot: Path,
              size: str = "1280,2000") -> tuple[list[str], list[str]]:
    """Open ``page`` in headless Chromium; return (console lines, URLs the page requested
    that are not file: or data:)."""
    netlog = tmp_path / "netlog.json"
    command = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
               "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--hide-scrollbars",
               f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0",
               f"--log-net-log={netlog}", f"--screenshot={screenshot}",
               f"--window-size={size}", page.as_uri()]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    # Page console output (console.* and uncaught errors) is logged as INFO:CONSOLE.
    console = [line for line in done.stderr.splitlines() if ":CONSOLE" in line]
    events = json.loads(netlog.read_text())
    names = {v: k for k, v in events["constants"]["logEventTypes"].items()}
    requested = []
    for event in events["events"]:
        params = event.get("params") or {}
        # The browser's own requests (update checks...) have no origin; a page's have one
        # ("null" for a file: page).
        if names.get(event["type"]) == "URL_REQUEST_START_JOB" and \
                params.get("initiator") != "not an origin":
            url = params.get("url")  # absent on the event that ends the job
            if url and not url.startswith(("file:", "data:")):
                requested.append(url)
    return console, requested


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (Debian package "
                    "'chromium'; .ci/run installs it)")
def test_html_report_in_headless_chromium(broken_page, tmp_path):
    # The detector must see what it looks for: a page with a console error and two fetches.
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><head><link rel="stylesheet" '
                   'href="https://cdn.example.invalid/x.css"></head><body><img '
                   'src="http://example.invalid/a.png"><script>console.error("boom");'
                   "</script></body></html>")
    console, requested = _chromium(bad, tmp_path / "bad", tmp_path / "bad.png")
    assert any('"boom"' in line for line in console)
    assert sorted(requested) == ["http://example.invalid/a.png",
                                 "https://cdn.example.invalid/x.css"]

    page = tmp_path / "report.html"
    page.write_text(broken_page, encoding="utf-8")
    screenshot = tmp_path / "report.png"
    console, requested = _chromium(page, tmp_path / "run", screenshot)
    assert console == [] and requested == []
    import matplotlib.image

    image = matplotlib.image.imread(screenshot)
    assert image.shape[:2] == (2000, 1280)
    # The verdict banner (failed: #ffebe9) is painted at the top of the page.
    top = (image[:200, :, :3] * 255).round().astype(int).reshape(-1, 3)
    assert (top == [0xFF, 0xEB, 0xE9]).all(axis=1).sum() > 10000


# ------------------------------------------------------------------------------------------
# pytest plugin

def _plugin_args() -> list[str]:
    """``-p ecam.app.pytest_plugin`` unless the installed entry point already loads it."""
    installed = any(e.value == "ecam.app.pytest_plugin"
                    for e in entry_points(group="pytest11"))
    return [] if installed else ["-p", "ecam.app.pytest_plugin"]


def _write_scenes(pytester) -> Path:
    scenes = pytester.path / "scenes"
    scenes.mkdir()
    (scenes / "stiff.toml").write_text(_short_scene("stiff_coupling", passing=True))
    (scenes / "soft.toml").write_text(_short_scene("soft_coupling"))
    (scenes / "typo.toml").write_text(_short_scene("stiff_coupling").replace(
        "bitrate = 1000000", "bitrat = 1000000"))
    shutil.copy(CAMS / "modified_sine.toml", scenes / "cam.toml")
    return scenes


@pytest.mark.slow
def test_plugin_runs_scene_files_as_tests(pytester):
    _write_scenes(pytester)
    result = pytester.runpytest(*_plugin_args(), "--ecam-scenes", "scenes", "-ra", "-vv",
                                "--junitxml=junit.xml", "--ecam-html=report.html")
    result.assert_outcomes(passed=1, failed=2)
    result.stdout.fnmatch_lines([
        "*ecam scenes: *scenes",
        "FAILED scenes/soft.toml::soft - FAIL  tracking_error: * in, limit 0.002 in "
        "(exceeded by *x*); at master *",
        "FAILED scenes/typo.toml::typo - scene typo.toml: bus.bitrat: unknown field*",
    ])
    result.stdout.fnmatch_lines(["ecam: HTML report of 3 scene runs: report.html"])
    cases = {c.get("name"): c for c in ET.parse(pytester.path / "junit.xml").iter("testcase")}
    assert set(cases) == {"stiff", "soft", "typo"}
    _validate(ET.parse(pytester.path / "junit.xml").getroot())  # no <properties> in a case
    message = cases["soft"].find("failure").get("message")
    assert message.startswith("FAIL  tracking_error: ") and "\nFAIL  wind_up: " in message
    # The last line: how many failed, and the model's reason without a stray period.
    assert re.search(r"\nscene soft_coupling: \d of \d+ checks failed \(.*[^.]\)$", message)
    assert cases["stiff"].find("failure") is None
    page = (pytester.path / "report.html").read_text()
    assert "FAILED: 1 of 3 scenes passed, 1 could not run" in page and "bus.bitrat" in page


def test_plugin_reads_the_scene_directories_from_the_ini_file(pytester):
    _write_scenes(pytester)
    (pytester.path / "scenes" / "soft.toml").unlink()
    (pytester.path / "scenes" / "typo.toml").unlink()
    pytester.makeini("[pytest]\necam_scenes = scenes\n")
    result = pytester.runpytest(*_plugin_args(), "-v")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*scenes/stiff.toml::stiff PASSED*"])
    pytester.makeini("[pytest]\necam_scenes = nowhere\n")
    result = pytester.runpytest(*_plugin_args())
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*ini ecam_scenes: '*nowhere' should be a directory*"])


def test_plugin_adds_nothing_unless_asked(pytester):
    _write_scenes(pytester)
    pytester.makepyfile("def test_plain():\n    pass\n")
    result = pytester.runpytest(*_plugin_args(), "-v")
    result.assert_outcomes(passed=1)  # the scene files are not collected
    assert "ecam scenes" not in result.stdout.str() and ".toml" not in result.stdout.str()
    result = pytester.runpytest(*_plugin_args(), "--ecam-scenes", "nowhere")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--ecam-scenes: 'nowhere' should be a directory*"])


def test_run_scene_fixture_and_assertions(pytester):
    scenes = _write_scenes(pytester)
    stiff, soft = str(scenes / "stiff.toml"), str(scenes / "soft.toml")
    pytester.makepyfile(f"""
        import pytest
        from ecam.app.pytest_plugin import (assert_check, assert_margin, assert_passes,
                                            run_scene)

        def test_stiff(run_scene):  # the fixture: the run goes into --ecam-html
            report = run_scene({stiff!r}, cycles=200)
            assert report.cycles == 200
            assert_passes(report)
            assert_check(report, "tracking_error")
            assert_margin(report, "following_error", share=0.5)
            with pytest.raises(KeyError, match="has no check 'nope'; its checks: following"):
                assert_check(report, "nope")

        def test_soft():  # the function: the same run, not recorded
            assert_passes(run_scene({soft!r}, master_periods=0.25))

        def test_soft_check():
            assert_check(run_scene({soft!r}, cycles=100), "wind_up")

        def test_margin():
            assert_margin(run_scene({stiff!r}, cycles=100), share=0.01)

        def test_bad_duration(run_scene):
            run_scene({stiff!r}, cycles=10, seconds=1.0)
        """)
    result = pytester.runpytest(*_plugin_args(), "-ra", "-vv", "--ecam-html=report.html")
    result.assert_outcomes(passed=1, failed=4)
    result.stdout.fnmatch_lines([
        "*SceneFailure: FAIL  tracking_error: * in, limit 0.002 in (exceeded by *",
        "*FAIL  wind_up: * deg, limit 0.05 deg (exceeded by *",
        "*Captured stdout call*",
        "scene soft_coupling: FAILED after 100 cycles (tracking_error, wind_up failed)",
    ])
    result.stdout.fnmatch_lines([
        "FAILED test_run_scene_fixture_and_assertions.py::test_soft_check - AssertionError: "
        "FAIL  wind_up: * deg, limit 0.05 deg (exceeded by *",
        "FAILED *::test_margin - AssertionError: PASS  *: *",
        "FAILED *::test_bad_duration - *InputError: duration: cycles, seconds given;*",
    ])
    assert re.search(r"uses [\d.]+ % of its limit, more than the 1 % allowed",
                     result.stdout.str())
    page = (pytester.path / "report.html").read_text()
    # The fixture's runs, as run: the shortened duration is in the fields table.
    assert page.count("<code>duration.cycles</code></td><td>200</td>") == 1
    assert "FAILED: 1 of 2 scenes passed, 1 could not run" in page


# ------------------------------------------------------------------------------------------
# The command line

@pytest.mark.slow
def test_ecam_sim_several_scenes_writes_junit_and_html(tmp_path, scene_dir, broken):
    junit, page = tmp_path / "r.xml", tmp_path / "r.html"
    bad = broken[0][2][0]
    # A directory and a file, one of the three scenes broken: every scene still runs and is
    # reported, and the exit status is 2 (1 when a check fails, 0 when all pass:
    # exit_status above).
    run = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(scene_dir), str(bad),
                          "--junit", str(junit), "--html", str(page)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    # the summary, then where the reports went (issue 26: several scenes say where they wrote)
    lines = [line for line in run.stdout.splitlines() if line.strip()]
    assert lines[-3:] == ["1 of 3 scenes passed, 1 could not run", f"wrote {junit}",
                          f"wrote {page}"]
    progress = [line for line in run.stderr.splitlines() if line.startswith("[")]
    assert len(progress) == 3 and sum(" ERROR " in line for line in progress) == 1
    suites = ET.parse(junit).getroot()
    assert [s.get("name") for s in suites.iter("testsuite")] == ["a_stiff", "b_soft",
                                                                  "bad_field"]
    assert (suites.get("tests"), suites.get("errors")) == (
        str(sum(len(r.checks) for _, r, _ in broken[0][:2]) + 1), "1")
    assert int(suites.get("failures")) >= 2
    text = page.read_text()
    assert text.startswith("<!DOCTYPE html>") and "could not run (CamFileError)" in text
    one = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(SCENES), "--json"],
                         capture_output=True, text=True, timeout=60)
    assert one.returncode == 2 and len(one.stderr.strip().splitlines()) == 1


def test_ecam_sim_several_scenes_takes_fidelity_and_timing(tmp_path, scene_dir, capsys):
    # --fidelity and --timing were silently dropped once a run had JUnit, HTML or several
    # scenes: the scene's own fidelity ran. They apply to every scene of the call.
    from ecam.app.cli import main

    junit, page = tmp_path / "r.xml", tmp_path / "r.html"
    status = main(["sim", str(scene_dir / "a_stiff.toml"), "--fidelity", "full", "--timing",
                   "--junit", str(junit), "--html", str(page)])
    assert status == 0, capsys.readouterr().err
    out = ET.parse(junit).getroot().find("testsuite").find("system-out").text
    assert "\nfidelity full" in out and "ideal" not in out
    assert "Run time (not part of the verdict): " in page.read_text()
    assert [r.to_dict()["fidelity"] for _, r, _ in
            run_scenes([scene_dir / "a_stiff.toml"], fidelity="full")] == ["full"]
    with pytest.raises(InputError, match="fidelity: 'most' should be one of auto, full, ideal"):
        run_scenes([scene_dir], fidelity="most")
