"""The events panel of a scene's figure (a scene with ``[[event]]``, :mod:`hil_sim.events`): the
slave's ideal path over time (the cams as switched, the phase shift and the cam-out in it), a
vertical line at each switch's activation (red where it jumps and the scene does not allow it),
a ramp_in switch's correction shaded with its peak in the legend, the phase shift on a second axis, and the cam-out's stop shaded. Drawn into an axes of
:func:`hil_sim.rig.plot.report_figure`; matplotlib comes with the axes."""

from __future__ import annotations

import numpy as np

from hil_sim.report import Report
from hil_sim.rig.palette import GRID as _GRID, LIMIT as _LIMIT, PASSED as _PASSED

_PATH = "#1f77b4"
_PHASE = "#8250df"
_OUT = "#bf8700"
_RAMP = "#0a7ea4"


def has_events(report: Report) -> bool:
    """True when the report carries the events' ideal slave path."""
    return "event_reference" in (report.series or {})


def draw_events(ax, report: Report) -> None:
    """The panel (see the module)."""
    s, summary = report.series, report.summary
    units = summary.get("units") or {}
    time_s = np.asarray(s["time_s"], dtype=float)
    ax.plot(time_s, s["event_reference"], color=_PATH, lw=1.2, label="slave, ideal path")
    events = summary.get("events") or {}
    jumped = False
    for switch in events.get("switches", []):
        if switch["active_s"] is None:
            continue
        colour = _LIMIT if switch["failed"] else _PASSED
        jumped |= switch["failed"]
        ax.axvline(switch["active_s"], color=colour, lw=1.1, ls="--")
        ax.annotate(f" {switch['name'] or switch['action']} ({switch['activation']})",
                    (switch["active_s"], 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                    color=colour, rotation=90, va="top", ha="right")
        ramp = switch.get("ramp_in")
        if ramp:  # start_mode ramp_in: the correction's span, and its peak
            ax.axvspan(ramp["start_s"], ramp["start_s"] + ramp["duration_s"], color=_RAMP, alpha=0.25,
                       lw=0, label=f"ramp_in, peak correction {ramp['peak_correction']:.4g} "
                                   f"{units.get('slave', '')}")
    for motion in events.get("motions", []):
        if motion["action"] == "cam_out":
            ax.axvspan(motion["start_s"], motion["start_s"] + motion["duration_s"], color=_OUT,
                       alpha=0.25, lw=0, label="cam-out (to a stop)")
            ax.axvline(motion["start_s"], color=_OUT, lw=1.0)
    handles = []
    if "phase_shift" in s:
        # on a second axis whose ticks sit inside: the panel is the figure's right edge
        twin = ax.twinx()
        handles = twin.plot(time_s, s["phase_shift"], color=_PHASE, lw=1.0,
                            label=f"phase shift [{units.get('master', '')}], right axis")
        twin.tick_params(labelsize=8, colors=_PHASE, direction="in", pad=-22)
    ax.set_title("events: " + ("a switch jumps" if jumped else "every switch continuous"),
                 loc="left", fontsize=9, color=_LIMIT if jumped else _PASSED)
    ax.set_xlabel("time [s]", fontsize=8.5)
    ax.set_ylabel(f"slave position [{units.get('slave', '')}]", fontsize=8.5)
    ax.set_xlim(0.0, float(time_s[-1]) if time_s.size else 1.0)
    ax.tick_params(labelsize=8)
    ax.grid(True, color=_GRID, lw=0.5)
    lines, labels = ax.get_legend_handles_labels()
    ax.legend(lines + handles, labels + [h.get_label() for h in handles], loc="lower left",
              fontsize=7.5, framealpha=0.85)
