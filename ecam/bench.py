"""`ecam bench`: error against bytes and lookup cost of the table kinds, against peers, and the
speed of the rig.

What runs
---------
For each cam (the laws cycloidal, poly345, modified_sine, harmonic as a rise over half the period
and its mirror-image return, and the seed cam ``combination_drrd``), each interpolation kind and a
range of point counts (``auto``: a range of tolerances; every kind also at the target tolerance,
1e-6 of the stroke), one table is compiled and certified, then timed:

- ``python_random`` / ``python_sequential``: :meth:`ecam.CamTable.lookup` (vectorized integer
  lookup, positions only) on random and on sequential master positions;
- ``c`` / ``c_sequential``: the C runtime (``firmware_tables/ecam_table.c``), driven by
  ``firmware_tables/ecam_bench.c``, compiled once per run with ``cc -O2 -std=c99`` (skipped, with
  a note, when there is no compiler); the driver times its own loop and returns a checksum of the
  positions, which must equal the Python lookup's on the same queries (``c_checksum_match``);
- peers on an equivalent float table (the same points, positions in float64):
  ``numpy_interp`` / ``numpy_interp_sequential`` (:func:`numpy.interp`), and, when scipy is
  installed (the ``bench`` extra), ``scipy_cubic`` (:class:`scipy.interpolate.CubicSpline`,
  periodic end conditions for a periodic cam) and ``scipy_pchip``
  (:class:`scipy.interpolate.PchipInterpolator`), on the random queries.

Every implementation gets the same query arrays (int64 counts; float64 copies for the peers):
``random`` is uniform over one master period, ``sequential`` a monotone ramp over the period, as
a streaming master produces. Times are medians of repeated runs (interleaved across the Python
and peer implementations, so drift hits all alike) in ns per lookup, and each is also given as
a ratio to ``numpy.interp`` on the same query set in the same run.

Scale: every cam is compiled with ``slave_counts_per_unit`` chosen so that its stroke is
``STROKE_COUNTS`` = 1e9 counts (int32 holds +-2.1e9) over ``MASTER_COUNTS`` = 1179648 master
counts per period. So 1e-6 of the stroke is 1000 counts, far above the 1/2-count quantization
floor, and the kinds separate by interpolation error rather than by rounding.

The rig: the shipped scene ``hil_sim/scenes/stiff_coupling.toml`` at 1 kHz and 4 kHz bus cycles
(the scene's ``cycle_s`` overridden), real-time factor and the cost split per cycle.

JSON shape (``--json``)
-----------------------
A list of rows, the table rows first; every row has the contract keys ``law``, ``interp``,
``points``, ``bytes``, ``max_error_counts``, ``ns_per_lookup`` (None on rows that are not tables)
and a ``kind``:

- ``"table"``: ``law``, ``interp`` (``auto`` rows also ``chosen_interp``), ``points``, ``bytes``,
  ``max_error_counts`` / ``max_error_units`` / ``max_error_fraction`` (the certificate's measured
  error, in counts, slave units and fractions of the stroke), ``predicted_error_counts`` (the
  certified bound), ``tolerance_fraction`` (or None), ``compile_s``, ``ns_per_lookup`` (an object
  keyed by implementation as above; None where one did not run), ``ratio_to_numpy_interp`` (the
  same keys; sequential timings are divided by ``numpy_interp_sequential``, the others by
  ``numpy_interp``), ``max_error_counts_on_queries`` (the error of the Python lookup and of each
  peer on the random queries), ``c_checksum_match`` (True, False or None).
- ``"rig"``: ``cycle_hz``, ``real_time_factor``, ``loop_real_time_factor``, ``us_per_cycle`` and
  ``cost_us_per_cycle`` (``lookup``, ``canopen``, ``drive_loop``, ``plant``), or
  ``available: false`` with a ``reason``.
- ``"target"``: ``name``, ``value``, ``relation``, ``limit``, ``met``, ``factor`` (value / limit),
  ``verdict`` (one line saying met or missed and by how much), ``detail``.
- ``"note"``: ``text`` (the scale, the queries, what was skipped and why).

Targets are shown, never asserted: the numbers depend on the machine.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import statistics
import subprocess
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .errors import EcamError, InputError, SimulationError
from .export import plain

__all__ = [
    "run_bench", "plot_pareto", "pareto_front", "worst_over_cams", "evaluate_targets", "format_text", "main",
    "checksum", "MASTER_COUNTS", "STROKE_COUNTS", "LAW_NAMES", "SEED_CAM",
]

MASTER_COUNTS = 9 * 2**17  # 1179648: every 20-degree joint of the seed and every 1/16 period on a power-of-two step
STROKE_COUNTS = 1e9  # slave counts of every cam's stroke (positions stay inside int32)
LAW_NAMES = ("cycloidal", "poly345", "modified_sine", "harmonic")
SEED_CAM = "combination_drrd"
KIND_NAMES = ("linear", "cubic", "quintic", "auto")
TARGET_FRACTION = 1e-6  # of the stroke, for the bytes target
RIG_CYCLES_HZ = (1000, 4000)
RIG_SCENE = "stiff_coupling.toml"
_MIX = 0x9E3779B97F4A7C15  # checksum mixing constant, as in ecam_bench.c
_FIRMWARE = Path(__file__).resolve().parents[1] / "firmware_tables"
_RANDOM_SEED = 20240917

# Implementation keys of ns_per_lookup, and which numpy.interp timing each is a ratio to.
IMPLEMENTATIONS = ("python_random", "python_sequential", "c", "c_sequential", "numpy_interp",
                   "numpy_interp_sequential", "scipy_cubic", "scipy_pchip")
_SEQUENTIAL = {"python_sequential", "c_sequential", "numpy_interp_sequential"}


@dataclass(frozen=True)
class BenchPlan:
    """What one run measures. Intervals per kind are divisors of MASTER_COUNTS that put every
    joint of the cams on a table point; tolerances are fractions of the stroke."""

    laws: tuple[str, ...]
    intervals: dict
    auto_tolerances: tuple[float, ...]
    kind_tolerances: tuple[str, ...]  # kinds also compiled at TARGET_FRACTION
    queries: int
    repeats: int
    rig_repeats: int


def bench_plan(quick: bool) -> BenchPlan:
    """The full plan (about two minutes) or the quick one (seconds, for CI smoke tests)."""
    if quick:
        return BenchPlan(
            laws=("cycloidal", SEED_CAM),
            intervals={"linear": (144,), "cubic": (144,), "quintic": (144,)},
            auto_tolerances=(TARGET_FRACTION,),
            kind_tolerances=("linear",),
            queries=2**14, repeats=3, rig_repeats=1,
        )
    return BenchPlan(
        laws=(*LAW_NAMES, SEED_CAM),
        intervals={"linear": (144, 576, 2304, 9216, 36864), "cubic": (36, 144, 576, 2304, 9216),
                   "quintic": (18, 72, 288, 1152, 4608)},
        auto_tolerances=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8),
        kind_tolerances=("linear", "cubic", "quintic"),
        queries=2**18, repeats=7, rig_repeats=3,
    )


# --- cams and queries -----------------------------------------------------------------------------


def bench_profile(name: str):
    """The cam of one bench row: a law as a rise over half the period and its mirror-image
    return (periodic, stroke 1 'stroke' unit), or the seed cam file of that name."""
    from .camfile import load_cam, parse_cam

    if name in LAW_NAMES:
        return parse_cam({
            "name": name, "master_period": 360.0, "periodic": True, "master_unit": "deg",
            "slave_unit": "stroke",
            "segment": [{"law": name, "span": 180.0, "stroke": 1.0},
                        {"law": name, "span": 180.0, "stroke": -1.0}],
        }, source=f"<bench {name}>")
    return load_cam(Path(__file__).resolve().parent / "cams" / f"{name}.toml")


def bench_queries(count: int, master_counts: int = MASTER_COUNTS, seed: int = _RANDOM_SEED):
    """(random, sequential) int64 master positions: uniform over [0, M), and a monotone ramp
    from 0 to M - 1 (a master streaming through one period)."""
    rng = np.random.default_rng(seed)
    random = rng.integers(0, master_counts, size=count, dtype=np.int64)
    sequential = np.rint(np.linspace(0, master_counts - 1, count)).astype(np.int64)
    return random, sequential


def checksum(positions) -> int:
    """The checksum ecam_bench.c prints: s1 = sum p[k], s2 = sum (n - k) p[k], both mod 2^64,
    returned as (s1 + s2 * 0x9E3779B97F4A7C15) mod 2^64."""
    p = np.asarray(positions, dtype=np.int64).astype(np.uint64)
    n = p.size
    with np.errstate(over="ignore"):
        s1 = int(p.sum(dtype=np.uint64))
        s2 = int((p * (n - np.arange(n, dtype=np.uint64))).sum(dtype=np.uint64))
    return (s1 + s2 * _MIX) % 2**64


def _median_ns(functions: dict, repeats: int, count: int) -> dict:
    """Median ns per query of each callable, the runs interleaved round-robin after a warm-up."""
    times = {name: [] for name in functions}
    for fn in functions.values():
        fn()
    for _ in range(repeats):
        for name, fn in functions.items():
            start = time.perf_counter_ns()
            fn()
            times[name].append(time.perf_counter_ns() - start)
    return {name: statistics.median(values) / count for name, values in times.items()}


# --- the C runtime ------------------------------------------------------------------------------


class _CRuntime:
    """ecam_bench.c + ecam_table.c compiled once into a temporary directory."""

    def __init__(self, directory: Path):
        self.directory = directory
        self.executable = None
        self.note = ""
        self.command = ""
        sources = [_FIRMWARE / "ecam_bench.c", _FIRMWARE / "ecam_table.c"]
        missing = [str(s) for s in sources + [_FIRMWARE / "ecam_table.h"] if not s.is_file()]
        compiler = next((shutil.which(c) for c in (os.environ.get("CC", "cc"), "cc", "gcc", "clang")
                         if c and shutil.which(c)), None)
        if missing:
            self.note = f"C runtime skipped: {', '.join(missing)} not found (run from a source checkout)"
            return
        if compiler is None:
            self.note = "C runtime skipped: no C compiler (cc, gcc, clang) on PATH"
            return
        exe = directory / "ecam_bench"
        cmd = [compiler, "-O2", "-std=c99", "-I", str(_FIRMWARE), "-o", str(exe), *map(str, sources)]
        self.command = f"{Path(compiler).name} -O2 -std=c99 ecam_bench.c ecam_table.c"
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.TimeoutExpired) as exc:
            self.note = f"C runtime skipped: {self.command} failed: {exc}"
            return
        if proc.returncode != 0:
            first = (proc.stderr.strip().splitlines() or ["(no message)"])[0]
            self.note = f"C runtime skipped: {self.command} failed: {first}"
            return
        self.executable = exe

    def run(self, blob: bytes, repeats: int, query_files) -> list:
        """[(ns_per_lookup, checksum)] per query file; raises RuntimeError with the reason."""
        blob_path = self.directory / "table.bin"
        blob_path.write_bytes(blob)
        try:
            proc = subprocess.run([str(self.executable), str(blob_path), str(repeats), *map(str, query_files)],
                                  capture_output=True, text=True, timeout=600)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise RuntimeError(f"ecam_bench did not run: {exc}") from None
        if proc.returncode != 0:
            why = (proc.stdout.strip() or proc.stderr.strip() or f"exit status {proc.returncode}").splitlines()[0]
            raise RuntimeError(f"ecam_bench: {why}")
        out = []
        for line in proc.stdout.split("\n"):
            if line.strip():
                ns, total = line.split()
                out.append((float(ns), int(total)))
        if len(out) != len(query_files):
            raise RuntimeError(f"ecam_bench printed {len(out)} lines for {len(query_files)} query files")
        return out


# --- one table ----------------------------------------------------------------------------------


class _LawContext:
    """One cam at the bench scale, with the exact positions at the random queries."""

    def __init__(self, name: str, queries):
        self.name = name
        self.profile = bench_profile(name)
        low, high = self.profile.slave_range
        self.stroke_units = high - low
        self.scale = STROKE_COUNTS / self.stroke_units
        self.unit = self.profile.master_period / MASTER_COUNTS
        self.random, self.sequential = queries
        self.random_float = self.random.astype(np.float64)
        self.sequential_float = self.sequential.astype(np.float64)
        self.exact_random = np.asarray(self.profile(self.random_float * self.unit), dtype=np.float64) * self.scale


def _bench_table(ctx: _LawContext, job: dict, plan: BenchPlan, c_runtime, query_files, scipy_interpolate) -> dict:
    from .compile import compile_table

    kwargs = {"interp": job["interp"], "master_counts": MASTER_COUNTS, "slave_counts_per_unit": ctx.scale}
    if job.get("intervals") is not None:
        kwargs["points"] = job["intervals"] + 1
    else:
        kwargs["tolerance"] = job["tolerance_fraction"] * ctx.stroke_units
    start = time.perf_counter()
    table = compile_table(ctx.profile, **kwargs)
    compile_s = time.perf_counter() - start
    report = table.report
    f = table.format
    n = plan.queries

    # Peers: the same points, positions in float64.
    xp = np.arange(f.points, dtype=np.float64) * f.step_counts
    fp = table.positions.astype(np.float64) / 2.0**f.position_bits
    functions = {
        "python_random": lambda: table.lookup(ctx.random),
        "python_sequential": lambda: table.lookup(ctx.sequential),
        "numpy_interp": lambda: np.interp(ctx.random_float, xp, fp),
        "numpy_interp_sequential": lambda: np.interp(ctx.sequential_float, xp, fp),
    }
    peers = {"numpy_interp": functions["numpy_interp"]}
    if scipy_interpolate is not None:
        periodic = f.periodic and fp[0] == fp[-1]
        spline = scipy_interpolate.CubicSpline(xp, fp, bc_type="periodic" if periodic else "not-a-knot")
        pchip = scipy_interpolate.PchipInterpolator(xp, fp)
        functions["scipy_cubic"] = peers["scipy_cubic"] = lambda: spline(ctx.random_float)
        functions["scipy_pchip"] = peers["scipy_pchip"] = lambda: pchip(ctx.random_float)
    ns = dict.fromkeys(IMPLEMENTATIONS)
    ns.update(_median_ns(functions, plan.repeats, n))

    python_random = table.lookup(ctx.random)
    python_sequential = table.lookup(ctx.sequential)
    errors = {"python": float(np.abs(python_random - ctx.exact_random).max())}
    for name, fn in peers.items():
        errors[name] = float(np.abs(fn() - ctx.exact_random).max())

    match = None
    c_error = ""
    if c_runtime is not None and c_runtime.executable is not None:
        try:
            (ns["c"], c_random), (ns["c_sequential"], c_sequential) = c_runtime.run(
                table.to_bytes(), plan.repeats, query_files)
            match = c_random == checksum(python_random) and c_sequential == checksum(python_sequential)
        except RuntimeError as exc:
            c_error = str(exc)

    ratios = {}
    for key, value in ns.items():
        base = ns["numpy_interp_sequential" if key in _SEQUENTIAL else "numpy_interp"]
        ratios[key] = value / base if value is not None and base else None
    row = {
        "kind": "table",
        "law": ctx.name,
        "interp": job["interp"],
        "chosen_interp": f.interp,
        "tolerance_fraction": job.get("tolerance_fraction"),
        "points": f.points,
        "intervals": f.points - 1,
        "step_counts": f.step_counts,
        "master_counts": f.master_counts,
        "bytes": table.nbytes,
        "max_error_counts": report["max_error_counts"],
        "max_error_units": report["max_error_units"],
        "max_error_fraction": report["max_error_units"] / ctx.stroke_units,
        "predicted_error_counts": report["predicted_error_counts"],
        "slave_unit": ctx.profile.slave_unit,
        "slave_counts_per_unit": ctx.scale,
        "stroke_counts": STROKE_COUNTS,
        "compile_s": compile_s,
        "queries": n,
        "repeats": plan.repeats,
        "ns_per_lookup": ns,
        "ratio_to_numpy_interp": ratios,
        "max_error_counts_on_queries": errors,
        "c_checksum_match": match,
    }
    if c_error:
        row["c_error"] = c_error
    return row


def _jobs(plan: BenchPlan) -> list[dict]:
    jobs = []
    for law in plan.laws:
        for kind in ("linear", "cubic", "quintic"):
            for intervals in plan.intervals[kind]:
                jobs.append({"law": law, "interp": kind, "intervals": intervals})
        for kind in plan.kind_tolerances:
            jobs.append({"law": law, "interp": kind, "tolerance_fraction": TARGET_FRACTION})
        for tolerance in plan.auto_tolerances:
            jobs.append({"law": law, "interp": "auto", "tolerance_fraction": tolerance})
    return jobs


# --- the rig ------------------------------------------------------------------------------------


def bench_rig(repeats: int = 1, cycles_hz=RIG_CYCLES_HZ, progress=None) -> list[dict]:
    """Rows of kind 'rig': the shipped scene at each bus cycle rate.

    The rig is part of the package, not an option: a rig that fails to run is an error, raised,
    never a row that looks like a measurement.
    """
    from hil_sim.demo import SCENES_DIR
    from hil_sim.rig import run_scene
    from hil_sim.scene import load_scene

    base = load_scene(SCENES_DIR / RIG_SCENE)
    run_scene(base)  # warm-up, not counted: imports and first-call caches
    rows = []
    for hz in cycles_hz:
        rows.append(_rig_row(base, hz, repeats, run_scene))
        if progress:
            progress()
    return rows


def _rig_row(base, hz: int, repeats: int, run_scene) -> dict:
    scene = replace(base, drive=replace(base.drive, cycle_s=1.0 / hz))
    reports = [run_scene(scene) for _ in range(repeats)]
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
    import ecam

    profile = ecam.load_cam(scene.cam.file)
    spec = scene.cam
    kwargs = {"interp": spec.interp, "master_counts": spec.master_counts,
              "slave_counts_per_unit": spec.slave_counts_per_unit}
    if spec.points is not None:
        kwargs["points"] = spec.points
    if spec.tolerance is not None:
        kwargs["tolerance"] = spec.tolerance
    table = ecam.compile_table(profile, certify=False, **kwargs)
    per_unit = table.master_counts / profile.master_period
    counts_per_cycle = scene.master.units_per_second(profile.master_period) * per_unit * scene.drive.cycle_s
    k = np.arange(report.cycles, dtype=np.float64)
    master_end = np.rint((k + 1.0) * counts_per_cycle).astype(np.int64)
    master_mid = np.rint((k + 0.5) * counts_per_cycle).astype(np.int64)
    lookup_s = _median_ns({"lookup": lambda: (table.lookup(master_end), table.slope(master_mid))},
                          5, 1)["lookup"] * 1e-9
    from hil_sim import plant as plant_module

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


def _target(name: str, value, relation: str, limit: float, detail: dict, what: str) -> dict:
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
    for kind in ("linear", "cubic", "quintic"):
        ratios = [r["ratio_to_numpy_interp"]["python_random"] for r in tables
                  if r["interp"] == kind and r["ratio_to_numpy_interp"].get("python_random") is not None]
        value = statistics.median(ratios) if ratios else None
        out.append(_target(
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
    out.append(_target(
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
    out.append(_target("auto_bytes_vs_linear_at_1e-6", value, "<=", 0.1, {"cams": per_law},
                       "auto bytes / linear bytes at 1e-6 of the stroke (worst cam)"))
    # 4. Rig >= 20x real time at a 1 kHz cycle.
    rig = next((r for r in rows if r.get("kind") == "rig" and r.get("cycle_hz") == 1000 and r.get("available")), None)
    value = None if rig is None else rig.get("real_time_factor")
    out.append(_target("rig_real_time_factor_1khz", value, ">=", 20.0,
                       {} if rig is None else {"loop_real_time_factor": rig.get("loop_real_time_factor"),
                                               "wall_s": rig.get("wall_s"), "simulated_s": rig.get("simulated_s")},
                       "rig real-time factor at 1 kHz (whole run: compile, setup, loop, analysis)"))
    return out


_TARGET_TEXT = {
    "python_linear_vs_numpy_interp": "Python lookup <= 0.25x numpy.interp, random queries, linear tables (median)",
    "python_cubic_vs_numpy_interp": "Python lookup <= 0.25x numpy.interp, random queries, cubic tables (median)",
    "python_quintic_vs_numpy_interp": "Python lookup <= 0.25x numpy.interp, random queries, quintic tables (median)",
    "c_cubic_vs_c_linear": "C cubic lookup <= 2x C linear lookup (same cam and points, median)",
    "auto_bytes_vs_linear_at_1e-6": "auto <= 1/10 of the bytes of linear at 1e-6 of the stroke (worst cam)",
    "rig_real_time_factor_1khz": "rig >= 20x faster than real time at a 1 kHz cycle (whole run)",
}


# --- the whole run --------------------------------------------------------------------------------


def run_bench(quick: bool = False, progress=None) -> list[dict]:
    """Run the benchmark; return its rows (see the module docstring for their shape).

    Parameters
    ----------
    quick : bool
        A few seconds (2 cams, one point count per kind, 2^14 queries) instead of about two
        minutes (5 cams, 5 point counts per kind, 5 tolerances for auto, 2^18 queries).
    progress : callable, optional
        ``progress(done, total)`` after every table and rig run.
    """
    plan = bench_plan(quick)
    jobs = _jobs(plan)
    total = len(jobs) + len(RIG_CYCLES_HZ)
    done = 0

    def step():
        nonlocal done
        done += 1
        if progress:
            progress(done, total)

    rows = [
        {"kind": "note", "topic": "mode", "text": f"{'quick' if quick else 'full'} run: {len(plan.laws)} cams, "
         f"{len(jobs)} tables; {plan.queries} queries per set, median of {plan.repeats} runs"},
        {"kind": "note", "topic": "scale", "text": (
            f"scale: master period {MASTER_COUNTS} counts; every cam's stroke is {STROKE_COUNTS:.0e} counts "
            f"(slave_counts_per_unit = 1e9 / stroke), so 1e-6 of the stroke = {STROKE_COUNTS * 1e-6:.0f} counts, "
            f"{STROKE_COUNTS * 1e-6 / 0.5:.0f}x the 1/2-count quantization floor")},
        {"kind": "note", "topic": "queries", "text": (
            "queries: random = uniform over the master period; sequential = a monotone ramp over the period "
            "(a streaming master); the same int64 arrays for every implementation, float64 copies for the peers")},
    ]
    try:
        from scipy import interpolate as scipy_interpolate
    except ImportError:
        scipy_interpolate = None
        rows.append({"kind": "note", "topic": "scipy",
                     "text": "scipy not installed (pip install 'ecam[bench]'): peers scipy_cubic, scipy_pchip skipped"})
    queries = bench_queries(plan.queries)
    with tempfile.TemporaryDirectory(prefix="ecam-bench-") as tmp:
        directory = Path(tmp)
        c_runtime = _CRuntime(directory)
        query_files = [directory / "random.i64", directory / "sequential.i64"]
        for path, array in zip(query_files, queries):
            array.astype("<i8").tofile(path)
        rows.append({"kind": "note", "topic": "c", "text": c_runtime.note or (
            f"C runtime: {c_runtime.command}, position lookups (ecam_table_position) timed by the driver "
            "with clock_gettime, checksum compared with the Python lookup's")})
        contexts = {}
        c_failures = []
        for job in jobs:
            ctx = contexts.get(job["law"])
            if ctx is None:
                contexts.clear()
                ctx = contexts[job["law"]] = _LawContext(job["law"], queries)
            try:
                row = _bench_table(ctx, job, plan, c_runtime, query_files, scipy_interpolate)
                rows.append(row)
                if "c_error" in row:
                    c_failures.append(f"{row['law']} {row['interp']} {row['points']} points: {row['c_error']}")
            except EcamError as exc:
                what = (f"{job['intervals'] + 1} points" if job.get("intervals") is not None
                        else f"tolerance {job['tolerance_fraction']:g} of the stroke")
                rows.append({"kind": "note", "topic": "table",
                             "text": f"{job['law']} {job['interp']} {what}: not compiled: {exc}"})
            step()
        if c_failures:
            rows.append({"kind": "note", "topic": "c",
                         "text": f"C runtime failed on {len(c_failures)} tables, first: {c_failures[0]}"})
    rows += bench_rig(plan.rig_repeats, progress=step)
    rows += evaluate_targets(rows)
    return [plain(row) for row in rows]




# --- Pareto fronts and the plot -------------------------------------------------------------------


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
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --- text ---------------------------------------------------------------------------------------


def _cell(value, fmt="{:.1f}", width=7):
    return f"{'-' if value is None else fmt.format(value):>{width}s}"


def format_text(rows: list[dict]) -> str:
    """The human report: notes, the table, the rig and the targets."""
    lines = ["ecam bench: error against bytes and lookup cost of the cam-table kinds", ""]
    lines += [f"  {r['text']}" for r in rows if r.get("kind") == "note"]
    lines += [
        "",
        "  err: the certificate's measured max error over every master count (bound: its certified bound);",
        "  ns: median ns per lookup; py/np, pyseq/, C/np: ratio to numpy.interp on the same queries",
        "  (pyseq/: Python sequential / numpy.interp sequential);",
        "  peers use the same points in float64: np = numpy.interp, CS = scipy CubicSpline, PC = scipy Pchip;",
        "  C ok: the C checksum equals the Python lookup's on both query sets.",
        "",
    ]
    head = (f"{'law':16s} {'interp':14s} {'tol':>6s} {'points':>6s} {'bytes':>7s} {'err cnt':>9s} {'err/strk':>8s} "
            f"{'bound':>9s} {'comp ms':>7s} | {'py rnd':>7s} {'py seq':>7s} {'C rnd':>7s} {'C seq':>7s} "
            f"{'np rnd':>7s} {'np seq':>7s} {'CS':>7s} {'PC':>7s} | "
            f"{'py/np':>6s} {'pyseq/':>6s} {'C/np':>6s} {'C ok':>4s}")
    lines += [head, "-" * len(head)]
    for r in rows:
        if r.get("kind") != "table":
            continue
        ns, ratio = r["ns_per_lookup"], r["ratio_to_numpy_interp"]
        interp = r["interp"] if r["interp"] != "auto" else f"auto:{r['chosen_interp']}"
        tol = "" if r["tolerance_fraction"] is None else f"{r['tolerance_fraction']:.0e}"
        ok = {True: "yes", False: "NO", None: "-"}[r["c_checksum_match"]]
        lines.append(
            f"{r['law']:16s} {interp:14s} {tol:>6s} {r['points']:6d} {r['bytes']:7d} {r['max_error_counts']:9.3g} "
            f"{r['max_error_fraction']:8.1e} {r['predicted_error_counts']:9.3g} {1e3 * r['compile_s']:7.0f} | "
            + " ".join(_cell(ns[k]) for k in ("python_random", "python_sequential", "c", "c_sequential",
                                               "numpy_interp", "numpy_interp_sequential", "scipy_cubic", "scipy_pchip"))
            + " | " + " ".join(_cell(ratio[k], "{:.2f}x", 6) for k in ("python_random", "python_sequential", "c"))
            + f" {ok:>4s}")
    rig = [r for r in rows if r.get("kind") == "rig"]
    if rig:
        lines += ["", "rig (the shipped scene, cycle time overridden; median run):"]
    for r in rig:
        if not r.get("available"):
            lines.append(f"  {r['cycle_hz'] / 1000:g} kHz: not measured: {r['reason']}")
            continue
        c = r["cost_us_per_cycle"]
        split = ", ".join(f"{name} {_cell(c[key], '{:.2f}', 0).strip()} us"
                          for key, name in (("lookup", "lookup"), ("canopen", "CANopen"),
                                            ("drive_loop", "drive loop"), ("plant", "plant")))
        lines.append(
            f"  {r['scene']} at {r['cycle_hz'] / 1000:g} kHz: {r['cycles']} cycles ({r['simulated_s']:.3g} s "
            f"simulated) in {r['wall_s']:.3g} s: real-time factor {r['real_time_factor']:.3g}x "
            f"(loop alone {r['loop_real_time_factor']:.3g}x); "
            f"{r['us_per_cycle']:.1f} us per cycle: {split}; setup {1e3 * r['setup_s']:.0f} ms; "
            f"checks {'passed' if r['passed'] else 'failed: ' + ', '.join(r['failed_checks'])}")
    notes = next((r.get("notes") for r in rig if r.get("notes")), None)
    if notes:
        lines += [f"  ({n})" for n in notes]
    targets = [r for r in rows if r.get("kind") == "target"]
    if targets:
        lines += ["", "targets (shown, not asserted):"]
    for t in targets:
        mark = {True: "met   ", False: "MISSED", None: "n/a   "}[t["met"]]
        value = "-" if t["value"] is None else f"{t['value']:.3g}"
        lines.append(f"  [{mark}] {_TARGET_TEXT.get(t['name'], t['name'])}: {value} -> {t['verdict']}")
    return "\n".join(lines) + "\n"


# --- command line -------------------------------------------------------------------------------


CONTRACT_KEYS = ("law", "interp", "points", "bytes", "max_error_counts", "ns_per_lookup")


def contract_rows(rows: list[dict]) -> list[dict]:
    """The ``--json`` list: the table rows first, then the rig, target and note rows; every row
    carries the contract keys (None where a row is not a table), so a consumer that reads
    ``row["law"]`` or ``row["bytes"]`` on every row does not break."""
    ordered = [r for r in rows if r.get("kind") == "table"] + [r for r in rows if r.get("kind") != "table"]
    return [{**{key: None for key in CONTRACT_KEYS}, **row} for row in ordered]


def main(args) -> int:
    """`ecam bench [--json] [--plot FILE.png] [--quick]`."""
    from .app.progress import progress_bar as _progress

    rows = run_bench(quick=bool(args.quick), progress=_progress("ecam bench"))
    if args.plot:
        try:
            plot_pareto(rows, args.plot)
        except OSError as exc:
            raise InputError(f"--plot {str(args.plot)!r} cannot be written: {exc.strerror or exc}") from None
    if args.json:
        print(json.dumps(contract_rows(rows), indent=1, allow_nan=False))
    else:
        print(format_text(rows), end="")
        if args.plot:
            print(f"wrote {args.plot}")
    return 0
