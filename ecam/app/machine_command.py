"""`ecam sim MACHINE.toml`: a machine file (several ``[[axis]]``) run on the rig, its report
printed as text or JSON. Exit status: 0 when the machine passes, 1 when a check fails."""

from __future__ import annotations

import argparse
import json
import sys

from ecam.errors import InputError
from hil_sim.machine import Machine
from hil_sim.rig.machine_run import run_machine


def machine_command(args: argparse.Namespace, machine: Machine) -> int:
    """Run ``machine`` (read from ``args.scene``); print its report; 0 if it passed, else 1."""
    if args.plot or args.find_max_speed:
        raise InputError(f"scene {args.scene}: --plot and --find-max-speed take a single-axis "
                         f"scene; {machine.name} is a machine of {len(machine.axes)} axes")
    if getattr(args, "fidelity", None):
        machine = machine.with_fidelity(args.fidelity)
    report = run_machine(machine)
    if args.json:
        print(json.dumps(report.to_dict(timing=args.timing), indent=2, sort_keys=True,
                         allow_nan=False))
    else:
        sys.stdout.write(report.to_text())
    return 0 if report.passed else 1
