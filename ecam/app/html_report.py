"""One self-contained HTML file for rig runs, to keep as a CI artifact and open in a browser.

The file fetches nothing: the style sheet is inline, the plots are PNG images inline as
``data:`` URLs, and there is no script. It reads top to bottom the way a reviewer asks:

1. the verdict (how many scenes passed, and the failed checks' lines);
2. a table of the scenes;
3. per scene, failed scenes first: every check with its value, limit and margin; the plots
   (load tracking error, coupling torque against its ratings, following error over the
   master position); the model that ran and why, and the effects (included or left out,
   and why) where the report lists them; the bus and the faults; master, table and
   mechanics figures; the scene as run (its TOML, or a table of its fields when a Scene
   object was run); wall time.

Everything except wall times is deterministic: the same reports give the same bytes.
matplotlib is imported only when plots are drawn (inside :func:`plot_png`), with the Agg
canvas of a bare :class:`matplotlib.figure.Figure` (no pyplot, no global backend switch).
"""

from __future__ import annotations

import base64
import html
import io
import math
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np

from ecam.app.junit import scene_label

__all__ = ["html_report", "plot_png"]

#: Plotted points per curve at most; longer records are reduced to a min/max envelope per
#: bucket, which keeps every peak (the value a check reads) visible.
MAX_PLOT_POINTS = 6000

_CSS = """
:root { --pass: #1a7f37; --pass-bg: #dafbe1; --fail: #cf222e; --fail-bg: #ffebe9;
        --info: #57606a; --line: #d0d7de; --head: #f6f8fa; --text: #1f2328; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.45 -apple-system, "Segoe UI", "DejaVu Sans", Helvetica, Arial,
       sans-serif; color: var(--text); background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 20px 28px 40px; }
h1 { font-size: 26px; margin: 0 0 6px; }
h2 { font-size: 21px; margin: 0 0 4px; display: flex; align-items: center; gap: 10px; }
h3 { font-size: 16px; margin: 22px 0 8px; padding-bottom: 3px;
     border-bottom: 1px solid var(--line); }
code, pre, .mono { font-family: "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 13px; }
.verdict { border-radius: 8px; padding: 16px 20px; margin: 0 0 20px; border: 2px solid; }
.verdict.pass { background: var(--pass-bg); border-color: var(--pass); }
.verdict.fail { background: var(--fail-bg); border-color: var(--fail); }
.verdict h1 { color: inherit; }
.verdict.pass h1 { color: var(--pass); }
.verdict.fail h1 { color: var(--fail); }
.verdict ul { margin: 6px 0 0; padding-left: 20px; }
.verdict li { margin: 2px 0; }
.badge { display: inline-block; min-width: 52px; text-align: center; font-size: 12px;
         font-weight: 700; letter-spacing: .04em; padding: 2px 8px; border-radius: 10px;
         color: #fff; }
.badge.pass { background: var(--pass); } .badge.fail { background: var(--fail); }
.badge.info, .badge.error { background: var(--info); }
.badge.error { background: #9a6700; }
table { border-collapse: collapse; width: 100%; margin: 4px 0 8px; }
th, td { text-align: left; padding: 5px 9px; border-bottom: 1px solid var(--line);
         vertical-align: top; }
th { background: var(--head); font-weight: 600; font-size: 13px; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.fail td { background: var(--fail-bg); }
.bar { position: relative; width: 90px; height: 10px; background: #eaeef2; border-radius: 5px;
       display: inline-block; vertical-align: middle; margin-right: 8px; overflow: hidden; }
.bar span { position: absolute; left: 0; top: 0; bottom: 0; border-radius: 5px; }
.bar span.pass { background: var(--pass); } .bar span.fail { background: var(--fail); }
.margin { white-space: nowrap; }
td.where { min-width: 260px; font-size: 13.5px; }
.scene { border-top: 3px solid var(--line); padding-top: 18px; margin-top: 30px; }
.desc { color: var(--info); margin: 0 0 8px; }
.failed-lines { background: var(--fail-bg); border-left: 4px solid var(--fail); padding: 8px 12px;
                margin: 8px 0; white-space: pre-wrap; }
.grid { display: grid; grid-template-columns: 1fr 1fr; gap: 0 28px; }
.kv td:first-child { color: var(--info); width: 42%; }
img.plot { width: 100%; max-width: 1000px; border: 1px solid var(--line); border-radius: 4px; }
pre { background: var(--head); border: 1px solid var(--line); border-radius: 6px;
      padding: 10px 12px; overflow: auto; max-height: 420px; margin: 4px 0; }
details summary { cursor: pointer; font-weight: 600; margin: 18px 0 6px; }
.note { color: var(--info); font-size: 13px; }
footer { color: var(--info); font-size: 12px; margin-top: 36px; }
@media (max-width: 800px) { .grid { grid-template-columns: 1fr; } }
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
    """(text, bar fraction 0..1) for a check: the share of its limit used, or by how much it
    is exceeded."""
    if check.limit is None:
        return "no limit (information)", None
    if check.value is None:
        return "not measured", None
    ratio = check.ratio
    if ratio is None:  # limit 0: passes only at exactly 0
        return ("at the zero limit" if check.passed else "above the zero limit"), \
            (0.0 if check.passed else 1.0)
    if check.passed:
        return f"{100.0 * ratio:.3g} % of the limit", ratio
    return f"x{ratio:.3g}, {100.0 * (ratio - 1.0):.3g} % over", 1.0


def _checks_table(report) -> str:
    rows = []
    for check in report.checks:
        if check.limit is None:
            state = "info"
        else:
            state = "pass" if check.passed else "fail"
        text, fraction = _margin(check)
        bar = ""
        if fraction is not None:
            width = max(0.0, min(fraction, 1.0)) * 100.0
            bar = (f'<span class="bar"><span class="{state}" style="width:{width:.1f}%">'
                   f"</span></span>")
        unit = _e(check.unit)
        value_unit = unit if check.value is not None else ""
        limit_unit = unit if check.limit is not None else ""
        rows.append(
            f'<tr class="{state}" title="{_e(check.line())}">'
            f'<td><span class="badge {state}">{state.upper()}</span></td>'
            f"<td><code>{_e(check.name)}</code></td>"
            f'<td class="num">{_e(_num(check.value))} {value_unit}</td>'
            f'<td class="num">{_e(_num(check.limit))} {limit_unit}</td>'
            f'<td class="margin">{bar}{_e(text)}</td>'
            f'<td class="where">{_e(check.detail)}</td></tr>')
    return ('<table class="checks"><thead><tr><th></th><th>check</th><th>value</th>'
            "<th>limit</th><th>margin</th><th>where / how</th></tr></thead><tbody>"
            + "".join(rows) + "</tbody></table>")


def _kv_table(data: dict, skip=()) -> str:
    rows = []
    for key, value in data.items():
        if key in skip:
            continue
        if isinstance(value, dict):
            value = ", ".join(f"{k} {_num(v)}" for k, v in value.items()) or "none"
        elif isinstance(value, (list, tuple)):
            value = ", ".join(_num(v) for v in value) or "none"
        rows.append(f"<tr><td>{_e(str(key).replace('_', ' '))}</td><td>{_e(_num(value))}</td></tr>")
    return '<table class="kv"><tbody>' + "".join(rows) + "</tbody></table>"


def _effects(data: dict) -> str:
    """The effects the rig included or left out, from the report's ``effects`` entry."""
    effects = data.get("effects")
    if not effects:
        return ('<p class="note">This report lists no effects beyond the model above.</p>')
    if isinstance(effects, dict):
        effects = [dict(name=k, **v) if isinstance(v, dict) else {"name": k, "value": v}
                   for k, v in effects.items()]
    keys: list[str] = []
    for effect in effects:
        if isinstance(effect, dict):
            keys += [k for k in effect if k not in keys]
    rows = []
    for effect in effects:
        effect = effect if isinstance(effect, dict) else {"name": effect}
        rows.append("<tr>" + "".join(f"<td>{_e(_num(effect.get(k)))}</td>" for k in keys)
                    + "</tr>")
    head = "".join(f"<th>{_e(k.replace('_', ' '))}</th>" for k in keys)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def _bus_and_faults(data: dict) -> str:
    bus = dict(data.get("bus") or {})
    injected = bus.pop("faults", None)
    download = bus.pop("download", None)
    parts = [_kv_table(bus)]
    if download:
        parts.append("<p><b>table download</b></p>" + _kv_table(download))
    if injected:
        parts.append("<p><b>injected faults</b></p>" + _kv_table(injected))
    faults = data.get("faults") or []
    if faults:
        items = "".join(f"<li><code>{_e(f.get('code'))}</code> at {_e(_num(f.get('time_s')))} s"
                        "</li>" for f in faults)
        parts.append(f"<p><b>drive faults (EMCY)</b></p><ul>{items}</ul>")
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


def _scene_as_run(scene) -> str:
    if is_dataclass(scene):
        rows = "".join(f"<tr><td><code>{_e(k)}</code></td><td>{_e(_num(v))}</td></tr>"
                       for k, v in _scene_fields(scene))
        return ('<details open><summary>Scene as run (fields)</summary><table class="kv">'
                f"<tbody>{rows}</tbody></table></details>")
    if isinstance(scene, (str, Path)) and Path(scene).is_file():
        try:
            text = Path(scene).read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            text = f"(cannot be read: {exc})"
        return (f"<details open><summary>Scene as run: <code>{_e(Path(scene).name)}</code>"
                f"</summary><pre>{_e(text)}</pre></details>")
    return f'<p class="note">Scene {_e(scene)}: no file to show.</p>'


def _envelope(x: np.ndarray, *ys: np.ndarray, limit: int = MAX_PLOT_POINTS):
    """Reduce long records to at most about ``limit`` points, keeping each bucket's min and
    max of the first y (so the peaks a check reads stay in the plot)."""
    n = x.size
    if n <= limit:
        return (x, *ys)
    buckets = limit // 2
    edges = np.linspace(0, n, buckets + 1).astype(int)
    keep = []
    main = np.where(np.isfinite(ys[0]), ys[0], 0.0)
    for start, stop in zip(edges[:-1], edges[1:]):
        if stop <= start:
            continue
        chunk = main[start:stop]
        pair = sorted({start + int(np.argmin(chunk)), start + int(np.argmax(chunk))})
        keep.extend(pair)
    index = np.asarray(keep)
    return (x[index], *(y[index] for y in ys))


def plot_png(report, dpi: int = 100) -> bytes:
    """The report's plots as one PNG: load tracking error, coupling torque and motor torque over
    time, following error over the master position in the cam period; limits dashed in red."""
    from matplotlib.figure import Figure

    s = report.series
    units = report.summary.get("units", {})
    mechanics = report.summary.get("mechanics", {})
    limits = {c.name: c.limit for c in report.checks}
    time_s = np.asarray(s["time_s"], dtype=float)
    motor = s.get("peak_motor_torque")
    panels = 4 if motor is not None else 3
    fig = Figure(figsize=(10, 2.8 * panels), constrained_layout=True)
    axes = list(fig.subplots(panels, 1))

    def limit_lines(ax, limit, data):
        finite = np.abs(data[np.isfinite(data)])
        peak = float(finite.max()) if finite.size else 0.0
        if limit is None:
            return
        if limit <= 5.0 * peak or peak == 0.0:
            for sign in (1, -1):
                ax.axhline(sign * limit, color="tab:red", ls="--", lw=0.9,
                           label=f"limit \u00b1{limit:.4g}" if sign > 0 else None)
        else:  # far away: the curve would be a flat line at this scale
            ax.plot([], [], color="tab:red", ls="--", lw=0.9,
                    label=f"limit \u00b1{limit:.4g} (off scale)")

    ax = axes[0]
    t, y = _envelope(time_s, np.asarray(s["tracking_error"], dtype=float))
    ax.plot(t, y, lw=0.9, color="tab:blue", label="load tracking error")
    limit_lines(ax, limits.get("tracking_error"), y)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"tracking error [{units.get('slave', '')}]")
    ax.set_title("Load-side tracking error against the cam", loc="left", fontsize=11)
    ax.legend(loc="upper right", fontsize="small")

    ax = axes[1]
    t, y = _envelope(time_s, np.asarray(s["coupling_torque"], dtype=float))
    ax.plot(t, y, lw=0.9, color="tab:green", label="coupling torque")
    for key, style in (("coupling_rated_torque", ":"), ("coupling_max_torque", "--")):
        value = mechanics.get(key)
        if value:
            for sign in (1, -1):
                ax.axhline(sign * value, color="tab:red", ls=style, lw=0.9,
                           label=f"{key.replace('_', ' ')} \u00b1{value:.4g}" if sign > 0 else None)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("torque [N m]")
    ax.set_title("Coupling torque against its ratings", loc="left", fontsize=11)
    ax.legend(loc="upper right", fontsize="small")

    if motor is not None:
        ax = axes[2]
        t, y = _envelope(time_s, np.asarray(motor, dtype=float))
        ax.plot(t, y, lw=0.9, color="tab:orange", label="motor torque (peak per cycle)")
        limit_lines(ax, mechanics.get("motor_torque_limit"), y)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("torque [N m]")
        ax.set_title("Motor torque against the drive's torque limit", loc="left", fontsize=11)
        ax.legend(loc="upper right", fontsize="small")

    ax = axes[-1]
    master = np.asarray(s["master_position"], dtype=float)
    following = np.asarray(s["following_error"], dtype=float)
    # The envelope keeps the extremes of its first series: the following error.
    _, f, m = _envelope(time_s, following, master)
    ax.plot(m, f, ".", ms=2.0, color="tab:purple", label="following error")
    limit_lines(ax, limits.get("following_error"), f)
    ax.set_xlabel(f"master position in the cam period [{units.get('master', '')}]")
    ax.set_ylabel("following error [counts]")
    ax.set_title("Motor-side following error over the master position", loc="left", fontsize=11)
    ax.legend(loc="upper right", fontsize="small")

    buffer = io.BytesIO()
    # No Software/date metadata: the same report gives the same bytes.
    fig.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    return buffer.getvalue()


def _scene_section(scene, report, seconds) -> str:
    label = scene_label(scene)
    anchor = _anchor(label)
    if isinstance(report, BaseException):
        return (f'<section class="scene" id="{anchor}"><h2><span class="badge error">ERROR'
                f"</span>{_e(label)}</h2><p class=\"failed-lines mono\">{_e(report)}</p>"
                + _scene_as_run(scene) + "</section>")
    data = report.to_dict()
    state = "pass" if report.passed else "fail"
    parts = [f'<section class="scene" id="{anchor}">',
             f'<h2><span class="badge {state}">{state.upper()}</span>{_e(report.scene)}</h2>']
    description = getattr(scene, "description", "")
    if description:
        parts.append(f'<p class="desc">{_e(description)}</p>')
    parts.append(f'<p class="desc">{report.cycles} cycles of {_num(data.get("cycle_s"))} s '
                 f'({_num(data.get("simulated_s"))} s simulated), cam {_e(data.get("cam_mode"))}'
                 f"-side; model <b>{_e(report.model)}</b></p>")
    if report.failed:
        parts.append('<div class="failed-lines mono">'
                     + "\n".join(_e(c.line()) for c in report.failed) + "</div>")
    parts.append("<h3>Checks</h3>" + _checks_table(report))
    if report.series and "time_s" in report.series and len(report.series["time_s"]):
        png = base64.b64encode(plot_png(report)).decode("ascii")
        parts.append(f'<h3>Plots</h3><img class="plot" alt="tracking error, coupling torque and '
                     f'following error of {_e(report.scene)}" src="data:image/png;base64,{png}">')
    else:
        parts.append('<h3>Plots</h3><p class="note">No recorded samples to plot.</p>')
    parts.append('<div class="grid"><div>')
    parts.append(f"<h3>Model and effects</h3><p><b>{_e(report.model)}</b>: "
                 f"{_e(report.model_reason)}</p>" + _effects(data))
    parts.append("</div><div><h3>Bus and faults</h3>" + _bus_and_faults(data) + "</div></div>")
    parts.append('<div class="grid">')
    for key in ("master", "table", "mechanics"):
        if isinstance(data.get(key), dict):
            parts.append(f"<div><h3>{key.capitalize()}</h3>{_kv_table(data[key])}</div>")
    parts.append("</div>")
    parts.append(_scene_as_run(scene))
    timing = report.timing or {}
    wall = f"{seconds:.3g} s wall"
    if timing.get("real_time_factor"):
        wall += f", real-time factor {timing['real_time_factor']:.3g}x"
    parts.append(f'<p class="note">Run time (not part of the verdict): {_e(wall)}.</p>')
    parts.append("</section>")
    return "\n".join(parts)


def _overview(results) -> str:
    rows = []
    for scene, report, seconds in results:
        label = scene_label(scene)
        if isinstance(report, BaseException):
            rows.append(f'<tr class="fail"><td><span class="badge error">ERROR</span></td>'
                        f'<td><a href="#{_anchor(label)}">{_e(label)}</a></td><td>\u2013</td>'
                        f'<td class="num">\u2013</td><td>{_e(report)}</td>'
                        f'<td class="num">{seconds:.2f} s</td></tr>')
            continue
        state = "pass" if report.passed else "fail"
        failed = ", ".join(f"{c.name} x{c.ratio:.3g}" if c.ratio is not None else c.name
                           for c in report.failed) or "none"
        rows.append(f'<tr class="{state}"><td><span class="badge {state}">{state.upper()}</span>'
                    f'</td><td><a href="#{_anchor(label)}">{_e(label)}</a></td>'
                    f"<td>{_e(report.model)}</td><td class=\"num\">{report.cycles}</td>"
                    f"<td>{_e(failed)}</td><td class=\"num\">{seconds:.2f} s</td></tr>")
    return ("<table><thead><tr><th></th><th>scene</th><th>model</th><th>cycles</th>"
            "<th>failed checks</th><th>wall</th></tr></thead><tbody>" + "".join(rows)
            + "</tbody></table>")


def html_report(results, title: str = "ecam rig report") -> str:
    """A self-contained HTML page for rig results.

    Parameters
    ----------
    results : list of (scene, report, seconds)
        ``scene`` is the scene file's path (its TOML is shown), a
        :class:`hil_sim.scene.Scene` (its fields are shown) or a name; ``report`` a
        :class:`hil_sim.report.Report` or the exception the run raised; ``seconds`` its wall
        time. :func:`ecam.app.multi.run_scenes` returns this list.
    title : str

    Returns
    -------
    str
        The page (UTF-8 text); no external resources, no script.
    """
    results = list(results)
    ok = [r for _, r, _ in results if not isinstance(r, BaseException) and r.passed]
    passed = len(ok) == len(results) and bool(results)
    state = "pass" if passed else "fail"
    headline = (f"{'PASSED' if passed else 'FAILED'}: {len(ok)} of {len(results)} "
                f"scene{'s' if len(results) != 1 else ''} passed")
    lines = []
    for scene, report, _ in results:
        label = scene_label(scene)
        if isinstance(report, BaseException):
            lines.append(f"<li><b>{_e(label)}</b>: <span class=\"mono\">{_e(report)}</span></li>")
        else:
            lines += [f"<li><b>{_e(label)}</b>: <span class=\"mono\">{_e(c.line())}</span></li>"
                      for c in report.failed]
    failed = f"<ul>{''.join(lines)}</ul>" if lines else "<p>Every check of every scene holds.</p>"
    body = [f'<header class="verdict {state}"><h1>{_e(headline)}</h1>{failed}</header>',
            "<h3>Scenes</h3>", _overview(results)]
    # Failed scenes first (stable otherwise): the first section a reader sees is what broke.
    ordered = sorted(results, key=lambda item: not (isinstance(item[1], BaseException)
                                                    or not item[1].passed))
    body += [_scene_section(scene, report, seconds) for scene, report, seconds in ordered]
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
            f"<body>\n<main>\n<p class=\"note\">{_e(title)}</p>\n" + "\n".join(body)
            + "\n</main>\n</body>\n</html>\n")
