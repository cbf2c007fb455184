"""`ecam fit POINTS`: a cam from a point table (a text table, ecam's CSV export or a CODESYS XYVA
cam), fitted by a quintic smoothing spline with its deviation certified (:func:`ecam.fit_points`);
the cam file, the certificate as text or JSON, and a plot of the points, the fit and the residuals."""

from __future__ import annotations

import json
from pathlib import Path

from ecam.atomic_files import write_files
from ecam.errors import InputError
from ecam.export import json_safe
from ecam.fit import MAX_KNOTS, fit_points
from ecam.plot import check_figure_path, plot_fit
from ecam.points import read_points


def add_fit_command(sub) -> None:
    """Register ``ecam fit`` on the command line's subparsers."""
    p = sub.add_parser("fit", help="a cam from a point table: a quintic smoothing spline with a certified deviation")
    p.add_argument("points", help="point table: master, slave[, weight] columns (CSV or whitespace, '#' comments, "
                                  "a header line), ecam's CSV export or a CODESYS XYVA cam (.st)")
    p.add_argument("--tolerance", type=float,
                   help="largest |fit - point| in slave units: the smoothest fit within it (default: none, "
                        "generalized cross-validation chooses the smoothing)")
    p.add_argument("--periodic", action="store_true", default=None,
                   help="the cam repeats: continuous through jerk across the seam (default: no; ecam's CSV says)")
    p.add_argument("--net-stroke", type=float, metavar="S",
                   help="slave advance per period in slave units, for a cam that does not return (implies "
                        "--periodic; default: none; ecam's CSV says)")
    p.add_argument("--period", type=float,
                   help="master period (default: last master minus first: the last row repeats the first one "
                        "period on)")
    p.add_argument("--step", type=float, action="append", metavar="X",
                   help="a master position where the table steps on purpose: the stretches either side are "
                        "fitted on their own (repeat for more; default: none, and a step is refused)")
    p.add_argument("--name", help="the cam's name (default: the file's stem)")
    p.add_argument("--master-unit", help="master unit (default: deg, or what ecam's CSV says)")
    p.add_argument("--slave-unit", help="slave unit (default: mm, or what ecam's CSV says)")
    p.add_argument("--max-knots", type=int, default=MAX_KNOTS,
                   help=f"knot intervals beyond which knots are placed, not put at every point [{MAX_KNOTS}]")
    p.add_argument("-o", "--output", metavar="CAM.toml", help="write the cam file (default: none)")
    p.add_argument("--plot", metavar="FILE", help="plot points, fit, residuals and the motion diagram "
                                                  "(.png, .svg, .pdf; default: none)")
    p.add_argument("--json", action="store_true", help="the certificate as JSON")
    p.set_defaults(func=cmd_fit)


def cmd_fit(args) -> int:
    if args.plot:
        check_figure_path(args.plot)  # before the work
    table = read_points(args.points)
    settings = table.settings or {}
    master, slave = table.samples()
    weights = table.weights
    net_stroke = args.net_stroke if args.net_stroke is not None else settings.get("net_stroke") or None
    periodic = args.periodic if args.periodic is not None else settings.get("periodic", False)
    period = args.period if args.period is not None else settings.get("master_period")
    result = fit_points(master, slave, weights, tolerance=args.tolerance, periodic=bool(periodic or net_stroke),
                        net_stroke=net_stroke, period=period, name=args.name or Path(args.points).stem,
                        master_unit=args.master_unit or settings.get("master_unit", "deg"),
                        slave_unit=args.slave_unit or settings.get("slave_unit", "mm"), max_knots=args.max_knots,
                        steps=args.step)
    files = {}
    if args.output:
        path = Path(args.output)
        try:
            write_files({path: result.profile.to_toml()})
        except OSError as exc:
            raise InputError(f"output: {str(path)!r} cannot be written: {exc.strerror or exc}") from None
        files["cam"] = str(path)
    if args.plot:
        plot_fit(result, args.plot)
        files["plot"] = args.plot
    source = {"kind": table.kind, "rows": int(table.master.size)}
    if table.interpolation:
        source["sampled"] = (f"its {table.interpolation} Hermite curve (the rule its rows are joined by), "
                             f"{master.size} samples")
    if args.json:
        print(json.dumps(json_safe({**result.certificate, "source": source, "files": files}), indent=1,
                         sort_keys=True))
    else:
        if table.interpolation:
            print(f"{args.points}: {table.kind}, {table.master.size} rows; fitted to {source['sampled']}")
        print(result.report_text())
        for path in files.values():
            print(f"  wrote {path}")
    return 0
