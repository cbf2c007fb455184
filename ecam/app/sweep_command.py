"""The ``ecam sweep`` command: a robustness sweep of one scene on Dask (:mod:`ecam.app.sweep`).

Exit status: 0 when the yield at the first judged speed reaches ``sweep.required_yield`` with
confidence (the Wilson interval's lower bound), 1 when it does not, 2 on bad input (dask not
installed included).
"""

from __future__ import annotations

import argparse
import json
import sys


def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the ``sweep`` command."""
    parser.add_argument("scene", help="scene file (TOML) with a [sweep] table, see docs/sweep.md")
    parser.add_argument("--samples", type=int, default=None, metavar="N",
                        help="samples instead of sweep.samples [the scene's]")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="N",
                       help="worker processes of the local Dask cluster [one per core]")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on an existing Dask cluster, e.g. tcp://host:8786 (its workers "
                            "need ecam installed) [a local cluster]")
    parser.add_argument("--json", action="store_true",
                        help="print the summary as JSON (the same whatever the workers)")
    parser.add_argument("--html", metavar="FILE.html", default=None,
                        help="also write an HTML page: histograms per check, scatter plots of "
                             "the driving fields [none]")
    parser.add_argument("-o", "--output", default=None, metavar="DIR",
                        help="directory for results.jsonl, summary.json, worst_sample.json "
                             "[<scene name>-sweep]")
    parser.add_argument("--resume", action="store_true",
                        help="continue the results in DIR: only the missing samples run [off]")
    parser.add_argument("--sample", type=int, default=None, metavar="INDEX",
                        help="run sample INDEX alone, over CANopen at the first judged speed, and "
                             "print its report (text, or JSON with --json); no Dask needed [off]")


def _progress():
    """A progress line with the rate and the time left on stderr (a terminal only)."""
    if not sys.stderr.isatty():
        return None

    def show(done: int, total: int, seconds: float) -> None:
        rate = done / seconds if seconds > 0 else 0.0
        left = (total - done) / rate if rate > 0 else float("nan")
        width = 30
        filled = int(width * done / max(total, 1))
        sys.stderr.write(f"\recam sweep [{'#' * filled}{'.' * (width - filled)}] {done}/{total}, "
                         f"{rate:.3g}/s, about {left:.0f} s left   ")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return show


def sweep_command(args: argparse.Namespace) -> int:
    """`ecam sweep SCENE ...`: run the sweep, print the summary, write the files."""
    from pathlib import Path

    from ecam.errors import InputError

    from .sweep import format_summary, result_rows, run_sweep

    if args.sample is not None:
        return _one_sample(args)
    if args.html and not Path(args.html).resolve().parent.is_dir():  # before the sweep, not after
        raise InputError(f"--html: {args.html!r}: its directory does not exist")
    summary = run_sweep(args.scene, samples=args.samples, workers=args.workers,
                        scheduler=args.scheduler, directory=args.output, resume=args.resume,
                        progress=_progress())
    if args.html:
        from .sweep_html import write_sweep_html

        write_sweep_html(summary, result_rows(summary["timing"]["directory"]), args.html)
    if args.json:
        out = {k: v for k, v in summary.items() if k != "timing"}
        print(json.dumps(out, indent=2, sort_keys=True, allow_nan=False))
    else:
        sys.stdout.write(format_summary(summary))
        if args.html:
            print(f"html: {args.html}")
    lower = summary["yield_interval"][0] if summary["yield_interval"] else 0.0
    return 0 if lower >= summary["max_speed_at_yield"]["required"] else 1


def _one_sample(args: argparse.Namespace) -> int:
    """`ecam sweep SCENE --sample I`: the sample's report; 0 if it passed, else 1."""
    from hil_sim.rig import run_scene

    from .sweep import plan_sweep, sample_scene

    plan = plan_sweep(args.scene, args.samples)
    report = run_scene(sample_scene(plan, args.sample))
    if args.json:
        sys.stdout.write(report.to_json())
    else:
        values = ", ".join(f"{k} = {v:.6g}" for k, v in plan.design.sample(args.sample).items())
        sys.stdout.write(f"sample #{args.sample} of {plan.design.samples} (seed "
                         f"{plan.design.seeds[args.sample]}): {values}\n" + report.to_text())
    return 0 if report.passed else 1
