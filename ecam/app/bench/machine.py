"""Bench rows of kind "machine" and "machine_scaling": the shipped machine
(``hil_sim/machines/packaging_line.toml``) on both paths, and what N axes in one loop cost
against each axis run alone.

- ``"machine"``, one row per path (``fast``: bus-free; ``canopen``): ``axes``, ``cycles``,
  ``simulated_s``, ``wall_s`` (:func:`hil_sim.rig.machine_run.run_machine`, every axis's
  commissioning and effects' measurement included), ``real_time_factor``, ``loop_s`` and
  ``loop_real_time_factor`` (the lock-step loop alone), ``axis_s`` (each axis's servo and plant
  time, by name), ``us_per_cycle`` (the loop's), ``passed``.
- ``"machine_scaling"``, one row per path: ``loop_s`` of the machine's one loop, ``alone_s``
  (each axis run alone through the same loop, ``alone_sum_s`` their sum) and ``ratio`` =
  ``loop_s / alone_sum_s`` (1: N axes cost N times one; above 1: the overhead of their
  sharing one loop and one bus), best of ``repeats`` runs each, the axes commissioned once.

A quick run (``ecam bench --quick``) runs three master periods with every effect on (no
measurement of the effects), so its figures are smaller and not the shipped machine's.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

from hil_sim.machine import load_machine
from hil_sim.rig.machine_run import run_machine
from hil_sim.rig.run import PATHS, ready_axis, run_axes
from hil_sim.scene import DurationSpec

#: The shipped machine the bench runs, under ``hil_sim/machines``.
MACHINE_FILE = "packaging_line.toml"


def _machine_path():
    from pathlib import Path

    import hil_sim

    return Path(hil_sim.__file__).resolve().parent / "machines" / MACHINE_FILE


def bench_machine(quick: bool = False, repeats: int = 3, progress=None) -> list[dict]:
    """The rows (see the module docstring); ``progress()`` after each path."""
    machine = load_machine(_machine_path())
    if quick:
        machine = machine.with_fidelity("full")
        machine = replace(machine, axes=tuple(
            replace(a, duration=DurationSpec(master_periods=3.0)) for a in machine.axes))
        repeats = 1
    # made ready once for the scaling rows; this also warms the caches (cams, imports) the
    # first timed run would otherwise pay for
    axes = [ready_axis(scene) for scene in machine.axes]
    rows = []
    for path in PATHS:
        report = run_machine(machine, path=path)
        t = report.timing
        rows.append({
            "kind": "machine", "machine": report.machine, "path": path, "quick": quick,
            "axes": len(report.axes), "cycles": report.cycles,
            "simulated_s": t["simulated_s"], "wall_s": t["wall_s"],
            "real_time_factor": t["real_time_factor"],
            "tuning_s": t["tuning_s"], "effects_s": t["effects_s"], "loop_s": t["loop_s"],
            "loop_real_time_factor": t["loop_real_time_factor"],
            "axis_s": {a.scene: s for a, s in zip(report.axes, t["axis_s"])},
            "us_per_cycle": 1e6 * t["loop_s"] / max(report.cycles, 1),
            "passed": report.passed})
        if progress:
            progress()
    for path in PATHS:
        loop_s = _best(lambda: run_axes(axes, path), repeats)
        alone = {axis.run.scene.name: _best(lambda a=axis: run_axes([a], path), repeats)
                 for axis in axes}
        total = sum(alone.values())
        rows.append({"kind": "machine_scaling", "machine": machine.name, "path": path,
                     "quick": quick, "axes": len(axes), "loop_s": loop_s, "alone_s": alone,
                     "alone_sum_s": total, "ratio": loop_s / total if total > 0 else math.inf,
                     "repeats": repeats})
    return rows


def _best(run, repeats: int) -> float:
    """The shortest loop time of ``repeats`` runs (the least disturbed by other processes)."""
    best = math.inf
    for _ in range(repeats):
        _, timing = run()
        best = min(best, timing["loop_s"])
    return best


def machine_lines(rows: list[dict]) -> list[str]:
    """The rows as text lines for `ecam bench`."""
    machine = [r for r in rows if r.get("kind") == "machine"]
    lines = []
    if machine:
        lines += ["", f"machine (hil_sim/machines/{MACHINE_FILE}"
                  + ("; quick: 3 master periods, every effect on" if machine[0]["quick"] else "")
                  + "):"]
    for r in machine:
        lines.append(
            f"  {r['path']}: {r['axes']} axes, {r['cycles']} cycles ({r['simulated_s']:.3g} s "
            f"simulated) in {r['wall_s']:.3g} s: real-time factor {r['real_time_factor']:.3g}x "
            f"(commissioning {r['tuning_s']:.3g} s, effects {r['effects_s']:.3g} s); loop "
            f"{r['loop_s']:.3g} s, {r['loop_real_time_factor']:.3g}x real time, "
            f"{r['us_per_cycle']:.0f} us per cycle; {'passed' if r['passed'] else 'FAILED'}")
    for r in (r for r in rows if r.get("kind") == "machine_scaling"):
        alone = ", ".join(f"{name} {s:.3g}" for name, s in r["alone_s"].items())
        lines.append(
            f"  {r['path']}: one loop of {r['axes']} axes {r['loop_s']:.3g} s against "
            f"{r['alone_sum_s']:.3g} s for the axes alone ({alone} s): {r['ratio']:.3g}x their "
            f"sum (best of {r['repeats']})")
    return lines
