"""The drive's open loops as a Bode plot, the margins marked: what a commissioning engineer
reads off a drive's frequency-response tool (magnitude and phase of the velocity loop and of
the position loop, the crossover with its phase margin, the phase crossover with its gain
margin).

The responses are :mod:`hil_sim.tuning`'s, of the loop as the run has it; they travel in the
report's series (``loop_frequency_hz``, ``loop_velocity``, ``loop_position``, complex; and
``loop_gap_velocity``, the velocity loop in the backlash gap, with backlash), not in its JSON. The bytes are deterministic, as the rig's other figure (:mod:`hil_sim.rig.plot`), and
matplotlib is imported only inside the functions that draw.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from ecam.atomic_files import write_files
from ecam.errors import InputError
from ecam.plot import TEXT_AS_WRITTEN, check_figure_path
from hil_sim.control import AxisSetup
from hil_sim.report import Report
from hil_sim.rig.palette import GRID
from hil_sim.rig.plot import _LIMIT, _MUTED, _NO_METADATA, _PERIOD_COLOURS, _palette_png
from hil_sim.tuning import AxisLoops, margins_of

#: The series keys of the open loops.
SERIES = ("loop_frequency_hz", "loop_velocity", "loop_position")
#: Frequencies drawn: from this share of the velocity loop's crossover up to the Nyquist
#: frequency.
_LOWEST_SHARE = 0.01


def bode_series(setup: AxisSetup, cycle_s: float) -> dict:
    """The open loops of the axis ``setup`` builds, for the report's series."""
    loops = AxisLoops.from_setup(setup, cycle_s)
    contact = loops.contact
    velocity, position = contact.loops(setup.gains)
    out = {"loop_frequency_hz": contact.frequencies, "loop_velocity": velocity,
           "loop_position": position}
    if loops.gap is not None:  # the velocity loop in the backlash gap, on the same frequencies
        out["loop_gap_velocity"] = loops.gap.at(contact.frequencies).loops(setup.gains)[0]
    return out


def has_bode(report: Report) -> bool:
    """True when the report carries the open loops."""
    series = report.series or {}
    return all(key in series and len(series[key]) for key in SERIES)


def bode_figure(report: Report, width_in: float = 11.0):
    """A matplotlib figure: |L| [dB] and arg L [deg] of both loops over the frequency, the
    margins marked."""
    from matplotlib.figure import Figure

    if not has_bode(report):
        raise InputError(f"report {report.scene!r}: no open-loop response to plot")
    series = report.series
    f = np.asarray(series["loop_frequency_hz"])
    loops = [("velocity loop", np.asarray(series["loop_velocity"]), _PERIOD_COLOURS[0]),
             ("position loop", np.asarray(series["loop_position"]), _PERIOD_COLOURS[1])]
    if "loop_gap_velocity" in series:  # with backlash: the motor alone, in the gap
        loops.append(("velocity loop in the backlash gap", np.asarray(series["loop_gap_velocity"]),
                      _PERIOD_COLOURS[2]))
    first = margins_of(f, loops[0][1]).crossover_hz or f[-1]
    shown = f >= _LOWEST_SHARE * first
    fig = Figure(figsize=(width_in, 6.0), layout="constrained")
    magnitude_ax, phase_ax = fig.subplots(2, 1, sharex=True)
    for label, loop, colour in loops:
        x, value = f[shown], loop[shown]
        margins = margins_of(f, loop)
        pm = "inf" if not math.isfinite(margins.phase_margin_deg) else \
            f"{margins.phase_margin_deg:.3g} deg"
        gm = "inf" if not math.isfinite(margins.gain_margin_db) else \
            f"{margins.gain_margin_db:.3g} dB"
        magnitude_ax.semilogx(x, 20 * np.log10(np.abs(value)), color=colour, lw=1.2,
                              label=f"{label}: phase margin {pm}, gain margin {gm}, Ms "
                                    f"{margins.sensitivity_peak:.3g}")
        phase = np.degrees(np.unwrap(np.angle(value)))
        phase -= 360.0 * np.round((phase[0] + 90.0) / 360.0)  # the low end near -90..-180 deg
        phase_ax.semilogx(x, phase, color=colour, lw=1.2)
        if margins.crossover_hz is not None:
            at = np.interp(math.log(margins.crossover_hz), np.log(x), phase)
            phase_ax.annotate("", xy=(margins.crossover_hz, at),
                              xytext=(margins.crossover_hz, at - margins.phase_margin_deg
                                      if at > -180 else -180.0),
                              arrowprops={"arrowstyle": "<->", "color": colour})
            phase_ax.plot([margins.crossover_hz], [at], "o", color=colour, ms=4)
        if margins.phase_crossover_hz is not None:
            level = -margins.gain_margin_db
            magnitude_ax.annotate("", xy=(margins.phase_crossover_hz, level),
                                  xytext=(margins.phase_crossover_hz, 0.0),
                                  arrowprops={"arrowstyle": "<->", "color": colour})
    magnitude_ax.axhline(0.0, color=_LIMIT, lw=0.8)
    for level in (-180.0, -540.0):
        phase_ax.axhline(level, color=_LIMIT, lw=0.8)
    from matplotlib.ticker import FuncFormatter

    nyquist = f[-1]
    for ax in (magnitude_ax, phase_ax):
        ax.axvline(nyquist, color=_MUTED, lw=0.8, ls="--")
        # plain numbers: the rig draws text as written, never as mathtext
        ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        ax.grid(True, which="both", color=GRID, lw=0.5)
    magnitude_ax.set_ylabel("|L| [dB]")
    phase_ax.set_ylabel("arg L [deg]")
    phase_ax.set_xlabel("frequency [Hz] (dashed: the controller's Nyquist frequency)")
    magnitude_ax.legend(loc="lower left", fontsize=8)
    tuning = (report.summary or {}).get("tuning") or {}
    title = f"{report.scene}: open loops as the drive runs them"
    if tuning:
        title += f" (gains: {tuning.get('source')})"
    magnitude_ax.set_title(title, fontsize=10)
    return fig


def bode_bytes(report: Report, fmt: str = "png", dpi: int = 100) -> bytes:
    """The Bode figure as file contents, the same bytes for the same report."""
    import matplotlib

    buffer = io.BytesIO()
    with matplotlib.rc_context({"svg.hashsalt": "ecam", "pdf.compression": 6, **TEXT_AS_WRITTEN}):
        bode_figure(report).savefig(buffer, format=fmt, dpi=dpi, metadata=_NO_METADATA.get(fmt))
    return _palette_png(buffer.getvalue()) if fmt == "png" else buffer.getvalue()


def bode_path(path) -> Path:
    """Where the Bode plot of a run plotted to ``path`` goes: ``NAME_bode.SUFFIX`` beside it."""
    path = Path(path)
    return path.with_name(f"{path.stem}_bode{path.suffix}")


def plot_bode(report: Report, path, dpi: int = 110) -> None:
    """Draw the Bode figure into ``path`` (written atomically; format from the suffix)."""
    check_figure_path(path)
    path = Path(path)
    fmt = {"jpg": "jpeg", "tif": "tiff"}.get(path.suffix.lower().lstrip("."),
                                             path.suffix.lower().lstrip("."))
    data = bode_bytes(report, fmt=fmt, dpi=dpi)
    try:
        write_files({path: data})
    except OSError as exc:
        raise InputError(f"plot file {str(path)!r} cannot be written: {exc}") from None
