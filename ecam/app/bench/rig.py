"""Bench rows of kind "rig": the shipped scene at each bus cycle rate, and its cost split per cycle."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ecam.errors import SimulationError
from hil_sim import SCENES_DIR, plant as plant_module
from hil_sim.rig import find_max_speed, run_scene
from hil_sim.rig.cam import compile_cam
from hil_sim.scene import load_scene

from .plan import RIG_CYCLES_HZ, RIG_SCENE
from .tables import median_ns


def bench_rig(repeats: int = 1, cycles_hz=RIG_CYCLES_HZ, progress=None) -> list[dict]:
    """Rows of kind 'rig': the shipped scene at each bus cycle rate, over CANopen and bus-free;
    and one of kind 'rig_search': find-max-speed on it, its wall time and trials.

    The rig is part of the package, not an option: a rig that fails to run is an error, raised,
    never a row that looks like a measurement.
    """
    base = load_scene(SCENES_DIR / RIG_SCENE)
    run_scene(base)  # warm-up, not counted: imports and first-call caches
    rows = []
    for hz in cycles_hz:
        rows.append(_rig_row(base, hz, repeats, run_scene))
        if progress:
            progress()
    rows.append(_search_row(base))
    return rows


def _search_row(base) -> dict:
    """find-max-speed on the scene: bisection bus-free, the result confirmed over CANopen."""
    start = time.perf_counter()
    result = find_max_speed(base)
    wall_s = time.perf_counter() - start
    paths = [r["path"] for r in result["runs"]]
    return {"kind": "rig_search", "scene": base.name, "wall_s": wall_s,
            "speed": result["speed"], "unit": result["unit"],
            "trials_fast": paths.count("fast"), "trials_canopen": paths.count("canopen"),
            "limiting_check": result["limiting_check"], "resolution": result["resolution"]}


def _rig_row(base, hz: int, repeats: int, run_scene) -> dict:
    # the same 4 kHz controller at every bus rate: substeps follow the cycle
    substeps = max(1, round(base.drive.control_rate_hz / hz))
    scene = replace(base, drive=replace(base.drive, cycle_s=1.0 / hz, substeps=substeps))
    reports = [run_scene(scene) for _ in range(repeats)]
    fast = [run_scene(scene, path="fast") for _ in range(repeats)]
    fast.sort(key=lambda r: r.timing.get("loop_real_time_factor", 0.0))
    if not all(r.timing for r in reports):
        raise SimulationError(f"bench: scene {base.name}: the rig's report has no timing section")
    reports.sort(key=lambda r: r.timing.get("real_time_factor", 0.0))
    report = reports[len(reports) // 2]  # the median run, with its own consistent split
    t = report.timing
    cycles = max(report.cycles, 1)
    lookup_s, plant_s, notes = _rig_split(scene, report)
    axis_s = t.get("axis_s")
    drive_loop_s = None if axis_s is None else max(axis_s - (plant_s or 0.0), 0.0)
    per_cycle = {
        "lookup": lookup_s, "canopen": t.get("protocol_s"), "drive_loop": drive_loop_s, "plant": plant_s,
    }
    return {
        "kind": "rig",
        "available": True,
        "scene": report.scene,
        "cycle_hz": hz,
        "cycles": report.cycles,
        "simulated_s": t.get("simulated_s"),
        "wall_s": t.get("wall_s"),
        "real_time_factor": t.get("real_time_factor"),
        "loop_real_time_factor": t.get("loop_real_time_factor"),
        "fast_real_time_factor": fast[len(fast) // 2].timing.get("loop_real_time_factor"),
        "effects_s": t.get("effects_s"),
        "fidelity_runs": (report.summary.get("fidelity_proof") or {}).get("runs"),
        "substeps": substeps,
        "us_per_cycle": t.get("us_per_cycle"),
        "cost_us_per_cycle": {k: (None if v is None else 1e6 * v / cycles) for k, v in per_cycle.items()},
        "setup_s": t.get("setup_s"),
        "analysis_s": t.get("analysis_s"),
        "runs": repeats,
        "passed": report.passed,
        "failed_checks": [c.name for c in report.failed],
        "notes": notes,
    }


def _rig_split(scene, report):
    """(lookup_s, plant_s, notes): the rig times its loop as servo+plant ('axis') and the
    rest; the table lookups (done for all cycles at once before the loop) and the plant's share
    of 'axis' are measured here, standalone, for the same number of cycles."""
    notes = ["canopen = loop time outside the drive's control loop (bus, PDO/SYNC handling); "
             "drive_loop = the drive's servo loop minus plant; lookup and plant measured standalone "
             "for the same cycles"]
    compiled = compile_cam(scene)  # the rig's own table: what its lookups cost
    profile, table = compiled.profile, compiled.table
    per_unit = table.master_counts / profile.master_period
    counts_per_cycle = scene.master.units_per_second(profile.master_period) * per_unit * scene.drive.cycle_s
    k = np.arange(report.cycles, dtype=np.float64)
    master_end = np.rint((k + 1.0) * counts_per_cycle).astype(np.int64)
    master_mid = np.rint((k + 0.5) * counts_per_cycle).astype(np.int64)
    lookup_s = median_ns({"lookup": lambda: (table.lookup(master_end), table.slope(master_mid))},
                          5, 1)["lookup"] * 1e-9
    plant_class = plant_module.RigidPlant if report.model == "rigid" else plant_module.TwoMassPlant
    plant = plant_class(scene.mechanics.build(), scene.drive.cycle_s / scene.drive.substeps)
    plant.reset()
    steps = report.cycles * scene.drive.substeps
    step = plant.step
    start = time.perf_counter()
    for _ in range(steps):
        step(0.01)
    plant_s = time.perf_counter() - start
    return lookup_s, plant_s, notes


# --- targets ------------------------------------------------------------------------------------
