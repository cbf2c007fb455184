"""The rig in a user's CI: several scenes per call, JUnit XML, the HTML report (opened in headless
Chromium) and the pytest plugin (tested with pytest's own ``pytester``)."""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
from importlib.metadata import entry_points
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from ecam.app.html_report import html_report
from ecam.app.junit import junit_xml
from ecam.app.multi import exit_status, is_scene_file, run_scenes, scene_files, summary_table
from ecam.errors import CamFileError, InputError, SimulationError

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "hil_sim" / "scenes"
CAMS = ROOT / "firmware_tables" / "cams"
CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists()
                                        else None)


def _short_scene(name: str, cycles: int = 300) -> str:
    """A shipped scene's TOML with its cam path made absolute and a short duration."""
    text = (SCENES / f"{name}.toml").read_text()
    text = re.sub(r'file = "[^"]*/([^/"]+\.toml)"',
                  lambda m: f'file = "{(CAMS / m.group(1)).as_posix()}"', text)
    text = re.sub(r"\[duration\][^\[]*$", f"[duration]\ncycles = {cycles}\n", text, flags=re.S)
    return text


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """A passing and a failing scene (short runs) beside a cam file, which is not a scene."""
    path = tmp_path_factory.mktemp("scenes")
    (path / "a_stiff.toml").write_text(_short_scene("stiff_coupling"))
    (path / "b_soft.toml").write_text(_short_scene("soft_coupling"))
    shutil.copy(CAMS / "combination_drrd.toml", path / "cam.toml")
    return path


@pytest.fixture(scope="module")
def results(scene_dir):
    return run_scenes([scene_dir])


# ------------------------------------------------------------------------------------------
# Several scenes

def test_directory_holds_scenes_and_a_cam_file(scene_dir):
    assert is_scene_file(scene_dir / "a_stiff.toml")
    assert not is_scene_file(scene_dir / "cam.toml")
    assert [p.name for p in scene_files([scene_dir])] == ["a_stiff.toml", "b_soft.toml"]


def test_bad_scene_stops_before_any_run(tmp_path, scene_dir):
    bad = tmp_path / "bad.toml"
    bad.write_text(_short_scene("stiff_coupling").replace("tracking_error = 0.002",
                                                          "tracking_error = -1.0"))
    lines = []
    with pytest.raises(CamFileError, match="limits.tracking_error: -1 should be > 0"):
        run_scenes([scene_dir, bad], progress=lines.append)
    assert lines == []  # nothing ran
    with pytest.raises(InputError, match="does not exist"):
        run_scenes([tmp_path / "missing.toml"])
    with pytest.raises(InputError, match="jobs: 0"):
        run_scenes([scene_dir], jobs=0)


def test_serial_and_parallel_runs_give_the_same_reports(scene_dir, results):
    lines = []
    parallel = run_scenes([scene_dir / "b_soft.toml", scene_dir / "a_stiff.toml",
                           SCENES / "drive_side.toml"], jobs=2, progress=lines.append)
    serial = run_scenes([scene_dir / "b_soft.toml", scene_dir / "a_stiff.toml",
                         SCENES / "drive_side.toml"])
    assert [p for p, _, _ in parallel] == [p for p, _, _ in serial]  # input order kept
    for (_, one, _), (_, other, _) in zip(serial, parallel):
        assert one.to_json() == other.to_json()
    assert len(lines) == 3 and all(re.match(r"\[\d/3\] \S+\.toml: (PASSED|FAILED)", x)
                                   for x in lines)
    assert any("b_soft.toml: FAILED tracking_error x" in x for x in lines)


def test_summary_table_and_exit_status(results):
    (_, stiff, _), (_, soft, _) = results
    assert stiff.passed and not soft.passed  # the premise of the two scenes
    table = summary_table(results)
    rows = table.splitlines()
    assert rows[0].split()[:3] == ["scene", "verdict", "model"]
    assert rows[2].startswith("a_stiff.toml") and " PASS " in rows[2]
    assert rows[3].startswith("b_soft.toml") and " FAIL " in rows[3]
    assert rows[-1] == "1 of 2 scenes passed"
    assert exit_status(results) == 1
    assert exit_status(results[:1]) == 0
    assert exit_status([(results[0][0], SimulationError("bus gone"), 0.1)]) == 1


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
    if "time" in element.attrib:
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
    for suite, (_, report, seconds) in zip(suites, results):
        cases = suite.findall("testcase")
        assert [c.get("name") for c in cases] == [c.name for c in report.checks]
        assert int(suite.get("tests")) == len(cases)
        failures = [c.find("failure") for c in cases if c.find("failure") is not None]
        assert int(suite.get("failures")) == len(failures) == len(report.failed)
        assert suite.get("errors") == "0"
        assert [f.get("message") for f in failures] == [c.line() for c in report.failed]
        assert float(suite.get("time")) == pytest.approx(seconds, abs=1e-3)
        out = suite.find("system-out").text
        assert report.model_reason in out and "bus: " in out and "faults: " in out
    assert int(root.get("tests")) == sum(len(r.checks) for _, r, _ in results)
    assert int(root.get("failures")) == sum(len(r.failed) for _, r, _ in results) > 0
    message = suites[1].find("testcase/failure").get("message")
    assert re.search(r"FAIL  \w+: [-\d.e]+ \S+, limit [\d.e-]+ .*\(exceeded by .* %, x[\d.]+\); "
                     r"\S", message)


def test_junit_deterministic_except_times_and_reports_errors(results):
    again = [(p, r, s + 1.234) for p, r, s in results]
    strip = re.compile(r' time="[^"]*"')
    assert strip.sub("", junit_xml(results)) == strip.sub("", junit_xml(again))
    assert junit_xml(results) != junit_xml(again)  # the times are there
    error = SimulationError("drive did not answer SDO 0x6041")
    root = ET.fromstring(junit_xml(results[:1] + [(Path("c.toml"), error, 0.5)]))
    _validate(root)
    suite = root.findall("testsuite")[1]
    assert (suite.get("tests"), suite.get("errors"), suite.get("failures")) == ("1", "1", "0")
    assert suite.find("testcase/error").get("message") == str(error)
    assert root.get("errors") == "1"


# ------------------------------------------------------------------------------------------
# HTML report

_EXTERNAL = re.compile(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//""", re.I)


def test_html_report_content(results, scene_dir):
    page = html_report(results)
    assert page == html_report(results)  # deterministic (the wall times are the inputs')
    assert not _EXTERNAL.search(page) and "<script" not in page.lower()
    assert "@import" not in page and "url(" not in page
    body = page[page.index("<body>"):]
    # The verdict comes first, with the failed checks' lines.
    first = body.index("FAILED: 1 of 2 scenes passed")
    _, soft, _ = results[1]
    for check in soft.failed:
        assert body.index(_html(check.line())) > first
    assert first < body.index("<h3>Checks</h3>")
    for _, report, _ in results:
        for check in report.checks:
            assert f"<code>{check.name}</code>" in body
        assert _html(report.model_reason) in body
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) == 2
    assert all(base64.b64decode(data)[:8] == b"\x89PNG\r\n\x1a\n" for data in images)
    assert _html((scene_dir / "b_soft.toml").read_text().splitlines()[0]) in body  # the TOML
    assert "% of the limit" in body and "% over" in body


def test_html_report_of_a_scene_object_and_an_error(results):
    from hil_sim.scene import load_scene

    scene = load_scene(SCENES / "stiff_coupling.toml")
    page = html_report([(scene, results[0][1], 0.1),
                        (Path("broken.toml"), SimulationError("no TPDO"), 0.0)])
    assert "<code>mechanics.coupling_stiffness</code>" in page and "2e+06" in page
    assert "ERROR" in page and "no TPDO" in page and "FAILED: 1 of 2" in page


def test_effects_listed_when_the_report_has_them(results):
    from dataclasses import replace

    _, report, seconds = results[1]
    effects = [{"name": "gear_backlash", "included": True,
                "reason": "moves wind_up by 45 % of its limit"},
               {"name": "encoder_resolution", "included": False,
                "reason": "moves no check by more than 2 % of its limit"}]
    with_effects = replace(report, summary={**report.summary, "effects": effects})
    out = ET.fromstring(junit_xml([("s.toml", with_effects, seconds)])).find(
        "testsuite/system-out").text
    assert "effect gear_backlash: included; moves wind_up by 45 % of its limit" in out
    assert "effect encoder_resolution: left out; moves no check" in out
    page = html_report([("s.toml", with_effects, seconds)])
    assert "<td>gear_backlash</td><td>yes</td>" in page
    assert "<td>encoder_resolution</td><td>no</td>" in page
    assert "lists no effects" in html_report(results)


def _html(text: str) -> str:
    import html

    return html.escape(text, quote=True)


def _chromium(page: Path, tmp_path: Path, screenshot: Path) -> tuple[list[str], list[str]]:
    """Open ``page`` in headless Chromium; return (console lines, URLs the page requested
    that are not file: or data:)."""
    netlog = tmp_path / "netlog.json"
    command = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
               "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync",
               f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0",
               f"--log-net-log={netlog}", f"--screenshot={screenshot}",
               "--window-size=1280,2000", page.as_uri()]
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


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (Debian package "
                    "'chromium'; .ci/run installs it)")
def test_html_report_in_headless_chromium(results, tmp_path):
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
    page.write_text(html_report(results), encoding="utf-8")
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
    (scenes / "stiff.toml").write_text(_short_scene("stiff_coupling"))
    (scenes / "soft.toml").write_text(_short_scene("soft_coupling"))
    (scenes / "typo.toml").write_text(_short_scene("stiff_coupling").replace(
        "bitrate = 1000000", "bitrat = 1000000"))
    shutil.copy(CAMS / "modified_sine.toml", scenes / "cam.toml")
    return scenes


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
    cases = {c.get("name"): c for c in ET.parse(pytester.path / "junit.xml").iter("testcase")}
    assert set(cases) == {"stiff", "soft", "typo"}
    message = cases["soft"].find("failure").get("message")
    assert message.startswith("FAIL  tracking_error: ") and "\nFAIL  wind_up: " in message
    assert cases["stiff"].find("failure") is None
    page = (pytester.path / "report.html").read_text()
    assert "FAILED: 1 of 3 scenes passed" in page and "bus.bitrat" in page


def test_plugin_adds_nothing_unless_asked(pytester):
    _write_scenes(pytester)
    result = pytester.runpytest(*_plugin_args())
    assert result.ret == pytest.ExitCode.NO_TESTS_COLLECTED
    assert "ecam scenes" not in result.stdout.str()
    result = pytester.runpytest(*_plugin_args(), "--ecam-scenes", "nowhere")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--ecam-scenes: 'nowhere' should be a directory*"])


def test_run_scene_fixture_and_assert_passes(pytester):
    scenes = _write_scenes(pytester)
    pytester.makepyfile(f"""
        from ecam.app.pytest_plugin import assert_passes

        def test_stiff(run_scene):
            report = run_scene({str(scenes / 'stiff.toml')!r}, cycles=200)
            assert report.cycles == 200
            assert_passes(report)

        def test_soft(run_scene):
            assert_passes(run_scene({str(scenes / 'soft.toml')!r}, master_periods=0.25))

        def test_bad_duration(run_scene):
            run_scene({str(scenes / 'stiff.toml')!r}, cycles=10, seconds=1.0)
        """)
    result = pytester.runpytest(*_plugin_args(), "-ra")
    result.assert_outcomes(passed=1, failed=2)
    result.stdout.fnmatch_lines([
        "*SceneFailure: FAIL  tracking_error: * in, limit 0.002 in (exceeded by *",
        "*FAIL  wind_up: * deg, limit 0.05 deg (exceeded by *",
        "*Captured stdout call*",
        "scene soft_coupling: FAILED after 100 cycles (tracking_error, wind_up failed)",
        "*duration: cycles, seconds given; expected at most one of*",
    ])


def test_ecam_sim_several_scenes_writes_junit_and_html(tmp_path):
    import subprocess
    import sys
    import xml.etree.ElementTree as ET

    scenes = Path(__file__).resolve().parent.parent / "hil_sim" / "scenes"
    junit, html = tmp_path / "r.xml", tmp_path / "r.html"
    run = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(scenes / "stiff_coupling.toml"),
                          str(scenes / "soft_coupling.toml"), "--junit", str(junit), "--html", str(html)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr  # soft_coupling fails: not every scene passed
    assert "1 of 2 scenes passed" in run.stdout
    assert len([line for line in run.stderr.splitlines() if line.startswith("[")]) == 2  # progress
    suites = ET.parse(junit).getroot()
    assert [s.get("name") for s in suites.iter("testsuite")] == ["stiff_coupling", "soft_coupling"]
    assert int(suites.get("failures")) >= 2
    assert html.read_text().lstrip().lower().startswith("<!doctype html>")
    one = subprocess.run([sys.executable, "-m", "ecam.app", "sim", str(scenes), "--json"],
                         capture_output=True, text=True, timeout=60)
    assert one.returncode == 2 and len(one.stderr.strip().splitlines()) == 1
