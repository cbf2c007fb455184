"""`ecam export CAM --to FORMAT`: the cam as the table a machine builder's controller reads, with
the fewest points that meet the tolerance under that controller's own interpolation, and the error
certificate. The library returns the text (``ecam.export.export_cam``); this writes the file."""

from __future__ import annotations

import json
from pathlib import Path

from ecam.atomic_files import check_outputs, write_files
from ecam.camfile import load_cam
from ecam.errors import InputError
from ecam.export import export_cam, identifier, json_safe


def cmd_export(args) -> int:
    profile = load_cam(args.cam)
    name = profile.name or Path(args.cam).stem
    if args.output:  # before the work (the default name depends on the format's suffix)
        check_outputs([args.output], [args.cam])
    result = export_cam(profile, args.to, tolerance=args.tolerance, points=args.points, interp=args.interp,
                        master_counts=args.master_counts, slave_counts_per_unit=args.slave_counts_per_unit,
                        name=name)
    path = Path(args.output) if args.output else Path(f"{identifier(name)}.{result.format}{result.suffix}")
    try:
        write_files({path: result.content}, inputs=[args.cam])
    except OSError as exc:
        raise InputError(f"output: {str(path)!r} cannot be written: {exc.strerror or exc}") from None
    if args.json:
        summary = result.summary()
        summary["file"] = str(path)
        print(json.dumps(json_safe(summary), indent=1, sort_keys=True))
    else:
        print(result.report_text(name))
        if "interpolation_tolerance" in (profile.table or {}):
            # the key sizes ecam's own fixed-point tables against their final rounding; a
            # controller interpolates and rounds in its own way, so an export is sized by the
            # tolerance alone
            print("  note: the cam file's [table] interpolation_tolerance applies to `ecam compile`'s "
                  "tables, not to vendor exports (sized by the tolerance under the controller's "
                  "own interpolation)")
        print(f"  wrote {path}")
    return 0
