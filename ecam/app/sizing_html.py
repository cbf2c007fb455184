"""The sizing summary of a scene's HTML section: per component (motor, module, gearhead,
coupling, brake resistor) what the duty needs, what the part is rated for, and the utilisation
in percent, the table sizing tools show."""

from __future__ import annotations

import html
import math

from hil_sim.sizing_text import COMPONENTS


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _number(value) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "\u2013"
    return f"{value:.4g}" if isinstance(value, (int, float)) else str(value)


def _pairs(values: dict | None) -> str:
    return "<br>".join(f"{_e(k.replace('_', ' '))} {_e(_number(v))}"
                       for k, v in (values or {}).items() if v is not None)


def sizing_section(data: dict) -> str:
    """``<h3>Sizing</h3>`` and the component table of a report's JSON (``data["sizing"]``);
    "" when the scene sizes no part (no motor, module or gearhead)."""
    sizing = data.get("sizing") or {}
    if not sizing.get("applicable"):
        return ""
    rows = []
    for name in COMPONENTS:
        part = sizing["components"].get(name) or {}
        used = part.get("utilisation_percent")
        state = "pass" if used is not None and used <= 100.0 else (
            "fail" if used is not None else "info")
        source = f'<br><span class="note">{_e(part["source"])}</span>' if part.get("source") else ""
        rows.append(f'<tr class="{state}"><td>{_e(name.replace("_", " "))}</td>'
                    f"<td>{_e(part.get('model') or '')}{source}</td>"
                    f"<td>{_pairs(part.get('required'))}</td><td>{_pairs(part.get('rated'))}</td>"
                    f'<td class="num">{_e(_number(used))}{" %" if used is not None else ""}</td>'
                    "</tr>")
    return (f"<h3>Sizing</h3><p class=\"note\">{_e(sizing.get('duty', ''))}; utilisation = "
            "required / rated (the torque-speed plot is the figure's last panel).</p>"
            '<table class="checks"><thead><tr><th>component</th><th>model</th><th>required</th>'
            '<th>rated</th><th class="num">utilisation</th></tr></thead><tbody>'
            + "".join(rows) + "</tbody></table>")
