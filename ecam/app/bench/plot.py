"""Pareto fronts of error against bytes and against lookup cost, and their plot."""

from __future__ import annotations

import math
import statistics

from ecam.plot import save_figure

from .plan import IMPLEMENTATIONS, STROKE_COUNTS, TARGET_FRACTION


def pareto_front(points) -> list[int]:
    """Indices of the non-dominated points, lowest x first (both coordinates minimized).

    A point is dominated when another is no worse in both coordinates and better in one; equal
    points do not dominate each other. Points with a None or non-finite coordinate are ignored.
    """
    valid = [(i, float(x), float(y)) for i, (x, y) in enumerate(points)
             if x is not None and y is not None and math.isfinite(x) and math.isfinite(y)]
    front = [
        (x, y, i) for i, x, y in valid
        if not any(ox <= x and oy <= y and (ox < x or oy < y) for _, ox, oy in valid)
    ]
    return [i for _, _, i in sorted(front)]


_KIND_STYLE = {"linear": "tab:blue", "cubic": "tab:orange", "quintic": "tab:green", "auto": "tab:red"}
_PEER_STYLE = {"numpy_interp": ("numpy.interp", "0.3"), "scipy_cubic": ("scipy CubicSpline", "0.5"),
               "scipy_pchip": ("scipy Pchip", "0.7")}


def worst_over_cams(tables: list[dict]) -> list[dict]:
    """One point per configuration (kind and point count, or kind and tolerance) over all cams:
    the largest error (fraction of the stroke) and bytes, and the median cost per implementation.
    What it takes to meet that error on every cam of the run."""
    groups: dict = {}
    for r in tables:
        key = (r["interp"], r["points"] if r["tolerance_fraction"] is None else None, r["tolerance_fraction"])
        groups.setdefault(key, []).append(r)
    out = []
    for (kind, points, tolerance), members in groups.items():
        cost = {}
        for key in IMPLEMENTATIONS:
            values = [m["ns_per_lookup"].get(key) for m in members if m["ns_per_lookup"].get(key)]
            cost[key] = statistics.median(values) if values else None
        out.append({"interp": kind, "points": points, "tolerance_fraction": tolerance, "cams": len(members),
                    "bytes": max(m["bytes"] for m in members),
                    "max_error_fraction": max(m["max_error_fraction"] for m in members),
                    "ns_per_lookup": cost})
    return out


def plot_pareto(rows: list[dict], path) -> None:
    """Error against bytes and error against lookup cost: the Pareto fronts, one line per kind.

    Each configuration (a kind at a point count, or ``auto`` at a tolerance) is one point: its
    worst certified error over the cams of the run, as a fraction of the stroke, against its
    largest size, or against its median cost per lookup (C runtime, solid; Python vectorized
    lookup, dotted; random queries). The line joins the non-dominated points of the kind; faint
    dots are the single tables. The cost panel also shows the peers' fronts (the same points in
    float64; their error is measured on the random queries only).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tables = [r for r in rows if r.get("kind") == "table"]
    configs = worst_over_cams(tables)
    from matplotlib.ticker import FuncFormatter

    fig, (ax_bytes, ax_cost) = plt.subplots(1, 2, figsize=(15.5, 5.6), constrained_layout=True,
                                            gridspec_kw={"width_ratios": [1, 1.05]})

    def front(ax, pts, style, color, label, **kw):
        pts = [(x, y) for x, y in pts if x and y]
        if pts:
            chosen = [pts[i] for i in pareto_front(pts)]
            ax.plot(*zip(*chosen), style, color=color, label=label, **kw)

    for kind, color in _KIND_STYLE.items():
        singles = [r for r in tables if r["interp"] == kind]
        mine = [c for c in configs if c["interp"] == kind]
        ax_bytes.scatter([r["bytes"] for r in singles], [r["max_error_fraction"] for r in singles],
                         s=9, color=color, alpha=0.2, linewidths=0)
        front(ax_bytes, [(c["bytes"], c["max_error_fraction"]) for c in mine], "-o", color, kind, ms=4)
        front(ax_cost, [(c["ns_per_lookup"]["c"], c["max_error_fraction"]) for c in mine], "-o", color,
              f"{kind} (C)", ms=4)
        front(ax_cost, [(c["ns_per_lookup"]["python_random"], c["max_error_fraction"]) for c in mine], ":^",
              color, f"{kind} (Python, vectorized)", ms=4)
    for key, (label, color) in _PEER_STYLE.items():
        pts = [(r["ns_per_lookup"].get(key), (r["max_error_counts_on_queries"].get(key) or 0) / r["stroke_counts"])
               for r in tables]
        front(ax_cost, pts, "--s", color, f"{label} (same points, float64)", ms=3)
    floor = 0.5 / STROKE_COUNTS
    for ax in (ax_bytes, ax_cost):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axhline(TARGET_FRACTION, color="0.4", lw=0.8, ls=":")
        ax.axhline(floor, color="0.6", lw=0.8, ls="-.")
        ax.grid(True, which="major", alpha=0.3)
        ax.set_ylabel("max error / stroke (certified; worst cam)")
    for ax in (ax_bytes, ax_cost):
        left = ax.get_xlim()[0]
        ax.text(left, TARGET_FRACTION, " 1e-6 of the stroke", va="bottom", fontsize=8, color="0.3")
        ax.text(left, floor, " 1/2-count floor", va="bottom", fontsize=8, color="0.4")
    ax_bytes.legend(fontsize=8)
    ax_cost.legend(fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    plain = FuncFormatter(lambda value, _: f"{value:g}")
    ax_cost.xaxis.set_major_formatter(plain)
    ax_cost.xaxis.set_minor_formatter(FuncFormatter(
        lambda value, _: f"{value:g}" if f"{value:.0e}"[0] in "25" else ""))
    ax_bytes.set_xlabel("table bytes (header + payload; largest over the cams)")
    cams = len({r["law"] for r in tables})
    ax_bytes.set_title(f"error against size ({cams} cams, stroke {STROKE_COUNTS:.0e} counts)")
    ax_cost.set_xlabel("ns per lookup (median over the cams; random queries)")
    ax_cost.set_title("error against lookup cost")
    save_figure(fig, path)


# --- text ---------------------------------------------------------------------------------------
