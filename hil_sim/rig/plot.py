"""The rig's figure: tracking error, coupling torque with its ratings, following error.

matplotlib is imported inside :func:`plot_report`, and only there, so that a run without
``plot`` (every test, every CI job) never loads it.
"""

from __future__ import annotations

import numpy as np

from ecam.plot import save_figure
from hil_sim.report import Report


def plot_report(report: Report, path) -> None:
    """Tracking error, coupling torque with its limits, and following error, in one figure,
    saved to ``path`` (its format from the suffix, see :func:`ecam.plot.check_figure_path`)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = report.series
    time_s = s["time_s"]
    units = report.summary.get("units", {})
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), constrained_layout=True)
    ax = axes[0]
    ax.plot(time_s, s["tracking_error"], lw=0.8)
    _limit_lines(ax, _limit(report, "tracking_error"), s["tracking_error"])
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"load tracking error [{units.get('slave', '')}]")
    ax.set_title(f"{report.scene}: {report.model} model, "
                 f"{'passed' if report.passed else 'failed'}")
    ax = axes[1]
    ax.plot(time_s, s["coupling_torque"], lw=0.8, label="coupling torque")
    mechanics = report.summary.get("mechanics", {})
    for key, style in (("coupling_rated_torque", ":"), ("coupling_max_torque", "--")):
        value = mechanics.get(key)
        if value:
            for sign in (1, -1):
                ax.axhline(sign * value, color="tab:red", ls=style, lw=0.8,
                           label=key.replace("_", " ") if sign > 0 else None)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("torque [N m]")
    ax.legend(loc="upper right", fontsize="small")
    ax = axes[2]
    ax.plot(s["master_position"], s["following_error"], ".", ms=1.5)
    _limit_lines(ax, _limit(report, "following_error"), s["following_error"])
    ax.set_xlabel(f"master position in the cam period [{units.get('master', '')}]")
    ax.set_ylabel("following error [counts]")
    save_figure(fig, path)


def _limit_lines(ax, limit, data) -> None:
    """Dashed +-limit lines, unless the limit is so far away that the data would be a flat line
    (then the limit goes into the legend only)."""
    if limit is None:
        return
    finite = np.abs(np.asarray(data, dtype=float))
    finite = finite[np.isfinite(finite)]
    peak = float(finite.max()) if finite.size else 0.0
    if limit <= 5.0 * peak:
        for sign in (1, -1):
            ax.axhline(sign * limit, color="tab:red", ls="--", lw=0.8,
                       label=f"limit {limit:.4g}" if sign > 0 else None)
    else:
        ax.plot([], [], color="tab:red", ls="--", lw=0.8, label=f"limit {limit:.4g} (off scale)")
    ax.legend(loc="upper right", fontsize="small")


def _limit(report: Report, name: str):
    try:
        return report.check(name).limit
    except KeyError:
        return None
