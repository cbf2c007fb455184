"""Motion diagrams (matplotlib, imported only here, only when a plot is asked for)."""

from __future__ import annotations

import numpy as np

from .profile import ORDER_NAMES, CamProfile

__all__ = ["plot_profile", "check_figure_path", "save_figure"]

FIGURE_FORMATS = ("png", "svg", "pdf", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def check_figure_path(path) -> None:
    """Reject, before any work, a figure file whose format or directory cannot be written."""
    from pathlib import Path

    from .errors import InputError

    path = Path(path)
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in FIGURE_FORMATS:
        raise InputError(f"plot file {str(path)!r} has format {suffix or '(none)'!r}; "
                         f"expected one of {', '.join(FIGURE_FORMATS)}")
    if not path.parent.is_dir():
        raise InputError(f"plot file {str(path)!r}: directory {str(path.parent)!r} does not exist")


def save_figure(fig, path, dpi: int = 110) -> None:
    """Save and close a matplotlib figure; a bad path is one InputError line, not a traceback."""
    import matplotlib.pyplot as plt

    from .errors import InputError

    check_figure_path(path)
    try:
        fig.savefig(path, dpi=dpi)
    except OSError as exc:
        raise InputError(f"plot file {str(path)!r} cannot be written: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)


def plot_profile(profile: CamProfile, path, samples: int = 4001) -> None:
    """Position, velocity, acceleration and jerk against master position, joints marked and
    discontinuities found by ``check()`` flagged, written to ``path`` (PNG, SVG or PDF)."""
    check_figure_path(path)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.linspace(0.0, profile.master_period, samples)
    x = np.unique(np.concatenate([x, profile.joints()]))
    report = profile.check()
    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(9, 9), constrained_layout=True)
    units = [profile.slave_unit] + [f"{profile.slave_unit}/{profile.master_unit}" + (f"^{k}" if k > 1 else "") for k in (1, 2, 3)]
    for order, ax in enumerate(axes):
        # draw each segment separately so jumps are not bridged by a line
        for seg in profile.segments:
            xs = x[(x >= seg.master_start) & (x <= seg.master_end)]
            ax.plot(xs, seg.evaluate(xs, order, "right"), color="C0", lw=1.4)
        for joint in profile.joints():
            ax.axvline(joint, color="0.75", lw=0.8, ls="--", zorder=0)
        for d in report.discontinuities:
            if d.order == order:
                color = "C1" if d.severity == "warning" else "C3"
                ax.plot([d.master, d.master], [d.left, d.right], color=color, lw=2.5)
        ax.set_ylabel(f"{ORDER_NAMES[order]}\n[{units[order]}]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(f"master [{profile.master_unit}]")
    errors, warnings = len(report.errors), len(report.warnings)
    axes[0].set_title(
        f"{profile.name or 'cam'}: {len(profile.segments)} segments, "
        f"{errors} discontinuities (red), {warnings} jerk jumps (orange); dashed: joints"
    )
    for i, seg in enumerate(profile.segments):
        mid = (seg.master_start + seg.master_end) / 2
        axes[0].annotate(seg.label, (mid, 1.0), xycoords=("data", "axes fraction"), ha="center", va="top",
                         fontsize=7, xytext=(0, -4 - 10 * (i % 2)), textcoords="offset points")
    save_figure(fig, path)
