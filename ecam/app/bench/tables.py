"""One bench row of kind "table": a cam compiled at one setting, timed against its peers."""

from __future__ import annotations

import statistics
import time

import numpy as np

from ecam.compile import compile_table

from .plan import IMPLEMENTATIONS, MASTER_COUNTS, SEQUENTIAL, STROKE_COUNTS, BenchPlan, bench_profile, checksum


def median_ns(functions: dict, repeats: int, count: int) -> dict:
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


class LawContext:
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


def bench_table(ctx: LawContext, job: dict, plan: BenchPlan, c_runtime, query_files, scipy_interpolate) -> dict:
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
    ns.update(median_ns(functions, plan.repeats, n))

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
        base = ns["numpy_interp_sequential" if key in SEQUENTIAL else "numpy_interp"]
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
