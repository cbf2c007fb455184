"""One self-contained HTML page for a sweep: the yield, each check's spread against its limit,
what drives failure.

Like :mod:`ecam.app.html_report`, the file fetches nothing (inline style, inline SVG figures,
no script) and the same sweep gives the same bytes. It reads top to bottom:

1. the verdict: the yield with its interval, samples that could not run, the fastest speed at
   the required yield;
2. the checks: failure rate and interval, the worst sample, and a histogram of each check's
   value over the samples against its limit (the failing samples in red);
3. the sensitivity ranking, and scatter plots of the driving fields against each sample's
   severity (largest value / limit; above 1 a limit is exceeded), passing and failing samples
   told apart;
4. the yield at each judged speed, the worst sample (its values and its CANopen re-run), the
   samples that could not run, and the sweep's settings.
"""

from __future__ import annotations

import html
import io
from pathlib import Path

from ecam.app.shown_paths import shown_path, shown_text
from ecam.atomic_files import write_files
from ecam.errors import InputError

__all__ = ["sweep_html", "write_sweep_html"]

_CSS = """
body { margin: 0; font: 15px/1.45 -apple-system, "Segoe UI", "DejaVu Sans", Helvetica, Arial,
       sans-serif; color: #1f2328; }
main { max-width: 1180px; margin: 0 auto; padding: 18px 28px 40px; }
h1 { font-size: 26px; margin: 0 0 4px; } h2 { font-size: 19px; margin: 26px 0 8px;
     border-bottom: 1px solid #d0d7de; padding-bottom: 3px; }
.verdict { border-radius: 8px; padding: 14px 20px 12px; margin: 0 0 18px; border: 2px solid; }
.pass { background: #dafbe1; border-color: #1a7f37; } .fail { background: #ffebe9; border-color: #cf222e; }
table { border-collapse: collapse; margin: 6px 0 12px; }
th, td { border: 1px solid #d0d7de; padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: #f6f8fa; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
.figures { display: flex; flex-wrap: wrap; gap: 8px; } .figures svg { width: 380px; height: auto; }
.small { font-size: 12px; color: #57606a; } code { font-size: 13px; }
"""


def _e(value) -> str:
    return html.escape(str(value))


def _num(value, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return _e(value)


def _pct(value) -> str:
    return "-" if value is None else f"{100 * value:.3g} %"


def _interval(pair) -> str:
    return "-" if not pair else f"{_pct(pair[0])} .. {_pct(pair[1])}"


def _svg(fig) -> str:
    import matplotlib

    buffer = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": "ecam", "svg.fonttype": "none"}):
        fig.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
    text = buffer.getvalue()
    return text[text.index("<svg"):]


def _figure():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.6, 2.9), dpi=100, layout="constrained")
    return fig, fig.add_subplot()


def _histograms(summary: dict, rows: list) -> list[str]:
    """A histogram of each check with a limit: its value over the samples, the limit marked."""
    out = []
    for check in summary["checks"]:
        limit = check["limit"]
        if not isinstance(limit, (int, float)):
            continue
        values = [(c["value"], c["passed"]) for r in rows for c in r["checks"]
                  if c["name"] == check["name"] and c["value"] is not None]
        if not values:
            continue
        fig, ax = _figure()
        low = min(min(v for v, _ in values), limit)
        high = max(max(v for v, _ in values), limit)
        bins = 30 if high > low else 1
        span = (low, high) if high > low else (low - 0.5, high + 0.5)
        passed = [v for v, ok in values if ok]
        failed = [v for v, ok in values if not ok]
        ax.hist([passed, failed], bins=bins, range=span, stacked=True,
                color=["#1a7f37", "#cf222e"], label=["passed", "failed"])
        ax.axvline(limit, color="black", linestyle="--", linewidth=1.2, label=f"limit {limit:.4g}")
        ax.set_xlabel(f"{check['name']} [{check['unit']}]")
        ax.set_ylabel("samples")
        ax.legend(fontsize=7, loc="upper right")
        out.append(_svg(fig))
    return out


def _severity(row: dict) -> float | None:
    ratios = [c["value"] / c["limit"] for c in row["checks"]
              if c["value"] is not None and c["limit"] not in (None, 0)]
    return max(ratios) if ratios else None


def _scatters(summary: dict, rows: list, count: int = 4) -> list[str]:
    """The driving fields (the first of the sensitivity ranking) against each sample's severity."""
    out = []
    for entry in summary["sensitivity"]["parameters"][:count]:
        name = entry["name"]
        points = [(r["values"][name], _severity(r), r["passed"]) for r in rows
                  if not r.get("error") and name in r.get("values", {})]
        points = [p for p in points if p[1] is not None]
        if not points:
            continue
        fig, ax = _figure()
        for ok, colour, label in ((True, "#1a7f37", "passed"), (False, "#cf222e", "failed")):
            chosen = [(x, y) for x, y, p in points if p == ok]
            if chosen:
                ax.scatter([x for x, _ in chosen], [y for _, y in chosen], s=9, color=colour,
                           label=label, linewidths=0)
        ax.axhline(1.0, color="black", linestyle="--", linewidth=1.0, label="a limit")
        ax.set_xlabel(name)
        ax.set_ylabel("largest value / limit")
        ax.legend(fontsize=7, loc="best")
        out.append(_svg(fig))
    return out


def _sensitivity_table(summary: dict) -> str:
    sens = summary["sensitivity"]
    if sens["method"] == "sobol":
        head = "<tr><th>field</th><th>ST</th><th>+-</th><th>S1</th><th>+-</th></tr>"
        body = "".join(f"<tr><td><code>{_e(p['name'])}</code></td><td class=num>{_num(p['ST'], 3)}</td>"
                       f"<td class=num>{_num(p['ST_conf'], 2)}</td><td class=num>{_num(p['S1'], 3)}</td>"
                       f"<td class=num>{_num(p['S1_conf'], 2)}</td></tr>" for p in sens["parameters"])
    else:
        head = "<tr><th>field</th><th>Spearman rho</th></tr>"
        body = "".join(f"<tr><td><code>{_e(p['name'])}</code></td>"
                       f"<td class=num>{_num(p['spearman'], 3)}</td></tr>" for p in sens["parameters"])
    note = f"<p class=small>{_e(sens['note'])}</p>" if sens.get("note") else ""
    return f"<p>{_e(sens['about'])}</p><table>{head}{body}</table>{note}"


def sweep_html(summary: dict, rows: list) -> str:
    """The page, as text.

    Parameters
    ----------
    summary : dict
        :func:`ecam.app.sweep.run_sweep`'s summary.
    rows : list of dict
        The results at the first judged speed (:func:`ecam.app.sweep.result_rows`).
    """
    first = [r for r in rows if r.get("speed_index", 0) == 0]
    lower = summary["yield_interval"][0] if summary["yield_interval"] else 0.0
    required = summary["max_speed_at_yield"]["required"]
    state = "pass" if lower >= required else "fail"
    fastest = summary["max_speed_at_yield"]
    parts = [f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>sweep "
             f"{_e(summary['scene'])}</title><style>{_CSS}</style></head><body><main>",
             f"<div class='verdict {state}'><h1>sweep {_e(summary['scene'])}: yield "
             f"{_pct(summary['yield'])}</h1><p>{summary['passed']} of {summary['samples']} samples "
             f"passed at {_num(summary['speed'])} {_e(summary['unit'])}/s; "
             f"{_pct(summary['confidence'])} Wilson interval {_interval(summary['yield_interval'])}; "
             f"required {_pct(required)}"
             + (f"; {summary['errors']} could not run" if summary["errors"] else "") + ".</p>"
             f"<p>Fastest judged speed with a yield of at least {_pct(required)} (with confidence): "
             + ("none" if fastest["speed"] is None else f"{_num(fastest['speed'])} {_e(summary['unit'])}/s")
             + ("" if fastest["next_speed"] is None else f", not reached at {_num(fastest['next_speed'])}")
             + "</p></div>"]
    parts.append("<h2>Checks</h2><table><tr><th>check</th><th>limit</th><th>fails</th>"
                 "<th>failure rate</th><th>interval</th><th>min</th><th>median</th><th>max</th>"
                 "<th>worst sample</th></tr>")
    for c in summary["checks"]:
        worst = c["worst"]
        parts.append(f"<tr><td>{_e(c['name'])}</td><td class=num>{_num(c['limit'])} {_e(c['unit'])}</td>"
                     f"<td class=num>{c['failures']}</td><td class=num>{_pct(c['failure_rate'])}</td>"
                     f"<td>{_interval(c['failure_interval'])}</td><td class=num>{_num(c['min'])}</td>"
                     f"<td class=num>{_num(c['median'])}</td><td class=num>{_num(c['max'])}</td>"
                     f"<td>{'-' if worst is None else '#' + str(worst['index'])}</td></tr>")
    parts.append("</table><div class=figures>" + "".join(_histograms(summary, first)) + "</div>")
    parts.append("<h2>What drives failure</h2>" + _sensitivity_table(summary)
                 + "<div class=figures>" + "".join(_scatters(summary, first)) + "</div>")
    parts.append("<h2>Yield by speed</h2><table><tr><th>speed</th><th>samples</th><th>yield</th>"
                 "<th>interval</th></tr>" + "".join(
                     f"<tr><td class=num>{_num(e['speed'])} {_e(summary['unit'])}/s</td>"
                     f"<td class=num>{e['samples']}</td><td class=num>{_pct(e['yield'])}</td>"
                     f"<td>{_interval(e['yield_interval'])}</td></tr>" for e in summary["by_speed"])
                 + "</table>")
    worst = summary["worst_sample"]
    if worst is not None:
        canopen = worst.get("canopen") or {}
        again = ("" if not canopen else f"error: {_e(shown_text(canopen['error']))}" if "error" in canopen else
                 ("PASSED" if canopen["passed"] else "FAILED " + _e(", ".join(canopen["failed"])))
                 + f" (report <code>{_e(shown_path(canopen['report']))}</code>)")
        parts.append(f"<h2>Worst sample #{worst['index']}</h2><table>" + "".join(
            f"<tr><td><code>{_e(k)}</code></td><td class=num>{_num(v, 6)}</td></tr>"
            for k, v in worst["values"].items()) + "</table>"
            f"<p>bus-free: {'passed' if worst['passed'] else 'failed ' + _e(', '.join(worst['failed']))}"
            f"; over CANopen: {again or 'not run'}</p>")
    if summary["error_samples"]:
        parts.append("<h2>Samples that could not run</h2><ul>" + "".join(
            f"<li>#{e['index']}: {_e(shown_text(e['error']))}</li>" for e in summary["error_samples"]) + "</ul>")
    parts.append(f"<h2>Settings</h2><p>{_e(summary['method'])}, seed {summary['seed']}, tuning "
                 f"{_e(summary['tuning'])}, fidelity {_e(summary['fidelity'])}</p><table>"
                 "<tr><th>field</th><th>distribution</th><th>nominal</th></tr>" + "".join(
                     f"<tr><td><code>{_e(k)}</code></td><td>{_e(', '.join(f'{a} = {b}' for a, b in d.items()))}"
                     f"</td><td class=num>{_num(summary['nominal'].get(k))}</td></tr>"
                     for k, d in summary["vary"].items()) + "</table></main></body></html>\n")
    return "".join(parts)


def write_sweep_html(summary: dict, rows: list, path) -> None:
    """Write :func:`sweep_html` to ``path`` atomically (one InputError line when it cannot)."""
    text = sweep_html(summary, rows)
    try:
        write_files({Path(path): text})
    except OSError as exc:
        raise InputError(f"--html: {str(path)!r} cannot be written: {exc.strerror or exc}") from None
