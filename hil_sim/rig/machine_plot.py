"""The plots of a machine run: one figure of the machine (every axis's tracking error over the
virtual master's position, each as a share of its own limit, so stations of different units and
limits read on one scale) and each axis's own figure (:mod:`hil_sim.rig.plot`).

``plot_machine(report, "line.png")`` writes ``line.png`` (the machine) and ``line_<axis>.png``
per axis. Where an axis's tracking check does not look (before its settling time, outside its
tracking window: a knife's catch-up) its line is not drawn, as the check does not read it.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ecam.atomic_files import write_files
from ecam.errors import InputError
from ecam.plot import TEXT_AS_WRITTEN, check_figure_path
from hil_sim.rig.palette import GRID, LIMIT
from hil_sim.rig.plot import figure_bytes

#: One colour per axis (tab10 without its red, which marks the limit), repeated past nine axes.
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#17becf", "#e377c2",
           "#7f7f7f", "#bcbd22")
#: PNG metadata matplotlib would fill with its version: left out, the same bytes every run.
_NO_METADATA = {"png": {"Software": None}, "svg": {"Date": None, "Creator": None},
                "pdf": {"CreationDate": None, "Producer": None, "Creator": None}}


def axis_plot_path(path, axis: str) -> Path:
    """Where axis ``axis``'s figure goes beside the machine's ``path``: ``line_<axis>.png``."""
    path = Path(path)
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in axis)
    return path.with_name(f"{path.stem}_{safe}{path.suffix}")


def checked_tracking(report, machine_period: float):
    """One axis's tracking error where its check looks, over the machine's master position.

    Returns
    -------
    (x, share) : tuple of numpy.ndarray
        ``x`` the virtual master's position within the machine period [the first axis's master
        units: each axis's own master position, its phase taken off, as a share of its period];
        ``share`` |tracking error| / limit [%], NaN where the check does not look (before its
        ``after_s``, outside its master window) and where a master period wraps (no line
        across the seam). Empty arrays when the axis has no tracking limit or no samples.
    """
    series = report.series or {}
    try:
        tracking = report.check("tracking_error")
    except KeyError:
        tracking = None
    position = np.asarray(series.get("master_position", ()), dtype=float)
    if tracking is None or not tracking.limit or not len(position):
        return np.zeros(0), np.zeros(0)
    period = float(report.summary["master"]["period"])
    phase = float(report.summary.get("phase", 0.0))
    axis_master = position % period
    machine = (position - phase) % period
    share = 100.0 * np.abs(np.asarray(series["tracking_error"], dtype=float)) / tracking.limit
    window = tracking.to_dict().get("window") or {}
    looked = np.asarray(series["time_s"], dtype=float) >= float(window.get("after_s", 0.0))
    master = window.get("master")
    if master and len(master) == 2:
        start, end = (float(v) % period for v in master)
        inside = ((axis_master >= start) & (axis_master <= end) if start <= end
                  else (axis_master >= start) | (axis_master <= end))
        looked &= inside
    share = np.where(looked, share, np.nan)
    x = machine / period * machine_period
    wraps = np.flatnonzero(np.diff(x) < 0) + 1
    return np.insert(x, wraps, np.nan), np.insert(share, wraps, np.nan)


def machine_figure(report, width_in: float = 11.0):
    """The machine's figure: every axis's checked tracking error [% of its limit] over the
    virtual master's position, the limit at 100 %."""
    from matplotlib.figure import Figure

    first = report.axes[0]
    period = float(first.summary["master"]["period"])
    unit = (first.to_dict().get("units") or {}).get("master", "")
    fig = Figure(figsize=(width_in, 4.2), layout="constrained")
    ax = fig.add_subplot()
    peak = 100.0
    for i, axis in enumerate(report.axes):
        x, share = checked_tracking(axis, period)
        if not len(x):
            continue
        worst = np.nanmax(share) if np.any(np.isfinite(share)) else 0.0
        peak = max(peak, worst)
        ax.plot(x, share, lw=1.0, color=COLOURS[i % len(COLOURS)], label=f"{axis.scene} (node {axis.summary.get('node_id')}, "
                f"phase {axis.summary.get('phase', 0.0):g}; worst {worst:.3g} %)")
    ax.axhline(100.0, color=LIMIT, lw=1.0, ls="--", label="each axis's limit")
    ax.set_xlim(0.0, period)
    ax.set_ylim(0.0, 1.08 * peak)
    ax.set_xlabel(f"virtual master position within the machine cycle [{unit}]".replace(" []", ""))
    ax.set_ylabel("|tracking error| [% of the axis's limit]")
    verdict = "PASSED" if report.passed else "FAILED"
    ax.set_title(f"machine {report.machine}: {verdict}, {len(report.axes)} axes; tracking "
                 "error where each axis's check looks", loc="left", fontsize=10)
    ax.grid(True, color=GRID, lw=0.6)
    ax.legend(loc="upper right", fontsize=8)
    return fig


def machine_figure_bytes(report, fmt: str = "png", dpi: int = 100) -> bytes:
    """The machine's figure as file contents, the same bytes for the same report."""
    import matplotlib

    buffer = io.BytesIO()
    with matplotlib.rc_context({"svg.hashsalt": "ecam", **TEXT_AS_WRITTEN}):
        machine_figure(report).savefig(buffer, format=fmt, dpi=dpi,
                                       metadata=_NO_METADATA.get(fmt))
    return buffer.getvalue()


def plot_machine(report, path, dpi: int = 110) -> list[Path]:
    """Write the machine's figure to ``path`` and each axis's beside it
    (:func:`axis_plot_path`), atomically; return the paths written, the machine's first.

    Raises
    ------
    InputError
        A path whose format or directory cannot be written.
    """
    check_figure_path(path)
    path = Path(path)
    fmt = {"jpg": "jpeg", "tif": "tiff"}.get(path.suffix.lower().lstrip("."),
                                             path.suffix.lower().lstrip("."))
    files = {path: machine_figure_bytes(report, fmt=fmt, dpi=dpi)}
    for axis in report.axes:
        files[axis_plot_path(path, axis.scene)] = figure_bytes(axis, fmt=fmt, dpi=dpi)
    try:
        write_files(files)
    except OSError as exc:
        raise InputError(f"plot file {str(path)!r} cannot be written: "
                         f"{exc.strerror or exc}") from None
    return list(files)
