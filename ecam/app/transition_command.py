"""`ecam transition A.toml B.toml --span X -o T.toml`: the 7th-order transition cam from A's
period end to B's start (:func:`ecam.transition.transition_cam`)."""

from __future__ import annotations

import json
from pathlib import Path

from ecam import validate
from ecam.atomic_files import write_files
from ecam.cam_join import join_cams
from ecam.camfile import load_cam
from ecam.errors import InputError
from ecam.export import json_safe
from ecam.transition import transition_cam


def add_transition_parser(sub) -> None:
    """Register `ecam transition` on the command line's subparsers."""
    p = sub.add_parser("transition", help="design a 7th-order transition cam from one cam's end to another's "
                                          "start (VDI 2143 motion-to-motion)")
    p.add_argument("cam", help="cam file running before the change (left at its period end)")
    p.add_argument("then", help="cam file running after the change (entered at its master 0)")
    p.add_argument("--span", required=True, type=float, help="master span of the transition (master units)")
    p.add_argument("--slave", choices=("absolute", "relative"), default="absolute",
                   help="slave coordinates of both switches, PLCopen MC_CamTableSelect.SlaveAbsolute "
                        "(default: absolute)")
    p.add_argument("--name", help="the transition cam's name (default: A_to_B)")
    p.add_argument("-o", "--output", required=True, help="transition cam file to write (TOML)")
    p.add_argument("--json", action="store_true", help="machine-readable summary")
    p.set_defaults(func=cmd_transition)


def cmd_transition(args) -> int:
    first, then = load_cam(args.cam), load_cam(args.then)
    transition = transition_cam(first, then, args.span, slave=args.slave, name=args.name)
    text = transition.to_toml()
    out = Path(args.output)
    try:
        write_files({out: text})
    except OSError as exc:
        raise InputError(f"--output {validate.show_path(out)} cannot be written: {exc.strerror or exc}") from None
    joins = [join_cams(first, transition, master="relative", slave=args.slave),
             join_cams(transition, then, master="relative", slave=args.slave)]
    ok = all(j.report.ok and not j.report.warnings for j in joins)
    summary = {"file": str(out), "name": transition.name, "span": transition.master_period,
               "segments": len(transition.segments), "continuous": ok,
               "peaks_per_master_unit": {k: transition.peak(o) for o, k in
                                         ((1, "velocity"), (2, "acceleration"), (3, "jerk"))}}
    if args.json:
        print(json.dumps(json_safe(summary), indent=1))
    else:
        m, s = transition.master_unit, transition.slave_unit
        peaks = summary["peaks_per_master_unit"]
        print(f"{transition.name}: {len(transition.segments)} poly7 segment(s) over {transition.master_period:g} {m}, "
              f"slave {args.slave}; peak velocity {peaks['velocity']:.4g} {s}/{m}, acceleration "
              f"{peaks['acceleration']:.4g} {s}/{m}^2, jerk {peaks['jerk']:.4g} {s}/{m}^3")
        print(f"  continuous from {first.name} and into {then.name} in position, velocity, acceleration "
              f"and jerk: {'yes' if ok else 'NO'} (run the three with --master relative --slave {args.slave})")
        print(f"  wrote {out}")
    return 0 if ok else 1
