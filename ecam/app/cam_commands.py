"""The cam commands: `ecam laws`, `check`, `plot`, `compile`, and the certificate as text."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ecam import validate
from ecam.atomic_files import check_outputs, write_group
from ecam.camfile import load_cam
from ecam.compile import compile_table
from ecam.errors import InputError
from ecam.export import EXPORTERS, identifier, json_safe
from ecam.laws import LAWS
from ecam.plot import plot_profile

from .compile_notes import defaults_applied, defaults_text, joint_hint, rounding_hint
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
# The fastest master --speed takes (master units per second): far above any machine, and low
# enough that the peaks at that speed stay finite for every cam ecam accepts. The largest jerk a
# cam can have is about 1e188 per master unit^3 (a poly5/poly7 velocity condition of 1e150 over
# a span of 1e-18, the shortest: 1e-9 of a 1e-9 period), and 1e188 * (1e30)^3 is finite.
MAX_SPEED = 1e30
# Master units a speed in rpm can be given for: units per revolution.
_PER_REVOLUTION = {"deg": 360.0, "rad": 2 * math.pi, "rev": 1.0, "turn": 1.0}
_PER_MINUTE_WORDS = ("periods/min", "cycles/min", "cuts/min", "strokes/min", "/min")


def parse_speed(text, profile) -> tuple[float, str]:
    """``--speed``: master units per second, as (value, how the user gave it).

    A plain number is in master units per second; else a number and a unit: ``<master
    unit>/s``, ``<master unit>/min``, ``rpm`` (a master in deg, rad or rev) or ``periods/min``
    (also ``cycles/min``, ``cuts/min``: master periods per minute).
    """
    unit = profile.master_unit
    forms = f"a number > 0 (master {unit} per second) or e.g. '720 {unit}/s', '120 periods/min'"
    number, _, word = str(text).strip().partition(" ")
    word = word.strip()
    try:
        value = float(number)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise validate.fail("--speed", text, forms)
    if word in ("", f"{unit}/s"):
        factor = 1.0
    elif word == f"{unit}/min":
        factor = 1 / 60
    elif word in _PER_MINUTE_WORDS:
        factor = profile.master_period / 60
    elif word == "rpm" and unit in _PER_REVOLUTION:
        factor = _PER_REVOLUTION[unit] / 60
    else:
        raise validate.fail("--speed", text, forms + (f" ('rpm' needs a master in deg, rad or rev, not {unit})"
                                                      if word == "rpm" else ""))
    speed = value * factor
    if speed > MAX_SPEED:
        raise validate.fail("--speed", text, f"at most {MAX_SPEED:g} {unit}/s")
    return speed, f"{value:g} {word}".strip()


def check_summary(profile, speed=None) -> dict:
    """Stroke and peak velocity, acceleration and jerk of a profile, per master unit (slave units
    per master unit^k) and, given a speed in master units per second, per second."""
    low, high = profile.slave_range
    peaks = {name: profile.peak(order) for order, name in enumerate(("position", "velocity", "acceleration",
                                                                      "jerk")) if order}
    out = {"net_stroke": profile.net_stroke, "stroke": high - low, "slave_range": [low, high],
           "peaks_per_master_unit": peaks, "slave_unit": profile.slave_unit, "master_unit": profile.master_unit}
    if speed is not None:
        out["speed"] = {"master_units_per_second": speed, "periods_per_minute": 60 * speed / profile.master_period,
                        **{name: value * speed**order for order, (name, value) in enumerate(peaks.items(), start=1)}}
    return out


# The text output lists this many jumps (and joints off table points); the rest are counted, so a cam
# of 100 000 segments prints a screenful, not 10 MB. --json lists every one.
LISTED = 100


def cmd_check(args) -> int:
    profile = load_cam(args.cam)
    speed = None if getattr(args, "speed", None) is None else parse_speed(args.speed, profile)[0]
    report = profile.check()
    if args.json:
        print(json.dumps(json_safe({
            "cam": profile.name, "ok": report.ok, "errors": len(report.errors), "warnings": len(report.warnings),
            "discontinuities": [d.to_dict() for d in report.discontinuities], **check_summary(profile, speed),
        }), indent=1))
    else:
        print_check(profile, report, speed)
    return 0 if report.ok else 1


def print_check(profile, report, speed=None):
    """The check as text: the cam, each jump, what is continuous, and a one-line summary of its
    stroke and peaks (per master unit, and at ``speed`` master units per second) so that a
    stroke or a unit entered wrong shows."""
    kind_of = "periodic" if profile.periodic else "not periodic"
    if profile.net_stroke is not None:
        kind_of += f", net stroke {profile.net_stroke:+.6g} {profile.slave_unit} per period"
    print(f"{profile.name}: {len(profile.segments)} segments over {profile.master_period:g} {profile.master_unit}"
          f" ({kind_of})")
    if not report.discontinuities:
        seam = " (the seam too, the position continuing by the net stroke)" if profile.net_stroke else ""
        print(f"  continuous in position, velocity, acceleration and jerk everywhere{seam}")
    listed = report.discontinuities
    if len(listed) > LISTED:  # errors before warnings, so a long list never hides an error
        listed = sorted(listed, key=lambda d: d.severity == "warning")[:LISTED]
    for d in listed:
        kind = "WARNING" if d.severity == "warning" else "ERROR"
        print(f"  {kind:7s} {d.to_dict()['quantity']:12s} jumps by {d.jump:+.6g} at {d.master:g} "
              f"{profile.master_unit} ({d.where}; {d.left:.6g} -> {d.right:.6g})")
        if d.order == 0 and d.where.startswith("seam") and profile.net_stroke is None:
            print(f"          if the slave is meant to advance by {profile.advance:+.6g} {profile.slave_unit} every "
                  f"period (a rotary knife, an indexing table), say so in the cam file: "
                  f"net_stroke = {profile.advance!r}")
    if len(report.discontinuities) > LISTED:
        print(f"  ... and {len(report.discontinuities) - LISTED} more (ecam check --json lists every one)")
    orders = ["position", "velocity", "acceleration"]
    ok = [name for k, name in enumerate(orders) if report.continuous(k)]
    print(f"  continuous: {', '.join(ok) if ok else 'nothing'}; "
          f"{len(report.errors)} errors, {len(report.warnings)} warnings")
    summary = check_summary(profile, speed)
    s, m = profile.slave_unit, profile.master_unit
    low, high = summary["slave_range"]
    v, a, j = summary["peaks_per_master_unit"].values()
    print(f"  stroke {summary['stroke']:.6g} {s} ({low:.6g} .. {high:.6g}); peak per {m}: velocity {v:.4g} {s}/{m}, "
          f"acceleration {a:.4g} {s}/{m}^2, jerk {j:.4g} {s}/{m}^3")
    if speed is not None:
        at = summary["speed"]
        print(f"  at {speed:.6g} {m}/s ({at['periods_per_minute']:.4g} periods/min): velocity {at['velocity']:.4g} "
              f"{s}/s, acceleration {at['acceleration']:.4g} {s}/s^2, jerk {at['jerk']:.4g} {s}/s^3")


def cmd_plot(args) -> int:
    check_outputs([args.output], [args.cam])
    profile = load_cam(args.cam)
    plot_profile(profile, args.output)
    print(f"wrote {args.output}")
    return 0


# --- compile --------------------------------------------------------------------------------------
def cmd_compile(args) -> int:
    profile = load_cam(args.cam)
    formats = [f.strip() for f in args.format.split(",") if f.strip()]
    if not formats:
        raise InputError(f"--format {validate.show(args.format)} should name at least one of {', '.join(EXPORTERS)}")
    for f in formats:
        if f not in EXPORTERS:
            raise InputError(f"--format {validate.show(f)} should be one of {', '.join(EXPORTERS)}")
    name = profile.name or Path(args.cam).stem
    # before the work: an output that is the cam itself or a device is refused at once
    check_outputs([*table_paths(name, Path(args.output), formats), manifest_path(name, Path(args.output))],
                  [args.cam])
    table = compile_table(
        profile, interp=args.interp, points=args.points, tolerance=args.tolerance,
        master_counts=args.master_counts, slave_counts_per_unit=args.slave_counts_per_unit,
        horner_bits=getattr(args, "horner_bits", None),
        interpolation_tolerance=getattr(args, "interpolation_tolerance", None),
        progress=progress_bar(f"certifying {profile.name}"),
    )
    files = write_table(table, name, Path(args.output), formats, inputs=[args.cam])
    summary = table_summary(table, files)
    summary["manifest"] = str(manifest_path(name, Path(args.output)))
    applied = defaults_applied(profile, args)
    if args.json:
        summary["defaults_applied"] = applied
        print(json.dumps(summary, indent=1))
    else:
        print(certificate_text(name, table))
        for note in (rounding_hint(table), joint_hint(profile, table), defaults_text(applied)):
            if note:
                print(note)
        for path in files:
            print(f"  wrote {path}")
        print(f"  wrote {summary['manifest']} (the group's manifest, written last)")
    return 0


def table_paths(name, directory: Path, formats) -> list[Path]:
    """The files :func:`write_table` writes, in the order of ``formats``."""
    return [directory / (identifier(name) + EXPORTERS[f][0]) for f in formats]


def manifest_path(name, directory: Path) -> Path:
    """The manifest of the files :func:`write_table` writes (``ecam.atomic_files.write_group``)."""
    return directory / (identifier(name) + ".group.json")


def write_table(table, name, directory: Path, formats, inputs=()) -> list[str]:
    """Write the table in ``formats`` as one group, its manifest last (a reader checks it with
    ``ecam.atomic_files.check_group``); returns the files, the manifest not included."""
    contents = {}
    for f, path in zip(formats, table_paths(name, directory, formats)):
        contents[path] = EXPORTERS[f][1](table, name)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        write_group(contents, manifest_path(name, directory), inputs)
    except OSError as exc:
        raise InputError(f"output directory {validate.show_path(directory)} cannot be written: "
                         f"{exc.strerror or exc}") from None
    return [str(path) for path in contents]


def table_summary(table, files) -> dict:
    r = table.report
    keys = ["interp", "points", "bytes", "crc32", "max_error_counts", "max_error_units", "predicted_error_counts",
            "predicted_error_units", "predicted_interpolation_counts", "quantization_counts",
            "interpolation_error_counts", "max_error_at_master", "max_error_at_master_counts", "evaluated",
            "master_counts", "step_counts", "slave_counts_per_unit", "joints_off_points", "format",
            "max_slope_error_counts_per_count", "tolerance_units", "net_stroke_units", "net_stroke_counts",
            "net_stroke_fraction", "net_stroke_exact", "net_stroke_residual_counts", "format_version",
            "wrap_evaluated", "wrap_max_error_counts", "wrap_max_error_at_master_counts",
            "interpolation_tolerance_counts", "interpolation_tolerance_units", "final_rounding_counts",
            "predicted_above_rounding_counts"]
    out = {k: json_safe(r[k]) for k in keys if k in r}
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
    if "interpolation_tolerance_counts" in r:
        lines.append(f"  of which the final rounding {r['final_rounding_counts']:.3g} counts and the table "
                     f"{r['predicted_above_rounding_counts']:.3g} (within the interpolation tolerance "
                     f"{r['interpolation_tolerance_counts']:.4g} counts)")
    if "max_error_counts" in r:
        lines.append(
            f"  measured max error {r['max_error_counts']:.4g} counts = {r['max_error_units']:.4g} {unit} "
            f"at master {r['max_error_at_master']:.6g} {r['master_unit']} ({r['evaluated']}); "
            f"before quantization {r['interpolation_error_counts']:.3g} counts"
        )
    if r["joints_off_points"]:
        off = r["joints_off_points"]
        more = f" ... and {len(off) - LISTED} more (--json lists every one)" if len(off) > LISTED else ""
        lines.append(f"  joints not on table points (their cost is in the bound): {off[:LISTED]}{more}")
    if "net_stroke_counts" in r:
        num, den = r["net_stroke_fraction"]
        stored = f"{num} counts" if den == 1 else f"{num}/{den} counts (exact, rounded once per lookup)"
        drift = ("exact" if r["net_stroke_exact"] else
                 f"{r['net_stroke_residual_counts']:.3g} counts per period off the cam's")
        lines.append(f"  net stroke {r['net_stroke_units']:+.6g} {unit} per period = {stored}; {drift}; "
                     f"format version {r['format_version']}")
        if "wrap_max_error_counts" in r:
            lines.append(f"  across the seam and at far periods: max error {r['wrap_max_error_counts']:.4g} counts "
                         f"({r['wrap_evaluated']})")
    return "\n".join(lines)
