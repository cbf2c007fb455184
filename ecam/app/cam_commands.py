"""The cam commands: `ecam laws`, `check`, `plot`, `compile`, and the certificate as text."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ecam.atomic_files import write_files
from ecam.camfile import load_cam
from ecam.compile import compile_table
from ecam.errors import InputError
from ecam.export import EXPORTERS, identifier, plain
from ecam.laws import LAWS
from ecam.plot import plot_profile

from .progress import progress_bar


# --- laws ---------------------------------------------------------------------------------------
def cmd_laws(args) -> int:
    rows = [
        {"name": law.name, "cv": _finite(law.cv), "ca": _finite(law.ca), "cj": _finite(law.cj),
         "description": law.description}
        for law in LAWS.values()
    ]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print(f"{'law':28s} {'Cv':>8s} {'Ca':>8s} {'Cj':>8s}  description")
    for row in rows:
        cells = [("inf" if v is None else f"{v:.4f}") for v in (row["cv"], row["ca"], row["cj"])]
        print(f"{row['name']:28s} {cells[0]:>8s} {cells[1]:>8s} {cells[2]:>8s}  {row['description']}")
    print("Cv, Ca, Cj: peaks of |s'|, |s''|, |s'''| of the normalized rise s(u); inf: unbounded "
          "(a jump against the rest it starts or ends in)")
    return 0


def _finite(value):
    return None if not math.isfinite(value) else value


# --- check / plot ---------------------------------------------------------------------------------
def cmd_check(args) -> int:
    profile = load_cam(args.cam)
    report = profile.check()
    if args.json:
        print(json.dumps({
            "cam": profile.name, "ok": report.ok, "errors": len(report.errors), "warnings": len(report.warnings),
            "discontinuities": [d.to_dict() for d in report.discontinuities],
        }, indent=1))
    else:
        print_check(profile, report)
    return 0 if report.ok else 1


def print_check(profile, report):
    print(f"{profile.name}: {len(profile.segments)} segments over {profile.master_period:g} {profile.master_unit}"
          f" ({'periodic' if profile.periodic else 'not periodic'})")
    if not report.discontinuities:
        print("  continuous in position, velocity, acceleration and jerk everywhere")
    for d in report.discontinuities:
        kind = "WARNING" if d.severity == "warning" else "ERROR"
        print(f"  {kind:7s} {d.to_dict()['quantity']:12s} jumps by {d.jump:+.6g} at {d.master:g} "
              f"{profile.master_unit} ({d.where}; {d.left:.6g} -> {d.right:.6g})")
    orders = ["position", "velocity", "acceleration"]
    ok = [name for k, name in enumerate(orders) if report.continuous(k)]
    print(f"  continuous: {', '.join(ok) if ok else 'nothing'}; "
          f"{len(report.errors)} errors, {len(report.warnings)} warnings")


def cmd_plot(args) -> int:
    profile = load_cam(args.cam)
    plot_profile(profile, args.output)
    print(f"wrote {args.output}")
    return 0


# --- compile --------------------------------------------------------------------------------------
def cmd_compile(args) -> int:
    profile = load_cam(args.cam)
    formats = [f.strip() for f in args.format.split(",") if f.strip()]
    if not formats:
        raise InputError(f"--format {args.format!r} should name at least one of c, bin, csv, json")
    for f in formats:
        if f not in EXPORTERS:
            raise InputError(f"--format {f!r} should be one of {', '.join(EXPORTERS)}")
    table = compile_table(
        profile, interp=args.interp, points=args.points, tolerance=args.tolerance,
        master_counts=args.master_counts, slave_counts_per_unit=args.slave_counts_per_unit,
        progress=progress_bar(f"certifying {profile.name}"),
    )
    name = profile.name or Path(args.cam).stem
    files = write_table(table, name, Path(args.output), formats)
    summary = table_summary(table, files)
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(certificate_text(name, table))
        for path in files:
            print(f"  wrote {path}")
    return 0


def write_table(table, name, directory: Path, formats) -> list[str]:
    contents = {}
    for f in formats:
        suffix, render = EXPORTERS[f]
        contents[directory / (identifier(name) + suffix)] = render(table, name)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        write_files(contents)
    except OSError as exc:
        raise InputError(f"output directory {str(directory)!r} cannot be written: {exc.strerror or exc}") from None
    return [str(path) for path in contents]


def table_summary(table, files) -> dict:
    r = table.report
    keys = ["interp", "points", "bytes", "crc32", "max_error_counts", "max_error_units", "predicted_error_counts",
            "predicted_error_units", "predicted_interpolation_counts", "quantization_counts",
            "interpolation_error_counts", "max_error_at_master", "max_error_at_master_counts", "evaluated",
            "master_counts", "step_counts", "slave_counts_per_unit", "joints_off_points", "format",
            "max_slope_error_counts_per_count", "tolerance_units"]
    out = {k: plain(r[k]) for k in keys if k in r}
    out["files"] = files
    return out


def certificate_text(name, table) -> str:
    r = table.report
    unit = r["slave_unit"]
    lines = [
        f"{name}: {r['interp']} table, {r['points']} points, step {r['step_counts']} counts, {r['bytes']} bytes, "
        f"CRC-32 0x{r['crc32']:08x}",
        f"  predicted bound {r['predicted_error_counts']:.4g} counts = {r['predicted_error_units']:.4g} {unit} "
        f"(interpolation {r['predicted_interpolation_counts']:.3g} + quantization {r['quantization_counts']:.3g})",
    ]
    if "max_error_counts" in r:
        lines.append(
            f"  measured max error {r['max_error_counts']:.4g} counts = {r['max_error_units']:.4g} {unit} "
            f"at master {r['max_error_at_master']:.6g} {r['master_unit']} ({r['evaluated']}); "
            f"before quantization {r['interpolation_error_counts']:.3g} counts"
        )
    if r["joints_off_points"]:
        lines.append(f"  joints not on table points (their cost is in the bound): {r['joints_off_points']}")
    return "\n".join(lines)
