"""The HTML page of a machine run (`ecam sim MACHINE.toml --html FILE`): the machine first (its
verdict, its own checks, the bus with its sizing, the stations, the plot of every axis's
tracking over the virtual master's position), then each axis as a scene section of
:func:`ecam.app.html_report.html_report` below it."""

from __future__ import annotations

import base64
from types import SimpleNamespace

from hil_sim.machine_report import sizing_text

from .html_report import _anchor, _checks_table, _e, _num, html_report


def machine_html(report, machine=None, seconds: float = 0.0, timing: bool = False) -> str:
    """The page of a :class:`hil_sim.machine_report.MachineReport`.

    Parameters
    ----------
    report : MachineReport
    machine : hil_sim.machine.Machine, optional
        The machine as run: its description, and each axis's fields as run in its section.
    seconds : float
        The run's wall time (shown with ``timing``).
    timing : bool
        Show wall times (the page is then no longer the same bytes run to run).
    """
    description = getattr(machine, "description", "")
    scenes = {a.name: a for a in getattr(machine, "axes", ())}
    failed = report.failed
    headline = (f"{'PASSED' if report.passed else 'FAILED'}: machine {report.machine}, "
                f"{sum(a.passed for a in report.axes)} of {len(report.axes)} axes passed"
                + ("" if all(c.passed for c in report.machine_checks)
                   else "; the machine's own checks failed"))
    results = [(scenes.get(a.scene, a.scene), a, seconds) for a in report.axes]
    return html_report(results, title=f"ecam machine report: {report.machine}", timing=timing,
                       lead=(report.passed, headline, _machine_section(report, description,
                                                                       failed)))


def _machine_section(report, description: str, failed) -> str:
    state = "pass" if report.passed else "fail"
    parts = [f'<section class="scene" id="machine">',
             f'<h2><span class="badge {state}">{state.upper()}</span>machine '
             f"{_e(report.machine)}</h2>"]
    if description:
        parts.append(f'<p class="desc">{_e(description)}</p>')
    summary = report.summary
    parts.append(f'<p class="desc">{report.cycles} cycles of {_num(summary.get("cycle_s"))} s, '
                 f"{len(report.axes)} axes from one virtual master on one bus "
                 f"({_e(summary.get('path'))})</p>")
    if failed:
        parts.append('<div class="failed-lines mono">' + "\n".join(_e(c.line()) for c in failed)
                     + "</div>")
    parts.append("<h3>The machine's checks</h3>"
                 + _checks_table(SimpleNamespace(checks=report.machine_checks)))
    parts.append("<h3>Stations</h3>" + _stations(report))
    parts.append("<h3>Bus</h3>" + _bus(summary.get("bus") or {}, summary.get("cycle_s")))
    parts.append("<h3>Tracking of every axis over the virtual master</h3>" + _plot(report))
    parts.append("</section>")
    return "\n".join(parts)


def _stations(report) -> str:
    rows = []
    for axis in report.axes:
        state = "pass" if axis.passed else "fail"
        worst = ", ".join(c.name for c in axis.failed) or "\u2013"
        rows.append(f'<tr class="{state}"><td><span class="badge {state}">{state.upper()}'
                    f'</span></td><td><a href="#{_anchor(axis.scene)}">{_e(axis.scene)}</a></td>'
                    f'<td class="num">{_e(axis.summary.get("node_id"))}</td>'
                    f"<td>{_e(axis.summary.get('cam_mode'))}</td>"
                    f'<td class="num">{_e(_num(axis.summary.get("phase", 0.0)))}</td>'
                    f"<td>{_e(axis.model)}</td><td>{_e(worst)}</td></tr>")
    return ('<table class="overview"><thead><tr><th></th><th>axis</th><th class="num">node</th>'
            '<th>cam</th><th class="num">phase</th><th>model</th><th>failed checks</th></tr>'
            "</thead><tbody>" + "".join(rows) + "</tbody></table>")


def _bus(bus: dict, cycle_s) -> str:
    if not bus.get("measured"):
        return (f'<p class="note">Bus-free run: no bus load measured '
                f"({_e(_num(bus.get('bitrate')))} bit/s).</p>")
    parts = [f"<p>{_e(_num(bus['bitrate']))} bit/s, busiest cycle {_e(_num(bus['peak_bits']))} "
             f"of {_e(_num(bus['budget_bits']))} bits ({_e(_num(bus['peak_percent']))} %), mean "
             f"{_e(_num(bus['mean_percent']))} %; {_e(bus['overrun_cycles'])} of "
             f"{_e(bus['cycles'])} cycles over the budget.</p>"]
    late = bus.get("late") or {}
    if late:
        rows = "".join(f'<tr><td>{_e(name)}</td><td class="num">{_e(v["late_set_points"])}</td>'
                       f'<td class="num">{_e(v["late_tpdos"])}</td>'
                       f'<td class="num">{_e(_num(v["first_late_cycle"]))}</td></tr>'
                       for name, v in late.items())
        parts.append('<table class="overview"><thead><tr><th>axis</th><th class="num">late set '
                     'points</th><th class="num">late TPDOs</th><th class="num">first late '
                     f"cycle</th></tr></thead><tbody>{rows}</tbody></table>")
    sizing = bus.get("sizing")
    if sizing:
        parts.append(f"<p>{_e(sizing_text(sizing, cycle_s, bus['bitrate']))}</p>")
    return "".join(parts)


def _plot(report) -> str:
    from hil_sim.rig.machine_plot import machine_figure_bytes

    if not any(len((a.series or {}).get("master_position", ())) for a in report.axes):
        return '<p class="note">No recorded samples to plot.</p>'
    png = base64.b64encode(machine_figure_bytes(report)).decode("ascii")
    return (f'<img class="plot" width="1100" alt="tracking error of every axis of '
            f'{_e(report.machine)}, as a share of its limit, over the virtual master position" '
            f'src="data:image/png;base64,{png}">')


def sim_page(results, timing: bool = False) -> str:
    """The HTML page of `ecam sim`'s results: a machine's own page (:func:`machine_html`) when
    the one result is a machine; else :func:`ecam.app.html_report.html_report`, where a
    machine is a section of its own checks (bus, faults: ``<machine>``) and one per axis
    (``<machine>/<axis>``)."""
    from hil_sim.machine_report import MachineReport

    results = list(results)
    if len(results) == 1 and isinstance(results[0][1], MachineReport):
        scene, report, seconds = results[0]
        return machine_html(report, _machine_of(scene), seconds, timing)
    expanded = []
    for scene, report, seconds in results:
        if not isinstance(report, MachineReport):
            expanded.append((scene, report, seconds))
            continue
        scenes = {a.name: a for a in getattr(_machine_of(scene), "axes", ())}
        expanded.append((report.machine, machine_checks_report(report), seconds))
        expanded += [(_renamed(scenes.get(a.scene), f"{report.machine}/{a.scene}"), a, seconds)
                     for a in report.axes]
    return html_report(expanded, timing=timing)


def machine_checks_report(report):
    """The machine's own checks (bus load, faults) as a report of their own, for a page of
    several scenes and machines."""
    from hil_sim.report import Report

    return Report(scene=report.machine, model="machine", cycles=report.cycles,
                  model_reason=f"the machine's own checks: its {len(report.axes)} axes follow",
                  checks=list(report.machine_checks), summary={"cycle_s": report.summary.get(
                      "cycle_s"), "cam_mode": "each axis's"})


def _renamed(scene, name: str):
    from dataclasses import replace

    return name if scene is None else replace(scene, name=name)


def _machine_of(scene):
    """The Machine a result names: loaded from its file (None when it does not load)."""
    from pathlib import Path

    from ecam.errors import EcamError
    from hil_sim.machine import Machine, load_machine

    if isinstance(scene, Machine):
        return scene
    if isinstance(scene, (str, Path)):
        try:
            return load_machine(scene)
        except (EcamError, OSError):
            return None
    return None
