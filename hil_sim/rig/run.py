"""One rig run, start to end: a scene in, a report out (and the drive of a scene, for an
external master)."""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import replace

import canopen
import numpy as np

from ecam.mechanics import Mechanics
from ecam.plot import check_figure_path
from hil_sim.bus import BusLoad, FaultInjector, open_virtual_bus
from hil_sim.control import Gains
from hil_sim.drive import EDS_PATH, VirtualDrive, load_od
from hil_sim.plant import significant_harmonic_hz
from hil_sim.report import Report
from hil_sim.rig.analysis import analyse
from hil_sim.rig.cam import CompiledCam, cam_acceleration, compile_cam
from hil_sim.rig.loop import Record, run_cycles
from hil_sim.rig.network import LockstepMaster, set_up_drive
from hil_sim.rig.plan import PreparedRun, count_cycles, plan_run
from hil_sim.rig.plot import plot_report
from hil_sim.scene import Scene, load_scene

_channels = itertools.count(1)  # a virtual channel of its own for every run in the process


def run_scene(scene, *, plot=None) -> Report:
    """Run a scene on the rig and return its report.

    Parameters
    ----------
    scene : Scene or str or Path
        A scene, or the path of a scene file.
    plot : str or Path, optional
        Save the plots (tracking error, coupling torque, following error) to this file.

    Returns
    -------
    Report

    Raises
    ------
    ecam.errors.EcamError
        A bad scene, cam or table format (InputError and subclasses), or a run that cannot
        go on (SimulationError).
    """
    if plot is not None:
        check_figure_path(plot)  # before the run, not after it
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    wall_start = time.perf_counter()
    cam = compile_cam(scene)
    mechanics = scene.mechanics.build()
    cycle_s = scene.drive.cycle_s
    cycles = count_cycles(scene, cam.profile.master_period,
                          scene.master.units_per_second(cam.profile.master_period))
    injector = FaultInjector(scene.bus.faults, cycle_s) if scene.bus.faults.active else None
    jitter = injector.sync_offsets(cycles) if injector else np.zeros(cycles)
    plan = plan_run(scene, cam, jitter, cycles)
    options = _drive_options(scene, cam, mechanics)
    run = PreparedRun(scene=scene, cam=cam, mechanics=mechanics, plan=plan,
                      excitation_hz=options["excitation_hz"])
    record, timing = _run_on_the_bus(run, injector, options, wall_start)

    analysis_start = time.perf_counter()
    report = analyse(run, record)
    analysis_s = time.perf_counter() - analysis_start
    wall_s = time.perf_counter() - wall_start
    setup_s, loop_s, axis_s = timing["setup_s"], timing["loop_s"], timing["axis_s"]
    simulated_s = report.cycles * cycle_s
    report.timing = {
        "wall_s": wall_s, "setup_s": setup_s, "loop_s": loop_s, "axis_s": axis_s,
        "protocol_s": loop_s - axis_s, "analysis_s": analysis_s, "simulated_s": simulated_s,
        "real_time_factor": simulated_s / wall_s if wall_s > 0 else math.inf,
        "loop_real_time_factor": simulated_s / loop_s if loop_s > 0 else math.inf,
        "us_per_cycle": 1e6 * loop_s / max(report.cycles, 1),
    }
    if plot is not None:
        plot_report(report, plot)
    return report


def _run_on_the_bus(run: PreparedRun, injector: FaultInjector | None, options: dict,
                    wall_start: float) -> tuple[Record, dict]:
    """Boot the drive on a virtual channel of its own, set it up from a controller, run the
    cycles; always close the drive and the buses. Returns the record and where the time went."""
    scene = run.scene
    channel = f"hil-sim-{next(_channels)}"
    drive_bus = open_virtual_bus(channel)
    master_bus = open_virtual_bus(channel)
    load = BusLoad(scene.bus.bitrate, scene.drive.cycle_s)
    drive = None
    try:
        drive = VirtualDrive(bus=drive_bus, initial_counts=run.plan.initial_counts, **options)
        controller = LockstepMaster(master_bus, drive)
        node = canopen.RemoteNode(scene.drive.node_id, load_od(EDS_PATH, scene.drive.node_id))
        controller.add_node(node)
        setup = set_up_drive(scene, controller, node, drive, run.cam)
        setup_s = time.perf_counter() - wall_start
        record = run_cycles(scene, run.plan, controller, node, drive, load, injector, setup)
        loop_s = time.perf_counter() - wall_start - setup_s
        return record, {"setup_s": setup_s, "loop_s": loop_s, "axis_s": drive.axis_wall_s}
    finally:
        if drive is not None:
            drive.close()
        drive_bus.shutdown()
        master_bus.shutdown()


def drive_for_scene(scene, *, channel: str = "ecam", bus=None, node_id: int | None = None,
                    heartbeat_ms: int | None = None) -> VirtualDrive:
    """A :class:`VirtualDrive` with a scene's mechanics, gains and node id, at the cam's
    position for master 0, for an external master (``hil-sim drive --scene``).

    Parameters
    ----------
    scene : Scene or str or Path
    channel : str
        Virtual channel when ``bus`` is None.
    bus : can.BusABC, optional
    node_id : int, optional
        Overrides the scene's node id.
    heartbeat_ms : int, optional
        Producer heartbeat time at boot (default: the EDS value).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    cam = compile_cam(scene)
    options = _drive_options(scene, cam, scene.mechanics.build())
    if node_id is not None:
        options["node_id"] = node_id
    return VirtualDrive(channel=channel, bus=bus, initial_counts=int(cam.table.lookup(0)),
                        heartbeat_ms=heartbeat_ms, **options)


def _drive_options(scene: Scene, cam: CompiledCam, mechanics: Mechanics) -> dict:
    """Keyword arguments of :class:`VirtualDrive` for a scene (all but the bus and position)."""
    profile = cam.profile
    speed_units = scene.master.units_per_second(profile.master_period)
    excitation_hz = significant_harmonic_hz(cam_acceleration(profile),
                                            profile.master_period / abs(speed_units))
    return dict(node_id=scene.drive.node_id, mechanics=mechanics,
                gains=_gains(scene, mechanics), substeps=scene.drive.substeps,
                counts_per_motor_rad=(cam.scale * scene.mechanics.slave_units_per_load_radian
                                      * mechanics.gear_ratio),
                model=scene.drive.model, excitation_hz=excitation_hz)


def _gains(scene: Scene, mechanics: Mechanics) -> Gains:
    """The scene's gains: from the mechanics and bandwidths, then any gain given outright."""
    values = dict(scene.drive.gains)
    bandwidth = {k: values.pop(k) for k in ("velocity_bandwidth_hz", "position_bandwidth_hz",
                                            "integral_ratio") if k in values}
    # The controller streams the speed as velocity offset (0x60B1): no feed-forward twice.
    feedforward = {k: values.pop(k) for k in ("velocity_feedforward", "acceleration_feedforward")
                   if k in values}
    feedforward.setdefault("velocity_feedforward", 0.0)
    gains = Gains.from_mechanics(mechanics, **bandwidth, **feedforward)
    return replace(gains, **values) if values else gains
