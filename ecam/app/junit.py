"""JUnit XML for rig runs: what GitLab, Jenkins and GitHub Actions show as test results.

One ``testsuite`` per scene, one ``testcase`` per check of its report. A failed check carries
a ``failure`` element whose ``message`` is the check's one line (value, limit, by how much,
where: :meth:`hil_sim.report.Check.line`); the scene's model and why, its effects, bus load and
faults go into the suite's ``system-out``. A scene the rig could not run is one testcase with
an ``error`` element.

The layout follows the JUnit schema Jenkins' xUnit plugin validates against (``junit-10.xsd``;
GitLab and GitHub Actions read the same elements): ``testsuites`` > ``testsuite`` (required
``name``, ``tests``, ``failures``, ``errors``; ``time`` in seconds) > ``testcase`` (``name``,
``classname``) > ``failure``/``error`` (``message``, ``type``, text). The output is
deterministic except for the ``time`` attributes; there is no timestamp and no host name.
"""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree as ET

__all__ = ["junit_xml", "scene_label"]


def scene_label(scene) -> str:
    """The suite name of a scene given as a path (its file stem), a Scene, or a name."""
    if isinstance(scene, Path) or (isinstance(scene, str) and scene.endswith(".toml")):
        return Path(scene).stem
    return str(getattr(scene, "name", scene))


def _system_out(report) -> str:
    """Model, effects, bus and faults: the context a reader needs beside the check lines."""
    data = report.to_dict()
    lines = [f"scene {report.scene}: {'PASSED' if report.passed else 'FAILED'} after "
             f"{report.cycles} cycles", f"model: {report.model_reason}"]
    effects = data.get("effects")
    if isinstance(effects, list):
        for effect in effects:
            if isinstance(effect, dict):
                state = "included" if effect.get("included") else "left out"
                why = effect.get("reason") or effect.get("why") or ""
                lines.append(f"effect {effect.get('name', '?')}: {state}"
                             + (f"; {why}" if why else ""))
            else:
                lines.append(f"effect {effect}")
    elif isinstance(effects, dict):
        lines += [f"effect {name}: {value}" for name, value in sorted(effects.items())]
    if data.get("stopped_early"):
        lines.append(f"stopped early: {data['stopped_early']}")
    lines += [c.line() for c in report.checks]
    bus = data.get("bus") or {}
    if bus:
        lines.append(f"bus: {bus.get('bitrate')} bit/s, peak {bus.get('peak_percent')} %, mean "
                     f"{bus.get('mean_percent')} %, {bus.get('overrun_cycles')} cycles over "
                     f"budget, {bus.get('frames')} frames")
        injected = bus.get("faults")
        if injected:
            lines.append(f"injected faults: {_flat(injected)}")
    faults = data.get("faults") or []
    lines.append("faults: " + ("; ".join(f"{f['code']} at {f['time_s']} s" for f in faults)
                               if faults else "none"))
    return "\n".join(lines) + "\n"


def _flat(value) -> str:
    """``dropped rpdo 3, seed 1`` from nested mappings (the fault injector's summary)."""
    if isinstance(value, dict):
        parts = [f"{key} {_flat(item)}" for key, item in sorted(value.items())
                 if item not in (None, {}, [])]
        return ", ".join(parts) if parts else "none"
    return str(value)


def _time(seconds) -> str:
    # SUREFIRE_TIME of junit-10.xsd: digits and one dot, no exponent, no sign.
    return f"{max(float(seconds), 0.0):.3f}"


def junit_xml(results, suites_name: str = "ecam sim") -> str:
    """JUnit XML text for rig results.

    Parameters
    ----------
    results : list of (scene, report, seconds)
        ``scene`` is the scene file's path, a Scene, or a name; ``report`` a
        :class:`hil_sim.report.Report` or the exception a scene's run raised; ``seconds`` the
        run's wall time. (:func:`ecam.app.multi.run_scenes` returns this list.)
    suites_name : str
        ``name`` of the ``testsuites`` root element.

    Returns
    -------
    str
        The XML document, UTF-8 declared, ending with a newline.
    """
    root = ET.Element("testsuites", name=suites_name)
    totals = {"tests": 0, "failures": 0, "errors": 0, "time": 0.0}
    for scene, report, seconds in results:
        label = scene_label(scene)
        suite = ET.SubElement(root, "testsuite", name=label)
        if isinstance(report, BaseException):
            tests, failures, errors = 1, 0, 1
            case = ET.SubElement(suite, "testcase", name="run", classname=f"ecam.sim.{label}")
            error = ET.SubElement(case, "error", message=str(report), type=type(report).__name__)
            error.text = str(report)
            out = f"scene {label}: the rig could not run it: {report}\n"
        else:
            tests, failures, errors = len(report.checks), len(report.failed), 0
            for check in report.checks:
                case = ET.SubElement(suite, "testcase", name=check.name,
                                     classname=f"ecam.sim.{label}")
                if not check.passed:
                    line = check.line()
                    failure = ET.SubElement(case, "failure", message=line, type="CheckFailed")
                    failure.text = line
            out = _system_out(report)
        suite.set("tests", str(tests))
        suite.set("failures", str(failures))
        suite.set("errors", str(errors))
        suite.set("skipped", "0")
        suite.set("time", _time(seconds))
        if isinstance(scene, (str, Path)) and str(scene).endswith(".toml"):
            suite.set("file", str(scene))
        ET.SubElement(suite, "system-out").text = out
        totals["tests"] += tests
        totals["failures"] += failures
        totals["errors"] += errors
        totals["time"] += float(seconds)
    root.set("tests", str(totals["tests"]))
    root.set("failures", str(totals["failures"]))
    root.set("errors", str(totals["errors"]))
    root.set("time", _time(totals["time"]))
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
