"""The software-in-the-loop rig: a scene in, a tracking report out.

One run, in order:

1. **Cam and table.** The scene's cam file is loaded and compiled (:func:`ecam.compile_table`).
2. **Model.** The mechanics and the cam's excitation at the master speed go to
   :class:`hil_sim.control.ServoAxis`, which picks the simplest faithful plant
   (:func:`hil_sim.plant.choose_model`); the report says which and why.
3. **Master plan.** The master's motion (constant speed, jerk-limited start/stop, or a cam-in
   planned with ruckig) is sampled for every cycle up front: it does not depend on the slave.
   Controller-side, the set points are looked up in the table for all cycles at once
   (``table.lookup`` for the target at the end of the cycle, ``table.slope`` times the master
   speed at mid-cycle for the velocity offset). Drive-side, the master position is what goes
   on the bus.
4. **Lock-step over the virtual bus.** A controller (a canopen ``RemoteNode`` on its own
   virtual bus) boots the :class:`~hil_sim.drive.VirtualDrive`, configures it by SDO
   (interpolation period, following-error window, mode; drive-side: the table download and
   activation), starts it (NMT) and enables it (CiA 402 controlword by RPDO). Then, each cycle:
   the RPDO with the set point, the SYNC, the drive handles both (runs its control loop one
   period and answers with its TPDOs), the controller reads the TPDOs. Faults (lost or late
   frames, SYNC jitter) are applied here, from a seeded generator.
5. **Report.** Following error (motor side, from the TPDOs), load-side tracking error against
   the cam, coupling torque against its rating, wind-up, torsional resonance against the cam's
   harmonics, bus load, faults, torque saturation: each a check with a limit.

Nothing waits on a clock and no thread runs, so the same scene gives the same report, bit for
bit. :func:`find_max_speed` bisects the master speed for the highest one that passes.
"""

from __future__ import annotations

import itertools
import math
import struct
import time
from dataclasses import dataclass, replace

import can
import canopen
import numpy as np

import ecam
from ecam.errors import InputError, SimulationError
from hil_sim import drive as drive_module
from hil_sim import cia402
from hil_sim.bus import DELIVER, BusLoad, FaultInjector, SimNetwork, frame_bits, open_virtual_bus
from hil_sim.drive import EDS_PATH, VirtualDrive, load_od
from hil_sim.report import Report, check
from hil_sim.scene import Scene, _interpolation_period, load_scene

_channels = itertools.count(1)
_RESONANCE_SAMPLES = 4096  # samples of one cam period for its harmonic spectrum
_RECORDED = {0x6041: "statusword", 0x60F4: "following_error"}  # read from the TPDOs
_STRUCT_CODES = {0x02: "b", 0x03: "h", 0x04: "i", 0x05: "B", 0x06: "H", 0x07: "I"}


@dataclass(frozen=True)
class _Plan:
    """Everything about the run that does not depend on the slave, per cycle k (0..cycles-1)."""

    cycles: int
    cycle_s: float
    master_end: np.ndarray       # master counts sent for the end of cycle k (jittered sample)
    targets: np.ndarray          # controller-side target counts (int64)
    velocities: np.ndarray       # controller-side velocity offset [counts/s]
    reference_units: np.ndarray  # ideal slave position at the end of cycle k [slave units]
    master_units: np.ndarray     # true master position at the end of cycle k [master units]
    initial_counts: int
    speed_units: float           # cruise master speed [master units/s]
    sync_offsets: np.ndarray     # SYNC jitter of cycle k [s]


_compiled: dict = {}  # (cam file bytes, table spec) -> (profile, table, scale); tables are immutable


def _compile(scene: Scene):
    """Load and compile the scene's cam, once per cam file content and table format."""
    spec = scene.cam
    try:
        key = (spec.file.read_bytes(), spec.interp, spec.points, spec.tolerance,
               spec.master_counts, spec.slave_counts_per_unit)
    except OSError:
        key = None  # load_cam reports it
    if key in _compiled:
        return _compiled[key]
    result = _compile_uncached(scene)
    if key is not None:
        if len(_compiled) >= 8:
            _compiled.pop(next(iter(_compiled)))
        _compiled[key] = result
    return result


def _compile_uncached(scene: Scene):
    profile = ecam.load_cam(scene.cam.file)
    spec = scene.cam
    kwargs = dict(interp=spec.interp, master_counts=spec.master_counts,
                  slave_counts_per_unit=spec.slave_counts_per_unit)
    if spec.points is not None:
        kwargs["points"] = spec.points
    if spec.tolerance is not None:
        kwargs["tolerance"] = spec.tolerance
    table = ecam.compile_table(profile, **kwargs)
    scale = table.report.get("slave_counts_per_unit") or spec.slave_counts_per_unit \
        or profile.table.get("slave_counts_per_unit")
    return profile, table, float(scale)


def _cycles(scene: Scene, period_units: float, speed_units: float) -> int:
    d, cycle_s = scene.duration, scene.drive.cycle_s
    if d.cycles is not None:
        return d.cycles
    seconds = d.seconds if d.seconds is not None else d.master_periods * period_units / abs(speed_units)
    cycles = math.ceil(seconds / cycle_s - 1e-9)
    if cycles > 100_000_000:
        raise InputError(f"duration {seconds:.6g} s at cycle_s {cycle_s} gives {cycles:.3g} cycles, "
                         "should be <= 100000000")
    return max(cycles, 1)


def _plan(scene: Scene, profile, table, scale: float, jitter: np.ndarray, cycles: int) -> _Plan:
    """Sample the master (and a cam-in) for every cycle and look the set points up."""
    from hil_sim.master import ConstantSpeed, StartStop, cam_in

    cycle_s = scene.drive.cycle_s
    period = profile.master_period
    per_unit = table.master_counts / period  # master counts per master unit
    spec = scene.master
    speed_units = spec.units_per_second(period)
    speed = speed_units * per_unit
    if abs(speed_units) * cycle_s > period / 2:
        # a cam sampled less than twice per period aliases: the set points would be meaningless
        raise InputError(f"master speed {speed_units:.6g} {profile.master_unit}/s moves "
                         f"{abs(speed_units) * cycle_s:.6g} {profile.master_unit} per bus cycle, more than "
                         f"half the cam period ({period / 2:g}); should be <= {period / 2 / cycle_s:.6g}")
    k = np.arange(cycles, dtype=float)
    t_end = (k + 1.0) * cycle_s            # the target sent in cycle k is for its end
    t_set = t_end + jitter                 # sampled at the jittered SYNC instant
    t_mid = t_set - 0.5 * cycle_s
    slave_plan = None
    if spec.profile == "start_stop":
        master = StartStop(speed, spec.max_acceleration * per_unit, spec.max_jerk * per_unit,
                           start_s=spec.start_s, stop_s=spec.stop_s)
    elif spec.profile == "cam_in":
        def cam(m, order):
            return profile(m / per_unit, order) * scale / per_unit**order
        slave_plan = cam_in(cam, spec.slave_start * scale, 0.0, speed, spec.engage_at * per_unit,
                            spec.max_velocity * scale, spec.slave_max_acceleration * scale,
                            spec.slave_max_jerk * scale)
        master = slave_plan.master
    else:
        master = ConstantSpeed(speed)
    master_end = np.rint(master.position(t_set)).astype(np.int64)
    master_mid = np.rint(master.position(t_mid)).astype(np.int64)
    targets = table.lookup(master_end)
    velocities = table.slope(master_mid) / 65536.0 * master.velocity(t_mid)
    master_true = master.position(t_end)
    reference = profile(master_true / per_unit)
    if slave_plan is None:
        initial = int(table.lookup(int(round(float(master.position(0.0))))))
    else:
        # Before the engagement the set points and the reference follow the ruckig approach
        # (evaluated only there: the plan is a Python call per sample), after it the cam.
        engage_s = slave_plan.engage_s
        approach = t_set < engage_s
        targets = targets.copy()
        velocities = velocities.copy()
        targets[approach] = np.rint(slave_plan.position(t_set[approach])).astype(np.int64)
        velocities[approach] = slave_plan.velocity(t_mid[approach])
        approach = t_end < engage_s
        reference[approach] = slave_plan.position(t_end[approach]) / scale
        initial = int(round(spec.slave_start * scale))
    return _Plan(cycles=cycles, cycle_s=cycle_s, master_end=master_end,
                 targets=np.asarray(targets, dtype=np.int64), velocities=np.asarray(velocities),
                 reference_units=np.asarray(reference, dtype=float),
                 master_units=np.asarray(master_true, dtype=float) / per_unit,
                 initial_counts=initial, speed_units=speed_units, sync_offsets=jitter)


def _cam_acceleration(profile) -> np.ndarray:
    """The cam's slave acceleration [slave units / master unit^2] over one period, sampled."""
    x = np.arange(_RESONANCE_SAMPLES) * (profile.master_period / _RESONANCE_SAMPLES)
    return profile(x, 2)


def _cam_spectrum(profile) -> np.ndarray:
    """|FFT| of the cam's slave acceleration over one period, harmonics 0..n/2."""
    return np.abs(np.fft.rfft(_cam_acceleration(profile)))


def _drive_options(scene: Scene, profile, scale: float, mechanics) -> dict:
    """Keyword arguments of :class:`VirtualDrive` for a scene (all but the bus and position)."""
    from hil_sim.plant import significant_harmonic_hz
    speed_units = scene.master.units_per_second(profile.master_period)
    excitation_hz = significant_harmonic_hz(_cam_acceleration(profile),
                                            profile.master_period / abs(speed_units))
    return dict(node_id=scene.drive.node_id, mechanics=mechanics,
                gains=_gains(scene, mechanics), substeps=scene.drive.substeps,
                counts_per_motor_rad=(scale * scene.mechanics.slave_units_per_load_radian
                                      * mechanics.gear_ratio),
                model=scene.drive.model, excitation_hz=excitation_hz)


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
    profile, table, scale = _compile(scene)
    options = _drive_options(scene, profile, scale, scene.mechanics.build())
    if node_id is not None:
        options["node_id"] = node_id
    return VirtualDrive(channel=channel, bus=bus, initial_counts=int(table.lookup(0)),
                        heartbeat_ms=heartbeat_ms, **options)


def _gains(scene: Scene, mechanics):
    from hil_sim.control import Gains
    values = dict(scene.drive.gains)
    bandwidth = {k: values.pop(k) for k in ("velocity_bandwidth_hz", "position_bandwidth_hz",
                                            "integral_ratio") if k in values}
    # The controller streams the speed as velocity offset (0x60B1): no feed-forward twice.
    feedforward = {k: values.pop(k) for k in ("velocity_feedforward", "acceleration_feedforward")
                   if k in values}
    feedforward.setdefault("velocity_feedforward", 0.0)
    gains = Gains.from_mechanics(mechanics, **bandwidth, **feedforward)
    return replace(gains, **values) if values else gains


class LockstepMaster(SimNetwork):
    """A controller's canopen network in lock-step with one :class:`VirtualDrive`.

    Every frame it sends is handled by the drive at once, and the drive's answers are fed to
    this network before the call returns, so canopen's blocking SDO client, NMT master and
    ``RemoteNode`` work without threads, sleeps or timeouts; ``master.sync.transmit()`` runs
    the drive one interpolation period. Frames are stamped with the drive's simulated time.

    Parameters
    ----------
    bus : can.BusABC
        The controller's bus, on the drive's channel.
    drive : VirtualDrive
    load : BusLoad, optional
        Counts the bits of every frame sent or received.

    Examples
    --------
    >>> master = LockstepMaster(open_virtual_bus("demo"), drive)      # doctest: +SKIP
    >>> node = master.add_node(canopen.RemoteNode(1, str(EDS_PATH)))  # doctest: +SKIP
    >>> drive.boot(); master.settle(); node.sdo[0x6041].raw           # doctest: +SKIP
    576
    """

    def __init__(self, bus, drive: VirtualDrive, load: BusLoad | None = None) -> None:
        super().__init__(bus, lambda: drive.time_s)
        self.drive = drive
        self.load = load if load is not None else BusLoad(1_000_000, drive.cycle_s)
        self.frames = 0

    def send_message(self, can_id, data, remote=False):
        super().send_message(can_id, data, remote)
        self._count(len(data))
        self.settle()

    def _count(self, length: int) -> None:
        self.frames += 1
        self.load.add_frame(length)

    def settle(self) -> None:
        """Let the drive handle what was sent, then handle what it answered."""
        self.drive.process()
        while True:
            msg = self.bus.recv(timeout=0)
            if msg is None:
                return
            self._count(msg.dlc)
            self.notify(msg.arbitration_id, msg.data, msg.timestamp)


def _pdo_codec(pdo_map):
    codes = "<" + "".join(_STRUCT_CODES[var.od.data_type] for var in pdo_map.map)
    return struct.Struct(codes), [var.index for var in pdo_map.map]


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
        from ecam.plot import check_figure_path

        check_figure_path(plot)  # before the run, not after it
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    wall_start = time.perf_counter()
    profile, table, scale = _compile(scene)
    mechanics = scene.mechanics.build()
    cycle_s = scene.drive.cycle_s
    speed_units = scene.master.units_per_second(profile.master_period)
    cycles = _cycles(scene, profile.master_period, speed_units)
    injector = FaultInjector(scene.bus.faults, cycle_s) if scene.bus.faults.active else None
    jitter = injector.sync_offsets(cycles) if injector else np.zeros(cycles)
    plan = _plan(scene, profile, table, scale, jitter, cycles)

    spectrum = _cam_spectrum(profile)
    options = _drive_options(scene, profile, scale, mechanics)
    excitation_hz = options["excitation_hz"]
    channel = f"hil-sim-{next(_channels)}"
    drive_bus = open_virtual_bus(channel)
    master_bus = open_virtual_bus(channel)
    load = BusLoad(scene.bus.bitrate, cycle_s)
    drive = None
    try:
        drive = VirtualDrive(bus=drive_bus, initial_counts=plan.initial_counts, **options)
        controller = LockstepMaster(master_bus, drive)
        node = canopen.RemoteNode(scene.drive.node_id, load_od(EDS_PATH, scene.drive.node_id))
        controller.add_node(node)
        setup = _setup(scene, controller, node, drive, table)
        setup_s = time.perf_counter() - wall_start
        record, stopped = _loop(scene, plan, controller, node, drive, load, injector)
        loop_s = time.perf_counter() - wall_start - setup_s
        emcy = [(round(e.timestamp, 9), e.code) for e in node.emcy.log]
        axis_s = drive.axis_wall_s
        model, reason = drive.axis.model, drive.axis.model_reason
    finally:
        if drive is not None:
            drive.close()
        drive_bus.shutdown()
        master_bus.shutdown()

    analysis_start = time.perf_counter()
    report = _analyse(scene, profile, table, scale, mechanics, plan, record, stopped, load,
                      injector, setup, emcy, spectrum, excitation_hz, model, reason)
    analysis_s = time.perf_counter() - analysis_start
    wall_s = time.perf_counter() - wall_start
    simulated_s = report.cycles * cycle_s
    report.timing = {
        "wall_s": wall_s, "setup_s": setup_s, "loop_s": loop_s, "axis_s": axis_s,
        "protocol_s": loop_s - axis_s, "analysis_s": analysis_s, "simulated_s": simulated_s,
        "real_time_factor": simulated_s / wall_s if wall_s > 0 else math.inf,
        "loop_real_time_factor": simulated_s / loop_s if loop_s > 0 else math.inf,
        "us_per_cycle": 1e6 * loop_s / max(report.cycles, 1),
    }
    if plot is not None:
        report.plot(plot)
    return report


def _setup(scene: Scene, controller: LockstepMaster, node, drive: VirtualDrive, table) -> dict:
    """Boot, configure and enable the drive the way a CANopen master does; return facts."""
    drive.boot()
    controller.settle()
    if node.nmt.state != "PRE-OPERATIONAL":
        raise SimulationError(f"drive NMT state {node.nmt.state} after boot-up, "
                              "expected PRE-OPERATIONAL")
    sdo = node.sdo
    value, index = _interpolation_period(scene.drive.cycle_s)
    sdo[0x60C2][1].raw = value
    sdo[0x60C2][2].raw = index
    sdo[0x6065].raw = scene.drive.following_error_window
    sdo[0x6060].raw = cia402.CYCLIC_SYNCHRONOUS_POSITION
    facts = {}
    if scene.cam_mode == "drive":
        blob = table.to_bytes()
        before = controller.frames
        sdo.download(0x2000, 0, blob)
        frames = controller.frames - before
        if sdo[0x2005].raw != table.crc32:
            raise SimulationError(f"drive pending table CRC 0x{sdo[0x2005].raw:08x}, "
                                  f"expected 0x{table.crc32:08x}")
        sdo[0x2001][1].raw = drive_module.CAM_COMMAND_ACTIVATE
        if sdo[0x2002].raw != table.crc32:
            raise SimulationError(f"drive active table CRC 0x{sdo[0x2002].raw:08x}, "
                                  f"expected 0x{table.crc32:08x}")
        sdo[0x2004].raw = 1
        facts["download"] = {"bytes": len(blob), "frames": frames,
                             "seconds_at_bitrate": frames * frame_bits(8) / scene.bus.bitrate}
    node.tpdo.read()
    node.rpdo.read()
    node.nmt.state = "OPERATIONAL"
    controller.settle()
    rpdo1 = node.rpdo[1]
    codec, indexes = _pdo_codec(rpdo1)
    for controlword in (0x06, 0x07, 0x0F):  # shutdown, switch on, enable operation
        fields = {0x6040: controlword, 0x6060: cia402.CYCLIC_SYNCHRONOUS_POSITION}
        controller.send_message(rpdo1.cob_id, codec.pack(*[fields[i] for i in indexes]))
    statusword = sdo[0x6041].raw
    if statusword & 0x6F != 0x27:
        raise SimulationError(f"drive statusword 0x{statusword:04x} after enabling, expected "
                              "OPERATION ENABLED (0x27 under mask 0x6F)")
    facts["setup_frames"] = controller.frames
    return facts


def _loop(scene: Scene, plan: _Plan, controller: LockstepMaster, node, drive: VirtualDrive,
          load: BusLoad, injector: FaultInjector | None):
    """The lock-step cycles; returns per-cycle records and why the run stopped early, if so."""
    cycles = plan.cycles
    cycle_s = plan.cycle_s
    mbus = controller.bus
    notify = controller.notify
    drive_mode = scene.cam_mode == "drive"
    rpdo = node.rpdo[3] if drive_mode else node.rpdo[2]
    rpdo_codec, rpdo_indexes = _pdo_codec(rpdo)
    # On the wire, INTEGER32: positions wrap (two's complement), velocities are rounded.
    def wrapped(counts):
        return ((counts + 2**31) % 2**32 - 2**31).tolist()

    if drive_mode:
        wire = [wrapped(plan.master_end)]
    else:
        velocities = np.clip(np.rint(plan.velocities), -2**31, 2**31 - 1).astype(np.int64)
        wire = [wrapped(plan.targets) if i == 0x607A else velocities.tolist()
                for i in rpdo_indexes]
    set_points = list(zip(*wire))
    rpdo_cob = rpdo.cob_id
    nan = math.nan
    record = {name: [nan] * cycles for name in _RECORDED.values()}
    decoders = {}
    for tpdo in node.tpdo.map.values():
        if not tpdo.enabled:
            continue
        codec, indexes = _pdo_codec(tpdo)
        slots = [(i, record[_RECORDED[index]]) for i, index in enumerate(indexes)
                 if index in _RECORDED]
        decoders[tpdo.cob_id] = (codec.unpack_from, slots)
    probe = {name: [nan] * cycles for name in ("load_angle", "coupling_torque",
                                                "peak_coupling_torque", "peak_twist",
                                                "peak_motor_torque", "saturated")}
    load_angle, coupling, peak_coupling = (probe["load_angle"], probe["coupling_torque"],
                                           probe["peak_coupling_torque"])
    peak_twist, peak_torque, saturated = (probe["peak_twist"], probe["peak_motor_torque"],
                                          probe["saturated"])
    decide = injector.decide if injector else None
    held_tx: dict[int, list] = {}
    held_rx: dict[int, list] = {}
    add_frame, end_cycle = load.add_frame, load.end_cycle
    pack = rpdo_codec.pack
    rpdo_length = rpdo_codec.size
    axis = drive.axis
    drive.axis_wall_s = 0.0
    process = drive.process
    send = mbus.send
    recv = mbus.recv
    Message = can.Message
    stopped = None
    ran = 0
    sync = Message(arbitration_id=0x80, data=b"", is_extended_id=False, check=False)
    sync_offsets = plan.sync_offsets.tolist()
    for k in range(cycles):
        now = k * cycle_s
        # Frames of earlier cycles that were held back arrive first.
        if held_tx:
            for msg in held_tx.pop(k, ()):
                send(msg)
                add_frame(msg.dlc)
        msg = Message(arbitration_id=rpdo_cob, data=pack(*set_points[k]), is_extended_id=False,
                      timestamp=now, check=False)
        fate = decide(k, "rpdo") if decide else DELIVER
        if fate == DELIVER:
            send(msg)
            add_frame(rpdo_length)
        elif fate > 0:
            held_tx.setdefault(k + fate, []).append(msg)
        fate = decide(k, "sync") if decide else DELIVER
        if fate == DELIVER:
            sync.timestamp = now + sync_offsets[k]
            send(sync)  # the bus hands a copy to each receiver
            add_frame(0)
            process()
        else:
            process()
            drive.free_run()
        if held_rx:
            for msg in held_rx.pop(k, ()):
                unpack, slots = decoders[msg.arbitration_id]
                fields_ = unpack(msg.data)
                for i, target in slots:
                    target[k] = fields_[i]
        while True:
            msg = recv(timeout=0)
            if msg is None:
                break
            add_frame(msg.dlc)
            decoder = decoders.get(msg.arbitration_id)
            if decoder is None:
                notify(msg.arbitration_id, msg.data, msg.timestamp)
                continue
            fate = decide(k, "tpdo") if decide else DELIVER
            if fate == DELIVER:
                unpack, slots = decoder
                fields_ = unpack(msg.data)
                for i, target in slots:
                    target[k] = fields_[i]
            elif fate > 0:
                held_rx.setdefault(k + fate, []).append(msg)
        state = axis.state
        load_angle[k] = state["load_angle"]
        coupling[k] = state["coupling_torque"]
        peak_coupling[k] = state["peak_coupling_torque"]
        peak_twist[k] = state["peak_twist"]
        peak_torque[k] = state["peak_motor_torque"]
        saturated[k] = state["saturated"]
        end_cycle()
        ran = k + 1
        if drive.state in (cia402.FAULT, cia402.FAULT_REACTION_ACTIVE):
            code = drive.values[(0x603F, 0)]
            stopped = (f"drive fault 0x{code:04X} at cycle {k} (t {now + cycle_s:.6g} s), "
                       f"statusword 0x{drive.values[(0x6041, 0)]:04X}")
            break
    arrays = {name: np.asarray(values[:ran], dtype=float) for name, values in record.items()}
    arrays.update({name: np.asarray(values[:ran], dtype=float) for name, values in probe.items()})
    arrays["cycles"] = ran
    return arrays, stopped


def _analyse(scene, profile, table, scale, mechanics, plan: _Plan, record, stopped, load,
             injector, setup, emcy, spectrum, excitation_hz, model, reason) -> Report:
    """Turn the records into checks and the JSON summary."""
    ran = record["cycles"]
    units = {"master": profile.master_unit, "slave": profile.slave_unit}
    checks = []
    # Following error (motor side, counts, as the drive reports it in its TPDO).
    fe = np.abs(record["following_error"])
    received = np.isfinite(fe)
    fe_limit = scene.limits.following_error or scene.drive.following_error_window
    if received.any():
        worst = int(np.nanargmax(fe))
        checks.append(check("following_error", fe[worst], fe_limit, "counts",
                            f"at master {plan.master_units[worst] % profile.master_period:.6g} "
                            f"{units['master']}, cycle {worst}"))
    else:
        checks.append(check("following_error", None, fe_limit, "counts", "no TPDO received"))
    # Load-side tracking error against the cam (or the cam-in plan).
    load_units = record["load_angle"] * scene.mechanics.slave_units_per_load_radian
    tracking = load_units - plan.reference_units[:ran]
    worst = int(np.argmax(np.abs(tracking)))
    checks.append(check("tracking_error", abs(tracking[worst]), scene.limits.tracking_error,
                        units["slave"], f"at master {plan.master_units[worst] % profile.master_period:.6g} "
                        f"{units['master']}, t {(worst + 1) * plan.cycle_s:.6g} s"))
    # Coupling torque: peak against the maximum, RMS against the rated torque.
    peak = record["peak_coupling_torque"]
    worst = int(np.argmax(peak))
    checks.append(check("coupling_peak_torque", peak[worst], mechanics.coupling_max_torque, "N m",
                        f"at master {plan.master_units[worst] % profile.master_period:.6g} "
                        f"{units['master']}"))
    rms = float(np.sqrt(np.mean(record["coupling_torque"] ** 2)))
    checks.append(check("coupling_rms_torque", rms, mechanics.coupling_rated_torque, "N m",
                        "continuous load against the rated torque"))
    # Wind-up: the two-mass model's twist, or T/k when a stiff coupling ran as rigid.
    if mechanics.coupling_stiffness is not None:
        if model == "two_mass":
            wind_up, how = float(np.max(record["peak_twist"])), "coupling twist"
        else:
            wind_up, how = peak[worst] / mechanics.coupling_stiffness, "peak torque / stiffness"
        checks.append(check("wind_up", math.degrees(wind_up), scene.limits.wind_up_deg, "deg", how))
    else:
        checks.append(check("wind_up", 0.0, scene.limits.wind_up_deg, "deg", "no coupling"))
    # Torsional resonance against the cam's harmonics.
    cam_hz = abs(plan.speed_units) / profile.master_period
    torsion_hz = mechanics.torsional_frequency_hz()
    if math.isfinite(torsion_hz):
        harmonic = torsion_hz / cam_hz
        amplitudes = spectrum[1:]
        strongest = float(amplitudes.max()) if amplitudes.size else 0.0
        nearest = [n for n in {max(1, math.floor(harmonic)), max(1, math.ceil(harmonic))}
                   if n <= amplitudes.size]
        share = (100.0 * max(amplitudes[n - 1] for n in nearest) / strongest
                 if nearest and strongest > 0 else 0.0)
        if nearest:
            hit = max(nearest, key=lambda n: amplitudes[n - 1])
            what = f"harmonic {hit} carries {share:.3g} % of the strongest acceleration harmonic"
        else:
            what = f"above the {amplitudes.size} harmonics resolved"
        checks.append(check("resonance_excitation", share, scene.limits.resonance_excitation_percent,
                            "%", f"torsional mode {torsion_hz:.4g} Hz = {harmonic:.4g} x the "
                            f"{cam_hz:.4g} Hz cam cycle; {what}"))
    else:
        harmonic = None
        checks.append(check("resonance_excitation", None, None, "%", "no coupling: no torsional mode"))
    # Bus load.
    bus = load.summary()
    detail = (f"{bus['overrun_cycles']} of {bus['cycles']} cycles need more than "
              f"{bus['budget_bits']} bits" + (f", first at cycle {bus['first_overrun_cycle']}"
                                              if bus["overrun_cycles"] else ""))
    checks.append(check("bus_load", bus["peak_percent"], scene.limits.bus_load_percent, "%", detail))
    # Motor torque saturation.
    saturation = 100.0 * float(np.mean(record["saturated"])) if ran else 0.0
    checks.append(check("motor_saturation", saturation, scene.limits.motor_saturation_percent, "%",
                        f"cycles with the torque clamped at {mechanics.motor_torque_limit} N m"
                        if mechanics.motor_torque_limit else "no torque limit"))
    # Faults: EMCYs with an error code (0x00xx is 'no error / reset').
    faults = [{"time_s": t, "code": f"0x{code:04X}"} for t, code in emcy if code & 0xFF00]
    checks.append(check("faults", len(faults), 0, "count",
                        stopped or ("; ".join(f"{f['code']} at {f['time_s']:.6g} s" for f in faults)
                                    or "none")))

    missing = int(np.count_nonzero(~np.isfinite(record["statusword"])))
    bus.update({"setup_frames": setup.get("setup_frames"), "missing_status_samples": missing,
                "faults": injector.summary() if injector else None})
    if "download" in setup:
        bus["download"] = setup["download"]
    report_table = table.report
    summary = {
        "cam_mode": scene.cam_mode,
        "cycles_planned": plan.cycles,
        "cycle_s": plan.cycle_s,
        "simulated_s": ran * plan.cycle_s,
        "stopped_early": stopped,
        "units": units,
        "master": {"profile": scene.master.profile, "speed": plan.speed_units,
                   "speed_unit": f"{units['master']}/s", "cam_frequency_hz": cam_hz,
                   "periods": ran * plan.cycle_s * cam_hz},
        "table": {"interp": table.interp, "points": table.points, "bytes": table.nbytes,
                  "crc32": f"0x{table.crc32:08x}", "master_counts": table.master_counts,
                  "slave_counts_per_unit": scale,
                  "max_error_units": report_table.get("max_error_units")},
        "mechanics": {"torsional_frequency_hz": torsion_hz if math.isfinite(torsion_hz) else None,
                      "torsional_harmonic": harmonic, "excitation_hz": excitation_hz,
                      "coupling_rated_torque": mechanics.coupling_rated_torque,
                      "coupling_max_torque": mechanics.coupling_max_torque,
                      "motor_torque_limit": mechanics.motor_torque_limit,
                      "peak_motor_torque": float(np.max(record["peak_motor_torque"])) if ran else 0.0},
        "bus": bus,
        "faults": faults,
    }
    series = {"time_s": (np.arange(ran) + 1.0) * plan.cycle_s,
              "master_position": plan.master_units[:ran] % profile.master_period,
              "tracking_error": tracking, "coupling_torque": record["coupling_torque"],
              "peak_coupling_torque": peak, "following_error": record["following_error"]}
    return Report(scene=scene.name, model=model, model_reason=reason, cycles=ran,
                  checks=checks, summary=summary, series=series)


def find_max_speed(scene, *, tolerance: float = 0.01, max_runs: int = 24) -> dict:
    """Highest master speed at which every check passes, by bisection.

    Parameters
    ----------
    scene : Scene or str or Path
        The scene; its master speed is the starting point (its sign is kept).
    tolerance : float
        Stop when the bracket [passing, failing] is narrower than this fraction of the
        passing speed, > 0.
    max_runs : int
        Upper bound on rig runs.

    Returns
    -------
    dict
        ``speed`` (highest passing speed found, None if none passed), ``failing_speed``
        (lowest failing speed found, None if none failed), ``unit``, ``failed_checks`` (what
        failed at ``failing_speed``), ``runs`` (speed, passed, failed checks of every run).

    Notes
    -----
    Assumes that a scene that passes at a speed passes at every lower one (true for the
    tracking, torque and following-error limits of a cam; resonance can break it: a slower
    master can put a stronger harmonic on the coupling mode, so the answer is the highest
    passing speed of the bracket the search found, not a proof that no faster speed passes).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 1):
        raise InputError(f"tolerance {tolerance!r} should be a number in (0, 1)")
    profile = ecam.load_cam(scene.cam.file)
    start = scene.master.units_per_second(profile.master_period)
    sign = math.copysign(1.0, start)
    runs = []

    def passes(speed: float) -> bool:
        report = run_scene(scene.with_master_speed(sign * speed))
        runs.append({"speed": sign * speed, "passed": report.passed,
                     "failed": [c.name for c in report.failed]})
        return report.passed

    low, high = None, None
    speed = abs(start)
    if passes(speed):
        low = speed
        while len(runs) < max_runs // 2:
            speed *= 2.0
            if not passes(speed):
                high = speed
                break
            low = speed
    else:
        high = speed
        while len(runs) < max_runs // 2:
            speed /= 2.0
            if passes(speed):
                low = speed
                break
            high = speed
    while low is not None and high is not None and len(runs) < max_runs \
            and (high - low) > tolerance * low:
        middle = 0.5 * (low + high)
        if passes(middle):
            low = middle
        else:
            high = middle
    failed = next((r["failed"] for r in runs if high is not None and abs(r["speed"]) == high), [])
    return {"speed": None if low is None else sign * low,
            "failing_speed": None if high is None else sign * high,
            "unit": f"{profile.master_unit}/s", "failed_checks": failed, "runs": runs}
