"""JUnit XML for rig runs: what GitLab, Jenkins and GitHub Actions show as test results.

One ``testsuite`` per scene, one ``testcase`` per check of its report. A failed check carries
a ``failure`` element whose ``message`` and text are the check's one line (value, limit, by
how much, where: :meth:`hil_sim.report.Check.line`); the scene's model and why, its effects,
bus load and faults go into the suite's ``system-out``, and into the failed testcase's too
(GitLab shows a testcase's output, not a suite's, and only for failed tests). A scene that
could not run (a bad scene file, a rig error) is one testcase named ``run`` with an ``error``
element: its message, and for a crash inside the rig the traceback.

The layout follows the JUnit schema Jenkins' xUnit plugin validates against (``junit-10.xsd``;
GitLab and GitHub Actions read the same elements): ``testsuites`` > ``testsuite`` (required
``name``, ``tests``, ``failures``, ``errors``; ``time`` in seconds) > ``testcase`` (``name``,
``classname``) > ``failure``/``error`` (``message``, ``type``, text). Suites are named by
:func:`ecam.app.multi.scene_labels` (distinct, since CI servers key results by name), cases
``ecam.sim.<scene>`` / ``<check>``. The output is deterministic except for the ``time``
attributes; there is no timestamp and no host name.
"""

from __future__ import annotations

import re
from pathlib import Path
from xml.etree import ElementTree as ET

from ecam.app.multi import scene_labels

__all__ = ["junit_xml"]


def _system_out(report) -> str:
    """Model, effects, bus and faults: the context a reader needs beside the check lines."""
    data = report.to_dict()
    lines = [f"scene {report.scene}: {'PASSED' if report.passed else 'FAILED'} after "
             f"{report.cycles} cycles", f"model: {report.model_reason}"]
    effects = data.get("effects")
    if data.get("fidelity") is not None:
        proof = data.get("fidelity_proof")
        lines.append(f"fidelity {data['fidelity']}"
                     + (f"; proof: {_flat(proof)}" if isinstance(proof, dict) and proof else ""))
    if isinstance(effects, list):
        for effect in effects:
            if isinstance(effect, dict):
                state = "included" if effect.get("included") else "left out"
                why = effect.get("why") or effect.get("reason") or ""
                # The value and why say it; the other fields (how much it moves which
                # check, where the value came from) are in the HTML report's table.
                shown = ("value",) if why else tuple(effect)
                rest = ", ".join(_flat(effect[key]) for key in shown
                                 if key not in ("name", "included", "why", "reason")
                                 and effect.get(key) not in (None, ""))
                lines.append(f"effect {effect.get('name', '?')}: {state}"
                             + (f", {rest}" if rest else "") + (f"; {why}" if why else ""))
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


# XML 1.0 (Fifth Edition), section 2.2, production [2] Char: #x9 | #xA | #xD | [#x20-#xD7FF] |
# [#xE000-#xFFFD] | [#x10000-#x10FFFF]. ElementTree writes any other character as it is, and a
# document holding one is not well-formed (a CI server then drops the whole report).
_NOT_XML_CHAR = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _xml_chars(text: str) -> str:
    """``text`` with each character XML 1.0 cannot hold written as its Python escape."""
    return _NOT_XML_CHAR.sub(lambda m: ascii(m.group())[1:-1], text)


def _well_formed(root: ET.Element) -> None:
    """Every attribute and text of the tree within XML 1.0's characters (file names and error
    messages may hold control characters)."""
    for element in root.iter():
        for key, value in element.attrib.items():
            element.set(key, _xml_chars(value))
        if element.text:
            element.text = _xml_chars(element.text)


def _time(seconds) -> str:
    # SUREFIRE_TIME of junit-10.xsd: digits and one dot, no exponent, no sign.
    return f"{max(float(seconds), 0.0):.3f}"


def _scene_file(scene) -> str | None:
    """The scene's file, for the suite's ``file`` attribute."""
    if isinstance(scene, (str, Path)):
        return str(scene)
    path = getattr(scene, "path", None)
    return str(path) if path is not None else None


def junit_xml(results, suites_name: str = "ecam sim") -> str:
    """JUnit XML text for rig results.

    Parameters
    ----------
    results : list of (scene, report, seconds)
        ``scene`` is the scene file's path, a Scene, or a name; ``report`` a
        :class:`hil_sim.report.Report` or the exception that kept the scene from running;
        ``seconds`` the run's wall time. (:func:`ecam.app.multi.run_scenes` returns this list.)
    suites_name : str
        ``name`` of the ``testsuites`` root element.

    Returns
    -------
    str
        The XML document, UTF-8 declared, ending with a newline.
    """
    results = list(results)
    root = ET.Element("testsuites", name=suites_name)
    totals = {"tests": 0, "failures": 0, "errors": 0, "time": 0.0}
    labels = scene_labels([scene for scene, _, _ in results])
    for label, (scene, report, seconds) in zip(labels, results):
        suite = ET.SubElement(root, "testsuite", name=label)
        # Jenkins shows a classname a.b.c as package a.b, class c: keep the label one name.
        classname = "ecam.sim." + label.replace("/", "_").replace(".", "_")
        if isinstance(report, BaseException):
            tests, failures, errors = 1, 0, 1
            case = ET.SubElement(suite, "testcase", name="run", classname=classname)
            error = ET.SubElement(case, "error", message=str(report), type=type(report).__name__)
            details = getattr(report, "details", "")
            error.text = str(report) + (f"\n\n{details}" if details else "")
            out = f"scene {label}: could not run: {report}\n"
        else:
            tests, failures, errors = len(report.checks), len(report.failed), 0
            out = _system_out(report)
            for check in report.checks:
                case = ET.SubElement(suite, "testcase", name=check.name, classname=classname)
                if not check.passed:
                    line = check.line()
                    failure = ET.SubElement(case, "failure", message=line, type="CheckFailed")
                    failure.text = line
                    ET.SubElement(case, "system-out").text = out
        suite.set("tests", str(tests))
        suite.set("failures", str(failures))
        suite.set("errors", str(errors))
        suite.set("skipped", "0")
        suite.set("time", _time(seconds))
        file = _scene_file(scene)
        if file is not None:
            suite.set("file", file)
        ET.SubElement(suite, "system-out").text = out
        totals["tests"] += tests
        totals["failures"] += failures
        totals["errors"] += errors
        totals["time"] += float(seconds)
    root.set("tests", str(totals["tests"]))
    root.set("failures", str(totals["failures"]))
    root.set("errors", str(totals["errors"]))
    root.set("time", _time(totals["time"]))
    _well_formed(root)
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
