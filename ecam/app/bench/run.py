"""The whole bench run, and the `ecam bench` command."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

from ecam.errors import EcamError, InputError
from ecam.export import json_safe

from ..progress import progress_bar
from .c_runtime import CRuntime
from .instructions import instruction_rows
from .machine import bench_machine
from .plan import MASTER_COUNTS, RIG_CYCLES_HZ, STROKE_COUNTS, bench_plan, bench_queries, plan_jobs
from .plot import plot_pareto
from .rig import bench_rig
from .sweep import bench_sweep
from .tables import LawContext, bench_table
from .targets import evaluate_targets
from .text import contract_rows, format_text


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
    jobs = plan_jobs(plan)
    # + instructions, sweeps, the machine's two paths
    total = len(jobs) + len(RIG_CYCLES_HZ) + 1 + (1 if quick else 2) + 2
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
        c_runtime = CRuntime(directory)
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
                ctx = contexts[job["law"]] = LawContext(job["law"], queries)
            try:
                row = bench_table(ctx, job, plan, c_runtime, query_files, scipy_interpolate)
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
        counts = directory / "instructions"
        counts.mkdir()
        rows += instruction_rows(counts, quick)
        step()
    rows += bench_rig(plan.rig_repeats, progress=step)
    rows += bench_sweep(quick, progress=step)
    rows += bench_machine(quick, progress=step)
    rows += evaluate_targets(rows)
    return [json_safe(row) for row in rows]




# --- Pareto fronts and the plot -------------------------------------------------------------------


def main(args) -> int:
    """`ecam bench [--json] [--plot FILE.png] [--quick]`."""
    rows = run_bench(quick=bool(args.quick), progress=progress_bar("ecam bench"))
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
