"""PDOs: the drive's PDO engine, compiled from the communication and mapping objects
(0x1400-0x1BFF) into struct packers and network subscriptions.

canopen 2.4 packs PDOs for a master but leaves a slave's to the application, and it does not
write received RPDO values into the slave's object dictionary: both are done here.
"""

from __future__ import annotations

import struct

from canopen.objectdictionary import ODVariable
from canopen.sdo import SdoAbortedError

from hil_sim.drive.cia402 import OPERATIONAL
from hil_sim.drive.emcy import EMCY_PDO_LENGTH, ERROR_REGISTER_COMMUNICATION
from hil_sim.drive.objects import (
    CAN_ID_MASK, COB_ID_SYNC, COB_ID_USED_BY_PDO, COMMUNICATION_PARAMETERS, MAPPING_PARAMETERS,
    NUMBER_OF_MAPPED_OBJECTS, PDO_NOT_VALID, RPDO_COMMUNICATION_PARAMETER, RPDO_MAPPING_PARAMETER,
    STRUCT_CODES, SYNC_START_VALUE, TPDO_COMMUNICATION_PARAMETER, TPDO_MAPPING_PARAMETER,
    TRANSMISSION_TYPE, ObjectKey,
)
from hil_sim.drive.sdo import ABORT_CANNOT_MAP, ABORT_INVALID_VALUE, ABORT_PDO_LENGTH

PDOS_PER_DIRECTION = 4  # NrOfRXPDO and NrOfTXPDO of the EDS
MAX_MAPPED_OBJECTS = 8  # mapping subindexes 1..8 in the EDS
MAX_PDO_BITS = 64  # one classic CAN frame

# CiA 301 transmission types: 0 synchronous acyclic (sent on a SYNC when the data changed),
# 1..240 every n-th SYNC, 254/255 event-driven; an RPDO of type 0..240 is applied at the next SYNC.
SYNCHRONOUS_ACYCLIC = 0
LAST_SYNCHRONOUS = 240
FIRST_EVENT_DRIVEN = 254

# CiA 301 COB-ID bits beside the CAN-ID.
FRAME_29_BIT = 1 << 29
SYNC_PRODUCER = 1 << 30  # 0x1005: the node generates the SYNC
#: CAN-IDs CiA 301 reserves for NMT, SDO, heartbeat/boot-up and LSS: no PDO or SYNC on them
#: (a PDO on 0x601 would take the SDO requests as process data).
RESTRICTED_CAN_IDS = frozenset([0x000, *range(0x001, 0x080), *range(0x101, 0x181),
                                *range(0x581, 0x600), *range(0x601, 0x680), *range(0x6E0, 0x700),
                                *range(0x701, 0x780), *range(0x780, 0x800)])


#: A synchronous TPDO's countdown before its first SYNC in OPERATIONAL, and while it waits for
#: the SYNC whose counter equals its SYNC start value (the states CANopenNode's CO_TPDO_process,
#: 301/CO_PDO.c, keeps in its syncCounter as 255 and 254).
COUNTDOWN_UNSTARTED = -1
COUNTDOWN_AWAITING_START = -2


class Pdo:
    """One PDO as the drive uses it: COB-ID, transmission type, SYNC start value (TPDOs) and a
    struct for its mapping."""

    __slots__ = ("number", "cob_id", "trans_type", "start", "keys", "codec", "length", "last",
                 "countdown")

    def __init__(self, number, cob_id, trans_type, keys, codec, start=0):
        self.number = number
        self.cob_id = cob_id
        self.trans_type = trans_type
        self.start = start
        self.keys = keys
        self.codec = codec
        self.length = codec.size
        self.last = None
        self.countdown = COUNTDOWN_UNSTARTED

    def due(self, counter: int | None) -> bool:
        """Whether this synchronous cyclic TPDO (type n, 1..240) goes on this SYNC.

        CiA 301 7.5.2.37 (TPDO communication parameter): type n is sent on every n-th SYNC;
        with the SYNC counter on (0x1019 > 0, ``counter`` the SYNC's counter byte) and a SYNC
        start value s (sub-index 06h, 1..240) the SYNC whose counter equals s counts as the first
        one received, so the first transmission is on it; without either the first is on the
        n-th SYNC after entering OPERATIONAL. The same order as CANopenNode's CO_TPDO_process.
        """
        if self.countdown == COUNTDOWN_UNSTARTED:
            self.countdown = (COUNTDOWN_AWAITING_START if counter is not None and self.start
                              else self.trans_type)
        if self.countdown == COUNTDOWN_AWAITING_START:
            if counter != self.start:
                return False
            self.countdown = self.trans_type
            return True
        self.countdown -= 1
        if self.countdown:
            return False
        self.countdown = self.trans_type
        return True


def mapped_object(objects, entry: int, transmit: bool) -> ODVariable:
    """The object a mapping entry (index << 16 | subindex << 8 | bit length, CiA 301) names;
    aborts 0x06040041 if the drive cannot map it that way."""
    target, sub, length = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
    try:
        obj = objects.find(ObjectKey(target, sub))
    except SdoAbortedError:
        raise SdoAbortedError(ABORT_CANNOT_MAP) from None
    readable_ok = obj.readable if transmit else obj.writable
    if (not obj.pdo_mappable or not readable_ok or obj.data_type not in STRUCT_CODES
            or len(obj) != length):
        raise SdoAbortedError(ABORT_CANNOT_MAP)
    return obj


def check_cob_id(value: int, sync: bool = False) -> None:
    """A COB-ID the drive can use (CiA 301, 0x1005 and the PDO communication parameters), else
    abort 0x06090030: an 11-bit CAN-ID (bit 29, the 29-bit frame, is not supported, and bits
    11..28 are then 0), none of the CAN-IDs CiA 301 restricts (NMT, SDO, heartbeat, LSS...)
    while the COB-ID is valid, and for 0x1005 bit 30 clear (the drive consumes the SYNC, it
    does not produce it)."""
    if value & FRAME_29_BIT or value & ~CAN_ID_MASK & 0x1FFFFFFF:
        raise SdoAbortedError(ABORT_INVALID_VALUE)
    if sync and value & SYNC_PRODUCER:
        raise SdoAbortedError(ABORT_INVALID_VALUE)
    valid = sync or not value & PDO_NOT_VALID
    if valid and value & CAN_ID_MASK in RESTRICTED_CAN_IDS:
        raise SdoAbortedError(ABORT_INVALID_VALUE)


def check_transmission_type(value: int) -> None:
    """CiA 301 transmission types the drive runs: 0..240 synchronous, 254/255 event-driven.
    241..251 are reserved and 252/253 (TPDO on RTR only) need remote frames, which the drive
    does not answer: abort 0x06090030."""
    if not (value <= LAST_SYNCHRONOUS or value >= FIRST_EVENT_DRIVEN):
        raise SdoAbortedError(ABORT_INVALID_VALUE)


def check_sync_start_value(objects, index: int, value: int) -> None:
    """A TPDO's SYNC start value (CiA 301 7.5.2.37, sub-index 06h): 0..240, written only while
    the TPDO does not exist (bit 31 of its COB-ID set), else abort 0x06090030 (as CANopenNode's
    OD_write_18xx)."""
    if value > LAST_SYNCHRONOUS or not objects.stored(ObjectKey(index, COB_ID_USED_BY_PDO)) & PDO_NOT_VALID:
        raise SdoAbortedError(ABORT_INVALID_VALUE)


def check_pdo_write(objects, index: int, subindex: int, value: int) -> None:
    """Refuse PDO parameters the drive cannot use and mappings it cannot pack (CiA 301 abort
    codes)."""
    if any(index in area for area in COMMUNICATION_PARAMETERS):
        if subindex == COB_ID_USED_BY_PDO:
            check_cob_id(value)
        elif subindex == TRANSMISSION_TYPE:
            check_transmission_type(value)
        elif subindex == SYNC_START_VALUE and index >= TPDO_COMMUNICATION_PARAMETER:
            check_sync_start_value(objects, index, value)
        return
    if not any(index in area for area in MAPPING_PARAMETERS):
        return
    transmit = index >= TPDO_MAPPING_PARAMETER
    count = objects.stored(ObjectKey(index, NUMBER_OF_MAPPED_OBJECTS))
    entries = {sub: objects.stored(ObjectKey(index, sub)) for sub in range(1, count + 1)}
    if subindex != NUMBER_OF_MAPPED_OBJECTS:
        if subindex > count:  # not in the mapping in use: checked when the count takes it in
            return
        entries[subindex] = value  # an entry of the mapping in use: the PDO must still pack
    else:
        if value > MAX_MAPPED_OBJECTS:
            raise SdoAbortedError(ABORT_PDO_LENGTH)
        entries = {sub: objects.stored(ObjectKey(index, sub)) for sub in range(1, value + 1)}
    bits = sum(len(mapped_object(objects, entry, transmit)) for entry in entries.values())
    if bits > MAX_PDO_BITS:
        raise SdoAbortedError(ABORT_PDO_LENGTH)


class PdoEngine:
    """The drive's RPDOs and TPDOs, and its subscription to SYNC.

    Parameters
    ----------
    network : canopen.Network
        Where PDOs are received and sent.
    objects : hil_sim.drive.sdo.StoredObjects
        The PDO parameters and the EDS defaults of mapped objects.
    values : dict
        The drive's live objects, read by TPDOs and written by RPDOs.
    nmt : hil_sim.drive.nmt.NmtSlave
        PDOs move only in OPERATIONAL.
    emcy : hil_sim.drive.emcy.EmcyProducer
        Reports an RPDO shorter than its mapping.
    writers : dict
        Live object -> ``writer(value)`` for the objects whose write has side effects; a value
        the writer refuses (SdoAbortedError) is dropped, since a PDO has no answer.
    on_sync : callable
        Network callback for the SYNC COB-ID (0x1005).
    """

    def __init__(self, network, objects, values: dict, nmt, emcy, writers: dict, on_sync) -> None:
        self.network = network
        self.objects = objects
        self.values = values
        self.nmt = nmt
        self.emcy = emcy
        self.writers = writers
        self._on_sync = on_sync
        self.rpdos: dict[int, Pdo] = {}  # by COB-ID
        self.tpdos: list[Pdo] = []
        self.sync_tpdos: list[Pdo] = []
        self.event_tpdos: list[Pdo] = []
        self.latched: dict[int, bytes] = {}  # synchronous RPDO data by COB-ID, until the SYNC
        self.rpdo_subscriptions: tuple[int, ...] = ()
        self.sync_cob: int | None = None
        # A PDO parameter was written: the PDOs are rebuilt once the SDO transfer is over.
        self.dirty = False

    def build(self) -> None:
        """Compile the PDO communication and mapping objects into packers and subscriptions."""
        network, stored = self.network, self.objects.stored
        for cob_id in self.rpdo_subscriptions:
            network.unsubscribe(cob_id, self.on_rpdo)
        self.rpdos = {}
        self.tpdos = []
        for transmit, comm_base, map_base in (
                (False, RPDO_COMMUNICATION_PARAMETER, RPDO_MAPPING_PARAMETER),
                (True, TPDO_COMMUNICATION_PARAMETER, TPDO_MAPPING_PARAMETER)):
            for number in range(PDOS_PER_DIRECTION):
                cob = stored(ObjectKey(comm_base + number, COB_ID_USED_BY_PDO))
                if cob & PDO_NOT_VALID:
                    continue
                trans_type = stored(ObjectKey(comm_base + number, TRANSMISSION_TYPE))
                count = stored(ObjectKey(map_base + number, NUMBER_OF_MAPPED_OBJECTS))
                keys, codes = [], "<"
                for sub in range(1, count + 1):
                    entry = stored(ObjectKey(map_base + number, sub))
                    obj = mapped_object(self.objects, entry, transmit)
                    keys.append((obj.index, obj.subindex))
                    codes += STRUCT_CODES[obj.data_type]
                start = stored(ObjectKey(comm_base + number, SYNC_START_VALUE)) if transmit else 0
                pdo = Pdo(number + 1, cob & CAN_ID_MASK, trans_type, tuple(keys),
                          struct.Struct(codes), start)
                if transmit:
                    self.tpdos.append(pdo)
                else:
                    self.rpdos[pdo.cob_id] = pdo
        for pdo in self.tpdos + list(self.rpdos.values()):
            for key in pdo.keys:
                self.values.setdefault(key, stored(key))
        self.rpdo_subscriptions = tuple(self.rpdos)
        for cob_id in self.rpdo_subscriptions:
            network.subscribe(cob_id, self.on_rpdo)
        self.sync_tpdos = [p for p in self.tpdos if p.trans_type <= LAST_SYNCHRONOUS]
        self.event_tpdos = [p for p in self.tpdos if p.trans_type >= FIRST_EVENT_DRIVEN]
        self.latched = {}
        sync_cob = stored(COB_ID_SYNC) & CAN_ID_MASK
        if self.sync_cob is not None:
            network.unsubscribe(self.sync_cob, self._on_sync)
        self.sync_cob = sync_cob
        network.subscribe(sync_cob, self._on_sync)
        self.dirty = False

    def on_rpdo(self, can_id, data, timestamp) -> None:
        """Network callback for the COB-IDs of the RPDOs."""
        if self.nmt.state != OPERATIONAL:
            return
        pdo = self.rpdos.get(can_id)
        if pdo is None:
            return
        if len(data) < pdo.length:
            self.emcy.send(EMCY_PDO_LENGTH, ERROR_REGISTER_COMMUNICATION)
            return
        if pdo.trans_type <= LAST_SYNCHRONOUS:
            self.latched[can_id] = bytes(data)
        else:
            self._apply(pdo, data)
            self.send_event_tpdos()

    def apply_latched(self) -> None:
        """At a SYNC: write the synchronous RPDOs received since the last one."""
        if self.latched:
            for cob_id, data in self.latched.items():
                self._apply(self.rpdos[cob_id], data)
            self.latched.clear()

    def _apply(self, pdo: Pdo, data) -> None:
        values = self.values
        writers = self.writers
        for key, value in zip(pdo.keys, pdo.codec.unpack_from(data)):
            writer = writers.get(key)
            if writer is None:
                values[key] = value
            else:
                try:
                    writer(value)
                except SdoAbortedError:
                    pass  # a PDO has no answer: an invalid value is ignored

    def restart_sync_tpdos(self) -> None:
        """Entering OPERATIONAL: the synchronous TPDOs count their SYNCs afresh (CiA 301
        7.5.2.37; CANopenNode resets the count whenever the node is not operational)."""
        for pdo in self.sync_tpdos:
            pdo.countdown = COUNTDOWN_UNSTARTED

    def send_sync_tpdos(self, counter: int | None = None) -> None:
        """At a SYNC: send the synchronous TPDOs that are due (``counter``: the SYNC's counter
        byte with 0x1019 > 0, else None)."""
        if self.nmt.state != OPERATIONAL:
            return
        values = self.values
        for pdo in self.sync_tpdos:
            if pdo.trans_type == SYNCHRONOUS_ACYCLIC:
                data = pdo.codec.pack(*[values[key] for key in pdo.keys])
                if data == pdo.last:
                    continue
            elif pdo.due(counter):
                data = pdo.codec.pack(*[values[key] for key in pdo.keys])
            else:
                continue
            pdo.last = data
            self.network.send_message(pdo.cob_id, data)

    def send_event_tpdos(self) -> None:
        """Send the event-driven TPDOs whose data changed."""
        if self.nmt.state != OPERATIONAL:
            return
        for pdo in self.event_tpdos:
            data = pdo.codec.pack(*[self.values[key] for key in pdo.keys])
            if data != pdo.last:
                pdo.last = data
                self.network.send_message(pdo.cob_id, data)
