"""The rig commands: `ecam sim` (one scene or many) and `ecam drive` (a virtual drive for an
external CANopen master). Exit status: 0 when every scene passes (or the drive was stopped), 1 when
a check fails, 2 on bad input."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path

import can

from ecam.atomic_files import write_files
from ecam.errors import EcamError, InputError
from hil_sim.drive import VirtualDrive
from hil_sim.rig import drive_for_scene, find_max_speed, run_scene
from hil_sim.scene import load_scene
from hil_sim.udp_bus import DEFAULT_GROUP, EchoFreeUdpMulticastBus

from .html_report import html_report
from .junit import junit_xml
from .multi import exit_status, run_scenes, summary_table


def run_sim(args: argparse.Namespace) -> int:
    """`ecam sim`: one scene prints its report (text or JSON); several run through :func:`sim_many`."""
    single = len(args.scene) == 1 and Path(args.scene[0]).suffix == ".toml"
    if single and not (args.junit or args.html or args.jobs != 1):
        args.scene = args.scene[0]
        return sim_command(args)
    return sim_many(args)


def sim_command(args: argparse.Namespace) -> int:
    """Run one scene, ``args.scene``; print the report (text or JSON); 0 if it passed, else 1."""
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


def sim_many(args) -> int:
    """Several scenes: a progress line each, a summary table, JUnit XML and HTML on request."""
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


# Transports and how the drive opens them. The in-process `virtual` bus reaches only masters in this
# process; the others reach other processes. On udp_multicast every sender hears its own frames
# back, so the drive opens it as the echo-free variant (same wire format and groups).
_DEFAULT_CHANNELS = {"virtual": "ecam", "udp_multicast": DEFAULT_GROUP, "ecam_udp": DEFAULT_GROUP,
                     "socketcan": "vcan0"}


def open_drive_bus(interface: str, channel: str | None):
    """(bus, channel): None for the in-process virtual bus, which the drive opens itself."""
    channel = channel or _DEFAULT_CHANNELS[interface]
    if interface == "virtual":
        return None, channel
    try:
        if interface in ("udp_multicast", "ecam_udp"):
            return EchoFreeUdpMulticastBus(channel=channel), channel
        return can.Bus(interface=interface, channel=channel), channel
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise EcamError(f"interface {interface!r} channel {channel!r} cannot be opened: {exc}") from None


def drive_command(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Run a virtual drive until Ctrl-C or SIGTERM (or until ``stop`` is set); return 0."""
    bus, channel = open_drive_bus(args.interface, args.channel)
    try:
        if args.scene is not None:
            drive = drive_for_scene(args.scene, channel=channel, bus=bus, node_id=args.node_id,
                                    heartbeat_ms=args.heartbeat_ms)
        else:
            drive = VirtualDrive(channel=channel, node_id=1 if args.node_id is None else args.node_id, bus=bus,
                                 heartbeat_ms=args.heartbeat_ms)
    except BaseException:
        if bus is not None:
            bus.shutdown()
        raise
    stop = stop or threading.Event()
    restore = _stop_on_sigterm(stop)
    print(f"virtual CiA 402 drive, node {drive.node_id}, on {args.interface} channel "
          f"{channel!r}; Ctrl-C or SIGTERM stops it", flush=True)
    drive.start()
    try:
        while not stop.wait(0.1):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        drive.stop()
        if bus is not None:
            bus.shutdown()
        restore()
    print("virtual drive stopped", flush=True)
    return 0


def _stop_on_sigterm(stop: threading.Event):
    """Let SIGTERM (a service manager, `kill`) stop the drive as Ctrl-C does: the bus is shut down
    and the process exits 0. Returns the function that puts the previous handler back."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None  # signal handlers can be set from the main thread only
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())
    return lambda: signal.signal(signal.SIGTERM, previous)
