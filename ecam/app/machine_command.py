"""`ecam sim MACHINE.toml`: a machine file (several ``[[axis]]``) run on the rig, its report
printed as text or JSON; ``--find-max-speed`` searches the machine's speed and names the
station and the check that limit it. Exit status: 0 when the machine passes, 1 when a check
fails."""

from __future__ import annotations

import argparse
import json
import sys
import time

from ecam.errors import InputError
from hil_sim.machine import Machine
from hil_sim.rig.machine_run import run_machine
from hil_sim.rig.machine_search import find_machine_max_speed


def machine_command(args: argparse.Namespace, machine: Machine, write_reports=None,
                    format_search=None) -> int:
    """Run ``machine`` (read from ``args.scene``); print its report; 0 if it passed, else 1.
    ``write_reports(report, seconds)`` writes ``--junit`` (one testcase per machine check and
    per axis check, named ``axis.check``); ``format_search(result)`` is the text of a
    ``--find-max-speed`` result."""
    if args.plot or getattr(args, "html", None):
        raise InputError(f"scene {args.scene}: --plot and --html take a single-axis scene; "
                         f"{machine.name} is a machine of {len(machine.axes)} axes")
    if getattr(args, "fidelity", None):
        machine = machine.with_fidelity(args.fidelity)
    start = time.perf_counter()
    report = run_machine(machine)
    seconds = time.perf_counter() - start
    search = None
    if args.find_max_speed:
        search = find_machine_max_speed(machine, progress=lambda line: print(
            line, file=sys.stderr, flush=True))
    if args.json:
        out = report.to_dict(timing=args.timing)
        if search is not None:
            out["max_speed"] = search
        print(json.dumps(out, indent=2, sort_keys=True, allow_nan=False))
    else:
        sys.stdout.write(report.to_text())
        if search is not None and format_search is not None:
            sys.stdout.write(format_search(search))
    if getattr(args, "junit", None) and write_reports is not None:
        write_reports(report, seconds)
    return 0 if report.passed else 1
