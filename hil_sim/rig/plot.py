"""The rig's figure: what each check reads, over the master position in the cam period.

A machine builder asks *where in the cycle* a limit is hit, so every panel has the master
position in the cam period on its x axis (a net-stroke cam's master wraps every period too) and
the periods of the run drawn over each other, one colour per period:

- load-side tracking error against its limit;
- motor-side following error against the drive's window (or the scene's limit);
- coupling torque (peak per cycle) against the coupling's maximum and rated torque;
- coupling wind-up against its limit, where the report's series carry the twist
  (``peak_twist`` [rad], two-mass runs);
- motor torque (peak per cycle) against the drive's torque limit, clamped cycles marked;
- for a scene with a ``[motor]``: the torque-speed plot of a sizing tool (the S1 and peak curves,
  the duty's operating points, :mod:`hil_sim.rig.sizing_plot`);
- for a scene with ``[[event]]``: the slave's ideal path over time with its switches, phase shift
  and cam-out (:mod:`hil_sim.rig.event_plot`).

Each panel's title is its check's verdict; the sample a check reads as its worst is ringed
(in red, with its master position and period in the legend, when the check failed), master
positions a check does not look at are greyed (when the check gives its window), drive faults
are red vertical lines. A run of more than :data:`MAX_OVERLAID_PERIODS` periods is drawn as
the band of all periods (least to largest value at each master position), the period with
the worst sample and the last period.

The bytes are deterministic: fixed size, layout and dpi, no date or software version in the
file (an SVG's element ids from a fixed salt), so the same report gives the same PNG, and the
HTML report that inlines it the same bytes. matplotlib is imported only inside the functions
that draw, so a run without plots (every test, every CI job) never loads it.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ecam.atomic_files import write_files
from ecam.errors import InputError
from ecam.plot import TEXT_AS_WRITTEN, check_figure_path
from hil_sim.report import Report
from hil_sim.rig.palette import GRID as _GRID, LIMIT as _LIMIT, PASSED as _PASSED
from hil_sim.rig.event_plot import draw_events, has_events
from hil_sim.rig.sizing_plot import draw_torque_speed, has_torque_speed

__all__ = ["plot_report", "figure_bytes", "report_figure", "period_index", "master_period",
           "MAX_OVERLAID_PERIODS"]

#: Up to this many periods each is its own line; more are drawn as a band.
MAX_OVERLAID_PERIODS = 6
#: Points per line at most: a longer period is reduced to the min and max of each bucket, which
#: keeps every peak (the value a check reads) in the picture and keeps the PNG small.
MAX_POINTS_PER_LINE = 1500
#: Master positions in the band of many periods.
BAND_BINS = 720

# tab10 without its red, which marks limits and failures here.
_PERIOD_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#17becf",
                   "#e377c2", "#7f7f7f", "#bcbd22")
_BAND = "#b6c2cf"
_WINDOW = "#8250df"  # the tracking window (cut zone) edges
_MUTED = "#57606a"

# Metadata matplotlib writes by default that would make the bytes depend on the date or the
# library version (per format; PNG's Software key, SVG's and PDF's dates).
_NO_METADATA = {"png": {"Software": None}, "svg": {"Date": None, "Creator": None},
                "pdf": {"CreationDate": None, "Producer": None, "Creator": None},
                "eps": {"Creator": None}, "ps": {"Creator": None}}


# --------------------------------------------------------------------------------------------
# The master's periods

def master_period(report: Report) -> float | None:
    """The cam's master period [master units], from the report's summary.

    ``summary["master"]["period"]`` when the report states it, else cruise speed over cam
    frequency (the rig's definition of the cam frequency); None when neither is known.
    """
    master = report.summary.get("master") or {}
    period = master.get("period")
    if period:
        return float(period)
    speed, hz = master.get("speed"), master.get("cam_frequency_hz")
    if speed and hz:
        return abs(float(speed)) / float(hz)
    return None


def period_index(position: np.ndarray, period: float) -> np.ndarray:
    """The master period of each sample, 0 for the first, from positions wrapped into
    ``[0, period)``.

    A jump of more than half a period between two samples is a wrap (forwards when the
    position falls, backwards when it rises). The rig refuses a master that moves more than
    half a period per bus cycle, so this is exact for its records; a master that reverses
    across the seam goes back a period.
    """
    position = np.asarray(position, dtype=float)
    if position.size == 0:
        return np.zeros(0, dtype=np.int64)
    step = np.diff(position)
    wraps = np.where(step < -period / 2, 1, np.where(step > period / 2, -1, 0))
    index = np.concatenate([[0], np.cumsum(wraps)])
    return (index - index.min()).astype(np.int64)


def _reduce(x: np.ndarray, y: np.ndarray, limit: int = MAX_POINTS_PER_LINE):
    """At most about ``limit`` points, in order: each bucket's min and max of ``y`` (NaN kept
    as a break in the line)."""
    n = x.size
    if n <= limit:
        return x, y
    edges = np.linspace(0, n, limit // 2 + 1).astype(int)
    keep = []
    filled = np.where(np.isfinite(y), y, 0.0)
    for start, stop in zip(edges[:-1], edges[1:]):
        if stop > start:
            chunk = filled[start:stop]
            keep.extend(sorted({start + int(np.argmin(chunk)), start + int(np.argmax(chunk))}))
    index = np.asarray(keep)
    return x[index], y[index]


def _period_line(position, values, periods, k: int, period: float):
    """Period ``k``'s line (reduced): its samples, continued to the first sample of the next
    period drawn at the end of this one, so the line reaches the seam."""
    index = np.flatnonzero(periods == k)
    after = index[-1] + 1
    if after < periods.size and periods[after] == k + 1:
        x = np.append(position[index], position[after] + period)
        y = np.append(values[index], values[after])
    else:
        x, y = position[index], values[index]
    return _reduce(x, y)


def _segments(x: np.ndarray, y: np.ndarray, period: float):
    """The line of one period with breaks (NaN) where the master jumps across the seam
    (a master reversing there) so no line is drawn across the whole plot."""
    if x.size < 2:
        return x, y
    jump = np.flatnonzero(np.abs(np.diff(x)) > period / 2) + 1
    if jump.size:
        x = np.insert(x, jump, np.nan)
        y = np.insert(y, jump, np.nan)
    return x, y


# --------------------------------------------------------------------------------------------
# What each panel draws

@dataclass
class _Panel:
    """One panel: a series over the master position, its check and its limit lines."""

    title: str
    ylabel: str
    values: np.ndarray
    check: object = None                 # the Check the panel shows, or None
    limits: list = field(default_factory=list)  # (value, label, line style)
    symmetric: bool = True               # +-limit (a signed series) or +limit (magnitudes)
    worst: int | None = None             # index of the sample the check reads
    clamped: np.ndarray | None = None    # motor torque: True where clamped at the limit


def _check(report: Report, name: str):
    try:
        return report.check(name)
    except KeyError:
        return None


def _worst_index(values: np.ndarray, check=None) -> int | None:
    """The sample the check reads as its worst: the first whose magnitude is the check's
    value (a check may look at a window of the run only, so this is not always the largest
    sample), else the largest."""
    magnitude = np.abs(values)
    finite = np.isfinite(magnitude)
    if not finite.any():
        return None
    if check is not None and check.value is not None:
        distance = np.where(finite, np.abs(magnitude - check.value), np.inf)
        index = int(np.argmin(distance))
        if distance[index] <= 1e-9 * max(abs(check.value), 1e-300):
            return index
    return int(np.nanargmax(magnitude))


def _panels(report: Report) -> list[_Panel]:
    s = report.series
    units = report.summary.get("units") or {}
    mech = report.summary.get("mechanics") or {}
    panels = []
    if "tracking_error" in s:
        check = _check(report, "tracking_error")
        values = np.asarray(s["tracking_error"], dtype=float)
        panels.append(_Panel(
            "Tracking error", f"load tracking error [{units.get('slave', '')}]", values, check,
            [(check.limit, "limit", "--")] if check and check.limit is not None else [],
            worst=_worst_index(values, check)))
    if "following_error" in s:
        check = _check(report, "following_error")
        values = np.asarray(s["following_error"], dtype=float)
        panels.append(_Panel(
            "Following error", "motor following error [counts]", values, check,
            [(check.limit, "window", "--")] if check and check.limit is not None else [],
            worst=_worst_index(values, check)))
    torque_key = "peak_coupling_torque" if "peak_coupling_torque" in s else "coupling_torque"
    if torque_key in s:
        check = _check(report, "coupling_peak_torque")
        values = np.abs(np.asarray(s[torque_key], dtype=float))
        limits = []
        if mech.get("coupling_max_torque"):
            limits.append((mech["coupling_max_torque"], "maximum", "--"))
        if mech.get("coupling_rated_torque"):
            rms = _check(report, "coupling_rms_torque")
            rms_text = f"; RMS {rms.value:.3g}" if rms and rms.value is not None else ""
            limits.append((mech["coupling_rated_torque"], f"rated (RMS limit{rms_text})", ":"))
        panels.append(_Panel(
            "Coupling torque", "|torque|, peak per cycle [N m]", values, check, limits,
            symmetric=False, worst=_worst_index(values, check)))
    if "peak_twist" in s and report.model != "rigid":
        check = _check(report, "wind_up")
        values = np.degrees(np.abs(np.asarray(s["peak_twist"], dtype=float)))
        panels.append(_Panel(
            "Coupling wind-up", "|twist|, peak per cycle [deg]", values, check,
            [(check.limit, "limit", "--")] if check and check.limit is not None else [],
            symmetric=False, worst=_worst_index(values, check)))
    if "peak_motor_torque" in s:
        check = _check(report, "motor_saturation")
        values = np.abs(np.asarray(s["peak_motor_torque"], dtype=float))
        limit = mech.get("motor_torque_limit")
        panels.append(_Panel(
            "Motor torque, cycles clamped", "|torque|, peak per cycle [N m]", values, check,
            [(limit, "drive's torque limit", "--")] if limit else [], symmetric=False,
            worst=_worst_index(values),
            clamped=(values >= limit * (1.0 - 1e-9)) if limit else None))
    return panels


def _title(panel: _Panel) -> tuple[str, str]:
    """(title, colour): the panel's name and its check's verdict in a few words."""
    check = panel.check
    if check is None or check.value is None:
        return panel.title, "black"
    value = f"{check.value:.3g} {check.unit}"
    if check.limit is None:
        return f"{panel.title}: {value}", "black"
    limit = f"{check.limit:.6g} {check.unit}"
    if not check.passed:
        ratio = f"x{check.ratio:.3g} the" if check.ratio is not None else "over the"
        return f"{panel.title}: FAIL {value}, {ratio} limit {limit}", _LIMIT
    if check.ratio is None:
        return f"{panel.title}: PASS {value} (limit {limit})", _PASSED
    return (f"{panel.title}: PASS {value}, margin {100 * (1.0 - check.ratio):.3g} % of "
            f"{limit}"), _PASSED


# --------------------------------------------------------------------------------------------
# The figure

def report_figure(report: Report, width_in: float = 11.0):
    """The figure of a report (a :class:`matplotlib.figure.Figure`, no pyplot state).

    Parameters
    ----------
    report : Report
        A rig report with its ``series``.
    width_in : float
        Figure width [in]; each row of two panels is 0.3 of it high.

    Raises
    ------
    InputError
        A report without recorded samples (nothing to draw).
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    s = report.series
    if not s or "master_position" not in s or not len(s["master_position"]):
        raise InputError(f"report {report.scene!r}: no recorded samples to plot")
    position = np.asarray(s["master_position"], dtype=float)
    period = master_period(report) or float(np.nanmax(position)) or 1.0
    periods = period_index(position, period)
    if periods.size > 1 and periods[-1] > periods[-2]:
        # A run of whole periods ends on the seam: its last sample is the end of the last
        # period (at the period's length), not a period of its own.
        position = position.copy()
        position[-1] += period
        periods = periods.copy()
        periods[-1] -= 1
    count = int(periods.max()) + 1
    units = report.summary.get("units") or {}
    panels = _panels(report)
    sized = int(has_torque_speed(report))  # a torque-speed panel after the others
    evented = int(has_events(report))  # and an events panel (hil_sim.rig.event_plot)
    rows = math.ceil((len(panels) + sized + evented) / 2)
    # A fixed layout (margins in inches), not matplotlib's constrained layout: it measures
    # every text again and again, which doubles the time to draw, and the panels here always
    # have the same furniture (a one-line title, axis labels, ticks).
    row_in = 0.3 * width_in
    height_in = row_in * rows + 0.4
    fig = Figure(figsize=(width_in, height_in))
    axes = fig.subplots(rows, 2, squeeze=False).ravel()
    fig.subplots_adjust(left=0.9 / width_in, right=1.0 - 0.15 / width_in,
                        bottom=0.5 / height_in, top=1.0 - 0.7 / height_in,
                        wspace=1.1 / (width_in / 2), hspace=0.95 / row_in)
    for ax in axes[len(panels) + sized + evented:]:
        ax.set_visible(False)
    if sized:
        draw_torque_speed(axes[len(panels)], report)
    if evented:
        draw_events(axes[len(panels) + sized], report)
    band = count > MAX_OVERLAID_PERIODS
    # Bins of the band: at most BAND_BINS, and about two samples of each period per bin so
    # that no bin is empty (an empty bin would cut the band).
    per_period = position.size / max(count - 1, 1)
    nbins = int(max(8, min(BAND_BINS, per_period // 2)))
    bins = np.clip((position / period * nbins).astype(int), 0, nbins - 1)
    legend_periods: dict[int, str] = {}
    window = _tracking_window(report, period)
    for ax, panel in zip(axes, panels):
        y = panel.values
        worst_period = int(periods[panel.worst]) if panel.worst is not None else None
        if band:
            _draw_band(ax, bins, nbins, y, period)
            shown = sorted({count - 1} | ({worst_period} if worst_period is not None else set()))
        else:
            shown = list(range(count))
        # The period with the worst sample on top, so the marked sample is on its own line.
        shown.sort(key=lambda k: k == worst_period)
        for k in shown:
            colour = _PERIOD_COLOURS[k % len(_PERIOD_COLOURS)]
            x, v = _period_line(position, y, periods, k, period)
            x, v = _segments(x, v, period)
            ax.plot(x, v, lw=1.3 if k == worst_period and count > 1 else 1.0, color=colour)
            legend_periods.setdefault(k, colour)
        _draw_limits(ax, panel, y)
        _mark_window(ax, panel, period, window, units.get("master", ""))
        _mark_worst(ax, panel, position, periods, count, units)
        if panel.clamped is not None and panel.clamped.any():
            ax.plot(position[panel.clamped], y[panel.clamped], "|", ms=8, mew=1.2,
                    color=_LIMIT, label="torque clamped")
        _mark_faults(ax, report, position, periods, count, label=ax is axes[0])
        title, colour = _title(panel)
        ax.set_title(title, loc="left", fontsize=9, color=colour)
        ax.set_xlim(0.0, period)
        ax.set_xlabel(f"master position in the cam period [{units.get('master', '')}]",
                      fontsize=8.5)
        ax.set_ylabel(panel.ylabel, fontsize=8.5)
        ax.tick_params(labelsize=8)
        ax.grid(True, color=_GRID, lw=0.5)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=7.5, framealpha=0.85)
    handles = []
    if band:
        handles.append(Line2D([], [], color=_BAND, lw=6,
                              label=f"all {count} periods (min to max)"))
    for k, colour in sorted(legend_periods.items()):
        handles.append(Line2D([], [], color=colour, lw=2, label=f"period {k + 1}"))
    verdict = "passed" if report.passed else "FAILED"
    fig.text(0.1 / width_in, 1.0 - 0.12 / height_in,
             f"{report.scene}: {verdict}, {report.model} model, {report.cycles} cycles, "
             f"{_periods_text(position, periods, period)}", fontsize=11, va="top",
             color=_PASSED if report.passed else _LIMIT)
    fig.legend(handles=handles, loc="upper right", bbox_to_anchor=(1.0, 1.0 - 0.02 / height_in),
               ncol=min(len(handles), 8), fontsize=8, frameon=False)
    return fig


def _periods_text(position, periods, period) -> str:
    travel = (periods[-1] * period + position[-1]) - position[0]
    return f"{abs(travel) / period:.3g} master periods"


def _draw_band(ax, bins, nbins: int, y, period) -> None:
    """The band from the least to the largest value of all periods in each bin of master
    positions, drawn through the bins' centres."""
    low = np.full(nbins, np.inf)
    high = np.full(nbins, -np.inf)
    finite = np.isfinite(y)
    np.minimum.at(low, bins[finite], y[finite])
    np.maximum.at(high, bins[finite], y[finite])
    seen = np.isfinite(low)
    centre = (np.arange(nbins) + 0.5) * period / nbins
    ax.fill_between(centre, np.where(seen, low, np.nan), np.where(seen, high, np.nan),
                    color=_BAND, lw=0)


def _draw_limits(ax, panel: _Panel, y) -> None:
    """Limit lines; a limit far above the data (where the curve would be a flat line at its
    scale) goes into the legend only, with '(off scale)'."""
    finite = np.abs(y[np.isfinite(y)])
    peak = float(finite.max()) if finite.size else 0.0
    for value, label, style in panel.limits:
        if value is None:
            continue
        text = f"{label} {'±' if panel.symmetric else ''}{value:.6g}"
        if peak > 0 and value > 5.0 * peak:
            ax.plot([], [], color=_LIMIT, ls=style, lw=1.0, label=f"{text} (off scale)")
            continue
        ax.axhline(value, color=_LIMIT, ls=style, lw=1.0, label=text)
        if panel.symmetric:
            ax.axhline(-value, color=_LIMIT, ls=style, lw=1.0)


def _tracking_window(report, period: float):
    """(start, end) of the master window the tracking check looks at (master units within the
    period; start > end when it spans the seam, as a knife's cut zone does), or None."""
    try:
        window = report.check("tracking_error").to_dict().get("window")
    except KeyError:
        return None
    master = window.get("master") if isinstance(window, dict) else None
    if not master or len(master) != 2:
        return None
    return tuple(float(v) % period for v in master)


def _mark_window(ax, panel: _Panel, period: float, window, unit: str) -> None:
    """The tracking window (a knife's cut zone) on every panel: its edges as dashed lines, named
    on the tracking panel, whose master positions outside it are greyed out (not checked)."""
    if window is None:
        return
    start, end = window
    tracking = panel.check is not None and panel.check.name == "tracking_error"
    for edge in (start, end):
        ax.axvline(edge, color=_WINDOW, lw=0.9, ls="--",
                   label=f"tracking window {start:g}..{end:g} {unit}".rstrip()
                   if tracking and edge == start else None)
    if not tracking:
        return
    outside = [(end, start)] if start > end else [(0.0, start), (end, period)]
    label = "outside it: not checked"
    for low, high in outside:
        if high > low:
            ax.axvspan(low, high, color=_GRID, alpha=0.45, lw=0, label=label)
            label = None


def _mark_worst(ax, panel: _Panel, position, periods, count, units) -> None:
    """Ring the sample the check reads as its worst; when the check failed, the legend says
    where (a legend, unlike a note beside the ring, never covers the curves)."""
    i = panel.worst
    if i is None:
        return
    x, y = float(position[i]), float(panel.values[i])
    if panel.check is not None and not panel.check.passed:
        where = f"at {x:.4g} {units.get('master', '')}" + \
            (f", period {int(periods[i]) + 1}" if count > 1 else "")
        ax.plot([x], [y], "o", ms=11, mfc="none", mec=_LIMIT, mew=2.0, zorder=5,
                label=f"worst, {where}")
    else:
        ax.plot([x], [y], "o", ms=7, mfc="none", mec=_MUTED, mew=1.2, zorder=5,
                label="worst sample")


def _mark_faults(ax, report: Report, position, periods, count, label: bool) -> None:
    """A red dash-dot line at the master position of each drive fault (EMCY), named in the
    legend when ``label``."""
    time_s = report.series.get("time_s")
    faults = report.summary.get("faults") or []
    if time_s is None or not len(time_s) or not faults:
        return
    time_s = np.asarray(time_s, dtype=float)
    for number, fault in enumerate(faults):
        k = min(int(np.searchsorted(time_s, float(fault["time_s"]))), time_s.size - 1)
        where = f" (period {int(periods[k]) + 1})" if count > 1 else ""
        ax.axvline(position[k], color=_LIMIT, lw=1.2, ls="-.",
                   label=f"EMCY {fault['code']}{where}" if label and number < 3 else None)


# --------------------------------------------------------------------------------------------
# Bytes and files

def figure_bytes(report: Report, fmt: str = "png", dpi: int = 100,
                 width_in: float = 11.0) -> bytes:
    """The report's figure as file contents, the same bytes for the same report.

    Parameters
    ----------
    report : Report
    fmt : str
        A matplotlib format (``png``, ``svg``, ``pdf`` ...).
    dpi : int
        Pixels per inch (a PNG of the default width is ``11 * dpi`` pixels wide).
    width_in : float
        Figure width [in].
    """
    import matplotlib

    buffer = io.BytesIO()
    # text from the scene and the cam (names, units) drawn as written, never as mathtext
    with matplotlib.rc_context({"svg.hashsalt": "ecam", "pdf.compression": 6, **TEXT_AS_WRITTEN}):
        fig = report_figure(report, width_in=width_in)
        fig.savefig(buffer, format=fmt, dpi=dpi, metadata=_NO_METADATA.get(fmt))
    if fmt != "png":
        return buffer.getvalue()
    return _palette_png(buffer.getvalue())


def _palette_png(data: bytes) -> bytes:
    """The PNG with a palette (8 bits a pixel), about a third of the bytes of matplotlib's RGBA.

    The palette is every colour the figure draws with, blended with the white background in
    12 steps (what anti-aliasing makes of a line on white); each pixel takes its nearest
    palette colour, without dithering. Fast (no colour search over the image), deterministic,
    and a colour in a legend stays the colour of its line. Pillow comes with matplotlib.
    """
    from PIL import Image

    colours = _palette_colours()
    palette = Image.new("P", (1, 1))
    palette.putpalette([v for colour in colours for v in colour])
    with Image.open(io.BytesIO(data)) as image:
        indexed = image.convert("RGB").quantize(palette=palette, dither=Image.Dither.NONE)
    out = io.BytesIO()
    indexed.save(out, format="PNG")
    return out.getvalue()


def _palette_colours() -> list[tuple[int, int, int]]:
    """White, then every ink and its blends with white, without the blends within 10 of
    white: Pillow finds the nearest colour through a cache of 4-unit cells, so a blend that
    close could take the place of white itself."""
    inks = [(0, 0, 0)] + [_rgb(c) for c in (*_PERIOD_COLOURS, _LIMIT, _PASSED, _BAND, _GRID,
                                             _MUTED)]
    colours = [(255, 255, 255)]
    for ink in inks:
        for step in range(12):
            blend = tuple(round(v + (255 - v) * step / 12) for v in ink)
            if min(blend) < 245 and blend not in colours:
                colours.append(blend)
    return colours[:256]


def _rgb(colour: str) -> tuple[int, int, int]:
    return tuple(int(colour[i:i + 2], 16) for i in (1, 3, 5))


def plot_report(report: Report, path, dpi: int = 110) -> None:
    """Draw the report's figure (see the module) into ``path``, written atomically; its
    format from the suffix (:func:`ecam.plot.check_figure_path`).

    Raises
    ------
    InputError
        A path whose format or directory cannot be written, or a report without samples.
    """
    check_figure_path(path)
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    fmt = {"jpg": "jpeg", "tif": "tiff"}.get(fmt, fmt)
    data = figure_bytes(report, fmt=fmt, dpi=dpi)
    try:
        write_files({path: data})
    except OSError as exc:
        raise InputError(f"plot file {str(path)!r} cannot be written: "
                         f"{exc.strerror or exc}") from None
