"""Motion diagrams (matplotlib, imported only here, only when a plot is asked for)."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from .atomic_files import write_files
from .errors import InputError
from .profile import ORDER_NAMES, CamProfile

__all__ = ["plot_profile", "plot_fit", "check_figure_path", "save_figure", "MARKED", "LABELLED", "PER_SEGMENT",
           "TEXT_AS_WRITTEN"]

#: matplotlib settings under which every text is drawn as written: names and units come from
#: files, and a ``$`` in them must not start mathtext (a ``"$$"`` unit ended in a parser
#: traceback, issue 28) nor a backslash a TeX command. No figure here uses mathtext.
TEXT_AS_WRITTEN = {"text.parse_math": False, "text.usetex": False}

FIGURE_FORMATS = ("png", "svg", "pdf", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def check_figure_path(path) -> None:
    """Reject, before any work, a figure file whose format or directory cannot be written."""
    path = Path(path)
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in FIGURE_FORMATS:
        raise InputError(f"plot file {str(path)!r} has format {suffix or '(none)'!r}; "
                         f"expected one of {', '.join(FIGURE_FORMATS)}")
    if not os.path.isdir(path.parent):  # never raises (Path.is_dir does past NAME_MAX)
        raise InputError(f"plot file {str(path)!r}: directory {str(path.parent)!r} does not exist")


def save_figure(fig, path, dpi: int = 110) -> None:
    """Save and close a matplotlib figure; a bad path is one InputError line, not a traceback."""
    import matplotlib.pyplot as plt

    check_figure_path(path)
    # rendered in memory and written atomically: a plot path that is a symlink is replaced, never
    # followed, and a failed write leaves the old figure intact
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format=Path(path).suffix.lower().lstrip("."), dpi=dpi)
        write_files({Path(path): buffer.getvalue()})
    except OSError as exc:
        raise InputError(f"plot file {str(path)!r} cannot be written: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)


# Up to this many joints (and, per derivative, jumps) each is drawn; beyond, they fall closer
# together than a pixel of the 9-inch figure and would only paint it grey, so the figure says so
# instead.
MARKED = 1000
# Up to this many segments each is named along the top of the position plot; beyond, the names
# overlap into an unreadable band.
LABELLED = 60
# Beyond MARKED segments each curve is drawn as its band: the smallest and largest value in each of
# BANDS equal slices of the period (about four per pixel of the 9-inch figure at 110 dpi), which is
# what a line through millions of points would paint, at the cost of a few thousand.
BANDS = 4096
# Points inside every segment besides the even samples: with more segments than samples, the
# samples alone would fall on the joints only and show a dwell-to-dwell velocity of zero where the
# cam moves; these keep each segment's shape (its band of values, once the segments are narrower
# than a pixel).
PER_SEGMENT = 16


def plot_profile(profile: CamProfile, path, samples: int = 4001) -> None:
    """Position, velocity, acceleration and jerk against master position, written to ``path``.

    Each derivative is one artist (:meth:`~ecam.CamProfile.polyline`: every segment on its own
    points, never bridging a jump), the joints are dashed and the discontinuities found by
    ``check()`` are drawn as bars from one side's value to the other's, each kind in one artist,
    so the cost grows with the samples plus the segments, not with their product; beyond
    ``MARKED`` segments each curve is drawn as its band of values per ``1 / BANDS`` of the period
    (narrower than a pixel), the line through all its points would paint the same. Joints and
    jumps are drawn up to ``MARKED`` of each, segment names up to ``LABELLED`` segments; the
    title says what was left out beyond.

    Parameters
    ----------
    profile : CamProfile
    path : str or Path
        The figure file; its suffix picks the format (``FIGURE_FORMATS``).
    samples : int
        Evenly spaced master positions over the period; every joint and ``PER_SEGMENT`` points
        inside each segment are added.

    Raises
    ------
    InputError
        A figure format that is not known or a directory that does not exist (before any work),
        or a file that cannot be written.
    """
    check_figure_path(path)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    joints = profile.joints()
    starts = np.concatenate([[0.0], joints])
    spans = np.diff(np.append(starts, profile.master_period))
    inside = starts[:, None] + spans[:, None] * (np.arange(1, PER_SEGMENT + 1) / (PER_SEGMENT + 1))
    x = np.unique(np.concatenate([np.linspace(0.0, profile.master_period, samples), joints, inside.ravel()]))
    report = profile.check()
    with matplotlib.rc_context(TEXT_AS_WRITTEN):  # read when each text is made, and when drawn
        _draw_profile(plt, profile, x, joints, report, path)


def _draw_profile(plt, profile: CamProfile, x, joints, report, path) -> None:
    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(9, 9), constrained_layout=True)
    units = [profile.slave_unit] + [f"{profile.slave_unit}/{profile.master_unit}" + (f"^{k}" if k > 1 else "")
                                    for k in (1, 2, 3)]
    unmarked = [f"{joints.size} joints"] if joints.size > MARKED else []  # for the title
    for order, ax in enumerate(axes):
        xs, ys = profile.polyline(x, order)
        if len(profile.segments) <= MARKED:
            ax.add_collection(_curve(xs, ys), autolim=True)
            ax.autoscale_view()
        else:
            ax.plot(*_band(xs, ys, profile.master_period), color="C0", lw=1.4)
        if joints.size <= MARKED:
            ax.vlines(joints, 0.0, 1.0, transform=ax.get_xaxis_transform(), colors="0.75", lw=0.8,
                      linestyles="--", zorder=0)
        for severity, color in (("error", "C3"), ("warning", "C1")):
            found = [d for d in report.discontinuities if d.order == order and d.severity == severity]
            if len(found) > MARKED:
                unmarked.append(f"{len(found)} {ORDER_NAMES[order]} jumps")
            elif found:
                ax.vlines([d.master for d in found], [d.left for d in found], [d.right for d in found],
                          colors=color, lw=2.5, capstyle="projecting")  # as ax.plot draws a bar
        ax.set_ylabel(f"{ORDER_NAMES[order]}\n[{units[order]}]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(f"master [{profile.master_unit}]")
    title = (f"{profile.name or 'cam'}: {len(profile.segments)} segments, {len(report.errors)} discontinuities "
             f"(red), {len(report.warnings)} jerk jumps (orange)")
    title += "; dashed: joints" if joints.size <= MARKED else ""
    left_out = [f"too dense to mark: {', '.join(unmarked)}"] if unmarked else []
    if len(profile.segments) > LABELLED:
        left_out.append(f"segment names left out (over {LABELLED} segments)")
    axes[0].set_title("\n".join([title, "; ".join(left_out)]) if left_out else title)
    if len(profile.segments) <= LABELLED:
        for i, seg in enumerate(profile.segments):
            mid = (seg.master_start + seg.master_end) / 2
            axes[0].annotate(seg.label, (mid, 1.0), xycoords=("data", "axes fraction"), ha="center", va="top",
                             fontsize=7, xytext=(0, -4 - 10 * (i % 2)), textcoords="offset points")
    save_figure(fig, path)


def _curve(xs, ys):
    """One artist for all segments' lines (``polyline``'s points, split at its NaNs), drawn as
    ``ax.plot`` draws one line per segment: each piece is its own path, so a straight one (a
    dwell) is snapped to the pixel grid and stays crisp, and the ends are projecting caps."""
    from matplotlib.collections import LineCollection

    pieces = np.split(np.column_stack([xs, ys]), np.flatnonzero(np.isnan(xs)) + 1)  # each ends in its NaN
    return LineCollection([piece[:-1] if np.isnan(piece[-1, 0]) else piece for piece in pieces if piece.shape[0] > 1],
                          colors="C0", linewidths=1.4, capstyle="projecting", joinstyle="round")


def _band(xs, ys, period: float, bands: int = BANDS):
    """``polyline``'s points (sorted by master, NaN between segments) as one line that runs up and
    down each slice of the period from its smallest value to its largest."""
    keep = ~np.isnan(xs)
    xs, ys = xs[keep], ys[keep]
    which = np.minimum((xs * (bands / period)).astype(np.int64), bands - 1)
    present, first = np.unique(which, return_index=True)
    low, high = np.minimum.reduceat(ys, first), np.maximum.reduceat(ys, first)
    centres = (present + 0.5) * (period / bands)
    return np.repeat(centres, 2), np.column_stack([low, high]).ravel()


def plot_fit(result, path, samples: int = 4001) -> None:
    """A fit (:func:`ecam.fit_points`) over its motion diagram: the points and the fitted
    position, the residuals (fit - point), and the fit's velocity, acceleration and jerk.

    Parameters
    ----------
    result : ecam.fit.FitResult
    path : str or Path
        The figure file (``FIGURE_FORMATS``).
    """
    check_figure_path(path)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with matplotlib.rc_context(TEXT_AS_WRITTEN):  # names and units come from files
        _draw_fit(plt, result, path, samples)


def _draw_fit(plt, result, path, samples: int) -> None:
    profile = result.profile
    c = result.certificate
    offset = c["master_offset"]
    x = np.linspace(0.0, profile.master_period, samples)
    fig, axes = plt.subplots(5, 1, sharex=True, figsize=(9, 11), constrained_layout=True)
    unit, munit = profile.slave_unit, profile.master_unit
    shown = slice(None, None, max(1, result.master.size // 20000))  # a point per pixel is enough
    axes[0].plot(result.master[shown] - offset, result.slave[shown], ".", ms=2.5, color="0.45", label="points")
    axes[0].plot(x, profile(x), color="C0", lw=1.2, label="fit")
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_ylabel(f"position\n[{unit}]")
    axes[1].plot(result.master[shown] - offset, result.residuals[shown], ".", ms=2.5, color="C3")
    if c["tolerance"] is not None:
        for sign in (-1, 1):
            axes[1].axhline(sign * c["tolerance"], color="C1", lw=0.8, ls="--")
    axes[1].set_ylabel(f"fit - point\n[{unit}]")
    for order, ax in zip((1, 2, 3), axes[2:]):
        ax.plot(x, profile(x, order), color="C0", lw=1.2)
        ax.set_ylabel(f"{ORDER_NAMES[order]}\n[{unit}/{munit}" + (f"^{order}]" if order > 1 else "]"))
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(f"master [{munit}]" + (f" from {offset:.6g}" if offset else ""))
    how = "tolerance" if c["smoothing"] == "tolerance" else "GCV"
    axes[0].set_title(f"{profile.name or 'fit'}: {c['points']} points, quintic smoothing spline ({how})\n"
                      f"max deviation {c['max_deviation']:.3g} {unit}, rms {c['rms_deviation']:.3g} {unit}")
    save_figure(fig, path)
