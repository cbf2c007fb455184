"""The ``ecam`` command line. Bad input: one line on stderr, exit status 2, no traceback."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from .app.progress import progress_bar as _progress
from .camfile import CAMS_DIR
from .errors import EcamError, InputError

EXIT_BAD_INPUT = 2
SEED_CAMS = ("combination_drrd", "modified_sine")


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, status 2, as for every other bad input
        raise InputError(f"{self.prog}: {message}")


# --- laws ---------------------------------------------------------------------------------------
def cmd_laws(args) -> int:
    from .laws import LAWS

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
    from .camfile import load_cam

    profile = load_cam(args.cam)
    report = profile.check()
    if args.json:
        print(json.dumps({
            "cam": profile.name, "ok": report.ok, "errors": len(report.errors), "warnings": len(report.warnings),
            "discontinuities": [d.to_dict() for d in report.discontinuities],
        }, indent=1))
    else:
        _print_check(profile, report)
    return 0 if report.ok else 1


def _print_check(profile, report):
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
    from .camfile import load_cam
    from .plot import plot_profile

    profile = load_cam(args.cam)
    plot_profile(profile, args.output)
    print(f"wrote {args.output}")
    return 0


# --- compile --------------------------------------------------------------------------------------
def cmd_compile(args) -> int:
    from .camfile import load_cam
    from .compile import compile_table
    from .export import EXPORTERS

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
        progress=_progress(f"certifying {profile.name}"),
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
    from .atomic_files import write_files
    from .export import EXPORTERS, identifier

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
    from .export import plain

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


# --- demo -----------------------------------------------------------------------------------------
def cmd_demo(args) -> int:
    from .camfile import load_cam
    from .compile import compile_table
    from .plot import plot_profile

    out = Path(args.output)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"output directory {str(out)!r} cannot be created: {exc.strerror or exc}") from None
    print("ecam demo: the seed cams, checked, plotted and compiled into certified tables\n")
    for stem in SEED_CAMS:
        profile = load_cam(CAMS_DIR / f"{stem}.toml")
        _print_check(profile, profile.check())
        picture = out / f"{stem}.png"
        plot_profile(profile, picture)
        table = compile_table(profile, progress=_progress(f"certifying {stem}"))
        files = write_table(table, stem, out, ["c", "bin"])
        print(certificate_text(stem, table))
        print(f"  wrote {picture}, {', '.join(files)}\n")
    try:
        from hil_sim import demo as sim_demo
    except ImportError:
        return 0
    return sim_demo.run(out)


# --- bench / sim / drive --------------------------------------------------------------------------
def cmd_bench(args) -> int:
    from . import bench

    return bench.main(args)


def cmd_sim(args) -> int:
    from hil_sim import cli as hil_cli

    single = len(args.scene) == 1 and Path(args.scene[0]).suffix == ".toml"
    if single and not (args.junit or args.html or args.jobs != 1):
        args.scene = args.scene[0]  # one scene: the report as before, text or JSON
        return hil_cli.sim_command(args)
    return _sim_many(args)


def _sim_many(args) -> int:
    """Several scenes: a progress line each, a summary table, JUnit XML and HTML on request."""
    from .app.html_report import html_report
    from .app.junit import junit_xml
    from .app.multi import exit_status, run_scenes, summary_table
    from .atomic_files import write_files

    if args.json or args.plot or args.find_max_speed:
        raise InputError("--json, --plot and --find-max-speed take one scene file; "
                         f"{len(args.scene)} scene argument(s) given")
    for option in (args.junit, args.html):
        if option is not None and not Path(option).resolve().parent.is_dir():
            raise InputError(f"output {option!r}: its directory does not exist")
    results = run_scenes(args.scene, args.jobs, progress=lambda line: print(line, file=sys.stderr))
    print(summary_table(results))
    outputs = {}
    if args.junit:
        outputs[Path(args.junit)] = junit_xml(results)
    if args.html:
        outputs[Path(args.html)] = html_report(results)
    try:
        write_files(outputs)
    except OSError as exc:
        raise InputError(f"report files cannot be written: {exc.strerror or exc}") from None
    return exit_status(results)


def cmd_drive(args) -> int:
    from hil_sim import cli as hil_cli

    return hil_cli.drive_command(args)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="ecam", description="Electronic cams: motion laws, certified cam tables, a CANopen rig.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("laws", help="the motion laws and their characteristic values")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_laws)

    p = sub.add_parser("check", help="report every jump of position, velocity, acceleration (and jerk)")
    p.add_argument("cam", help="cam file (TOML)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("plot", help="motion diagram: position, velocity, acceleration, jerk")
    p.add_argument("cam")
    p.add_argument("-o", "--output", required=True, help="image file (.png, .svg, .pdf)")
    p.set_defaults(func=cmd_plot)

    p = sub.add_parser("compile", help="compile a cam into a certified fixed-point table")
    p.add_argument("cam")
    p.add_argument("--interp", choices=["linear", "cubic", "quintic", "auto"])
    group = p.add_mutually_exclusive_group()
    group.add_argument("--points", type=int, help="stored points (intervals + 1)")
    group.add_argument("--tolerance", help="max error in slave units, or e.g. '2 counts'")
    p.add_argument("--master-counts", type=int, help="master period in counts")
    p.add_argument("--slave-counts-per-unit", type=float, help="slave counts per slave unit")
    p.add_argument("-o", "--output", default=".", help="output directory (default: .)")
    p.add_argument("--format", default="c,bin", help="comma list of c, bin, csv, json (default: c,bin)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_compile)

    p = sub.add_parser("demo", help="the main job on the built-in seed cams")
    p.add_argument("-o", "--output", default="ecam-demo", help="directory for plots and tables")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("bench", help="speed against error of the table kinds and the rig")
    p.add_argument("--json", action="store_true")
    p.add_argument("--plot", help="Pareto plot file (.png)")
    p.add_argument("--quick", action="store_true", help="a few seconds, for smoke tests")
    p.set_defaults(func=cmd_bench)

    try:
        from hil_sim import cli as hil_cli
    except ImportError:
        hil_cli = None
    p = sub.add_parser("sim", help="run a scene on the software-in-the-loop rig")
    if hil_cli is not None and hasattr(hil_cli, "add_sim_arguments"):
        hil_cli.add_sim_arguments(p)
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="run several scenes in N parallel processes (same reports) [1]")
    p.add_argument("--junit", metavar="FILE.xml",
                   help="write JUnit XML: a testsuite per scene, a testcase per check")
    p.add_argument("--html", metavar="FILE.html",
                   help="write one self-contained HTML report (verdict, checks, plots, scene)")
    p.set_defaults(func=cmd_sim)
    p = sub.add_parser("drive", help="run a virtual CiA 402 drive until interrupted")
    if hil_cli is not None and hasattr(hil_cli, "add_drive_arguments"):
        hil_cli.add_drive_arguments(p)
    p.set_defaults(func=cmd_drive)
    return parser


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except EcamError as exc:
        print(f"ecam: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("ecam: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
