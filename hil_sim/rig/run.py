"""One rig run, start to end: a scene in, a report out (and the drive of a scene, for an
external master)."""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, replace

import canopen
import numpy as np

from ecam.mechanics import Mechanics
from ecam.plot import check_figure_path
from ecam.validate import choice
from hil_sim import effects, tuning
from hil_sim.bus import BusLoad, FaultInjector, open_virtual_bus
from hil_sim.control import AxisSetup
from hil_sim.drive import EDS_PATH, VirtualDrive, load_od
from hil_sim.plant import significant_harmonic_hz
from hil_sim.report import Report, check
from hil_sim.rig.acceptance import filter_frames
from hil_sim.rig.analysis import analyse
from hil_sim.rig.bode import bode_path, bode_series, plot_bode
from hil_sim.rig.cam import CompiledCam, cam_acceleration, compile_cam
from hil_sim.rig.fast import run_fast
from hil_sim.rig.fidelity import Selection, select
from hil_sim.rig.loop import Station, run_stations
from hil_sim.rig.network import LockstepMaster, set_up_drive
from hil_sim.rig.plan import PreparedRun, count_cycles, cruise_s, plan_run
from hil_sim.rig.plot import plot_report
from hil_sim.rig.record import Record
from hil_sim.rig.shared_master import shared_master_cob_id
from hil_sim.scene import Scene, load_scene
from hil_sim.tuning import AxisLoops

_channels = itertools.count(1)  # a virtual channel of its own for every run in the process
#: How a run moves its set points: over CANopen (the default), or bus-free.
PATHS = ("canopen", "fast")


def run_scene(scene, *, plot=None, path: str = "canopen", tuning=None) -> Report:
    """Run a scene on the rig and return its report.

    Parameters
    ----------
    scene : Scene or str or Path
        A scene, or the path of a scene file.
    plot : str or Path, optional
        Save the plots (tracking error, torques, following error) to this file.
    path : {"canopen", "fast"}
        Over the virtual CANopen bus (the default), or bus-free (:mod:`hil_sim.rig.fast`: the
        same control and plant without frames; no bus load, no bus faults).
    tuning : hil_sim.tuning.Tuning, optional
        The drive's commissioning, when it is already known (a search's trials at other master
        speeds of the same machine); None: :func:`commission` it.

    Returns
    -------
    Report

    Raises
    ------
    ecam.errors.EcamError
        A bad scene, cam or table format (InputError and subclasses), or a run that cannot
        go on (SimulationError).
    """
    choice("path", path, PATHS)
    if plot is not None:
        check_figure_path(plot)  # before the run, not after it
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    wall_start = time.perf_counter()
    axis = ready_axis(scene, tuning)
    records, timing = run_axes([axis], path)
    report = report_axis(axis, records[0], timing, 0, wall_start)
    if plot is not None:
        plot_report(report, plot)
        plot_bode(report, bode_path(plot))
    return report


@dataclass
class AxisRun:
    """One axis made ready to run (a single-axis run is a machine of one of these):

    Attributes
    ----------
    run : PreparedRun
    injector : FaultInjector or None
        The bus's fault injector (a machine uses its first axis's: one bus).
    selection : hil_sim.rig.fidelity.Selection
        The effects the run models, and why.
    setup : AxisSetup
        The drive's axis with those effects.
    tuning_s, effects_s : float
        Wall time of the commissioning and of the effects' measurement [s].
    """

    run: PreparedRun
    injector: FaultInjector | None
    selection: Selection
    setup: AxisSetup
    tuning_s: float
    effects_s: float


def ready_axis(scene: Scene, tuning=None) -> AxisRun:
    """Commission (unless ``tuning`` is given), prepare and select the effects of one axis."""
    start = time.perf_counter()
    if tuning is None:  # the drive's commissioning, timed on its own
        tuning = commission(scene)
    tuning_s = time.perf_counter() - start
    run, injector = prepare(scene, tuning)
    prepared = time.perf_counter()
    selection = select_effects(run)
    effects_s = time.perf_counter() - prepared
    return AxisRun(run, injector, selection, axis_setup(run, selection.included), tuning_s,
                   effects_s)


def run_axes(axes: list, path: str) -> tuple[list, dict]:
    """Run the axes in lock-step: bus-free (each axis alone: without a bus nothing couples
    them) or over one CANopen network. Returns one record per axis and the timing:
    ``setup_s``, ``loop_s`` (the machine's), ``axis_s`` (a list: each axis's servo and plant
    time)."""
    loop_start = time.perf_counter()
    if path == "fast":
        records, axis_s = [], []
        for axis in axes:
            start = time.perf_counter()
            records.append(run_fast(axis.run, axis.setup))
            axis_s.append(time.perf_counter() - start)
        return records, {"setup_s": 0.0, "loop_s": time.perf_counter() - loop_start,
                         "axis_s": axis_s}
    return _run_on_the_bus(axes)


def report_axis(axis: AxisRun, record: Record, timing: dict, index: int,
                wall_start: float) -> Report:
    """Axis ``index``'s report from its record (``timing``: :func:`run_axes`')."""
    run, setup, scene = axis.run, axis.setup, axis.run.scene
    analysis_start = time.perf_counter()
    report = analyse(run, record, setup)
    describe_selection(report, axis.selection)
    report.summary["tuning"] = run.tuning.to_dict()
    report.series.update(bode_series(setup, scene.drive.cycle_s))
    analysis_s = time.perf_counter() - analysis_start
    wall_s = time.perf_counter() - wall_start
    loop_s, axis_s = timing["loop_s"], timing["axis_s"][index]
    simulated_s = report.cycles * scene.drive.cycle_s
    report.timing = {
        "wall_s": wall_s, "tuning_s": axis.tuning_s, "effects_s": axis.effects_s,
        "setup_s": timing["setup_s"],
        "loop_s": loop_s, "axis_s": axis_s, "protocol_s": loop_s - axis_s,
        "analysis_s": analysis_s, "simulated_s": simulated_s, "path": record.path,
        "real_time_factor": simulated_s / wall_s if wall_s > 0 else math.inf,
        "loop_real_time_factor": simulated_s / loop_s if loop_s > 0 else math.inf,
        "us_per_cycle": 1e6 * loop_s / max(report.cycles, 1),
    }
    return report


def prepare(scene: Scene, tuning=None) -> tuple[PreparedRun, FaultInjector | None]:
    """Everything known before the drive boots: the cam and its table, the mechanics, the
    master's plan, every effect's value, the drive's commissioning (``tuning``, when already
    known, else :func:`commission`); and the bus's fault injector."""
    cam = compile_cam(scene)
    mechanics = scene.mechanics.build()
    cycle_s = scene.drive.cycle_s
    profile = cam.profile
    speed_units = scene.master.units_per_second(profile.master_period)
    cycles = count_cycles(scene, profile.master_period, speed_units)
    injector = FaultInjector(scene.bus.faults, cycle_s) if scene.bus.faults.active else None
    jitter = injector.sync_offsets(cycles) if injector else np.zeros(cycles)
    plan = plan_run(scene, cam, jitter, cycles)
    excitation_hz = significant_harmonic_hz(cam_acceleration(profile),
                                            profile.master_period / abs(speed_units))
    gearhead = scene.sizing.gearhead
    values = effects.resolve(mechanics, dict(scene.mechanics.effects), dict(scene.drive.effects),
                             scene.drive.control_rate_hz,
                             gearhead.idle_torque if gearhead is not None else None)
    if tuning is None:
        tuning = commission(scene, mechanics, values)
    run = PreparedRun(scene=scene, cam=cam, mechanics=mechanics, plan=plan,
                      excitation_hz=excitation_hz, effect_values=values,
                      gains=tuning.gains, tuning=tuning)
    return run, injector


def commission(scene: Scene, mechanics: Mechanics | None = None, values=None):
    """The drive's tuning for a scene (:func:`hil_sim.tuning.commission`): on the full model,
    once per machine, whatever the master's speed and the run's fidelity."""
    mechanics = scene.mechanics.build() if mechanics is None else mechanics
    if values is None:
        values = effects.resolve(mechanics, dict(scene.mechanics.effects),
                                 dict(scene.drive.effects), scene.drive.control_rate_hz)
    limits = scene.limits
    return tuning.commission(mechanics, values, scene.drive.cycle_s / scene.drive.substeps,
                             dict(scene.drive.gains), scene.drive.feedforward,
                             tuning.MarginLimits(limits.phase_margin_deg, limits.gain_margin_db,
                                                 limits.sensitivity_peak))


def axis_setup(run: PreparedRun, included) -> AxisSetup:
    """The drive's axis with the ``included`` effects on (:meth:`EffectValues.build`)."""
    scene = run.scene
    model, plant_effects, drive_effects = run.effect_values.build(included)
    drive_effects = replace(drive_effects, speed_symmetrization=scene.drive.speed_symmetrization,
                            friction_feedforward=friction_feedforward(run),
                            voltage_limit=scene.sizing.voltage_limit())
    return AxisSetup(run.mechanics, run.gains, substeps=scene.drive.substeps,
                     counts_per_motor_rad=_counts_per_motor_rad(scene, run.cam, run.mechanics),
                     model=model, excitation_hz=run.excitation_hz, plant_effects=plant_effects,
                     drive_effects=drive_effects, feedforward=scene.drive.feedforward)


def friction_feedforward(run: PreparedRun) -> float:
    """The Coulomb friction the drive feeds forward [N m at the motor] with ``[drive]
    friction_feedforward = true``: the machine's, as commissioning identifies it (the full
    model's motor friction and the load's through the gear, F_m + F_L r / eta), whatever the
    run's fidelity models; 0 when off."""
    if not run.scene.drive.friction_feedforward:
        return 0.0
    values, m = run.effect_values, run.mechanics
    motor = values["motor_coulomb_friction"].value or 0.0
    load = values["load_coulomb_friction"].value or 0.0
    return motor + load * m.gear_ratio / m.gear_efficiency


#: Whole cam periods at cruise speed the effects are measured over (after the master got there
#: and the checks' settling time): a long run at a constant master repeats its periods, so the
#: measurement is a quick run (issue 10, item 3), not as long as the scene.
MEASURE_PERIODS = 3


def measuring_run(run: PreparedRun) -> PreparedRun:
    """The run the effects are measured on: the scene's first cycles up to the master's cruise
    speed, the settling time and :data:`MEASURE_PERIODS` periods at cruise; the whole run when
    it is not longer, or when the master stops again (``start_stop``: its stop comes last)."""
    scene, plan = run.scene, run.plan
    if scene.master.profile == "start_stop" or run.cam_hz == 0.0:
        return run
    seconds = max(cruise_s(scene, run.cam), scene.limits.settle_s) + MEASURE_PERIODS / run.cam_hz
    cycles = math.ceil(seconds / plan.cycle_s - 1e-9)
    if cycles >= plan.cycles:
        return run
    cut = {name: getattr(plan, name)[:cycles] for name in (
        "master_end", "targets", "velocities", "reference_units", "master_units", "sync_offsets")}
    return replace(run, plan=replace(plan, cycles=cycles, **cut))


def select_effects(run: PreparedRun) -> Selection:
    """The effects the run models, by the scene's fidelity (:mod:`hil_sim.rig.fidelity`),
    measured on a quick run (:func:`measuring_run`)."""
    scene = run.scene
    forced = None if scene.drive.model == "auto" else scene.drive.model
    quick = measuring_run(run)

    def measure(included) -> list:
        setup = axis_setup(quick, included)
        return analyse(quick, run_fast(quick, setup), setup).checks + margin_lines(quick, setup)

    # fidelity ideal: an ideal drive (no current loop), the controller's rate weighed (a coupling
    # mode above its Nyquist frequency is rung by the torque steps: the reason says so)
    rule = (run.mechanics, run.excitation_hz, run.gains.velocity_bandwidth_hz(run.mechanics),
            10.0, scene.drive.control_rate_hz, None)
    selection = select(scene.fidelity, run.effect_values, forced, measure, rule)
    if selection.proof is not None:
        selection.proof["cycles"] = quick.plan.cycles
    return selection


def margin_lines(run: PreparedRun, setup: AxisSetup) -> list:
    """The loop's phase and gain margins as lines without a limit, for the fidelity's proof
    only: the reduced model's margins must lie within its share of the full model's (the
    sensitivity peak is the loop_stability check's own value), or the effect that moved them
    goes back in. An infinite margin is None (no crossing)."""
    overall = AxisLoops.from_setup(setup, run.plan.cycle_s).assess(setup.gains).overall
    return [check(name, value if math.isfinite(value) else None, None, unit)
            for name, value, unit in (("loop_phase_margin", overall.phase_margin_deg, "deg"),
                                      ("loop_gain_margin", overall.gain_margin_db, "dB"))]


def describe_selection(report: Report, selection: Selection) -> None:
    """Put the effects and why into the report (the model's reason: the compliance's)."""
    report.summary["fidelity"] = selection.fidelity
    report.summary["effects"] = [c.to_dict() for c in selection.choices]
    if selection.proof is not None:
        report.summary["fidelity_proof"] = selection.proof
    compliance = next(c for c in selection.choices if c.name == "torsional_compliance")
    if compliance.value == "n/a":
        report.model_reason = "rigid model: no coupling stiffness given, motor and load move as one."
    else:
        kind = "two-mass model" if report.model == "two_mass" else "rigid model"
        why = compliance.why.rstrip(".")
        report.model_reason = f"{why}." if why.startswith(kind) else f"{kind}: {why}."


def _run_on_the_bus(axes: list) -> tuple[list, dict]:
    """Boot the axes' drives on a virtual channel of their own, set each up from one
    controller, run the cycles; always close the drives and the buses. Returns the records and
    where the time went."""
    first = axes[0].run.scene
    master_cob_id = shared_master_cob_id(axes)  # before anything opens: a refusal is bad input
    channel = f"hil-sim-{next(_channels)}"
    buses = [open_virtual_bus(channel) for _ in axes]
    master_bus = open_virtual_bus(channel)
    load = BusLoad(first.bus.bitrate, first.drive.cycle_s)
    drives = []
    start = time.perf_counter()
    try:
        for axis, drive_bus in zip(axes, buses):
            drives.append(VirtualDrive(bus=drive_bus, node_id=axis.run.scene.drive.node_id,
                                       initial_counts=axis.run.plan.initial_counts,
                                       **drive_options(axis.setup)))
            if len(axes) > 1:  # each drive handles its own frames, not every node's
                filter_frames(drives[-1])
        controller = LockstepMaster(master_bus, drives)
        stations = []
        for axis, drive in zip(axes, drives):
            scene = axis.run.scene
            node = canopen.RemoteNode(scene.drive.node_id, load_od(EDS_PATH, scene.drive.node_id))
            controller.add_node(node)
            facts = set_up_drive(scene, controller, node, drive, axis.run.cam, master_cob_id)
            stations.append(Station(scene, axis.run.plan, node, drive, facts))
        setup_s = time.perf_counter() - start
        records = run_stations(stations, controller, load, axes[0].injector)
        loop_s = time.perf_counter() - start - setup_s
        return records, {"setup_s": setup_s, "loop_s": loop_s,
                         "axis_s": [drive.axis_wall_s for drive in drives]}
    finally:
        for drive in drives:
            drive.close()
        for bus in buses:
            bus.shutdown()
        master_bus.shutdown()


def drive_options(setup: AxisSetup) -> dict:
    """:class:`VirtualDrive` keyword arguments of an axis setup."""
    return dict(mechanics=setup.mechanics, gains=setup.gains, substeps=setup.substeps,
                counts_per_motor_rad=setup.counts_per_motor_rad, model=setup.model,
                excitation_hz=setup.excitation_hz, plant_effects=setup.plant_effects,
                drive_effects=setup.drive_effects, feedforward=setup.feedforward)


def drive_for_scene(scene, *, channel: str = "ecam", bus=None, node_id: int | None = None,
                    heartbeat_ms: int | None = None) -> VirtualDrive:
    """A :class:`VirtualDrive` with a scene's mechanics, gains, effects and node id, at the
    cam's position for master 0, for an external master (``ecam drive --scene``).

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
    options, scene_node_id = scene_drive_options(scene)
    return VirtualDrive(channel=channel, bus=bus, node_id=node_id or scene_node_id,
                        heartbeat_ms=heartbeat_ms, **options)


def scene_drive_options(scene) -> tuple[dict, int]:
    """The :class:`VirtualDrive` keyword arguments of a scene (mechanics, gains, effects, the
    cam's position for master 0), worked out once for any number of drives
    (``ecam drive --scene S --node-id 5,6``), and the scene's node id."""
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    run, _ = prepare(scene)
    setup = axis_setup(run, select_effects(run).included)
    return (dict(initial_counts=int(run.cam.table.lookup(0)), **drive_options(setup)),
            scene.drive.node_id)


def _counts_per_motor_rad(scene: Scene, cam: CompiledCam, mechanics: Mechanics) -> float:
    """Position counts per motor radian: the cam's counts per slave unit, the slave units per
    load radian and the gear."""
    return cam.scale * scene.mechanics.slave_units_per_load_radian * mechanics.gear_ratio
