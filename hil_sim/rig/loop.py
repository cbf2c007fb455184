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
from hil_sim.rig.network import LockstepMaster, pdo_codec
from hil_sim.rig.plan import Plan, cam_modes, wire_set_points
from hil_sim.rig.record import FROM_TPDOS, Record, Recorder

_SYNC_COB_ID = 0x80


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
    cycles = _Cycles(scene, plan, controller, node, drive, load, injector)
    stopped = cycles.run()
    bus = load.summary()
    bus.update(cycles.deferred)
    return cycles.recorder.record(
        stopped=stopped, emcy=[(round(e.timestamp, 9), e.code) for e in node.emcy.log],
        model=drive.axis.model, model_reason=drive.axis.model_reason, setup=setup, bus=bus,
        faults=injector.summary() if injector else None, path="canopen")


class _Cycles:
    """The cycles of one run: each method below :meth:`run` is one step of a cycle.

    The per-cycle state (bound methods, codecs, the record's arrays) is looked up once here:
    a run is up to millions of cycles of a handful of frames each.
    """

    def __init__(self, scene, plan: Plan, controller: LockstepMaster, node,
                 drive: VirtualDrive, load: BusLoad, injector: FaultInjector | None) -> None:
        self.cycles = plan.cycles
        self.cycle_s = plan.cycle_s
        self.drive = drive
        self.axis = drive.axis
        self.send = controller.bus.send
        self.recv = controller.bus.recv
        self.notify = controller.notify
        self.add_frame = load.add_frame
        self.end_cycle = load.end_cycle
        self.budget_bits = load.budget_bits
        self.decide = injector.decide if injector else None
        self.streams = _set_point_streams(scene, plan, node)
        self.sync = can.Message(arbitration_id=_SYNC_COB_ID, data=b"", is_extended_id=False,
                                check=False)
        self.sync_bits = frame_bits(0)
        self.sync_offsets = plan.sync_offsets.tolist()
        self.recorder = Recorder(self.cycles)
        self.decoders = self._tpdo_decoders(node)
        self.held_tx: dict[int, list] = {}  # cycle -> RPDOs that go out after its SYNC
        self.held_rx: dict[int, list] = {}  # cycle -> TPDOs that reach the controller in it
        self.rpdo_fate = DELIVER  # of the next cycle's RPDOs, decided in the cycle before
        self.rpdo_late: set = set()  # COB-IDs of the next cycle's RPDOs that miss its SYNC
        self.carried_bits = 0  # bits of frames that go right after the next SYNC
        self.deferred = {"late_set_points": 0, "late_tpdos": 0, "first_late_cycle": None}

    def _tpdo_decoders(self, node) -> dict:
        """COB-ID -> (unpack, [(field number, the record's array)]) of each enabled TPDO."""
        decoders = {}
        series = self.recorder.series
        for tpdo in node.tpdo.map.values():
            if not tpdo.enabled:
                continue
            codec, indexes = pdo_codec(tpdo)
            slots = [(i, series[FROM_TPDOS[index]]) for i, index in enumerate(indexes)
                     if index in FROM_TPDOS]
            decoders[tpdo.cob_id] = (codec.unpack_from, slots)
        return decoders

    def run(self) -> str | None:
        """All cycles, or up to a drive fault; return why the run stopped early, if so."""
        self.drive.axis_wall_s = 0.0
        cycle_s = self.cycle_s
        recorder = self.recorder
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
            self.drive.process()
            if self.held_rx:
                self._release_held_tpdos(k)
            self._receive_and_arbitrate(k)
            recorder.probe(k, self.axis)
            self.end_cycle()
            recorder.ran = k + 1
            stopped = self._fault(k, now)
            if stopped:
                return stopped
        return None

    def _fate(self, k: int, kind: str) -> int:
        """DELIVER, DROP, or the cycles a frame of ``kind`` is held back (the injector's call)."""
        return self.decide(k, kind) if self.decide else DELIVER

    def _set_points(self, k: int, now: float) -> list:
        """Cycle k's RPDOs that go on the bus now (delayed ones are held, lost ones are gone)."""
        fate = self.rpdo_fate
        out = []
        for cob_id, pack, length, fields, until in self.streams:
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
        """The SYNC runs the drive one period; without it the drive still handles the RPDO and
        runs free (its control loop goes on, no TPDOs)."""
        self.add_frame(0)  # a lost frame took its bus time too
        if self._fate(k, "sync") == DELIVER:
            self.sync.timestamp = now + self.sync_offsets[k]
            self.send(self.sync)  # the bus hands a copy to each receiver
        else:
            self.drive.process()
            self.drive.free_run()

    def _decode(self, k: int, msg) -> None:
        unpack, slots = self.decoders[msg.arbitration_id]
        fields = unpack(msg.data)
        for i, target in slots:
            target[k] = fields[i]

    def _release_held_tpdos(self, k: int) -> None:
        for msg in self.held_rx.pop(k, ()):
            self._decode(k, msg)

    def _receive_and_arbitrate(self, k: int) -> None:
        """Read every frame the drive answered: TPDOs go through the fault injector and, with
        the next cycle's RPDO, through arbitration; anything else (EMCY, heartbeat) to canopen."""
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
                frames += [(cob_id, length, None) for cob_id, _, length, _, until in self.streams
                           if k + 1 < until]
        used = self.sync_bits + self.carried_bits
        on_time, late = arbitrate(frames, self.budget_bits, used)
        for _, _, msg in on_time:
            if msg is not None:
                self._decode(k, msg)
        self.carried_bits = sum(frame_bits(length) for _, length, _ in late)
        for cob_id, _, msg in late:
            if msg is None:
                self.rpdo_late.add(cob_id)
                self.deferred["late_set_points"] += 1
            else:
                self.held_rx.setdefault(k + 1, []).append(msg)
                self.deferred["late_tpdos"] += 1
        if late and self.deferred["first_late_cycle"] is None:
            self.deferred["first_late_cycle"] = k

    def _fault(self, k: int, now: float) -> str | None:
        """Why the run stops after cycle ``k`` (a drive fault), or None."""
        drive = self.drive
        if drive.state not in (cia402.FAULT, cia402.FAULT_REACTION_ACTIVE):
            return None
        code = drive.values[ERROR_CODE]
        return (f"drive fault 0x{code:04X} at cycle {k} (t {now + self.cycle_s:.6g} s), "
                f"statusword 0x{drive.values[STATUSWORD]:04X}")


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
