"""`ecam check A.toml --then B.toml`: continuity across a cam switch at A's period end
(:mod:`ecam.cam_join`), reported in the shape of `ecam check`."""

from __future__ import annotations

import json

from ecam.cam_join import join_cams
from ecam.camfile import load_cam
from ecam.errors import InputError
from ecam.export import json_safe
from ecam.profile import ORDER_NAMES

from . import cam_commands


def cmd_check(args) -> int:
    """`ecam check`: the cam alone, or, with ``--then``, the join of it to the next cam."""
    if getattr(args, "then", None) is None:
        for option in ("master", "slave"):
            if getattr(args, option, None) is not None:
                raise InputError(f"--{option}: {getattr(args, option)} should be given with --then (it places "
                                 "the next cam's coordinates)")
        return cam_commands.cmd_check(args)
    first, then = load_cam(args.cam), load_cam(args.then)
    join = join_cams(first, then, master=args.master or "absolute", slave=args.slave or "absolute")
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


def print_join(first, then, join) -> None:
    """The join as text: the two cams, where the second is entered, each jump, what is
    continuous."""
    m, s = first.master_unit, first.slave_unit
    report = join.report
    print(f"{first.name} -> {then.name}: switched at {join.master:g} {m}, {first.name}'s period end; "
          f"master {join.master_coordinates} ({then.name} entered at {join.entry:g} {m}), slave "
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
