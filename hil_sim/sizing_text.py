"""The sizing summary of a report as text, the way sizing tools show it: per component what
the cycle needs, what the part is rated for, and the utilisation in percent."""

from __future__ import annotations

COMPONENTS = ("motor", "module", "gearhead", "coupling", "infeed", "brake_resistor")


def _value(value) -> str:
    if value is None:
        return "n/a"
    return value if isinstance(value, str) else f"{value:.4g}"


def sizing_lines(sizing: dict | None) -> list[str]:
    """The summary's lines (none when the scene sizes no part: no motor, module or
    gearhead)."""
    if not sizing or not sizing.get("applicable"):
        return []
    lines = [f"sizing ({sizing.get('duty', '')}; utilisation = required / rated):"]
    for name in COMPONENTS:
        part = sizing["components"].get(name) or {}
        used = part.get("utilisation_percent")
        head = name.replace("_", " ") + (f" {part['model']}" if part.get("model") else "")
        required = ", ".join(f"{k} {_value(v)}" for k, v in (part.get("required") or {}).items()
                             if v is not None)
        rated = ", ".join(f"{k} {_value(v)}" for k, v in (part.get("rated") or {}).items()
                          if v is not None)
        lines.append(f"  {head}: " + (f"{used:.3g} %" if used is not None else "not rated")
                     + (f"; needs {required}" if required else "")
                     + (f"; rated {rated}" if rated else ""))
    return lines
