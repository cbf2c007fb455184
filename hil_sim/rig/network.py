"""The controller's side of the bus: a canopen network in lock-step with one virtual drive, the
PDO codec, and the set-up a CANopen master does before the first cycle (boot, configuration
by SDO, table download when the cam runs in the drive, NMT start, CiA 402 enable)."""

from __future__ import annotations

import struct

from canopen.sdo import SdoAbortedError, SdoCommunicationError

from ecam.errors import SimulationError
from hil_sim.bus import BusLoad, SimNetwork, frame_bits
from hil_sim.drive import VirtualDrive, cia402
from hil_sim.drive.cam_slot import CAM_COMMAND_ACTIVATE, CAM_MODE_DRIVE_SIDE
from hil_sim.drive.objects import (
    ACTIVE_CAM_TABLE_CRC32, CAM_COMMAND, CAM_MODE, CAM_TABLE_DOWNLOAD, CONTROLWORD,
    FOLLOWING_ERROR_WINDOW, INTERPOLATION_TIME_INDEX, INTERPOLATION_TIME_PERIOD_VALUE,
    MASTER_POSITION, MODES_OF_OPERATION, PENDING_CAM_TABLE_CRC32, STATUSWORD, STRUCT_CODES,
    SYNC_COUNTER_OVERFLOW, ObjectKey, interpolation_period,
)
from hil_sim.rig.cam import CompiledCam
from hil_sim.scene import Scene


class LockstepMaster(SimNetwork):
    """A controller's canopen network in lock-step with one :class:`VirtualDrive` (or a list
    of them: a machine's drives on one bus).

    Every frame it sends is handled by the drive at once, and the drive's answers are fed to
    this network before the call returns, so canopen's blocking SDO client, NMT master and
    ``RemoteNode`` work without threads, sleeps or timeouts; ``master.sync.transmit()`` runs
    the drive one interpolation period. Frames are stamped with the drive's simulated time.

    Parameters
    ----------
    bus : can.BusABC
        The controller's bus, on the drive's channel.
    drive : VirtualDrive or list of VirtualDrive
    load : BusLoad, optional
        Counts the bits of every frame sent or received.

    Examples
    --------
    >>> master = LockstepMaster(open_virtual_bus("demo"), drive)      # doctest: +SKIP
    >>> node = master.add_node(canopen.RemoteNode(1, str(EDS_PATH)))  # doctest: +SKIP
    >>> drive.boot(); master.settle(); node.sdo[0x6041].raw           # doctest: +SKIP
    576
    """

    def __init__(self, bus, drive, load: BusLoad | None = None) -> None:
        # a machine's drives share the bus (and the simulated clock: they run in lock-step)
        drives = list(drive) if isinstance(drive, (list, tuple)) else [drive]
        super().__init__(bus, lambda: drives[0].time_s)
        self.drive = drives[0]
        self.drives = drives
        self.load = load if load is not None else BusLoad(1_000_000, self.drive.cycle_s)
        self.frames = 0
        # while set (send_cam_commands): the frames go to acyclic_load's queue under this tag
        self.acyclic_tag = None
        self.acyclic_load: BusLoad | None = None

    def send_message(self, can_id, data, remote=False):
        super().send_message(can_id, data, remote)
        self._count(len(data))
        self.settle()

    def _count(self, length: int) -> None:
        self.frames += 1
        if self.acyclic_tag is None:
            self.load.add_frame(length)
        else:  # an event's SDO transfer: into the cycles' spare bits (BusLoad.queue_frame)
            self.acyclic_load.queue_frame(length, self.acyclic_tag)

    def settle(self) -> None:
        """Let the drives handle what was sent, then handle what they answered."""
        for drive in self.drives:
            drive.process()
        while True:
            msg = self.bus.recv(timeout=0)
            if msg is None:
                return
            self._count(msg.dlc)
            self.notify(msg.arbitration_id, msg.data, msg.timestamp)


def pdo_codec(pdo_map) -> tuple[struct.Struct, list[int]]:
    """The struct packing a PDO's mapped objects, and their indexes in mapping order."""
    codes = "<" + "".join(STRUCT_CODES[var.od.data_type] for var in pdo_map.map)
    return struct.Struct(codes), [var.index for var in pdo_map.map]


def sdo_entry(sdo, key: ObjectKey):
    """The entry of a canopen SDO client (``node.sdo``) for an object key: the variable itself for
    subindex 0 (the drive's keys with subindex 0 are plain variables), else that subindex of the
    record or array."""
    entry = sdo[key.index]
    return entry[key.subindex] if key.subindex else entry


def set_up_drive(scene: Scene, controller: LockstepMaster, node, drive: VirtualDrive,
                 cam: CompiledCam, master_cob_id: int | None = None) -> dict:
    """Boot, configure and enable the drive the way a CANopen master does.

    ``master_cob_id``: drive-side, the COB-ID of the master position PDO the machine shares
    among its drive-side drives (:mod:`hil_sim.rig.shared_master`); None, the drive's own RPDO3.

    Returns
    -------
    dict
        ``setup_frames`` (frames on the bus until enabled) and, drive-side, ``download``
        (``bytes``, ``frames``, ``seconds_at_bitrate`` of the table download).

    Raises
    ------
    SimulationError
        The drive did not reach the state or the table CRC a step expects.
    """
    before = controller.frames  # a machine's drives are set up one after the other
    drive.boot()
    controller.settle()
    if node.nmt.state != "PRE-OPERATIONAL":
        raise SimulationError(f"drive NMT state {node.nmt.state} after boot-up, "
                              "expected PRE-OPERATIONAL")
    facts = {}
    step = "configuration (0x60C2, 0x6065, 0x6060)"
    try:
        _configure(scene, node)
        cam_in = scene.master.profile == "cam_in"
        if scene.cam_mode == "drive":
            step = "table download (0x2000..0x2004)"
            facts["download"] = _download_table(scene, controller, node, cam.table,
                                                select=not cam_in)
        step = "PDO set-up"
        node.tpdo.read()
        node.rpdo.read()
        step = "TPDO timing (0x1800..0x1803 sub 2 and 6)"
        _time_tpdos(scene, node)
        if scene.cam_mode == "drive" and master_cob_id not in (None, node.rpdo[3].cob_id):
            step = f"shared master position (0x1402 COB-ID 0x{master_cob_id:03X})"
            rpdo = node.rpdo[3]
            rpdo.cob_id = master_cob_id
            rpdo.save()
        if scene.cam_mode == "drive" and cam_in:
            step = "RPDO3 mapping (0x1602: 0x2003, 0x2004)"
            _map_cam_mode(node)
    except (SdoAbortedError, SdoCommunicationError) as exc:
        raise SimulationError(f"drive set-up failed at the {step}: {exc}") from None
    node.nmt.state = "OPERATIONAL"
    controller.settle()
    _enable(controller, node)
    facts["setup_frames"] = controller.frames - before
    return facts


def _configure(scene: Scene, node) -> None:
    """Interpolation period, following-error window and mode, by SDO."""
    sdo = node.sdo
    value, index = interpolation_period(scene.drive.cycle_s)
    sdo_entry(sdo, INTERPOLATION_TIME_PERIOD_VALUE).raw = value
    sdo_entry(sdo, INTERPOLATION_TIME_INDEX).raw = index
    sdo_entry(sdo, FOLLOWING_ERROR_WINDOW).raw = scene.drive.following_error_window
    sdo_entry(sdo, MODES_OF_OPERATION).raw = cia402.CYCLIC_SYNCHRONOUS_POSITION
    if scene.bus.sync_counter_overflow:  # the SYNC will carry the counter: the drive expects it
        sdo_entry(sdo, SYNC_COUNTER_OVERFLOW).raw = scene.bus.sync_counter_overflow


def _time_tpdos(scene: Scene, node) -> None:
    """Every synchronous TPDO of the drive on every n-th SYNC (the scene's
    ``drive.tpdo_transmission_type``), started on the SYNC whose counter is
    ``drive.tpdo_sync_start`` (CiA 301 7.5.2.37: written while the TPDO is not valid, which
    canopen's ``Map.save`` does first)."""
    every, start = scene.drive.tpdo_transmission_type, scene.drive.tpdo_sync_start
    if every == 1 and not start:
        return  # the EDS defaults: type 1, no start value
    for tpdo in node.tpdo.map.values():
        if tpdo.enabled and 1 <= tpdo.trans_type <= 240:
            tpdo.trans_type = every
            tpdo.sync_start_value = start
            tpdo.save()


def _map_cam_mode(node) -> None:
    """A drive-side cam-in: the cam mode (0x2004) rides in RPDO3 with the master position, so
    the drive switches to its cam in the cycle the controller's approach ends (mapped by SDO in
    PRE-OPERATIONAL in the order CiA 301 gives for the RPDO mapping parameter 0x1600..0x17FF:
    disable the PDO, zero entries, map, set the count, enable)."""
    rpdo = node.rpdo[3]
    rpdo.clear()
    rpdo.add_variable(MASTER_POSITION.index, MASTER_POSITION.subindex)
    rpdo.add_variable(CAM_MODE.index, CAM_MODE.subindex)
    rpdo.enabled = True
    rpdo.save()


def _download_table(scene: Scene, controller: LockstepMaster, node, table,
                    select: bool = True) -> dict:
    """Download the table, activate it and (``select``) select it; return what the download
    cost."""
    sdo = node.sdo
    blob = table.to_bytes()
    before = controller.frames
    sdo.download(CAM_TABLE_DOWNLOAD.index, CAM_TABLE_DOWNLOAD.subindex, blob)
    frames = controller.frames - before
    pending = sdo_entry(sdo, PENDING_CAM_TABLE_CRC32).raw
    if pending != table.crc32:
        raise SimulationError(f"drive pending table CRC 0x{pending:08x}, expected 0x{table.crc32:08x}")
    sdo_entry(sdo, CAM_COMMAND).raw = CAM_COMMAND_ACTIVATE
    active = sdo_entry(sdo, ACTIVE_CAM_TABLE_CRC32).raw
    if active != table.crc32:
        raise SimulationError(f"drive active table CRC 0x{active:08x}, expected 0x{table.crc32:08x}")
    if select:
        sdo_entry(sdo, CAM_MODE).raw = CAM_MODE_DRIVE_SIDE
    return {"bytes": len(blob), "frames": frames,
            "seconds_at_bitrate": frames * frame_bits(8) / scene.bus.bitrate}


def _enable(controller: LockstepMaster, node) -> None:
    """CiA 402 enable by the controlword in RPDO 1; check the drive reached OPERATION ENABLED."""
    rpdo1 = node.rpdo[1]
    codec, indexes = pdo_codec(rpdo1)
    for controlword in (0x06, 0x07, 0x0F):  # shutdown, switch on, enable operation
        fields = {CONTROLWORD.index: controlword, MODES_OF_OPERATION.index: cia402.CYCLIC_SYNCHRONOUS_POSITION}
        controller.send_message(rpdo1.cob_id, codec.pack(*[fields[i] for i in indexes]))
    statusword = sdo_entry(node.sdo, STATUSWORD).raw
    if statusword & 0x6F != 0x27:
        raise SimulationError(f"drive statusword 0x{statusword:04x} after enabling, expected "
                              "OPERATION ENABLED (0x27 under mask 0x6F)")


def send_cam_commands(node, commands, load: BusLoad | None = None) -> None:
    """The events' writes to the drive's cam slot (:class:`hil_sim.events.DriveCommand`) by SDO:
    a table blob downloaded (segmented) into 0x2000, a number written expedited (a 64-bit one
    segmented). With ``load``, every frame of an event's writes, both ways, is queued there as
    acyclic traffic under (node id, event) (:meth:`hil_sim.bus.BusLoad.queue_frame`)."""
    sdo = node.sdo
    network = node.network
    try:
        for command in commands:
            if load is not None:
                network.acyclic_load, network.acyclic_tag = load, (node.id, command.event)
            if isinstance(command.value, bytes):
                sdo.download(command.index, command.subindex, command.value)
            else:
                sdo_entry(sdo, ObjectKey(command.index, command.subindex)).raw = command.value
    finally:
        if load is not None:
            network.acyclic_tag = network.acyclic_load = None
