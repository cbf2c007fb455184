"""``hil-sim``: run a scene on the rig, or run a virtual drive for an external CANopen master.

    hil-sim sim SCENE.toml [--json] [--timing] [--plot FILE.png] [--find-max-speed]
    hil-sim drive [--channel ecam] [--node-id 1] [--interface virtual]

Exit status: 0 when the scene passes (or the drive was stopped with Ctrl-C), 1 when a check
fails, 2 on bad input (one line on stderr, no traceback).

The ``ecam`` command line shares these commands: it calls :func:`add_sim_arguments` /
:func:`add_drive_arguments` on its own sub-parsers and dispatches to :func:`sim_command` /
:func:`drive_command`.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading

from ecam.errors import EcamError, InputError


def add_sim_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the ``sim`` command."""
    parser.add_argument("scene", nargs="+",
                        help="scene file(s) (TOML) or directories of them, see hil_sim/scenes/")
    parser.add_argument("--json", action="store_true",
                        help="print the report as JSON (deterministic: same scene, same bytes)")
    parser.add_argument("--timing", action="store_true",
                        help="add the wall-clock timing (real-time factor) to the JSON")
    parser.add_argument("--plot", metavar="FILE.png",
                        help="save tracking error, coupling torque and following error plots")
    parser.add_argument("--find-max-speed", action="store_true",
                        help="also bisect the master speed for the highest one that passes")


def add_drive_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the ``drive`` command."""
    parser.add_argument("--channel", default="ecam",
                        help="CAN channel (virtual channel name, or e.g. can0) [ecam]")
    parser.add_argument("--node-id", type=int, default=None,
                        help="CANopen node id 1..127 [1, or the scene's]")
    parser.add_argument("--interface", default="virtual",
                        help="python-can interface, e.g. virtual or socketcan [virtual]")
    parser.add_argument("--heartbeat-ms", type=int, default=None,
                        help="producer heartbeat time at boot [ms] (default: the EDS value)")
    parser.add_argument("--scene", metavar="SCENE.toml", default=None,
                        help="take mechanics, gains and node id from a scene (default: a "
                             "small servo on a rigid load)")


def sim_command(args: argparse.Namespace) -> int:
    """Run ``args.scene``; print the report (text or JSON); 0 if it passed, else 1."""
    from hil_sim.rig import find_max_speed, run_scene
    from hil_sim.scene import load_scene

    path = args.scene
    if isinstance(path, list):  # `hil-sim sim` parses SCENE... like `ecam sim`
        if len(path) != 1:
            raise InputError(f"hil-sim sim: {len(path)} scenes given; it runs one "
                             "(`ecam sim` runs several)")
        path = path[0]
    scene = load_scene(path)
    report = run_scene(scene, plot=args.plot)
    search = find_max_speed(scene) if args.find_max_speed else None
    if args.json:
        out = report.to_dict(timing=args.timing)
        if search is not None:
            out["max_speed"] = search
        print(json.dumps(out, indent=2, sort_keys=True, allow_nan=False))
    else:
        sys.stdout.write(report.to_text())
        if search is not None:
            if search["speed"] is None:
                print(f"max speed: no tested speed passes (lowest tried "
                      f"{search['failing_speed']:.6g} {search['unit']})")
            else:
                failing = search["failing_speed"]
                tail = (f"; at {failing:.6g} {search['unit']} fails "
                        f"{', '.join(search['failed_checks'])}" if failing is not None else "")
                print(f"max speed: {search['speed']:.6g} {search['unit']} passes"
                      f"{tail} ({len(search['runs'])} runs)")
        if args.plot:
            print(f"plots: {args.plot}")
    return 0 if report.passed else 1


def drive_command(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Run a virtual drive until Ctrl-C (or until ``stop`` is set); return 0."""
    import can

    from hil_sim.drive import VirtualDrive

    bus = None
    if args.interface != "virtual":
        try:
            bus = can.Bus(interface=args.interface, channel=args.channel)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise EcamError(f"interface {args.interface!r} channel {args.channel!r} cannot be "
                            f"opened: {exc}") from None
    if args.scene is not None:
        from hil_sim.rig import drive_for_scene
        drive = drive_for_scene(args.scene, channel=args.channel, bus=bus, node_id=args.node_id,
                                heartbeat_ms=args.heartbeat_ms)
    else:
        drive = VirtualDrive(channel=args.channel, node_id=1 if args.node_id is None else args.node_id, bus=bus,
                             heartbeat_ms=args.heartbeat_ms)
    stop = stop or threading.Event()
    print(f"virtual CiA 402 drive, node {drive.node_id}, on {args.interface} channel "
          f"{args.channel!r}; Ctrl-C stops it", flush=True)
    drive.start()
    try:
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        drive.stop()
        if bus is not None:
            bus.shutdown()
    return 0


def main(argv=None) -> int:
    """Entry point of the ``hil-sim`` script."""
    parser = argparse.ArgumentParser(prog="hil-sim", description=(
        "Software-in-the-loop rig for ecam: a CANopen master, a virtual CiA 402 drive and the "
        "mechanics, in lock-step over a python-can virtual bus."))
    commands = parser.add_subparsers(dest="command", required=True)
    add_sim_arguments(commands.add_parser(
        "sim", help="run a scene and report tracking, torque and bus checks"))
    add_drive_arguments(commands.add_parser(
        "drive", help="run a virtual drive for an external CANopen master until Ctrl-C"))
    args = parser.parse_args(argv)
    try:
        if args.command == "sim":
            return sim_command(args)
        return drive_command(args)
    except (EcamError, OSError) as exc:
        print(f"hil-sim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
