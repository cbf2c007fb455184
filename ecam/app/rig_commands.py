"""The rig command `ecam sim` (one scene or many; `ecam drive` is in :mod:`.drive_command`).
Exit status: 0 when every scene passes, 1 when a check fails, 2 on bad input."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from ecam.atomic_files import check_outputs, write_files
from ecam.errors import EcamError, InputError
from hil_sim.rig import find_max_speed, run_scene
from hil_sim.rig.bode import bode_path
from hil_sim.machine import load_machine

from .machine_html import sim_page
from .junit import junit_xml
from .machine_command import machine_command
from .multi import exit_status, run_scenes, scene_files, summary_table
from .report_output import print_report


def run_sim(args: argparse.Namespace) -> int:
    """`ecam sim`: one scene prints its report (text or JSON); several run through :func:`sim_many`."""
    # one path that is not a directory is one scene, whatever its name (a bad path is then one
    # `ecam: error:` line, not a batch of one ERROR row)
    # os.path.isdir never raises (Path.is_dir does, on a name longer than NAME_MAX)
    single = len(args.scene) == 1 and not os.path.isdir(args.scene[0])
    if single:  # its report, JSON, plot and search, and JUnit XML or HTML as well when asked
        args.scene = args.scene[0]
        return sim_command(args)
    return sim_many(args)


def _check_outputs(args, inputs) -> None:
    """Refuse a --junit or --html file whose directory does not exist, or that is one of the
    ``inputs`` (a scene or its cam), before anything runs."""
    outputs = [option for option in (getattr(args, "junit", None), getattr(args, "html", None))
               if option is not None]
    for option in outputs:  # os.path never raises (Path.resolve does on a symbolic link loop)
        if not os.path.isdir(os.path.dirname(os.path.abspath(option))):
            raise InputError(f"output {option!r}: its directory does not exist")
    check_outputs(outputs, inputs)


def _write_reports(args, results, stream, inputs=()) -> None:
    """Write the --junit and --html files of ``results``; say where, on ``stream``."""
    outputs = {}
    if getattr(args, "junit", None):
        outputs[Path(args.junit)] = junit_xml(results)
    if getattr(args, "html", None):
        outputs[Path(args.html)] = sim_page(results, timing=getattr(args, "timing", False))
    try:
        write_files(outputs, inputs)
    except OSError as exc:
        raise InputError(f"report files cannot be written: {exc.strerror or exc}") from None
    for path in outputs:
        print(f"wrote {path}", file=stream)


def sim_command(args: argparse.Namespace) -> int:
    """Run one scene, ``args.scene``; print the report (text or JSON); 0 if it passed, else 1."""
    path = args.scene
    if isinstance(path, list):  # `hil-sim sim` parses SCENE... like `ecam sim`
        if len(path) != 1:
            raise InputError(f"hil-sim sim: {len(path)} scenes given; it runs one "
                             "(`ecam sim` runs several)")
        path = path[0]
    if not str(path):
        raise InputError("scene '': should be a path (an empty argument names no file)")
    machine = load_machine(path)  # a scene file in today's format is a machine of one
    if not machine.single:
        inputs = [path] + [a.cam.file for a in machine.axes if a.cam.file]
        _check_outputs(args, inputs)  # before the run: never over the machine or its cams
        if args.plot:
            check_outputs([args.plot], inputs)
        return machine_command(
            argparse.Namespace(**{**vars(args), "scene": path}), machine,
            lambda report, seconds: _write_reports(args, [(Path(path), report, seconds)],
                                                   sys.stderr if args.json else sys.stdout,
                                                   inputs), format_search)
    scene = machine.axes[0]
    inputs = [path] + ([scene.cam.file] if scene.cam.file else [])
    _check_outputs(args, inputs)  # before the run: never over the scene or its cam
    if args.plot:
        check_outputs([args.plot], inputs)
    if getattr(args, "fidelity", None):
        scene = scene.with_fidelity(args.fidelity)
    start = time.perf_counter()
    report = run_scene(scene, plot=args.plot)
    seconds = time.perf_counter() - start
    search = None
    if args.find_max_speed:
        search = find_max_speed(scene, progress=lambda line: print(line, file=sys.stderr,
                                                                   flush=True))
    print_report(args, report, search, format_search)
    if args.plot and not args.json:
        print(f"plots: {args.plot}, {bode_path(args.plot)} (the open loops)")
    if getattr(args, "junit", None) or getattr(args, "html", None):
        _write_reports(args, [(Path(path), report, seconds)], sys.stderr if args.json else sys.stdout,
                       inputs)
    return 0 if report.passed else 1


#: How the text says whose limit a search's limiting check is (``limiting_kind``).
WHOSE = {"machine": "the machine (mechanics, sizing): ",
         "drive": "the drive (tuning, stability, torque): ",
         "bus": "the bus: "}


def format_search(search: dict) -> str:
    """The text of a find-max-speed result."""
    unit = search["unit"]
    if search["speed"] is None:
        lowest = search["failing_speed"]
        return (f"max speed: no tried speed passes (lowest tried {lowest:.6g} {unit}; "
                f"{len(search['runs'])} trials)\n" if lowest is not None else
                "max speed: no trial could run\n")
    lines = [f"max speed: {search['speed']:.6g} {unit} = {search['periods_per_minute']:.6g} "
             f"periods per minute"
             + (" (confirmed over CANopen)" if search["confirmed"] else " (NOT confirmed over CANopen)")]
    if search["failing_speed"] is not None:
        kind = search.get("limiting_kind")
        whose = WHOSE.get(kind, "")
        if "limiting_station" in search:  # a machine's: which station, or the machine itself
            station = search["limiting_station"]
            whose = (f"station {station}, " if station else "the machine's own check, ") + whose
        lines.append(f"  limited by: at {search['failing_speed']:.6g} {unit} {whose}"
                     f"{search['limiting_check'] or ', '.join(search['failed_checks'])}")
    else:
        lines.append("  no failing speed found within the trials")
    lines.append(f"  resolution {search['resolution']:.3g} {unit}: {search['resolution_reason']}")
    lines.append(f"  each trial: until cruise speed and the settling time, then "
                 f"{search['periods_at_cruise']} periods ({len(search['runs'])} trials)")
    return "\n".join(lines) + "\n"


def sim_many(args) -> int:
    """Several scenes: a progress line each, a summary table, JUnit XML and HTML on request.
    ``--fidelity`` applies to every scene; ``--timing`` adds the wall times to the HTML page."""
    given = [option for option, on in (("--json", args.json), ("--plot", args.plot),
                                        ("--find-max-speed", args.find_max_speed)) if on]
    if given:
        what = f"{len(args.scene)} scene arguments" if len(args.scene) > 1 else "a directory"
        raise InputError(f"{', '.join(given)}: one scene file only, {what} given (several scenes "
                         "take --jobs, --junit, --html, --fidelity and --timing)")
    _check_outputs(args, scene_inputs(args.scene))
    results = run_scenes(args.scene, args.jobs,
                         progress=lambda line: print(line, file=sys.stderr),
                         fidelity=getattr(args, "fidelity", None))
    print(summary_table(results))
    _write_reports(args, results, sys.stdout, scene_inputs(args.scene))
    return exit_status(results)


def scene_inputs(paths) -> list:
    """The files `ecam sim` reads for ``paths``: each scene or machine file and the cam files
    it names (a file that does not load names none; its error is its outcome)."""
    inputs = []
    for scene_path in scene_files(paths):
        inputs.append(scene_path)
        try:
            axes = load_machine(scene_path).axes  # a scene file is a machine of one
        except EcamError:
            continue
        inputs += [axis.cam.file for axis in axes if axis.cam.file is not None]
    return inputs
