"""`ecam sim MACHINE.toml`: a machine file (several ``[[axis]]``) run on the rig, its report
printed as text or JSON; ``--find-max-speed`` searches the machine's speed and names the
station and the check that limit it; ``--plot`` draws the machine and each axis
(:mod:`hil_sim.rig.machine_plot`), ``--html`` and ``--junit`` are written by ``write_reports``. Exit status: 0 when the machine passes, 1 when a check
fails."""

from __future__ import annotations

import argparse
import sys
import time

from ecam.plot import check_figure_path
from hil_sim.machine import Machine
from hil_sim.rig.machine_plot import plot_machine
from hil_sim.rig.machine_run import run_machine
from hil_sim.rig.machine_search import find_machine_max_speed

from .report_output import print_report


def machine_command(args: argparse.Namespace, machine: Machine, write_reports=None,
                    format_search=None) -> int:
    """Run ``machine`` (read from ``args.scene``); print its report; 0 if it passed, else 1.
    ``write_reports(report, seconds)`` writes ``--junit`` (one testcase per machine check and
    per axis check, named ``axis.check``) and ``--html`` (the machine, then each axis); ``format_search(result)`` is the text of a
    ``--find-max-speed`` result."""
    if args.plot:
        check_figure_path(args.plot)  # before the run, not after it
    if getattr(args, "fidelity", None):
        machine = machine.with_fidelity(args.fidelity)
    start = time.perf_counter()
    report = run_machine(machine)
    seconds = time.perf_counter() - start
    search = None
    if args.find_max_speed:
        search = find_machine_max_speed(machine, progress=lambda line: print(
            line, file=sys.stderr, flush=True))
    print_report(args, report, search, format_search)
    if args.plot:
        written = plot_machine(report, args.plot)
        print(f"plots: {written[0]} (the machine), {', '.join(str(p) for p in written[1:])} "
              "(each axis)", file=sys.stderr if args.json else sys.stdout)
    if (getattr(args, "junit", None) or getattr(args, "html", None)) and write_reports is not None:
        write_reports(report, seconds)
    return 0 if report.passed else 1
