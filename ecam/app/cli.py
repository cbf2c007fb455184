"""The ``ecam`` and ``hil-sim`` command lines. Bad input: one line on stderr, exit status 2, no
traceback.

    ecam laws | check CAM | plot CAM -o FILE | compile CAM | demo | bench | sim SCENE... | drive
    hil-sim sim SCENE.toml [--json] [--timing] [--plot FILE.png] [--find-max-speed]
    hil-sim drive [--channel ecam] [--node-id 1] [--interface virtual]
"""

from __future__ import annotations

import argparse
import sys

from ecam import __version__
from ecam.errors import EcamError, InputError
from ecam.table import INTERPOLATIONS
from hil_sim.effects import FIDELITIES

from . import cam_commands, join_command
from .drive_command import INTERFACES, parse_node_ids
from .fit_command import add_fit_command
from .transition_command import add_transition_parser

EXIT_BAD_INPUT = 2


class UsageError(InputError):
    """A command line argparse refused; ``usage`` is the parser's usage line."""

    def __init__(self, message: str, usage: str) -> None:
        super().__init__(message)
        self.usage = usage


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, status 2, as for every other bad input
        # `ecam check: ...` reads `check: ...` after main's `ecam: error:` prefix.
        command = self.prog.partition(" ")[2]
        where = f"{command}: " if command else ""
        raise UsageError(f"{where}{message} (`{self.prog} --help` lists the options)",
                         self.format_usage().strip())


# The rig and the bench load the CAN stack and numpy-heavy modules; importing them only when their
# command runs keeps `ecam laws` or `ecam check` quick to start.
def _demo(args) -> int:
    from .demo import run_demo

    return run_demo(args.output)


def _bench(args) -> int:
    from .bench import main

    return main(args)


def _export(args) -> int:
    from .export_command import cmd_export

    return cmd_export(args)


def _firmware(args) -> int:
    from .firmware_command import cmd_firmware

    return cmd_firmware(args)


def _sim(args) -> int:
    from .rig_commands import run_sim

    return run_sim(args)


def _hil_sim(args) -> int:
    from .rig_commands import sim_command

    return sim_command(args)


def _drive(args) -> int:
    from .drive_command import drive_command

    return drive_command(args)


def _sweep(args) -> int:
    from .sweep_command import sweep_command

    return sweep_command(args)


def add_sim_arguments(parser: argparse.ArgumentParser, several: bool = True) -> None:
    """Options of the ``sim`` command (``several``: it takes several scenes and directories)."""
    parser.add_argument("scene", nargs="+" if several else 1,
                        help="scene files (TOML) or directories of them, see hil_sim/scenes/; "
                             "--json, --plot and --find-max-speed take one scene file" if several
                        else "one scene file (TOML), see hil_sim/scenes/")
    parser.add_argument("--json", action="store_true",
                        help="print the report as JSON (deterministic: same scene, same bytes)")
    parser.add_argument("--timing", action="store_true",
                        help="add the wall-clock timing (real-time factor) to the JSON (one scene) "
                             "or to the HTML page (--html)")
    parser.add_argument("--plot", metavar="FILE.png",
                        help="save tracking error, coupling torque and following error plots")
    parser.add_argument("--find-max-speed", action="store_true",
                        help="also search the highest master speed that passes (a machine: "
                             "and the station and check that limit it; a progress line per "
                             "trial on stderr) [off]")
    parser.add_argument("--fidelity", choices=FIDELITIES,
                        help="which effects to model: auto (measured; the scene's default), full "
                             "(every effect), ideal (none)")


def add_drive_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the ``drive`` command."""
    parser.add_argument("--channel", default=None,
                        help="CAN channel: a virtual channel name [ecam], a multicast group "
                             "[239.74.163.2] or a SocketCAN interface [vcan0]")
    parser.add_argument("--node-id", "--node", "--nodes", dest="node_id", action="append",
                        type=parse_node_ids, default=None, metavar="N[,N...]",
                        help="CANopen node id 1..127; several (repeated or comma-separated: "
                             "5,6) serve one virtual drive per node [1, or the scene's]")
    parser.add_argument("--interface", default=INTERFACES[0], choices=INTERFACES,
                        help="udp_multicast (= ecam_udp, without echoes) or socketcan: masters "
                             "in other processes; virtual: masters in this process only "
                             "[udp_multicast]")
    parser.add_argument("--heartbeat-ms", type=int, default=None,
                        help="producer heartbeat time at boot [ms] (default: the EDS value)")
    parser.add_argument("--scene", metavar="SCENE.toml", default=None,
                        help="take mechanics, gains and node id from a scene (default: a "
                             "small servo on a rigid load)")


def add_join_arguments(parser: argparse.ArgumentParser) -> None:
    """`ecam check A --then B`: the switch from A to B at A's period end (PLCopen coordinates)."""
    parser.add_argument("--then", metavar="CAM", help="check instead the switch to this cam at the first "
                                                      "cam's period end (default: the cam alone)")
    parser.add_argument("--master", choices=("absolute", "relative"),
                        help="with --then: the next cam's master coordinates, PLCopen MC_CamTableSelect."
                             "MasterAbsolute (default: absolute)")
    parser.add_argument("--slave", choices=("absolute", "relative"),
                        help="with --then: the next cam's slave coordinates, PLCopen MC_CamTableSelect."
                             "SlaveAbsolute (default: absolute)")
    join_command.add_at_arguments(parser)


# What each command's --help says above its options, and its exit status below them.
DESCRIPTIONS = {
    "laws": ("The normalized motion laws s(u), u in [0, 1], with their characteristic values Cv, Ca, "
             "Cj: the peaks of the first, second and third derivatives (inf where a lower derivative "
             "jumps).", "0 listed"),
    "check": ("Every jump of position, velocity and acceleration (errors) and jerk (warnings) of a "
              "cam file, at joints, inside laws and at the seam, with the stroke and the peaks.",
              "0 continuous, 1 a position, velocity or acceleration jump"),
    "plot": ("The motion diagram of a cam file: position, velocity, acceleration and jerk against "
             "the master position, joints dashed, jumps marked.", "0 written"),
    "compile": ("A cam file compiled into a fixed-point table whose error is certified against the "
                "exact cam at every master count; the cam's [table] gives what the options leave out, "
                "and the output says which of ecam's defaults it applied.", "0 written"),
    "export": ("A cam file as the table a vendor's controller reads, with the fewest points that "
               "meet the tolerance under that controller's own interpolation, and its certificate.",
               "0 written"),
    "demo": ("The main job on the built-in seed cams: checked, plotted, compiled, and run on the rig "
             "on a stiff coupling (passes) and a soft one (fails on purpose, to show a failing "
             "check).", "0 the demo ran (its failing scene is part of it)"),
    "bench": ("Speed against error of the table kinds (Python and C lookups against numpy and scipy) "
              "and the rig's speed.", "0 measured"),
    "sim": ("Run scenes on the software-in-the-loop rig: a master streaming over CANopen to a "
            "virtual CiA 402 drive on the scene's mechanics, every check with its limit. One scene "
            "prints its report (--json, --plot, --find-max-speed); several, or directories, print a "
            "progress line each and a summary table. --junit and --html write reports for either.",
            "0 every scene passed, 1 a check failed, 2 a scene could not run"),
    "firmware": ("The C reference runtime (ecam_table.c, ecam_table.h), the table switch at a period "
                 "boundary (ecam_table_pair.c, .h) and the table format they implement (FORMAT.md), "
                 "written from the installed package.", "0 written"),
    "drive": ("A virtual CiA 402 drive as a CANopen node for a master in another process (python "
              "canopen, a soft PLC, CANopenNode), until Ctrl-C or SIGTERM.",
              "0 stopped, 2 the bus could not be opened"),
}


def _document(parser: argparse.ArgumentParser) -> None:
    """Every subcommand's description and exit status, and every option's default in its help
    (a command added without a description shows its one-line help)."""
    for action in parser._actions:
        if not isinstance(action, argparse._SubParsersAction):
            continue
        helps = {choice.dest: choice.help for choice in action._choices_actions}
        for name, sub in action.choices.items():
            description, exits = DESCRIPTIONS.get(name, (helps.get(name) or "", "0 done"))
            sub.description = sub.description or description
            sub.epilog = sub.epilog or f"Exit status: {exits}, 2 bad input (one line on stderr)."
            for option in sub._actions:
                default = option.default
                if (option.option_strings and option.help and default not in (None, False, argparse.SUPPRESS)
                        and str(default) not in option.help):
                    option.help += f" (default: {default})"


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="ecam", description="Electronic cams: motion laws, certified cam tables, a CANopen rig.",
                     epilog="Exit status: 0 success, 1 a check failed, 2 bad input (one line on stderr). "
                            "`ecam COMMAND --help` describes each command.")
    parser.add_argument("--version", action="version", version=f"ecam {__version__}",
                        help="print ecam's version and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="COMMAND")

    p = sub.add_parser("laws", help="the motion laws and their characteristic values")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cam_commands.cmd_laws)

    p = sub.add_parser("check", help="report every jump of position, velocity, acceleration (and jerk)")
    p.add_argument("cam", help="cam file (TOML)")
    p.add_argument("--json", action="store_true", help="every jump as JSON, none left out")
    p.add_argument("--speed", metavar="SPEED",
                   help="also give the peaks at this master speed: master units per second, or e.g. "
                        "'720 deg/s', '120 periods/min', '120 rpm'")
    add_join_arguments(p)
    p.set_defaults(func=join_command.cmd_check)

    add_transition_parser(sub)

    p = sub.add_parser("plot", help="motion diagram: position, velocity, acceleration, jerk")
    p.add_argument("cam", help="cam file (TOML)")
    p.add_argument("-o", "--output", required=True, help="image file (.png, .svg, .pdf)")
    p.set_defaults(func=cam_commands.cmd_plot)

    p = sub.add_parser("compile", help="compile a cam into a certified fixed-point table")
    p.add_argument("cam", help="cam file (TOML)")
    p.add_argument("--interp", choices=INTERPOLATIONS,
                   help="interpolation kind (default: the cam's [table] interp, else cubic)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--points", type=int, help="stored points (intervals + 1) (default: the cam's [table])")
    group.add_argument("--tolerance", help="max error in slave units, or e.g. '2 counts' (default: the cam's [table])")
    p.add_argument("--interpolation-tolerance", metavar="TOLERANCE",
                   help="with a tolerance: max error the table adds to the final rounding's 1/2 count, e.g. "
                        "'0.05 counts' (default: the cam's [table] when its tolerance applies, else none: the "
                        "tolerance alone sizes the table)")
    p.add_argument("--master-counts", type=int,
                   help="master period in counts (default: the cam's [table], else 65536)")
    p.add_argument("--slave-counts-per-unit", type=float,
                   help="slave counts per slave unit (default: the cam's [table], else 1000)")
    p.add_argument("--horner-bits", type=int, choices=(64, 32),
                   help="32: a format whose expanded form (ecam_poly_init) runs in 32-bit words on 32-bit "
                        "cores, at a certified cost in precision (default: 64; docs/table_formats.md)")
    p.add_argument("-o", "--output", default=".", help="output directory (default: .)")
    p.add_argument("--format", default="c,bin", help="comma list of c, bin, csv, json (default: c,bin)")
    p.add_argument("--json", action="store_true", help="the table's summary and certificate as JSON")
    p.set_defaults(func=cam_commands.cmd_compile)

    p = sub.add_parser("export", help="a cam table for your controller, certified under its own interpolation")
    p.add_argument("cam", help="cam file (TOML)")
    p.add_argument("--to", required=True, metavar="FORMAT", type=str.lower,
                   help="codesys, twincat-cnc, kollmorgen, elmo, technosoft or csv (any case)")
    p.add_argument("--interp", help="twincat-cnc: linear (default) or cubic; csv: linear (default), cubic or "
                                    "quintic")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--tolerance", help="max error in slave units, or e.g. '2 counts' "
                                           "(default: the cam file's [table] tolerance)")
    group.add_argument("--points", type=int, help="points in the table instead of a tolerance")
    p.add_argument("--master-counts", type=int, help="master period in counts (Elmo, Technosoft; reports)")
    p.add_argument("--slave-counts-per-unit", type=float, help="slave counts per slave unit (reports in counts)")
    p.add_argument("-o", "--output", help="file to write (default: NAME.FORMAT.EXT here)")
    p.add_argument("--json", action="store_true", help="the export's summary and certificate as JSON")
    p.set_defaults(func=_export)

    add_fit_command(sub)

    p = sub.add_parser("demo", help="the main job on the built-in seed cams")
    p.add_argument("-o", "--output", default="ecam-demo",
                   help="directory for plots, tables and report.html (default: ecam-demo)")
    p.set_defaults(func=_demo)

    p = sub.add_parser("bench", help="speed against error of the table kinds and the rig")
    p.add_argument("--json", action="store_true", help="the rows as JSON")
    p.add_argument("--plot", help="Pareto plot file (.png)")
    p.add_argument("--quick", action="store_true", help="a few seconds, for smoke tests")
    p.set_defaults(func=_bench)

    p = sub.add_parser("sim", help="run a scene on the software-in-the-loop rig")
    add_sim_arguments(p)
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="run several scenes in N parallel processes (same reports) [1]")
    p.add_argument("--junit", metavar="FILE.xml",
                   help="write JUnit XML: a testsuite per scene, a testcase per check")
    p.add_argument("--html", metavar="FILE.html",
                   help="write one self-contained HTML report (verdict, checks, plots, scene)")
    p.set_defaults(func=_sim)
    p = sub.add_parser("firmware", help="write the C runtime (ecam_table.c, .h) and FORMAT.md into a directory")
    p.add_argument("--emit", metavar="DIR", required=True,
                   help="directory to write ecam_table.c/.h, ecam_table_pair.c/.h and FORMAT.md into "
                        "(created if missing)")
    p.set_defaults(func=_firmware)
    p = sub.add_parser("sweep", help="robustness sweep of a scene over manufacturing spread, on Dask")
    from .sweep_command import add_sweep_arguments

    add_sweep_arguments(p)
    p.set_defaults(func=_sweep)
    p = sub.add_parser("drive", help="run a virtual CiA 402 drive until interrupted")
    add_drive_arguments(p)
    p.set_defaults(func=_drive)
    _document(parser)
    return parser


def main(argv=None) -> int:
    arguments = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    if not arguments:  # a bare `ecam`: what it takes, not only that something is missing
        print(parser.format_usage().rstrip(), file=sys.stderr)
        print(f"ecam: error: give a command, one of {', '.join(_commands(parser))} "
              "(`ecam --help` says what each does)", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        args = parser.parse_args(arguments)
        return args.func(args)
    except EcamError as exc:
        print(f"ecam: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("ecam: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


def _commands(parser: argparse.ArgumentParser) -> list[str]:
    """The subcommand names of ``parser``."""
    return [name for action in parser._actions if isinstance(action, argparse._SubParsersAction)
            for name in action.choices]


def build_hil_sim_parser() -> argparse.ArgumentParser:
    """The ``hil-sim`` command line: `ecam sim` for one scene and `ecam drive`."""
    parser = argparse.ArgumentParser(prog="hil-sim", description=(
        "Software-in-the-loop rig for ecam: a CANopen master, a virtual CiA 402 drive and the "
        "mechanics, in lock-step over a python-can virtual bus."))
    commands = parser.add_subparsers(dest="command", required=True)
    sim = commands.add_parser("sim", help="run a scene and report tracking, torque and bus checks",
                              description="Run one scene on the rig, as `ecam sim SCENE` does.",
                              epilog="Exit status: 0 passed, 1 a check failed, 2 bad input.")
    add_sim_arguments(sim, several=False)
    sim.set_defaults(func=_hil_sim)
    drive = commands.add_parser("drive", help="run a virtual drive for an external CANopen master until Ctrl-C")
    add_drive_arguments(drive)
    drive.set_defaults(func=_drive)
    return parser


def hil_sim_main(argv=None) -> int:
    """Entry point of the ``hil-sim`` script: `ecam sim` for one scene and `ecam drive`."""
    args = build_hil_sim_parser().parse_args(argv)
    try:
        return args.func(args)
    except (EcamError, OSError) as exc:
        print(f"hil-sim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
