"""Bench rows of kind "sweep": samples per second of a robustness sweep of the shipped scene.

The sweep is ``stiff_coupling`` at its nominal speed (60 rpm, 2 master periods, the full
model) under the spread of a zero-backlash machine as built: the coupling's stiffness normal
within +-15 % (one sigma, truncated at +-45 %), the load's inertia triangular -10 / +30 %, the
motor's Coulomb friction uniform 0.02 .. 0.08 N m. The unit of work is one bus-free run per
sample (:func:`ecam.app.sweep_sample.run_sample`).

- quick (``ecam bench --quick``): a few samples run one after the other in this process, no
  Dask: the rate of the unit of work alone;
- full: the same sweep through ``ecam sweep``'s runner on a LocalCluster of 1 and of 2
  workers, the cluster's start counted; and the target of issue 25, 1000 samples in under
  2 minutes, projected from the 2-worker rate.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from ecam.camfile import read_toml
from hil_sim import SCENES_DIR

from .plan import RIG_SCENE
from .targets import target

#: The spread of the bench's sweep ([sweep.vary] of the scene).
BENCH_VARY = {
    "mechanics.coupling_stiffness": {"distribution": "normal", "mean": 1.0, "std": 0.15,
                                     "relative": True, "minimum": 0.55, "maximum": 1.45},
    "mechanics.load_inertia": {"distribution": "triangular", "low": 0.9, "mode": 1.0,
                               "high": 1.3, "relative": True},
    "mechanics.motor_coulomb_friction": {"distribution": "uniform", "low": 0.02, "high": 0.08},
}
#: Issue 25's aim: 1000 samples of stiff_coupling at its nominal speed in under 2 minutes.
TARGET_SAMPLES, TARGET_S = 1000, 120.0
TARGET_NAME = "sweep_1000_samples_s"
TARGET_LABEL = "1000 samples of stiff_coupling at its nominal speed <= 120 s (2 workers, projected)"


def bench_data(samples: int) -> tuple[Path, dict]:
    """The bench's sweep: the shipped scene's path and its mapping with a [sweep] table."""
    path = SCENES_DIR / RIG_SCENE
    data = read_toml(path, "scene file")
    data["sweep"] = {"samples": samples, "seed": 1, "vary": BENCH_VARY}
    return path, data


def bench_sweep(quick: bool = False, progress=None) -> list[dict]:
    """Rows of kind "sweep" (and the target row of the full run)."""
    from ..sweep import plan_sweep
    from ..sweep_sample import run_sample

    if quick:
        path, data = bench_data(8)
        plan = plan_sweep(path, data=data)
        run_sample(plan.task(0, 0))  # warm-up: imports and the cam's compilation
        start = time.perf_counter()
        results = [run_sample(plan.task(i, 0)) for i in range(plan.design.samples)]
        wall_s = time.perf_counter() - start
        if progress:
            progress()
        return [_row(plan, "in-process, serial", None, wall_s, len(results), None, results)]
    rows = []
    samples = 200
    path, data = bench_data(samples)
    for workers in (1, 2):
        rows.append(_cluster_row(path, data, workers))
        if progress:
            progress()
    two = rows[-1]
    projected = None if not two["samples_per_s"] else (
        two["cluster_s"] + TARGET_SAMPLES / two["steady_samples_per_s"])
    rows.append(target(TARGET_NAME, projected, "<=", TARGET_S,
                       {"samples_per_s_2_workers": two["samples_per_s"],
                        "steady_samples_per_s_2_workers": two["steady_samples_per_s"],
                        "cluster_s": two["cluster_s"]}, "no 2-worker sweep ran"))
    return rows


def _cluster_row(path: Path, data: dict, workers: int) -> dict:
    from ..sweep import plan_sweep, run_sweep

    with tempfile.TemporaryDirectory(prefix="ecam-bench-sweep-") as tmp:
        summary = run_sweep(path, data=data, workers=workers, directory=Path(tmp) / "out",
                            rerun_worst=False)
    timing = summary["timing"]
    plan = plan_sweep(path, data=data)
    row = _row(plan, f"LocalCluster, {workers} worker(s)", workers, timing["wall_s"],
               timing["runs"], timing.get("steady_runs_per_s"), None)
    row["cluster_s"] = timing.get("cluster_s")
    row["yield"] = summary["yield"]
    return row


def _row(plan, how: str, workers, wall_s: float, samples: int, steady, results) -> dict:
    rate = samples / wall_s if wall_s > 0 else None
    row = {"kind": "sweep", "scene": plan.scene.name, "how": how, "workers": workers,
           "samples": samples, "wall_s": wall_s, "samples_per_s": rate,
           "steady_samples_per_s": steady if steady is not None else rate,
           "speed": plan.speeds[0], "unit": plan.unit, "fidelity": plan.spec.fidelity,
           "vary": sorted(BENCH_VARY), "cluster_s": None}
    if results is not None:
        row["errors"] = sum(1 for r in results if r["error"])
        row["passed"] = sum(1 for r in results if r["passed"])
    return row


def sweep_lines(rows: list[dict]) -> list[str]:
    """The text of the "sweep" rows."""
    sweeps = [r for r in rows if r.get("kind") == "sweep"]
    if not sweeps:
        return []
    first = sweeps[0]
    lines = ["", f"sweep ({first['scene']} at {first['speed']:.4g} {first['unit']}/s, fidelity "
                 f"{first['fidelity']}, one bus-free run per sample; varied: "
                 f"{', '.join(first['vary'])}):"]
    for r in sweeps:
        start = "" if r["cluster_s"] is None else f", cluster start {r['cluster_s']:.3g} s"
        lines.append(f"  {r['how']}: {r['samples']} samples in {r['wall_s']:.3g} s = "
                     f"{r['samples_per_s']:.3g} samples/s ({r['steady_samples_per_s']:.3g}/s "
                     f"once running{start}); 1000 samples would take about "
                     f"{(r['cluster_s'] or 0.0) + 1000 / r['steady_samples_per_s']:.3g} s")
    return lines
