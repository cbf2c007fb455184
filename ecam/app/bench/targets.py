"""The bench's targets: each met or missed, and by how much. Shown, never asserted."""

from __future__ import annotations

import math
import statistics

from ecam.table import KINDS

from .plan import TARGET_FRACTION


def target(name: str, value, relation: str, limit: float, detail: dict, what: str) -> dict:
    if value is None or not math.isfinite(value):
        return {"kind": "target", "name": name, "value": None, "relation": relation, "limit": limit,
                "met": None, "factor": None, "verdict": f"not measured ({what})", "detail": detail}
    met = value <= limit if relation == "<=" else value >= limit
    factor = value / limit
    if relation == "<=":
        verdict = (f"met, {limit / value:.3g}x margin" if met else
                   f"MISSED by {factor:.3g}x ({value:.3g} vs <= {limit:g}; {100 * (factor - 1):.0f}% over)")
    else:
        verdict = (f"met, {factor:.3g}x margin" if met else
                   f"MISSED by {1 / factor:.3g}x ({value:.3g} vs >= {limit:g}; {100 * (1 - factor):.0f}% short)")
    return {"kind": "target", "name": name, "value": value, "relation": relation, "limit": limit,
            "met": met, "factor": factor, "verdict": verdict, "detail": detail}


def evaluate_targets(rows: list[dict]) -> list[dict]:
    """The issue's targets, from the table and rig rows: each met or missed and by how much."""
    tables = [r for r in rows if r.get("kind") == "table"]
    out = []
    # 1. Python lookup <= 0.25x numpy.interp on random queries, per kind (median over the rows).
    for kind in KINDS:
        ratios = [r["ratio_to_numpy_interp"]["python_random"] for r in tables
                  if r["interp"] == kind and r["ratio_to_numpy_interp"].get("python_random") is not None]
        value = statistics.median(ratios) if ratios else None
        out.append(target(
            f"python_{kind}_vs_numpy_interp", value, "<=", 0.25,
            {"rows": len(ratios), "min": min(ratios, default=None), "max": max(ratios, default=None)},
            f"Python {kind} lookup / numpy.interp, random queries (median over {len(ratios)} tables)"))
    # 2. C cubic <= 2x C linear: same cam, same point count, random queries.
    by_key = {(r["law"], r["interp"], r["points"]): r for r in tables if r["tolerance_fraction"] is None}
    pairs = []
    for (law, kind, points), row in by_key.items():
        other = by_key.get((law, "linear", points))
        if kind == "cubic" and other and row["ns_per_lookup"]["c"] and other["ns_per_lookup"]["c"]:
            pairs.append((row["ns_per_lookup"]["c"] / other["ns_per_lookup"]["c"], law, points))
    value = statistics.median(p[0] for p in pairs) if pairs else None
    worst = max(pairs, default=None)
    out.append(target(
        "c_cubic_vs_c_linear", value, "<=", 2.0,
        {"pairs": len(pairs),
         "worst": None if worst is None else {"ratio": worst[0], "law": worst[1], "points": worst[2]}},
        f"C cubic / C linear lookup, same cam and points, random queries (median over {len(pairs)} pairs)"))
    # 3. auto at 1e-6 of the stroke <= 1/10 of the bytes of linear at 1e-6 (worst cam).
    per_law = []
    for law in dict.fromkeys(r["law"] for r in tables):
        at_target = [r for r in tables if r["law"] == law and r["tolerance_fraction"] == TARGET_FRACTION]
        auto = [r for r in at_target if r["interp"] == "auto"]
        linear = [r for r in at_target if r["interp"] == "linear"]
        if auto and linear:
            per_law.append({"law": law, "ratio": auto[0]["bytes"] / linear[0]["bytes"], "auto_bytes": auto[0]["bytes"],
                            "auto_kind": auto[0]["chosen_interp"], "linear_bytes": linear[0]["bytes"]})
    value = max((p["ratio"] for p in per_law), default=None)
    out.append(target("auto_bytes_vs_linear_at_1e-6", value, "<=", 0.1, {"cams": per_law},
                       "auto bytes / linear bytes at 1e-6 of the stroke (worst cam)"))
    # 4. Rig >= 20x real time at a 1 kHz cycle.
    rig = next((r for r in rows if r.get("kind") == "rig" and r.get("cycle_hz") == 1000 and r.get("available")), None)
    value = None if rig is None else rig.get("real_time_factor")
    out.append(target("rig_real_time_factor_1khz", value, ">=", 20.0,
                       {} if rig is None else {"loop_real_time_factor": rig.get("loop_real_time_factor"),
                                               "wall_s": rig.get("wall_s"), "simulated_s": rig.get("simulated_s")},
                       "rig real-time factor at 1 kHz (whole run: compile, setup, loop, analysis)"))
    # 5. The bus-free path (effects measurement, find-max-speed) >= 100x real time at 1 kHz.
    value = None if rig is None else rig.get("fast_real_time_factor")
    out.append(target("rig_fast_path_real_time_factor_1khz", value, ">=", 100.0,
                       {} if rig is None else {"substeps": rig.get("substeps")},
                       "the rig's bus-free path at a 1 kHz cycle (control and plant alone)"))
    return out


TARGET_TEXT = {
    "python_linear_vs_numpy_interp": "Python lookup <= 0.25x numpy.interp, random queries, linear tables (median)",
    "python_cubic_vs_numpy_interp": "Python lookup <= 0.25x numpy.interp, random queries, cubic tables (median)",
    "python_quintic_vs_numpy_interp": "Python lookup <= 0.25x numpy.interp, random queries, quintic tables (median)",
    "c_cubic_vs_c_linear": "C cubic lookup <= 2x C linear lookup (same cam and points, median)",
    "auto_bytes_vs_linear_at_1e-6": "auto <= 1/10 of the bytes of linear at 1e-6 of the stroke (worst cam)",
    "rig_real_time_factor_1khz": "rig >= 20x faster than real time at a 1 kHz cycle (whole run)",
    "rig_fast_path_real_time_factor_1khz": "the rig's bus-free path >= 100x real time at a 1 kHz cycle",
    "sweep_1000_samples_s": "1000 samples of stiff_coupling at its nominal speed <= 120 s (2 workers, projected)",
}


# --- the whole run --------------------------------------------------------------------------------
