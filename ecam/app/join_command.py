"""`ecam check A.toml --then B.toml`: continuity across a cam switch at A's period end, or at the
master position `--at` / the end of A's period `--at-period` (:mod:`ecam.cam_join`), reported in
the shape of `ecam check`."""

from __future__ import annotations

import json
import math

from ecam import validate
from ecam.cam_join import join_cams
from ecam.camfile import load_cam
from ecam.errors import InputError
from ecam.export import json_safe
from ecam.profile import ORDER_NAMES

from . import cam_commands


def add_at_arguments(parser) -> None:
    """`--at` and `--at-period`: where the switch happens."""
    parser.add_argument("--at", type=float, default=None, metavar="X",
                        help="with --then: the master position of the switch [master units]; with the master "
                             "absolute the next cam is evaluated there, with the net strokes of the periods "
                             "before, as the firmware and the rig do (default: the first cam's period end)")
    parser.add_argument("--at-period", type=int, default=None, metavar="N",
                        help="with --then: the switch at the end of the first cam's N-th period, master "
                             "N x master_period (default: 1)")


def cmd_check(args) -> int:
    """`ecam check`: the cam alone, or, with ``--then``, the join of it to the next cam."""
    if getattr(args, "then", None) is None:
        for option in ("master", "slave", "at", "at_period"):
            if getattr(args, option, None) is not None:
                raise InputError(f"--{option.replace('_', '-')}: {getattr(args, option)} should be given with "
                                 "--then (it places the next cam)")
        return cam_commands.cmd_check(args)
    first, then = load_cam(args.cam), load_cam(args.then)
    at = _switch_position(args, first)
    try:
        join = join_cams(first, then, master=args.master or "absolute", slave=args.slave or "absolute", at=at)
    except InputError as exc:  # the API's parameter `at` is the option --at here
        if getattr(exc, "field", None) == "at" and getattr(args, "at", None) is not None:
            raise validate.renamed(exc, lambda field: "--at") from None
        raise
    report = join.report
    if args.json:
        print(json.dumps(json_safe({
            "cam": first.name, "then": then.name, "ok": report.ok, "errors": len(report.errors),
            "warnings": len(report.warnings), "discontinuities": [d.to_dict() for d in report.discontinuities],
            "join": {"master": join.master, "entry": join.entry, "slave_offset": join.slave_offset,
                     "master_coordinates": join.master_coordinates,
                     "slave_coordinates": join.slave_coordinates,
                     "left": dict(zip(ORDER_NAMES, join.left)), "right": dict(zip(ORDER_NAMES, join.right))},
        }), indent=1))
    else:
        print_join(first, then, join)
    return 0 if report.ok else 1


def _switch_position(args, first) -> float | None:
    """The master position of the switch from `--at` or `--at-period` (None: the default)."""
    at, period = getattr(args, "at", None), getattr(args, "at_period", None)
    if at is not None and period is not None:
        raise InputError(f"--at-period: {period} should not be given with --at {at:g} (one place for the switch)")
    if period is None:
        return at
    if period < 1 or (not first.periodic and period != 1):
        raise InputError(f"--at-period: {period} should be " + (">= 1" if first.periodic else
                         f"1: {first.name} does not repeat"))
    return period * first.master_period


def _where(first, join) -> str:
    """Which end of which period of the first cam the switch is at, in words."""
    period = first.master_period
    if first.periodic and join.master % period == 0.0:
        turns = round(join.master / period)
        return f"{first.name}'s period end" + (f" (period {turns})" if turns != 1 else "")
    if not first.periodic and join.master == period:
        return f"{first.name}'s end"
    return f"within {first.name}'s period"


def print_join(first, then, join) -> None:
    """The join as text: the two cams, where the second is entered, each jump, what is
    continuous."""
    m, s = first.master_unit, first.slave_unit
    report = join.report
    turns = math.floor(join.entry / then.master_period) if then.periodic and then.net_stroke else 0
    strokes = (f", with {turns} x its net stroke {then.net_stroke:+g} {s}" if turns else "")
    print(f"{first.name} -> {then.name}: switched at {join.master:g} {m}, {_where(first, join)}; "
          f"master {join.master_coordinates} ({then.name} entered at {join.entry:g} {m}{strokes}), slave "
          f"{join.slave_coordinates}"
          + (f" (offset {join.slave_offset:+.6g} {s})" if join.slave_coordinates == "relative" else ""))
    if not report.discontinuities:
        print("  continuous in position, velocity, acceleration and jerk across the join")
    for d in report.discontinuities:
        kind = "WARNING" if d.severity == "warning" else "ERROR"
        print(f"  {kind:7s} {d.to_dict()['quantity']:12s} jumps by {d.jump:+.6g} at the join "
              f"({d.left:.6g} -> {d.right:.6g})")
    jumping = {d.order for d in report.discontinuities}
    ok = [name for k, name in enumerate(ORDER_NAMES) if k not in jumping]
    print(f"  no jump in: {', '.join(ok) if ok else 'anything'}; "
          f"{len(report.errors)} errors, {len(report.warnings)} warnings")
