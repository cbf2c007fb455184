"""The lock-step cycles of a run, over the virtual bus.

Each cycle, in this order: frames held back from earlier cycles arrive; the RPDO with the set
point goes out; the SYNC goes out and the drive handles both (runs its control loop one period
and answers with its TPDOs), or, the SYNC lost, runs free; TPDOs held back arrive; the
controller reads the drive's answers; the plant is probed; the bus load closes the cycle; a
drive fault ends the run. Faults (lost or late frames, SYNC jitter) are applied here, from the
seeded :class:`~hil_sim.bus.FaultInjector`, so the same scene gives the same record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import can
import numpy as np

from hil_sim.bus import DELIVER, BusLoad, FaultInjector
from hil_sim.drive import VirtualDrive, cia402
from hil_sim.rig.network import LockstepMaster, pdo_codec
from hil_sim.rig.plan import Plan

_RECORDED = {0x6041: "statusword", 0x60F4: "following_error"}  # read from the TPDOs
# read from the drive's axis after each cycle (what a real rig would measure at the load)
_PROBED = ("load_angle", "coupling_torque", "peak_coupling_torque", "peak_twist",
           "peak_motor_torque", "saturated")
_SYNC_COB_ID = 0x80


@dataclass(frozen=True)
class Record:
    """What a run recorded: one value per cycle run, NaN where a TPDO never arrived.

    Attributes
    ----------
    cycles : int
        Cycles run; fewer than planned when a drive fault stopped the run.
    stopped : str or None
        Why the run stopped early (the fault, the cycle, the statusword), None if it did not.
    statusword, following_error : numpy.ndarray
        From the drive's TPDOs (following error in counts, motor side).
    load_angle : numpy.ndarray
        Load angle [rad].
    coupling_torque : numpy.ndarray
        Coupling torque at the end of the cycle [N m].
    peak_coupling_torque, peak_twist, peak_motor_torque : numpy.ndarray
        Largest magnitudes within the cycle [N m, rad, N m].
    saturated : numpy.ndarray
        1.0 where the motor torque was clamped in the cycle, else 0.0.
    emcy : list of (float, int)
        (time [s], error code) of every EMCY the controller received.
    model, model_reason : str
        The plant the drive ran and why.
    setup : dict
        Facts of the set-up (:func:`hil_sim.rig.network.set_up_drive`).
    bus : dict
        :meth:`hil_sim.bus.BusLoad.summary` of the run.
    faults : dict or None
        :meth:`hil_sim.bus.FaultInjector.summary`, None without fault injection.
    """

    cycles: int
    stopped: str | None
    statusword: np.ndarray
    following_error: np.ndarray
    load_angle: np.ndarray
    coupling_torque: np.ndarray
    peak_coupling_torque: np.ndarray
    peak_twist: np.ndarray
    peak_motor_torque: np.ndarray
    saturated: np.ndarray
    emcy: list
    model: str
    model_reason: str
    setup: dict
    bus: dict
    faults: dict | None


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
    ran = cycles.ran
    series = {name: np.asarray(values[:ran], dtype=float)
              for name, values in cycles.series.items()}
    return Record(cycles=ran, stopped=stopped, **series,
                  emcy=[(round(e.timestamp, 9), e.code) for e in node.emcy.log],
                  model=drive.axis.model, model_reason=drive.axis.model_reason, setup=setup,
                  bus=load.summary(), faults=injector.summary() if injector else None)


def _wrapped(counts: np.ndarray) -> list:
    """Counts as INTEGER32 on the wire: positions wrap (two's complement)."""
    return ((counts + 2**31) % 2**32 - 2**31).tolist()


def _set_points(drive_side: bool, plan: Plan, indexes: list[int]) -> list[tuple]:
    """The RPDO fields of every cycle: the master position for a cam in the drive, else the
    target and velocity offset in the RPDO's mapping order (velocities rounded to INTEGER32)."""
    if drive_side:
        wire = [_wrapped(plan.master_end)]
    else:
        velocities = np.clip(np.rint(plan.velocities), -2**31, 2**31 - 1).astype(np.int64)
        wire = [_wrapped(plan.targets) if i == 0x607A else velocities.tolist() for i in indexes]
    return list(zip(*wire))


class _Cycles:
    """The cycles of one run: each method below :meth:`run` is one step of a cycle.

    The per-cycle state (bound methods, codecs, the record's lists) is looked up once here:
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
        self.decide = injector.decide if injector else None
        rpdo = node.rpdo[3] if scene.cam_mode == "drive" else node.rpdo[2]
        codec, indexes = pdo_codec(rpdo)
        self.set_points = _set_points(scene.cam_mode == "drive", plan, indexes)
        self.rpdo_cob_id = rpdo.cob_id
        self.pack = codec.pack
        self.rpdo_length = codec.size
        self.sync = can.Message(arbitration_id=_SYNC_COB_ID, data=b"", is_extended_id=False,
                                check=False)
        self.sync_offsets = plan.sync_offsets.tolist()
        self.series = {name: [math.nan] * self.cycles for name in (*_RECORDED.values(), *_PROBED)}
        self.probes = [(name, self.series[name]) for name in _PROBED]
        self.decoders = self._tpdo_decoders(node)
        self.held_tx: dict[int, list] = {}  # cycle -> RPDOs delayed to it
        self.held_rx: dict[int, list] = {}  # cycle -> TPDOs delayed to it
        self.ran = 0

    def _tpdo_decoders(self, node) -> dict:
        """COB-ID -> (unpack, [(field number, the record's list)]) of each enabled TPDO."""
        decoders = {}
        for tpdo in node.tpdo.map.values():
            if not tpdo.enabled:
                continue
            codec, indexes = pdo_codec(tpdo)
            slots = [(i, self.series[_RECORDED[index]]) for i, index in enumerate(indexes)
                     if index in _RECORDED]
            decoders[tpdo.cob_id] = (codec.unpack_from, slots)
        return decoders

    def run(self) -> str | None:
        """All cycles, or up to a drive fault; return why the run stopped early, if so."""
        self.drive.axis_wall_s = 0.0
        cycle_s = self.cycle_s
        for k in range(self.cycles):
            now = k * cycle_s
            if self.held_tx:
                self._release_held_rpdos(k)
            self._send_set_point(k, now)
            self._sync(k, now)
            if self.held_rx:
                self._release_held_tpdos(k)
            self._receive(k)
            self._probe(k)
            self.end_cycle()
            self.ran = k + 1
            stopped = self._fault(k, now)
            if stopped:
                return stopped
        return None

    def _fate(self, k: int, kind: str) -> int:
        """DELIVER, DROP, or the cycles a frame of ``kind`` is held back (the injector's call)."""
        return self.decide(k, kind) if self.decide else DELIVER

    def _release_held_rpdos(self, k: int) -> None:
        # Frames of earlier cycles that were held back arrive first.
        for msg in self.held_tx.pop(k, ()):
            self.send(msg)
            self.add_frame(msg.dlc)

    def _send_set_point(self, k: int, now: float) -> None:
        msg = can.Message(arbitration_id=self.rpdo_cob_id, data=self.pack(*self.set_points[k]),
                          is_extended_id=False, timestamp=now, check=False)
        fate = self._fate(k, "rpdo")
        if fate == DELIVER:
            self.send(msg)
            self.add_frame(self.rpdo_length)
        elif fate > 0:
            self.held_tx.setdefault(k + fate, []).append(msg)

    def _sync(self, k: int, now: float) -> None:
        """The SYNC runs the drive one period; without it the drive still handles the RPDO and
        runs free (its control loop goes on, no TPDOs)."""
        if self._fate(k, "sync") == DELIVER:
            self.sync.timestamp = now + self.sync_offsets[k]
            self.send(self.sync)  # the bus hands a copy to each receiver
            self.add_frame(0)
            self.drive.process()
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

    def _receive(self, k: int) -> None:
        """Read every frame the drive answered; TPDOs go through the fault injector, anything
        else (EMCY, heartbeat) to canopen."""
        while True:
            msg = self.recv(timeout=0)
            if msg is None:
                return
            self.add_frame(msg.dlc)
            if msg.arbitration_id not in self.decoders:
                self.notify(msg.arbitration_id, msg.data, msg.timestamp)
                continue
            fate = self._fate(k, "tpdo")
            if fate == DELIVER:
                self._decode(k, msg)
            elif fate > 0:
                self.held_rx.setdefault(k + fate, []).append(msg)

    def _probe(self, k: int) -> None:
        state = self.axis.state
        for name, values in self.probes:
            values[k] = state[name]

    def _fault(self, k: int, now: float) -> str | None:
        """Why the run stops after cycle ``k`` (a drive fault), or None."""
        drive = self.drive
        if drive.state not in (cia402.FAULT, cia402.FAULT_REACTION_ACTIVE):
            return None
        code = drive.values[(0x603F, 0)]
        return (f"drive fault 0x{code:04X} at cycle {k} (t {now + self.cycle_s:.6g} s), "
                f"statusword 0x{drive.values[(0x6041, 0)]:04X}")
