"""The lock-step cycles of a run, over the virtual bus.

One bus cycle is the time between two SYNCs. In it go: the SYNC, the drive's TPDOs answering
it, and the controller's RPDO with the set point for the next SYNC; frames carried over from the
cycle before go right after the SYNC. Each cycle, in this order: the RPDO goes out (unless it
missed its SYNC, see below); the SYNC goes out and the drive handles both (runs its control
loop one period and answers with its TPDOs), or, the SYNC lost, runs free; carried-over frames
arrive; the controller reads the drive's answers; the plant is probed; the bus load closes the
cycle; a drive fault ends the run.

Bus time: the virtual bus delivers any number of frames at once, so the cycle's frames are
arbitrated here (:func:`hil_sim.bus.arbitrate`): lowest COB-ID first, and whatever does not fit
into ``bitrate * cycle_s`` bits goes out after the next SYNC: a late RPDO is latched one SYNC
late (the drive repeats its last set point for a cycle), a late TPDO reaches the controller a
cycle late. The report counts them.

Faults (lost or late frames, SYNC jitter) are applied here too, from the seeded
:class:`~hil_sim.bus.FaultInjector`, so the same scene gives the same record.
"""

from __future__ import annotations

import can

from hil_sim.bus import DELIVER, DROP, BusLoad, FaultInjector, arbitrate, frame_bits
from hil_sim.drive import VirtualDrive, cia402
from hil_sim.drive.objects import (
    CAM_MODE, ERROR_CODE, MASTER_POSITION, STATUSWORD, TARGET_POSITION, VELOCITY_OFFSET,
)
from hil_sim.rig.network import LockstepMaster, pdo_codec, send_cam_commands
from hil_sim.rig.plan import Plan, cam_modes, wire_set_points
from hil_sim.rig.record import FROM_TPDOS, Record, Recorder
from hil_sim.sync_schedule import MAX_TRANSMISSION_TYPE, TpdoTiming

_SYNC_COB_ID = 0x80


class Station:
    """One axis of a run on the bus: its scene, plan, node on the controller's network, drive
    and the facts of its set-up (a single-axis run is a machine of one station)."""

    def __init__(self, scene, plan: Plan, node, drive: VirtualDrive, setup: dict) -> None:
        self.scene, self.plan, self.node, self.drive, self.setup = scene, plan, node, drive, setup
        self.axis = drive.axis
        self.streams = _set_point_streams(scene, plan, node)
        # the frames it puts on the bus at cruise, as (COB-ID, data length, every n-th SYNC,
        # phase) for the machine's bus sizing (hil_sim.bus_sizing): the set points streamed to
        # the end (every SYNC), the synchronous cyclic TPDOs (CiA 301 7.5.2.37: type n, started
        # by the SYNC start value when the SYNC counter is on)
        timing = TpdoTiming.of(scene)
        setup["cyclic_frames"] = (
            [(cob_id, length, 1, 0) for cob_id, _, length, _, until in self.streams
             if until >= plan.cycles]
            + [(tpdo.cob_id, pdo_codec(tpdo)[0].size, tpdo.trans_type, timing.phase)
               for tpdo in node.tpdo.map.values()
               if tpdo.enabled and 1 <= tpdo.trans_type <= MAX_TRANSMISSION_TYPE])
        self.recorder = Recorder(plan.cycles)
        self.deferred = {"late_set_points": 0, "late_tpdos": 0, "first_late_cycle": None}
        self.commands: dict = {}  # cycle -> the events' SDO writes to the cam slot (drive-side)
        for command in (plan.events.drive_commands if plan.events is not None else ()):
            self.commands.setdefault(command.cycle, []).append(command)
        self.stopped: str | None = None


def run_cycles(scene, plan: Plan, controller: LockstepMaster, node, drive: VirtualDrive,
               load: BusLoad, injector: FaultInjector | None, setup: dict) -> Record:
    """Run the planned cycles (or until a drive fault) and return the record.

    Parameters
    ----------
    scene : Scene
    plan : Plan
    controller : LockstepMaster
        The controller's network, the drive set up and enabled (``setup`` tells how).
    node : canopen.RemoteNode
        The drive's node on ``controller``.
    drive : VirtualDrive
    load : BusLoad
        Counts every frame of the cycles.
    injector : FaultInjector or None
    setup : dict
        Facts of the set-up, carried into the record.
    """
    return run_stations([Station(scene, plan, node, drive, setup)], controller, load,
                        injector)[0]


def run_stations(stations: list, controller: LockstepMaster, load: BusLoad,
                 injector: FaultInjector | None) -> list:
    """Run the stations' planned cycles in lock-step on one bus (one SYNC, every node's frames
    arbitrated together) until the end or a drive fault (which stops the machine); return one
    record per station, each with the machine's bus load and its own late frames."""
    cycles = _Cycles(stations, controller, load, injector)
    cycles.run()
    summary = load.summary()
    faults = injector.summary() if injector else None
    records = []
    for station in stations:
        bus = dict(summary)
        bus.update(station.deferred)
        drive = station.drive
        records.append(station.recorder.record(
            stopped=station.stopped,
            emcy=[(round(e.timestamp, 9), e.code) for e in station.node.emcy.log],
            model=drive.axis.model, model_reason=drive.axis.model_reason, setup=station.setup,
            bus=bus, faults=faults, path="canopen"))
    return records


class _Cycles:
    """The cycles of one run: each method below :meth:`run` is one step of a cycle.

    The per-cycle state (bound methods, codecs, the record's arrays) is looked up once here:
    a run is up to millions of cycles of a handful of frames each.
    """

    def __init__(self, stations: list, controller: LockstepMaster, load: BusLoad,
                 injector: FaultInjector | None) -> None:
        plan = stations[0].plan
        self.stations = stations
        self.cycles = plan.cycles
        self.cycle_s = plan.cycle_s
        self.drives = [s.drive for s in stations]
        self.send = controller.bus.send
        self.recv = controller.bus.recv
        self.notify = controller.notify
        self.load = load  # the events' SDO frames queue into its spare bits
        self.add_frame = load.add_frame
        self.end_cycle = load.end_cycle
        self.budget_bits = load.budget_bits
        self.decide = injector.decide if injector else None
        # every station's set points, in the stations' order: (station, stream); a COB-ID
        # several drives consume (the shared master position) goes once, for all of them
        self.streams = []
        self.owners: dict[int, list] = {}  # RPDO COB-ID -> the stations that consume it
        for s in stations:
            for stream in s.streams:
                if stream[0] not in self.owners:
                    self.streams.append((s, stream))
                    self.owners[stream[0]] = []
                self.owners[stream[0]].append(s)
        # CiA 301 7.5.2.22 (0x1019): with an overflow value the SYNC carries a counter, 1 at the
        # first SYNC, back to 1 after the overflow value
        self.sync_overflow = stations[0].scene.bus.sync_counter_overflow
        self.sync_length = 1 if self.sync_overflow else 0
        self.sync = can.Message(arbitration_id=_SYNC_COB_ID,
                                data=bytearray(self.sync_length), is_extended_id=False,
                                check=False)
        self.sync_bits = frame_bits(self.sync_length)
        self.sync_offsets = plan.sync_offsets.tolist()
        self.decoders = {}
        for station in stations:
            self.decoders.update(self._tpdo_decoders(station))
        self.held_tx: dict[int, list] = {}  # cycle -> RPDOs that go out after its SYNC
        self.held_rx: dict[int, list] = {}  # cycle -> TPDOs that reach the controller in it
        self.rpdo_fate = DELIVER  # of the next cycle's RPDOs, decided in the cycle before
        self.rpdo_late: set = set()  # COB-IDs of the next cycle's RPDOs that miss its SYNC
        self.carried_bits = 0  # bits of frames that go right after the next SYNC

    @staticmethod
    def _tpdo_decoders(station: Station) -> dict:
        """COB-ID -> (unpack, [(field number, the record's array)], station) of each enabled
        TPDO of the station's node."""
        decoders = {}
        series = station.recorder.series
        for tpdo in station.node.tpdo.map.values():
            if not tpdo.enabled:
                continue
            codec, indexes = pdo_codec(tpdo)
            slots = [(i, series[FROM_TPDOS[index]]) for i, index in enumerate(indexes)
                     if index in FROM_TPDOS]
            decoders[tpdo.cob_id] = (codec.unpack_from, slots, station)
        return decoders

    def run(self) -> None:
        """All cycles, or up to a drive fault (then every station's ``stopped`` says why)."""
        for drive in self.drives:
            drive.axis_wall_s = 0.0
        cycle_s = self.cycle_s
        stations = self.stations
        commands: dict = {}  # cycle -> [(station, the events' SDO writes to its cam slot)]
        for station in stations:
            for k, writes in station.commands.items():
                commands.setdefault(k, []).append((station, writes))
        self.rpdo_fate = self._fate(0, "rpdo")
        for k in range(self.cycles):
            now = k * cycle_s
            messages = self._set_points(k, now)
            late = self.rpdo_late
            for message in messages:
                if message.arbitration_id not in late:
                    self.send(message)  # before the SYNC: latched by it
            self._sync(k, now)
            for message in messages:
                if message.arbitration_id in late:
                    self.send(message)  # after the SYNC: latched by the next one
            if self.held_tx:
                for msg in self.held_tx.pop(k, ()):
                    self.send(msg)
            for drive in self.drives:
                drive.process()
            if self.held_rx:
                self._release_held_tpdos(k)
            self._receive_and_arbitrate(k)
            if commands and k in commands:  # drive-side events: after the cycle's TPDOs, so
                for station, writes in commands[k]:  # the SDO answers are the only frames read
                    send_cam_commands(station.node, writes, self.load)
            for station in stations:
                station.recorder.probe(k, station.axis)
            self.end_cycle()
            for station in stations:
                station.recorder.ran = k + 1
            if self._fault(k, now):
                return

    def _fate(self, k: int, kind: str) -> int:
        """DELIVER, DROP, or the cycles a frame of ``kind`` is held back (the injector's call)."""
        return self.decide(k, kind) if self.decide else DELIVER

    def _set_points(self, k: int, now: float) -> list:
        """Cycle k's RPDOs that go on the bus now (delayed ones are held, lost ones are gone)."""
        fate = self.rpdo_fate
        out = []
        for _, (cob_id, pack, length, fields, until) in self.streams:
            if k >= until:
                continue
            msg = can.Message(arbitration_id=cob_id, data=pack(*(int(v[k]) for v in fields)),
                              is_extended_id=False, timestamp=now, check=False)
            self.add_frame(length)  # a lost frame took its bus time too
            if fate == DELIVER:
                out.append(msg)
            elif fate > 0:
                self.held_tx.setdefault(k + fate, []).append(msg)
        return out

    def _sync(self, k: int, now: float) -> None:
        """The SYNC runs the drives one period; without it each drive still handles its RPDO
        and runs free (its control loop goes on, no TPDOs)."""
        self.add_frame(self.sync_length)  # a lost frame took its bus time too
        if self.sync_length:  # the producer counts every SYNC it sends, lost or not
            self.sync.data[0] = k % self.sync_overflow + 1
        if self._fate(k, "sync") == DELIVER:
            self.sync.timestamp = now + self.sync_offsets[k]
            self.send(self.sync)  # the bus hands a copy to each receiver
        else:
            for drive in self.drives:
                drive.process()
                drive.free_run()

    def _decode(self, k: int, msg) -> None:
        unpack, slots, _ = self.decoders[msg.arbitration_id]
        fields = unpack(msg.data)
        for i, target in slots:
            target[k] = fields[i]

    def _release_held_tpdos(self, k: int) -> None:
        for msg in self.held_rx.pop(k, ()):
            self._decode(k, msg)

    def _receive_and_arbitrate(self, k: int) -> None:
        """Read every frame the drives answered: TPDOs go through the fault injector and, with
        the next cycle's RPDOs, through arbitration; anything else (EMCY, heartbeat) to
        canopen."""
        waiting = []
        while True:
            msg = self.recv(timeout=0)
            if msg is None:
                break
            self.add_frame(msg.dlc)
            if msg.arbitration_id not in self.decoders:
                self.notify(msg.arbitration_id, msg.data, msg.timestamp)
                continue
            fate = self._fate(k, "tpdo")
            if fate == DELIVER:
                waiting.append((msg.arbitration_id, msg.dlc, msg))
            elif fate > 0:
                self.held_rx.setdefault(k + fate, []).append(msg)
        frames = list(waiting)
        self.rpdo_late = set()
        if k + 1 < self.cycles:
            self.rpdo_fate = self._fate(k + 1, "rpdo")
            if self.rpdo_fate != DROP:
                frames += [(cob_id, length, None) for _, (cob_id, _, length, _, until)
                           in self.streams if k + 1 < until]
        used = self.sync_bits + self.carried_bits
        on_time, late = arbitrate(frames, self.budget_bits, used)
        for _, _, msg in on_time:
            if msg is not None:
                self._decode(k, msg)
        self.carried_bits = sum(frame_bits(length) for _, length, _ in late)
        for cob_id, _, msg in late:
            if msg is None:
                self.rpdo_late.add(cob_id)
                late_at = self.owners[cob_id]  # every drive that consumes it
                for station in late_at:
                    station.deferred["late_set_points"] += 1
            else:
                self.held_rx.setdefault(k + 1, []).append(msg)
                late_at = [self.decoders[cob_id][2]]
                late_at[0].deferred["late_tpdos"] += 1
            for station in late_at:
                if station.deferred["first_late_cycle"] is None:
                    station.deferred["first_late_cycle"] = k

    def _fault(self, k: int, now: float) -> bool:
        """Whether a drive faulted in cycle ``k``: it stops the machine, every station's
        ``stopped`` says which drive and why."""
        faulted = None
        for station in self.stations:
            drive = station.drive
            if drive.state in (cia402.FAULT, cia402.FAULT_REACTION_ACTIVE):
                code = drive.values[ERROR_CODE]
                station.stopped = (f"drive fault 0x{code:04X} at cycle {k} (t "
                                   f"{now + self.cycle_s:.6g} s), statusword "
                                   f"0x{drive.values[STATUSWORD]:04X}")
                faulted = faulted or station
        if faulted is None:
            return False
        for station in self.stations:
            if station.stopped is None:
                station.stopped = (f"machine stopped at cycle {k}: axis {faulted.scene.name} "
                                   f"(node {faulted.drive.node_id}) faulted")
        return True


def _set_point_streams(scene, plan: Plan, node) -> list:
    """What the controller sends each cycle, as (COB-ID, pack, length, fields per cycle in the
    RPDO's mapping order, the cycle it stops before): controller-side the target and the velocity
    offset (RPDO2); drive-side the master position (RPDO3), with the cam mode for a cam-in, whose
    approach goes as CSP set points in RPDO2 until the engagement."""
    def stream(rpdo, arrays: dict, until: int):
        codec, indexes = pdo_codec(rpdo)
        return (rpdo.cob_id, codec.pack, codec.size, tuple(arrays[i] for i in indexes), until)

    targets, velocities = wire_set_points(plan, drive_side=False)
    controller = {TARGET_POSITION.index: targets, VELOCITY_OFFSET.index: velocities}
    if scene.cam_mode != "drive":
        return [stream(node.rpdo[2], controller, plan.cycles)]
    master, _ = wire_set_points(plan, drive_side=True)
    drive = {MASTER_POSITION.index: master, CAM_MODE.index: cam_modes(plan)}
    streams = [stream(node.rpdo[3], drive, plan.cycles)]
    if plan.engaged_from is not None:
        streams.insert(0, stream(node.rpdo[2], controller, plan.engaged_from))
    return streams
