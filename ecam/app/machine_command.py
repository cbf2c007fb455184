"""`ecam sim MACHINE.toml`: a machine file (several ``[[axis]]``) run on the rig, its report
printed as text or JSON. Exit status: 0 when the machine passes, 1 when a check fails."""

from __future__ import annotations

import argparse
import json
import sys
import time

from ecam.errors import InputError
from hil_sim.machine import Machine
from hil_sim.rig.machine_run import run_machine


def machine_command(args: argparse.Namespace, machine: Machine, write_reports=None) -> int:
    """Run ``machine`` (read from ``args.scene``); print its report; 0 if it passed, else 1.
    ``write_reports(report, seconds)`` writes ``--junit`` (one testcase per machine check and
    per axis check, named ``axis.check``)."""
    if args.plot or args.find_max_speed or getattr(args, "html", None):
        raise InputError(f"scene {args.scene}: --plot, --html and --find-max-speed take a "
                         f"single-axis scene; {machine.name} is a machine of {len(machine.axes)} "
                         "axes")
    if getattr(args, "fidelity", None):
        machine = machine.with_fidelity(args.fidelity)
    start = time.perf_counter()
    report = run_machine(machine)
    seconds = time.perf_counter() - start
    if args.json:
        print(json.dumps(report.to_dict(timing=args.timing), indent=2, sort_keys=True,
                         allow_nan=False))
    else:
        sys.stdout.write(report.to_text())
    if getattr(args, "junit", None) and write_reports is not None:
        write_reports(report, seconds)
    return 0 if report.passed else 1
