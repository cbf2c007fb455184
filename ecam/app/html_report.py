"""One self-contained HTML file for rig runs, to keep as a CI artifact and open in a browser.

The file fetches nothing: the style sheet is inline, the plots are PNG images inline as
``data:`` URLs, and there is no script. It reads top to bottom the way a reviewer asks:

1. the verdict: how many scenes passed, and every failed check's line (value, limit, by how
   much, where) or why a scene could not run;
2. a table of the scenes (verdict, model, the check nearest its limit), linking to
3. one section per scene, failed and broken scenes first: every check with its value, limit
   and margin; the plots over the master position (:mod:`hil_sim.rig.plot`: tracking error,
   following error against the window, coupling and motor torque against their limits, the
   periods overlaid and the failing sample marked); the model that ran and why, and the
   effects included or left out and why, where the report lists them; the bus and the
   faults; master, table and mechanics figures; the scene as run (its TOML, and every field
   with the defaults filled in). A scene that could not run shows its error and its file.

The same reports give the same bytes (the PNGs too: fixed size and dpi, no metadata). Wall
times differ from run to run, so they are left out unless asked for (``timing=True``).
"""

from __future__ import annotations

import base64
import html
import math
import os
import re
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np

from ecam.app.multi import scene_labels
from ecam.app.shown_paths import shown_path, shown_text
from ecam.app.sizing_html import sizing_section
from ecam.errors import EcamError

__all__ = ["html_report"]

_CSS = """
:root { --pass: #1a7f37; --pass-bg: #dafbe1; --fail: #cf222e; --fail-bg: #ffebe9;
        --near: #bf8700; --error: #9a6700; --info: #57606a; --line: #d0d7de; --head: #f6f8fa;
        --text: #1f2328; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.45 -apple-system, "Segoe UI", "DejaVu Sans", Helvetica, Arial,
       sans-serif; color: var(--text); background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 18px 28px 40px; }
a { color: #0969da; text-decoration: none; } a:hover { text-decoration: underline; }
.title { color: var(--info); font-size: 13px; margin: 0 0 8px; }
h1 { font-size: 26px; margin: 0 0 4px; }
h2 { font-size: 21px; margin: 0 0 4px; display: flex; align-items: center; gap: 10px; }
h3 { font-size: 16px; margin: 22px 0 8px; padding-bottom: 3px;
     border-bottom: 1px solid var(--line); }
code, pre, .mono { font-family: "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 13px; }
.small { font-size: 12px; }
.verdict { border-radius: 8px; padding: 14px 20px 12px; margin: 0 0 18px; border: 2px solid; }
.verdict.pass { background: var(--pass-bg); border-color: var(--pass); }
.verdict.fail { background: var(--fail-bg); border-color: var(--fail); }
.verdict.pass h1 { color: var(--pass); }
.verdict.fail h1 { color: var(--fail); }
.verdict .counts { margin: 0 0 6px; color: var(--info); }
.verdict ul { margin: 4px 0 0; padding-left: 20px; }
.verdict li { margin: 3px 0; }
.verdict li.mono, .verdict li .mono { font-size: 12.5px; }
.verdict ul ul { list-style: none; padding-left: 4px; margin: 2px 0 4px; }
.badge { display: inline-block; min-width: 52px; text-align: center; font-size: 12px;
         font-weight: 700; letter-spacing: .04em; padding: 2px 8px; border-radius: 10px;
         color: #fff; white-space: nowrap; }
.badge.pass { background: var(--pass); } .badge.fail { background: var(--fail); }
.badge.info { background: var(--info); } .badge.error { background: var(--error); }
table { border-collapse: collapse; width: 100%; margin: 4px 0 8px; }
th, td { text-align: left; padding: 5px 9px; border-bottom: 1px solid var(--line);
         vertical-align: top; }
th { background: var(--head); font-weight: 600; font-size: 13px; }
th.num, td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.fail td { background: var(--fail-bg); }
table.checks td { vertical-align: middle; }
table.effects td { font-size: 13.5px; }
.bar { position: relative; width: 90px; height: 10px; background: #eaeef2; border-radius: 5px;
       display: inline-block; vertical-align: middle; margin-right: 8px; overflow: hidden; }
.bar span { position: absolute; left: 0; top: 0; bottom: 0; border-radius: 5px; }
.bar span.pass { background: var(--pass); } .bar span.fail { background: var(--fail); }
.bar span.near { background: var(--near); }
.margin { white-space: nowrap; }
td.where { min-width: 260px; font-size: 13.5px; }
.scene { border-top: 3px solid var(--line); padding-top: 18px; margin-top: 30px; }
.desc { color: var(--info); margin: 0 0 8px; }
.failed-lines { background: var(--fail-bg); border-left: 4px solid var(--fail); padding: 8px 12px;
                margin: 8px 0; white-space: pre-wrap; }
.bad { color: var(--fail); }
.grid { display: grid; grid-template-columns: 1fr 1fr; gap: 0 28px; }
.kv td { font-size: 13.5px; padding: 3px 8px; }
.kv td:first-child { color: var(--info); width: 45%; }
img.plot { display: block; width: 100%; max-width: 1100px; height: auto;
           border: 1px solid var(--line); border-radius: 4px; }
pre { background: var(--head); border: 1px solid var(--line); border-radius: 6px;
      padding: 10px 12px; overflow: auto; max-height: 420px; margin: 4px 0; }
pre .ln { color: #8c959f; user-select: none; margin-right: 12px; }
pre.whole { max-height: none; }
pre .hl { background: #fff8c5; outline: 1px solid #d4a72c; }
details summary { cursor: pointer; font-weight: 600; margin: 12px 0 6px; }
.note { color: var(--info); font-size: 13px; }
footer { color: var(--info); font-size: 12px; margin-top: 36px; }
@media (max-width: 900px) { .grid { grid-template-columns: 1fr; } }
"""


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _num(value) -> str:
    """A number to 6 significant digits; None as an en dash."""
    if value is None:
        return "\u2013"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "\u2013" if not math.isfinite(value) else f"{float(value):.6g}"
    return str(value)


def _anchor(label: str) -> str:
    return "scene-" + "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in label)


def _margin(check) -> tuple[str, float | None]:
    """(text, bar fraction 0..1) for a check: the share of its limit left (the report's
    margin, 1 - value/limit) and used, or by how much it is exceeded."""
    if check.limit is None:
        return "no limit (information)", None
    if check.value is None:
        return "not measured", None
    ratio = check.ratio
    if ratio is None:  # limit 0: passes only at exactly 0
        return ("at the zero limit" if check.passed else "above the zero limit"), \
            (0.0 if check.passed else 1.0)
    if check.passed:
        return f"{100.0 * (1.0 - ratio):.3g} % left ({100.0 * ratio:.3g} % used)", ratio
    return f"x{ratio:.3g}, {100.0 * (ratio - 1.0):.3g} % over", 1.0


_STANDARD_CHECK_KEYS = {"name", "value", "limit", "passed", "unit", "ratio", "margin",
                        "detail"}


def _check_state(check) -> str:
    if check.limit is None:
        return "info"
    return "pass" if check.passed else "fail"


def _checks_table(report) -> str:
    """Every check: verdict, value, limit, margin (a bar of the limit used) and where."""
    rows = []
    for check in report.checks:
        state = _check_state(check)
        text, fraction = _margin(check)
        bar = ""
        if fraction is not None:
            width = max(0.0, min(fraction, 1.0)) * 100.0
            shade = "near" if state == "pass" and fraction >= 0.8 else state
            bar = (f'<span class="bar"><span class="{shade}" style="width:{width:.1f}%">'
                   f"</span></span>")
        unit = _e(check.unit)
        value_unit = unit if check.value is not None else ""
        limit_unit = unit if check.limit is not None else ""
        # Fields a newer report adds to a check (a window, a location) are shown as they come.
        extra = {k: v for k, v in check.to_dict().items() if k not in _STANDARD_CHECK_KEYS}
        where = _e(check.detail) + "".join(
            f'<br><span class="note">{_e(str(k).replace("_", " "))}: '
            f'{_e(_window(v) if k == "window" and isinstance(v, dict) else _flat(v))}</span>'
            for k, v in extra.items() if v not in (None, "", [], {}))
        rows.append(
            f'<tr class="{state}">'
            f'<td><span class="badge {state}">{state.upper()}</span></td>'
            f"<td><code>{_e(check.name)}</code></td>"
            f'<td class="num">{_e(_num(check.value))} {value_unit}</td>'
            f'<td class="num">{_e(_num(check.limit))} {limit_unit}</td>'
            f'<td class="margin">{bar}{_e(text)}</td>'
            f'<td class="where">{where}</td></tr>')
    return ('<table class="checks"><thead><tr><th></th><th>check</th><th class="num">value</th>'
            '<th class="num">limit</th><th>margin</th><th>where / how</th></tr></thead><tbody>'
            + "".join(rows) + "</tbody></table>")


def _window(window: dict) -> str:
    """A check's window as the text report says it: ``after 1 s and master 330..30``."""
    words, other = [], {}
    for key, value in window.items():
        if key == "after_s":
            words.append(f"after {_num(value)} s")
        elif key == "master" and isinstance(value, (list, tuple)) and len(value) == 2:
            words.append(f"master {_num(value[0])}..{_num(value[1])}")
        else:
            other[key] = value
    return " and ".join(words + ([_flat(other)] if other else []))


def _flat(value) -> str:
    """A nested value as one line: ``a 1, b 2`` for a mapping, ``1, 2`` for a list."""
    if isinstance(value, dict):
        return ", ".join(f"{str(k).replace('_', ' ')} {_flat(v)}" for k, v in value.items()) \
            or "none"
    if isinstance(value, (list, tuple)):
        return ", ".join(_flat(v) for v in value) or "none"
    return _num(value)


#: Label and unit of the report's figures whose names do not say them plainly (the rig works
#: in SI inside: torques in N m); other names ending in a unit (``excitation_hz``) give it up
#: to the value.
_LABELS = {"bitrate": ("bitrate", "bit/s"), "budget_bits": ("budget per cycle", "bits"),
           "peak_bits": ("peak per cycle", "bits"), "peak_percent": ("peak load", "%"),
           "mean_percent": ("mean load", "%"), "seconds_at_bitrate": ("at the bitrate", "s"),
           "coupling_rated_torque": ("coupling rated torque", "N m"),
           "coupling_max_torque": ("coupling max torque", "N m"),
           "motor_torque_limit": ("motor torque limit", "N m"),
           "peak_motor_torque": ("peak motor torque", "N m"),
           # an order of the cam's harmonics, not a frequency: say so beside the number
           "torsional_harmonic": ("torsional mode", "x the cam cycle frequency"),
           "inertia_ratio": ("load/motor inertia ratio", "")}
_SUFFIX_UNITS = (("_hz", "Hz"), ("_percent", "%"), ("_seconds", "s"))


def _label_unit(key: str, units: dict) -> tuple[str, str]:
    """(row label, unit) for a figure: ``excitation_hz`` -> (``excitation``, ``Hz``)."""
    key = str(key)
    if key in units:
        return units[key]
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix) and len(key) > len(suffix):
            return key[:-len(suffix)].replace("_", " "), unit
    return key.replace("_", " "), ""


def _kv_table(data: dict, skip=(), units: dict | None = None) -> str:
    """Name and value rows, numbers with their unit (:data:`_LABELS`, the name's suffix, or
    ``units``: key -> (label, unit), the report's own, such as the master's speed unit)."""
    units = {**_LABELS, **(units or {})}
    rows = []
    for key, value in data.items():
        if key in skip:
            continue
        label, unit = _label_unit(key, units)
        number = isinstance(value, (int, float, np.integer, np.floating)) \
            and not isinstance(value, bool)
        text = _flat(value) + (f" {unit}" if unit and number and _flat(value) != "\u2013"
                               else "")
        rows.append(f"<tr><td>{_e(label)}</td><td>{_e(text)}</td></tr>")
    return f'<table class="kv"><tbody>{"".join(rows)}</tbody></table>'


#: Columns of the effects table, in this order; other keys follow as they come.
_EFFECT_COLUMNS = ("name", "included", "value", "change", "why")


def _effects(data: dict) -> str:
    """The effects the rig included or left out, from the report's ``effects`` entry (a list
    of mappings such as ``{name, included, value, why}``, or a mapping by name), under the
    fidelity that chose them and its proof (``fidelity``, ``fidelity_proof``) when given."""
    effects = data.get("effects")
    head = ""
    if data.get("fidelity") is not None:
        head = f"<p>fidelity <b>{_e(data['fidelity'])}</b>"
        proof = data.get("fidelity_proof")
        # Unset entries (no check moved: ``check`` None) say nothing: left out, as in JUnit.
        proof = {k: v for k, v in proof.items() if v not in (None, "", [], {})} \
            if isinstance(proof, dict) else None
        if proof:
            head += f'<br><span class="note">proof: {_e(_proof_words(proof))}</span>'
        head += "</p>"
    if not effects:
        return head + '<p class="note">This report lists no effects beyond the model above.</p>'
    if isinstance(effects, dict):
        effects = [dict(name=k, **v) if isinstance(v, dict) else {"name": k, "value": v}
                   for k, v in effects.items()]
    effects = [e if isinstance(e, dict) else {"name": e} for e in effects]
    keys = [k for k in _EFFECT_COLUMNS if any(k in e for e in effects)]
    for effect in effects:
        keys += [k for k in effect if k not in keys]
    rows = []
    for effect in effects:
        cells = []
        for key in keys:
            value = effect.get(key)
            if key == "included" and isinstance(value, bool):
                state = "pass" if value else "info"
                cells.append(f'<td><span class="badge {state}">'
                             f'{"included" if value else "left out"}</span></td>')
            elif key == "name":
                cells.append(f"<td><code>{_e(_flat(value))}</code></td>")
            elif key == "change" and isinstance(value, (int, float)) and not isinstance(value, bool):
                # a share of the moved check's limit (hil_sim.rig.fidelity), shown as percent of it
                what = f" of {effect['check']}'s limit" if effect.get("check") else " of a limit"
                cells.append(f"<td>{_e(_num(100.0 * value))} %{_e(what)}</td>")
            else:
                cells.append(f"<td>{_e(_flat(value))}</td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    columns = "".join(f"<th>{_e(k.replace('_', ' '))}</th>" for k in keys)
    return (f'{head}<table class="effects"><thead><tr>{columns}</tr></thead><tbody>'
            f'{"".join(rows)}</tbody></table>')


def _proof_words(proof: dict) -> str:
    """The fidelity proof (:class:`hil_sim.rig.fidelity.Selection` ``proof``) in words: how the
    reduced model's checks compare with the full model's, rather than its keys."""
    words = []
    if "runs" in proof:
        cycles = f" of {proof['cycles']} cycles" if "cycles" in proof else ""
        words.append(f"{proof['runs']} bus-free runs{cycles}")
    if "largest_difference" in proof:
        where = f" ({proof['check']})" if proof.get("check") else ""
        words.append(f"the reduced model's checks within {_num(100.0 * proof['largest_difference'])} "
                     f"% of their limits of the full model's{where}")
    if "same_verdicts" in proof:
        words.append("the same verdicts" if proof["same_verdicts"] else "a verdict differs")
    if "largest_relative" in proof:
        where = f" ({proof['relative_check']})" if proof.get("relative_check") else ""
        words.append(f"every value within {_num(100.0 * proof['largest_relative'])} % of the full "
                     f"model's{where}")
    known = {"runs", "cycles", "largest_difference", "check", "same_verdicts", "largest_relative",
             "relative_check", "within_relative"}
    rest = {k: v for k, v in proof.items() if k not in known}
    if rest:
        words.append(_flat(rest))
    return "; ".join(words)


def _bus_and_faults(data: dict) -> str:
    bus = dict(data.get("bus") or {})
    injected = bus.pop("faults", None)
    download = bus.pop("download", None)
    parts = [_kv_table(bus)]
    if download:
        parts.append("<p><b>table download</b></p>" + _kv_table(download))
    parts.append("<p><b>injected bus faults:</b> "
                 + (_e(_flat(injected)) if injected else "none") + "</p>")
    faults = data.get("faults") or []
    if faults:
        items = "".join(f"<li><code>{_e(f.get('code'))}</code> at {_e(_num(f.get('time_s')))} s"
                        "</li>" for f in faults)
        parts.append(f'<p class="bad"><b>drive faults (EMCY):</b></p><ul>{items}</ul>')
    else:
        parts.append("<p><b>drive faults (EMCY):</b> none</p>")
    if data.get("stopped_early"):
        parts.append(f'<p class="failed-lines">stopped early: {_e(data["stopped_early"])}</p>')
    return "".join(parts)


def _scene_fields(scene, prefix: str = "") -> list[tuple[str, object]]:
    """Flatten a Scene dataclass into (dotted field, value) rows; unset (None) fields and
    empty tuples are left out, as they are in a scene file."""
    rows = []
    for item in fields(scene):
        value = getattr(scene, item.name)
        name = f"{prefix}{item.name}"
        if value is None or value == ():
            continue
        if is_dataclass(value):
            rows += _scene_fields(value, name + ".")
        elif isinstance(value, tuple) and all(isinstance(v, tuple) and len(v) == 2
                                              and isinstance(v[0], str) for v in value):
            # (key, value) pairs: MechanicsSpec.values holds the [mechanics] keys themselves.
            base = prefix if item.name == "values" else name + "."
            rows += [(f"{base}{k}", v) for k, v in value if v is not None]
        else:
            rows.append((name, value))
    return rows


def _toml_listing(path: Path, message: str = "") -> str:
    """The file with line numbers; the lines of the fields an error ``message`` names
    (``bus.bitrat: unknown field``) marked, so a reader sees at once what to fix."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        return f'<p class="note">{_e(path.name)} cannot be read: {_e(exc.strerror or exc)}</p>'
    named = {tuple(field.split(".")) for field in re.findall(r"\b(\w+(?:\.\w+)+):", message)}
    lines = text.splitlines() or [""]
    width = len(str(len(lines)))
    section: tuple = ()
    body = []
    for number, line in enumerate(lines, 1):
        header = re.match(r"\s*\[+\s*([\w.]+)\s*\]+", line)
        if header:
            section = tuple(header.group(1).split("."))
        key = re.match(r"\s*(\w+)\s*=", line)
        marked = key is not None and section + (key.group(1),) in named
        row = f'<span class="ln">{number:>{width}}</span>{_e(line)}'
        body.append(f'<span class="hl">{row}</span>' if marked else row)
    opening = '<pre class="whole">' if message else "<pre>"  # a broken file: all of it
    return opening + "\n".join(body) + "</pre>"


def _loaded(scene):
    """The Scene: ``scene`` itself, or its file loaded; None for a file that does not load
    (its error is on the page) or a bare name."""
    from hil_sim.scene import load_scene

    if is_dataclass(scene):
        return scene
    if isinstance(scene, (str, Path)) and Path(scene).is_file():
        try:
            return load_scene(scene)
        except (EcamError, OSError):
            return None
    return None


def _scene_as_run(scene, error: str = "") -> str:
    """The scene file (TOML, numbered; the fields ``error`` names marked) and every field as
    run with the defaults filled in (collapsed beside the file)."""
    loaded = _loaded(scene)
    path = getattr(loaded, "path", None) if is_dataclass(scene) else \
        Path(scene) if isinstance(scene, (str, Path)) else None
    parts = []
    if path is not None and Path(path).is_file():
        parts.append(f"<details open><summary>Scene file: <code>{_e(shown_path(path))}</code></summary>"
                     f"{_toml_listing(Path(path), error)}</details>")
    elif path is not None:
        parts.append(f'<p class="note">Scene file {_e(shown_path(path))}: not found.</p>')
    if loaded is not None:
        rows = "".join(f"<tr><td><code>{_e(k)}</code></td><td>{_e(_field_value(v))}</td></tr>"
                       for k, v in _scene_fields(loaded))
        # Open when a Scene object was run: it may differ from its file (a test shortened it).
        shown = " open" if is_dataclass(scene) or not parts else ""
        parts.append(f"<details{shown}><summary>Scene as run: every field, defaults filled in"
                     f'</summary><table class="kv fields"><tbody>{rows}</tbody></table>'
                     "</details>")
    return "".join(parts) or f'<p class="note">Scene {_e(shown_text(scene))}: no file to show.</p>'


def _field_value(value) -> str:
    """A scene field's value as the page shows it: a path (the scene's own, its cam file) as
    :func:`~ecam.app.shown_paths.shown_path` shows it, a number as :func:`_num` does."""
    if isinstance(value, Path) or (isinstance(value, str) and os.path.isabs(value)):
        return shown_path(value)
    return _num(value)


def _plots(report) -> str:
    """The report's figure as an inline PNG, or a note when there is nothing to plot."""
    from hil_sim.rig.plot import figure_bytes

    series = report.series or {}
    if "master_position" not in series or not len(series["master_position"]):
        return '<p class="note">No recorded samples to plot.</p>'
    png = base64.b64encode(figure_bytes(report)).decode("ascii")
    return (f'<img class="plot" width="1100" alt="tracking error, following error, coupling '
            f'and motor torque of {_e(report.scene)} over the master position" '
            f'src="data:image/png;base64,{png}">')


def _tuning_section(report) -> str:
    """The drive's commissioning: its tuning (gains, bandwidths, notch, margins on the full
    model) and the Bode plot of the loops as the run has them, the margins marked."""
    from hil_sim.rig.bode import bode_bytes, has_bode

    tuning = (report.summary or {}).get("tuning")
    if not tuning:
        return ""
    keys = ("source", "velocity_bandwidth_hz", "position_bandwidth_hz", "notch_hz",
            "velocity_kp", "velocity_ki", "position_kp", "phase_margin_deg", "gain_margin_db",
            "sensitivity_peak", "meets_limits")
    units = {"velocity_bandwidth_hz": ("velocity loop", "Hz"),
             "position_bandwidth_hz": ("position loop", "Hz"), "notch_hz": ("notch", "Hz"),
             "velocity_kp": ("velocity kp", "N m s/rad"), "velocity_ki": ("velocity ki", "N m/rad"),
             "position_kp": ("position kp", "1/s"), "phase_margin_deg": ("phase margin", "deg"),
             "gain_margin_db": ("gain margin", "dB"), "sensitivity_peak": ("Ms", "")}
    table = _kv_table({k: tuning.get(k) for k in keys}, units=units)
    parts = [f"<h3>Drive tuning ({_e(tuning.get('source'))}, on the full model)</h3>", table]
    if has_bode(report):
        png = base64.b64encode(bode_bytes(report)).decode("ascii")
        parts.append(f'<img class="plot" width="1100" alt="open-loop Bode plot of the velocity '
                     f'and position loops of {_e(report.scene)}, margins marked" '
                     f'src="data:image/png;base64,{png}">')
    return "".join(parts)


def _scene_section(label: str, scene, report, seconds: float, timing: bool) -> str:
    anchor = _anchor(label)
    if isinstance(report, BaseException):
        details = getattr(report, "details", "")
        trace = (f"<details><summary>Traceback</summary><pre>{_e(shown_text(details))}</pre></details>"
                 if details else "")
        return (f'<section class="scene" id="{anchor}"><h2><span class="badge error">ERROR'
                f"</span>{_e(label)}</h2><p class=\"desc\">This scene could not run "
                f"({_e(type(report).__name__)}); the other scenes ran.</p>"
                f'<div class="failed-lines mono">{_e(shown_text(report))}</div>{trace}'
                + _scene_as_run(scene, str(report)) + "</section>")
    data = report.to_dict()
    state = "pass" if report.passed else "fail"
    parts = [f'<section class="scene" id="{anchor}">',
             f'<h2><span class="badge {state}">{state.upper()}</span>{_e(label)}</h2>']
    description = getattr(_loaded(scene), "description", "")
    if description:
        parts.append(f'<p class="desc">{_e(description)}</p>')
    master = data.get("master") or {}
    units = data.get("units") or {}
    parts.append(
        f'<p class="desc">{report.cycles} cycles of {_num(data.get("cycle_s"))} s '
        f'({_num(data.get("simulated_s"))} s simulated, {_num(master.get("periods"))} master '
        f'periods at {_num(master.get("speed"))} {_e(master.get("speed_unit", ""))}); cam '
        f'{_e(data.get("cam_mode"))}-side; model <b>{_e(report.model)}</b></p>')
    if report.failed:
        parts.append('<div class="failed-lines mono">'
                     + "\n".join(_e(c.line()) for c in report.failed) + "</div>")
    parts.append("<h3>Checks</h3>" + _checks_table(report))
    parts.append(sizing_section(data))  # motor, module, gearhead: required against rated
    parts.append(f"<h3>Over the master position [{_e(units.get('master', ''))}]</h3>"
                 + _plots(report))
    parts.append(_tuning_section(report))
    parts.append(f"<h3>Model and effects</h3><p><b>{_e(report.model)}</b>: "
                 f"{_e(report.model_reason)}</p>" + _effects(data))
    # The report's own units: the master's speed and period, the table's error (slave units).
    own_units = {"speed": ("speed", master.get("speed_unit", "")),
                 "period": ("period", units.get("master", "")),
                 "max_error_units": ("max error", units.get("slave", ""))}
    parts.append('<div class="grid"><div><h3>Bus and faults</h3>' + _bus_and_faults(data)
                 + "</div>")
    for key in ("master", "table", "mechanics"):
        if isinstance(data.get(key), dict):
            parts.append(f"<div><h3>{key.capitalize()}</h3>"
                         f"{_kv_table(data[key], ('speed_unit',), own_units)}</div>")
    parts.append("</div>")
    parts.append("<h3>Scene as run</h3>" + _scene_as_run(scene))
    if timing:
        wall = f"{seconds:.3g} s wall"
        if (report.timing or {}).get("real_time_factor"):
            wall += f", real-time factor {report.timing['real_time_factor']:.3g}x"
        parts.append(f'<p class="note">Run time (not part of the verdict): {_e(wall)}.</p>')
    parts.append("</section>")
    return "\n".join(parts)


def _nearest(report) -> str:
    """The failed checks with their ratio, or the passed check nearest its limit."""
    if report.failed:
        return ", ".join(f"{c.name} x{c.ratio:.3g}" if c.ratio is not None else c.name
                         for c in report.failed)
    rated = [c for c in report.checks if c.ratio is not None and c.limit is not None]
    if not rated:
        return "\u2013"
    worst = max(rated, key=lambda c: c.ratio)
    return f"{worst.name} {100.0 * worst.ratio:.3g} % of its limit"


def _overview(labels, results, timing: bool) -> str:
    rows = []
    for label, (scene, report, seconds) in zip(labels, results):
        link = f'<a href="#{_anchor(label)}">{_e(label)}</a>'
        wall = f'<td class="num">{seconds:.2f} s</td>' if timing else ""
        if isinstance(report, BaseException):
            rows.append(f'<tr class="fail"><td><span class="badge error">ERROR</span></td>'
                        f'<td>{link}</td><td>\u2013</td><td class="num">\u2013</td>'
                        f'<td class="mono small">{_e(shown_text(report))}</td>{wall}</tr>')
            continue
        state = "pass" if report.passed else "fail"
        rows.append(f'<tr class="{state}"><td><span class="badge {state}">{state.upper()}</span>'
                    f"</td><td>{link}</td><td>{_e(report.model)}</td>"
                    f'<td class="num">{report.cycles}</td><td>{_e(_nearest(report))}</td>'
                    f"{wall}</tr>")
    head = ('<th></th><th>scene</th><th>model</th><th class="num">cycles</th>'
            "<th>failed checks, or the check nearest its limit</th>"
            + ('<th class="num">wall</th>' if timing else ""))
    return (f'<table class="overview"><thead><tr>{head}</tr></thead><tbody>{"".join(rows)}'
            "</tbody></table>")


def html_report(results, title: str = "ecam rig report", timing: bool = False,
                lead=None) -> str:
    """A self-contained HTML page for rig results.

    Parameters
    ----------
    results : list of (scene, report, seconds)
        ``scene`` is the scene file's path (its TOML is shown), a
        :class:`hil_sim.scene.Scene` (its file, and its fields, are shown) or a name;
        ``report`` a :class:`hil_sim.report.Report` or the exception that kept the scene
        from running; ``seconds`` its wall time. :func:`ecam.app.multi.run_scenes` returns
        this list.
    title : str
    timing : bool
        Show the wall times (then the page is no longer the same bytes run to run).
    lead : (bool, str, str), optional
        A machine's page (:mod:`ecam.app.machine_html`): its verdict and headline stand for the
        page's, its HTML section comes first, and ``results`` are its axes.

    Returns
    -------
    str
        The page (UTF-8 text); no external resources, no script.
    """
    results = list(results)
    labels = scene_labels([scene for scene, _, _ in results])
    errors = sum(1 for _, r, _ in results if isinstance(r, BaseException))
    passed = sum(1 for _, r, _ in results if not isinstance(r, BaseException) and r.passed)
    ok = passed == len(results) and bool(results)
    state = "pass" if ok else "fail"
    headline = (f"{'PASSED' if ok else 'FAILED'}: {passed} of {len(results)} "
                f"scene{'s' if len(results) != 1 else ''} passed"
                + (f", {errors} could not run" if errors else "")) if results \
        else "NO SCENE RAN"
    checks = sum(len(r.checks) for _, r, _ in results if not isinstance(r, BaseException))
    failed_checks = sum(len(r.failed) for _, r, _ in results if not isinstance(r, BaseException))
    lines = []
    for label, (_, report, _) in zip(labels, results):
        link = f'<a href="#{_anchor(label)}">{_e(label)}</a>'
        if isinstance(report, BaseException):
            lines.append(f'<li><b>{link}</b> could not run: <span class="mono">{_e(shown_text(report))}'
                         "</span></li>")
        elif report.failed:
            checks_ = "".join(f'<li class="mono">{_e(c.line())}</li>' for c in report.failed)
            lines.append(f"<li><b>{link}</b><ul>{checks_}</ul></li>")
    failed = (f"<ul>{''.join(lines)}</ul>" if lines
              else "<p>Every check of every scene holds.</p>")
    ran = len(results) - errors
    counts = (f'<p class="counts">{checks} checks in {ran} scene{"s" if ran != 1 else ""}, '
              f"{failed_checks} failed"
              + (f"; {errors} scene{'s' if errors != 1 else ''} could not run" if errors else "")
              + "</p>")
    preface = ""
    if lead is not None:  # a machine: its verdict (bus and faults too) and its section first
        ok, headline, preface = lead
        state = "pass" if ok else "fail"
        if not ok and not lines:
            failed = "<p>Every axis passed; the machine's own checks failed (below).</p>"
    body = [f'<header class="verdict {state}"><h1>{_e(headline)}</h1>{counts}{failed}</header>',
            preface, "<h3>Scenes</h3>", _overview(labels, results, timing)]
    # Broken and failed scenes first (stable otherwise): the first section is what broke.
    order = sorted(range(len(results)), key=lambda i: (
        0 if isinstance(results[i][1], BaseException) else 1 if not results[i][1].passed else 2))
    body += [_scene_section(labels[i], *results[i], timing) for i in order]
    from importlib.metadata import PackageNotFoundError, version

    try:
        made_by = f"ecam {version('ecam')}"
    except PackageNotFoundError:  # a source checkout on sys.path, not installed
        made_by = "ecam"
    body.append(f"<footer>Written by {_e(made_by)}. Self-contained: no network requests, "
                "no script.</footer>")
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{_e(title)}: {_e(headline)}</title>\n<style>{_CSS}</style>\n</head>\n"
            f"<body>\n<main>\n<p class=\"title\">{_e(title)}</p>\n" + "\n".join(body)
            + "\n</main>\n</body>\n</html>\n")
