"""pytest plugin: scene files as tests, and helpers to run scenes from Python tests.

Installed with the package (entry point group ``pytest11``, name ``ecam``), so pytest loads it
in every run, where it does nothing unless asked (an option on the command line, or the
``ecam_scenes`` ini setting):

``pytest --ecam-scenes DIR`` (or ``ecam_scenes = DIR ...`` in ``pytest.ini`` / ``[tool.pytest.ini_options]``)
    Every scene file under ``DIR`` (recursively: ``*.toml`` files with a scene section such
    as ``[master]`` or ``[limits]``, see :func:`ecam.app.multi.is_scene_file`; cam files in the
    same directory are skipped) becomes **one test item per scene**, named
    ``DIR/<file>.toml::<file stem>``. The item runs the scene on the rig; it fails when any
    check fails, and its failure message is the failed checks' lines (value, limit, by how
    much, where: :meth:`hil_sim.report.Check.line`), one per line, first failure first, so the
    one-line summary of ``pytest -ra`` and the ``failure`` message of ``--junitxml`` both name
    the check. A scene file with a bad field fails its item with the one-line error. The whole
    text report is attached to the item (``pytest -rA`` shows it for passing scenes too).
    One item per scene rather than per check: the checks are only known once the scene has
    run, and a scene runs once however many checks it has (per-check results are in
    ``ecam sim --junit``). A machine file (``[[axis]]``) is one item per axis,
    ``<file>.toml::<axis>``, and one for its own checks, ``<file>.toml::machine``; it runs
    once (:mod:`ecam.app.pytest_machine`). The option may be given several times; ini paths are relative to
    the ini file's directory.

``pytest --ecam-html FILE``
    Also write one self-contained HTML report (:func:`ecam.app.html_report.html_report`) of
    the scenes the session ran: the scene items, and the scenes run through the ``run_scene``
    fixture (shown as run, with a shortened duration where one was given).

For Python tests::

    from ecam.app.pytest_plugin import assert_check, assert_margin, assert_passes, run_scene

    def test_knife_at_120_rpm():
        report = run_scene("scenes/knife.toml", master_periods=1.0)
        assert_passes(report)          # prints every check line; fails with the failed ones
        assert_margin(report, "wind_up", share=0.5)   # at most half of its limit

or the ``run_scene`` fixture, which does the same and adds the run to ``--ecam-html``.

For robustness sweeps (``ecam sweep``, :mod:`ecam.app.sweep`)::

    summary = run_sweep("scenes/knife_sweep.toml", workers=2, directory=tmp_path)
    assert_yield(summary, "coupling_peak_torque", 0.99)   # 99 % of the machines built pass it

Only :mod:`pytest` is imported at module level: the plugin is loaded into every pytest
process, so the rig (the CAN stack, matplotlib) is imported only when a scene runs. Loading
the module imports the ``ecam`` package above it, and with it numpy (about 0.07 s).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

__all__ = ["run_scene", "scene_for_run", "assert_passes", "assert_check", "assert_margin",
           "assert_yield", "SceneFailure"]

_RESULTS = pytest.StashKey[list]()
_DIRS = pytest.StashKey[list]()
_WROTE = pytest.StashKey[str]()


class SceneFailure(AssertionError):
    """A scene ran and at least one of its checks failed; the message is the check lines."""

    def __init__(self, report) -> None:
        self.report = report
        lines = [c.line() for c in report.failed]
        lines.append(f"scene {report.scene}: {len(report.failed)} of {len(report.checks)} "
                     f"checks failed ({report.model_reason.rstrip('.')})")
        super().__init__("\n".join(lines))


def scene_for_run(scene, *, cycles: int | None = None, seconds: float | None = None,
                  master_periods: float | None = None):
    """The :class:`~hil_sim.scene.Scene` that :func:`run_scene` runs: ``scene`` loaded (if a
    path) with its duration replaced when one is given (see :func:`run_scene`)."""
    from dataclasses import replace

    from ecam.errors import InputError
    from hil_sim.scene import DurationSpec, Scene, load_scene

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    given = {k: v for k, v in (("cycles", cycles), ("seconds", seconds),
                                ("master_periods", master_periods)) if v is not None}
    if len(given) > 1:
        raise InputError(f"duration: {', '.join(given)} given; expected at most one of "
                         "cycles, seconds, master_periods")
    if given:
        (key, value), = given.items()
        if key == "cycles":
            valid = isinstance(value, int) and not isinstance(value, bool) and value >= 1
        else:
            valid = isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0
        if not valid:
            raise InputError(f"{key}: {value!r} should be "
                             f"{'an integer >= 1' if key == 'cycles' else 'a number > 0'}")
        scene = replace(scene, duration=DurationSpec(**given))
    return scene


def run_scene(scene, *, cycles: int | None = None, seconds: float | None = None,
              master_periods: float | None = None):
    """Run a scene on the rig and return its :class:`~hil_sim.report.Report`.

    Parameters
    ----------
    scene : str, Path or hil_sim.scene.Scene
        A scene file, or a scene already loaded.
    cycles, seconds, master_periods : optional
        At most one: run for this long instead of the scene's ``[duration]`` (a shorter run
        keeps a unit test fast).

    Raises
    ------
    ecam.errors.EcamError
        A bad scene file or duration, or a run the rig cannot do.
    """
    from hil_sim.rig import run_scene as rig_run_scene

    return rig_run_scene(scene_for_run(scene, cycles=cycles, seconds=seconds,
                                       master_periods=master_periods))


def assert_passes(report) -> None:
    """Print every check line of ``report``; raise :class:`SceneFailure` if any check failed.

    The printed text is the report's text (:meth:`hil_sim.report.Report.to_text`); pytest
    shows it beside a failure. The failure message is the failed checks' lines.
    """
    __tracebackhide__ = True
    print(report.to_text(), end="")
    if not report.passed:
        raise SceneFailure(report)


def assert_check(report, name: str) -> None:
    """Fail, with the check's line as the message, unless the check ``name`` passed.

    Raises
    ------
    KeyError
        The report has no check of that name (the message lists the names it has).
    """
    __tracebackhide__ = True
    check = _named_check(report, name)
    if not check.passed:
        raise AssertionError(f"{check.line()}\nscene {report.scene}: {report.model_reason}")


def assert_margin(report, name: str | None = None, share: float = 0.8) -> None:
    """Fail unless the check ``name`` (every check with a limit, when None) uses at most
    ``share`` of its limit: a margin kept, so that a change which eats most of it shows up
    before the check fails. The message is each offending check's line and its share.

    Raises
    ------
    KeyError
        ``name`` is not a check of the report.
    ValueError
        ``share`` not in (0, 1].
    """
    __tracebackhide__ = True
    if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 < share <= 1:
        from ecam.errors import InputError

        raise InputError(f"share: {share!r} should be a number in (0, 1]")
    checks = [_named_check(report, name)] if name is not None else \
        [c for c in report.checks if c.limit is not None]
    lines = []
    for check in checks:
        if check.limit is None:
            continue
        used = check.ratio
        if used is None:  # a zero limit or no value: the verdict is the margin
            if not check.passed:
                lines.append(check.line())
            continue
        if used > share:
            lines.append(f"{check.line()}\n  uses {100 * used:.3g} % of its limit, more than "
                         f"the {100 * share:.3g} % allowed")
    if lines:
        raise AssertionError("\n".join(lines) + f"\nscene {report.scene}: {report.model_reason}")


def assert_yield(report, check: str | None = None, at_least: float = 0.95, *,
                 confident: bool = False) -> None:
    """Fail unless a sweep's yield reaches ``at_least``: the share of its samples that passed
    ``check`` (every check, when None) at its first judged speed.

    Parameters
    ----------
    report : dict
        A sweep summary (:func:`ecam.app.sweep.run_sweep`, or ``ecam sweep --json``).
    check : str, optional
        A check name; None for the whole verdict (``yield``).
    at_least : float
        The required yield, in (0, 1].
    confident : bool
        Require the lower end of the Wilson interval to reach ``at_least``, not the observed
        share alone.

    Raises
    ------
    AssertionError
        The yield is lower: the message gives it, its interval and the worst sample.
    KeyError
        ``check`` is not a check of the sweep.
    """
    __tracebackhide__ = True
    from ecam.errors import InputError
    from ecam.statistics import wilson_interval

    if isinstance(at_least, bool) or not isinstance(at_least, (int, float)) or not 0 < at_least <= 1:
        raise InputError(f"at_least: {at_least!r} should be a number in (0, 1]")
    samples = report["samples"]
    if check is None:
        passed, worst, what = report["passed"], report.get("worst_sample"), "every check"
    else:
        entry = next((c for c in report["checks"] if c["name"] == check), None)
        if entry is None:
            raise KeyError(f"sweep {report['scene']} has no check {check!r}; its checks: "
                           f"{', '.join(c['name'] for c in report['checks'])}")
        # samples that could not run count as failures of every check
        passed, worst, what = samples - entry["failures"] - report["errors"], entry["worst"], check
    if samples == 0:
        raise AssertionError(f"sweep {report['scene']}: no sample ran")
    low, high = wilson_interval(passed, samples, report.get("confidence", 0.95))
    observed = passed / samples
    if (low if confident else observed) < at_least:
        raise AssertionError(
            f"sweep {report['scene']}: yield of {what} {100 * observed:.3g} % ({passed} of "
            f"{samples}; Wilson interval {100 * low:.3g} .. {100 * high:.3g} %) is below "
            f"{100 * at_least:.3g} %" + ("" if not confident else " with confidence")
            + ("" if worst is None else f"; worst sample #{worst['index']}: {worst.get('values')}"))


def _named_check(report, name: str):
    try:
        return report.check(name)
    except KeyError:
        raise KeyError(f"scene {report.scene} has no check {name!r}; its checks: "
                       f"{', '.join(c.name for c in report.checks)}") from None


# ------------------------------------------------------------------------------------------
# Hooks

def pytest_addoption(parser) -> None:
    group = parser.getgroup("ecam", "ecam software-in-the-loop scenes")
    group.addoption("--ecam-scenes", action="append", default=[], metavar="DIR",
                    help="run every scene file (*.toml with scene sections) under DIR as a "
                         "test item; may be given several times")
    group.addoption("--ecam-html", default=None, metavar="FILE",
                    help="write one self-contained HTML report of the scenes run")
    parser.addini("ecam_scenes", type="paths", default=[],
                  help="directories whose scene files run as test items, as --ecam-scenes "
                       "(relative to the ini file)")


def pytest_configure(config) -> None:
    config.stash[_RESULTS] = []
    dirs = []
    given = [("--ecam-scenes", item) for item in config.getoption("ecam_scenes") or []]
    given += [("ini ecam_scenes", item) for item in config.getini("ecam_scenes") or []]
    for source, item in given:
        path = Path(item)
        if not path.is_dir():
            raise pytest.UsageError(f"{source}: {str(item)!r} should be a directory")
        if path.resolve() not in dirs:
            dirs.append(path.resolve())
    config.stash[_DIRS] = dirs
    html = config.getoption("ecam_html")
    if html and not Path(html).resolve().parent.is_dir():
        raise pytest.UsageError(f"--ecam-html: directory of {html!r} does not exist")
    # Collect the directories even when they are outside the paths given to pytest (or its
    # testpaths); pytest drops a file it reaches twice.
    for path in dirs:
        if str(path) not in config.args:
            config.args.append(str(path))


def pytest_report_header(config):
    dirs = config.stash.get(_DIRS, [])
    if dirs:
        return "ecam scenes: " + ", ".join(str(d) for d in dirs)
    return None


def pytest_collect_file(file_path: Path, parent):
    dirs = parent.config.stash.get(_DIRS, [])
    if not dirs or file_path.suffix != ".toml":
        return None
    resolved = file_path.resolve()
    if not any(resolved.is_relative_to(d) for d in dirs):
        return None
    from ecam.app.multi import is_scene_file

    if not is_scene_file(resolved):
        return None
    from ecam.camfile import read_toml
    from ecam.errors import CamFileError
    from hil_sim.machine import is_machine_data

    try:
        machine = is_machine_data(read_toml(resolved, "scene file"))
    except CamFileError:  # a broken file: its scene item fails with the error
        machine = False
    if machine:  # an item per axis and one for the machine (ecam.app.pytest_machine)
        from ecam.app.pytest_machine import machine_file

        return machine_file(parent, file_path, _RESULTS)
    return SceneFile.from_parent(parent, path=file_path)


class SceneFile(pytest.File):
    """A scene file: one item, run when the session runs it (collection runs nothing)."""

    def collect(self):
        yield SceneItem.from_parent(self, name=self.path.stem)


class SceneItem(pytest.Item):
    """One scene on the rig; fails with the failed checks' lines."""

    def runtest(self) -> None:
        from ecam.errors import EcamError

        start = time.perf_counter()
        try:
            report = run_scene(self.path)
        except EcamError as exc:
            self.config.stash[_RESULTS].append((self.path, exc, time.perf_counter() - start))
            raise
        self.config.stash[_RESULTS].append((self.path, report, time.perf_counter() - start))
        # No user_properties: pytest writes them as <properties> inside <testcase>, which
        # junit-10.xsd (what Jenkins' xUnit plugin validates against) does not allow.
        self.add_report_section("call", "ecam report", report.to_text())
        if not report.passed:
            raise SceneFailure(report)

    def repr_failure(self, excinfo, style=None):
        from ecam.errors import EcamError

        if isinstance(excinfo.value, (SceneFailure, EcamError)):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style=style)

    def reportinfo(self):
        return self.path, None, f"scene {self.name}"


@pytest.fixture(name="run_scene")
def run_scene_fixture(request):
    """:func:`run_scene`, with the run added to the ``--ecam-html`` report."""

    from ecam.errors import EcamError
    from hil_sim.rig import run_scene as rig_run_scene

    def run(scene, **duration):
        start = time.perf_counter()
        results = request.config.stash[_RESULTS]
        try:
            # The scene as run: its duration replaced, if given, so the report shows that.
            ran = scene_for_run(scene, **duration) if duration else scene
            report = rig_run_scene(ran)
        except EcamError as exc:
            results.append((scene, exc, time.perf_counter() - start))
            raise
        results.append((ran, report, time.perf_counter() - start))
        return report

    return run


def pytest_sessionfinish(session) -> None:
    target = session.config.getoption("ecam_html")
    if not target:
        return
    from ecam.app.html_report import html_report
    from ecam.atomic_files import write_files

    results = session.config.stash.get(_RESULTS, [])
    try:
        write_files({Path(target): html_report(results, title="ecam scenes (pytest)")})
    except OSError as exc:  # one line at the end of the run, not an internal error
        session.config.stash[_WROTE] = (f"--ecam-html {target}: cannot be written: "
                                        f"{exc.strerror or exc}")
        session.exitstatus = pytest.ExitCode.USAGE_ERROR
        return
    session.config.stash[_WROTE] = (f"ecam: HTML report of {len(results)} scene run"
                                    f"{'s' if len(results) != 1 else ''}: {target}")


def pytest_terminal_summary(terminalreporter, config) -> None:
    line = config.stash.get(_WROTE, None)
    if line:
        terminalreporter.write_line(line)
