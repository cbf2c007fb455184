"""A virtual CiA 402 servo drive: a CANopen slave on a python-can bus, driving a simulated axis.

The drive is a canopen :class:`~canopen.LocalNode` (object dictionary from ``drive.eds``, SDO
server with segmented transfer) plus what canopen 2.4 leaves to the application:

* **NMT** slave written here (boot-up, pre-operational, operational, stopped, resets) with a
  heartbeat produced on the drive's own clock (canopen's uses a timer thread);
* **SYNC** handled by subscribing to 0x80: each SYNC latches the synchronous RPDOs, advances
  the drive by one interpolation period (0x60C2), runs :meth:`ServoAxis.cycle`, then sends the
  synchronous TPDOs;
* **PDOs** packed and unpacked here from the mapping objects (0x1400-0x1BFF), and received RPDO
  values written into the drive's object dictionary (canopen does not);
* the **CiA 402 power state machine** as data tables (:data:`COMMANDS`, :data:`TRANSITIONS`,
  :data:`STATUSWORD`), modes of operation 0x6060/0x6061 with cyclic synchronous position (8),
  following-error monitoring (window 0x6065, time out 0x6066) raising a fault with EMCY 0x8611;
* the **drive-side cam**: a table blob downloaded into 0x2000 is verified with
  :meth:`ecam.CamTable.from_bytes` into a pending slot and activated atomically by writing 1 to
  0x2001:01; a bad, truncated or aborted download is refused and the running table keeps
  running. With cam mode 0x2004 = 1 the target is the cam at the master position 0x2003.

canopen 2.4 internals this relies on (canopen is pinned below 2.5): the SDO server's transfer
state (``_buffer``, ``_index``), ``LocalNode._write_callbacks`` and ``LocalNode._find_object``.

Two ways to run it:

* lock-step (the rig): :meth:`boot`, then :meth:`process` whenever frames may be waiting; every
  frame is handled at a defined point and all timestamps are simulated;
* free-running (an external master, e.g. canopen's ``BaseNode402``): :meth:`start` /
  :meth:`stop` run a thread that handles frames as they come; heartbeats follow the wall clock,
  the control loop still advances one interpolation period per SYNC.
"""

from __future__ import annotations

import copy
import functools
import logging
import math
import struct
import threading
import time
from pathlib import Path

import can
import canopen
from canopen.objectdictionary import ODVariable
from canopen.sdo import SdoAbortedError, SdoServer
from canopen.sdo.constants import (EXPEDITED, NO_MORE_DATA, SIZE_SPECIFIED,
                                   ABORT_LENGTH_NOT_MATCHED)

from ecam.errors import InputError, TableFormatError
from hil_sim.bus import SimNetwork, open_virtual_bus, pump
from hil_sim.cia402 import (
    INITIALISING, OPERATIONAL, PRE_OPERATIONAL,
    NMT_COMMANDS, NOT_READY_TO_SWITCH_ON, SWITCH_ON_DISABLED, OPERATION_ENABLED,
    QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE, FAULT, STATUSWORD,
    SW_REMOTE, SW_FOLLOWING_COMMAND, SW_FOLLOWING_ERROR, CW_FAULT_RESET,
    COMMANDS, TRANSITIONS, ENERGIZED, CYCLIC_SYNCHRONOUS_POSITION,
    SUPPORTED_MODES,
)

logger = logging.getLogger(__name__)

#: The drive's electronic data sheet, shipped beside this module.
EDS_PATH = Path(__file__).with_name("drive.eds")

#: EMCY error codes (CiA 301 / 402) and error register bits (0x1001).
EMCY_FOLLOWING_ERROR = 0x8611
EMCY_PDO_LENGTH = 0x8210
ERROR_REGISTER_GENERIC = 0x01
ERROR_REGISTER_COMMUNICATION = 0x10
ERROR_REGISTER_PROFILE = 0x20

#: SDO abort codes used by the drive.
ABORT_INVALID_VALUE = 0x06090030
ABORT_CANNOT_MAP = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_CANNOT_STORE = 0x08000020
ABORT_DEVICE_STATE = 0x08000022

#: Cam control 0x2001:01 commands and 0x2001:02 status bits.
CAM_COMMAND_ACTIVATE = 1
CAM_COMMAND_DISCARD = 2
CAM_STATUS_ACTIVE = 0x01
CAM_STATUS_PENDING = 0x02
CAM_STATUS_LAST_DOWNLOAD_REFUSED = 0x04

#: Objects the drive keeps live (served by callbacks, written by RPDOs). Everything else lives
#: in canopen's data store with the EDS defaults.
PROCESS_OBJECTS = (
    (0x1001, 0), (0x603F, 0), (0x6040, 0), (0x6041, 0), (0x6060, 0), (0x6061, 0), (0x6064, 0),
    (0x6065, 0), (0x6066, 0), (0x606C, 0), (0x6076, 0), (0x6077, 0), (0x607A, 0), (0x60B1, 0),
    (0x60F4, 0), (0x2001, 1), (0x2001, 2), (0x2001, 3), (0x2001, 4), (0x2002, 0), (0x2003, 0),
    (0x2004, 0), (0x2005, 0),
)

_STRUCT_CODES = {  # canopen data type -> struct code for PDO packing
    0x01: "?", 0x02: "b", 0x03: "h", 0x04: "i", 0x05: "B", 0x06: "H", 0x07: "I",
    0x08: "f", 0x15: "q", 0x1B: "Q",
}
_INT32 = 1 << 32


@functools.lru_cache(maxsize=8)
def _parsed_od(path: str, node_id: int):
    return canopen.import_od(path, node_id)


def load_od(path, node_id: int):
    """The object dictionary of an EDS file for ``node_id``: parsed once, then a deep copy per
    caller, so runs share the parsing cost but never any state."""
    return copy.deepcopy(_parsed_od(str(path), node_id))


def interpolation_period_s(value: int, index: int) -> float:
    """0x60C2 (CiA 402: interpolation time period = value x 10^index s) in seconds.

    Divides for negative indexes: 10 x 10.0**-6 is 9.999...e-6, below the 10 us the scene
    validator allows, where 10 / 10**6 is exactly the float nearest 1e-5.
    """
    return value / 10.0 ** -index if index < 0 else value * 10.0 ** index


def _saturate_int32(value: int) -> int:
    """Clamp to INTEGER32, the data type of 0x60B1 (CiA 402 velocity offset).

    A position wraps like a modular counter, but a velocity that leaves its type has no
    meaningful wrap: a sign flip would command full speed backwards. It saturates.
    """
    return max(-0x80000000, min(0x7FFFFFFF, value))


def _wrap_int32(value: int) -> int:
    """Two's complement wrap of an integer to INTEGER32."""
    return (value + (1 << 31)) % _INT32 - (1 << 31)


class _SdoServer(SdoServer):
    """canopen's SDO server, plus: the indicated size of a segmented download is enforced, an
    abort from the client drops the partial buffer, and the drive hears about both."""

    def __init__(self, rx_cobid, tx_cobid, node, on_refused):
        super().__init__(rx_cobid, tx_cobid, node)
        self._expected_size = None
        self._on_refused = on_refused

    def init_download(self, request):
        command = request[0]
        self._expected_size = None
        if not command & EXPEDITED and command & SIZE_SPECIFIED:
            self._expected_size, = struct.unpack_from("<L", request, 4)
        super().init_download(request)

    def segmented_download(self, command, request):
        if self._buffer is None:
            raise SdoAbortedError(0x05040001)  # segment without an initiated download
        last = command & NO_MORE_DATA
        if last and self._expected_size is not None:
            size = len(self._buffer) + 7 - ((command >> 1) & 0x7)
            if size != self._expected_size:
                self._buffer = None
                self._on_refused(self._index, ABORT_LENGTH_NOT_MATCHED,
                                 f"download length {size} should be the indicated "
                                 f"{self._expected_size} bytes")
                raise SdoAbortedError(ABORT_LENGTH_NOT_MATCHED)
        try:
            super().segmented_download(command, request)
        finally:
            if last:
                self._buffer = None

    def abort(self, abort_code=0x08000000):
        # canopen packs the index of the transfer; a stray segment comes before any.
        self._index = self._index or 0
        self._subindex = self._subindex or 0
        super().abort(abort_code)

    def request_aborted(self, data):
        super().request_aborted(data)
        if self._buffer is not None:
            self._buffer = None
            self._on_refused(self._index, self.last_received_error,
                             f"download aborted by the client with code 0x{self.last_received_error:08X}")


class _DriveNode(canopen.LocalNode):
    """canopen's LocalNode, except that a cam blob written to 0x2000 is not kept a second time
    in the data store (the drive holds it in its pending slot)."""

    def set_data(self, index, subindex, data, check_writable=False):
        super().set_data(index, subindex, data, check_writable=check_writable)
        if index == 0x2000:
            self.data_store[index].pop(subindex, None)


class _Pdo:
    """One PDO as the drive uses it: COB-ID, transmission type and a struct for its mapping."""

    __slots__ = ("number", "cob_id", "trans_type", "keys", "codec", "length", "last", "syncs")

    def __init__(self, number, cob_id, trans_type, keys, codec):
        self.number = number
        self.cob_id = cob_id
        self.trans_type = trans_type
        self.keys = keys
        self.codec = codec
        self.length = codec.size
        self.last = None
        self.syncs = 0


def _default_mechanics():
    from hil_sim.mechanics import Mechanics
    # A small servo motor on a rigid load: enough for protocol tests and `hil-sim drive`.
    return Mechanics(motor_inertia=1.2e-4, load_inertia=3.0e-4, motor_damping=1e-4,
                     motor_torque_limit=4.0)


class VirtualDrive:
    """A CiA 402 servo drive on a CAN bus (see the module docstring).

    Parameters
    ----------
    channel : str
        Virtual channel to open when ``bus`` is None.
    node_id : int
        CANopen node id, 1..127.
    bus : can.BusABC, optional
        A bus of the caller's (then ``channel`` is unused and the caller shuts it down).
    mechanics : hil_sim.mechanics.Mechanics, optional
        The axis; default a small servo on a rigid load.
    gains : hil_sim.control.Gains, optional
        Control gains; default :meth:`Gains.from_mechanics` without velocity feed-forward
        (the master's velocity offset 0x60B1 carries the speed).
    substeps : int
        Controller periods per interpolation period.
    counts_per_motor_rad : float, optional
        Position counts per motor radian (the drive's position factor).
    model : {"auto", "rigid", "two_mass"}
        Plant model, see :class:`hil_sim.control.ServoAxis`.
    excitation_hz : float
        Highest significant cam harmonic, for the "auto" model choice.
    initial_counts : int
        Position at power-on [counts].
    heartbeat_ms : int, optional
        Producer heartbeat time 0x1017 at power-on (default: the EDS value).
    eds : str or Path, optional
        Object dictionary; default the shipped ``drive.eds``.
    """

    def __init__(self, channel: str = "ecam", node_id: int = 1, bus: can.BusABC | None = None,
                 *, mechanics=None, gains=None, substeps: int = 8,
                 counts_per_motor_rad: float | None = None, model: str = "auto",
                 excitation_hz: float = 0.0, initial_counts: int = 0,
                 heartbeat_ms: int | None = None, eds=None) -> None:
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
            raise InputError(f"node_id {node_id!r} should be an integer in 1..127")
        from hil_sim.control import Gains
        self.node_id = node_id
        self.mechanics = mechanics if mechanics is not None else _default_mechanics()
        self.gains = gains if gains is not None else Gains.from_mechanics(
            self.mechanics, velocity_feedforward=0.0)
        self.substeps = substeps
        self.counts_per_motor_rad = counts_per_motor_rad
        self.model = model
        self.excitation_hz = excitation_hz
        self._own_bus = bus is None
        self.bus = open_virtual_bus(channel) if bus is None else bus
        self.time_s = 0.0  # drive time: interpolation periods run so far
        self._wall_clock = False
        self.network = SimNetwork(self.bus, self._now)
        self.od = load_od(eds or EDS_PATH, node_id)
        self.node = _DriveNode(node_id, self.od)
        # canopen's SDO server, NMT slave and heartbeat are replaced (see the module docstring).
        self.node.sdo = _SdoServer(0x600 + node_id, 0x580 + node_id, self.node,
                                   self._download_refused)
        self.node._write_callbacks.remove(self.node.nmt.on_write)
        self.network.add_node(self.node)
        self.network.unsubscribe(0x600 + node_id, self.node.sdo.on_request)
        self.network.unsubscribe(0, self.node.nmt.on_command)
        self.network.subscribe(0x600 + node_id, self._on_sdo_request)
        self.network.subscribe(0, self._on_nmt)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)

        self.nmt_state = INITIALISING
        self.state = NOT_READY_TO_SWITCH_ON
        self.values: dict[tuple[int, int], object] = {}
        self.axis = None
        self.cycles = 0
        self.axis_wall_s = 0.0  # wall time spent in ServoAxis.cycle (profiling)
        self._active_table = None
        self._pending_table = None
        self._pending_blob = None
        self._active_blob = None
        self._initial_counts = int(initial_counts)
        self._heartbeat_ms_override = heartbeat_ms
        self._thread = None
        self._running = False
        self._lock = threading.RLock()
        self._reset_application()

    # ---------------------------------------------------------------------------- clocks
    def _now(self) -> float:
        return time.time() if self._wall_clock else self.time_s

    @property
    def cycle_s(self) -> float:
        """Interpolation time period 0x60C2 [s]: value x 10^index."""
        return self.axis.cycle_s

    # ---------------------------------------------------------------------- OD plumbing
    def _stored(self, index: int, subindex: int = 0):
        """Decoded value of an object kept in canopen's data store (EDS default if unset)."""
        obj = self.node._find_object(index, subindex)
        return obj.decode_raw(self.node.get_data(index, subindex))

    def _store(self, index: int, subindex: int, value) -> None:
        obj = self.node._find_object(index, subindex)
        self.node.data_store.setdefault(index, {})[subindex] = obj.encode_raw(value)

    def _default(self, index: int, subindex: int = 0):
        obj = self.node._find_object(index, subindex)
        return obj.value if obj.value is not None else obj.default

    def _on_read(self, index, subindex, od):
        key = (index, subindex)
        if key in self.values:
            return self.values[key]
        if index == 0x2000:
            return self._pending_blob or self._active_blob
        return None

    def _on_write(self, index, subindex, od, data):
        """SDO writes (and nothing else): validate, then update the drive."""
        if index == 0x2000:
            self._verify_download(bytes(data))
            return
        value = od.decode_raw(data)
        key = (index, subindex)
        if key == (0x6076, 0) and value == 0:
            # Motor rated torque divides every torque report (0x6077 is per mille of it): zero
            # would make them infinite, so it is out of range (CiA 301 abort 0x06090030).
            raise SdoAbortedError(ABORT_INVALID_VALUE)
        if key in self.values:
            self._set_value(key, value)
        elif index == 0x1017:
            self._heartbeat_period_s = value / 1000.0
            self._next_heartbeat = self._now() + self._heartbeat_period_s
        elif index == 0x60C2:
            if self.state in ENERGIZED:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            candidate = dict(value=self._stored(0x60C2, 1), index=self._stored(0x60C2, 2))
            candidate["value" if subindex == 1 else "index"] = value
            period = interpolation_period_s(candidate["value"], candidate["index"])
            if subindex in (1, 2):
                if not 1e-5 <= period <= 1.0:
                    raise SdoAbortedError(ABORT_INVALID_VALUE)
                self._make_axis(self.axis.position_counts, period)
        elif 0x1400 <= index <= 0x1BFF:
            self._check_pdo_write(index, subindex, value)
            self._pdo_dirty = True
        elif index == 0x1005:
            self._pdo_dirty = True

    def _set_value(self, key, value) -> None:
        """Write a live object (SDO or RPDO) and run its side effects."""
        index = key[0]
        if index == 0x6040:
            self.values[key] = value
            self._on_controlword(value)
        elif index == 0x6060:
            if value not in SUPPORTED_MODES:
                raise SdoAbortedError(ABORT_INVALID_VALUE)
            self.values[key] = value
            self.values[(0x6061, 0)] = value
            self._update_statusword()
        elif index == 0x2004:
            if value not in (0, 1):
                raise SdoAbortedError(ABORT_INVALID_VALUE)
            if value == 1 and self._active_table is None:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            if value != self.values[key]:
                self._master_unwrapped = None
            self.values[key] = value
        elif key == (0x2001, 1):
            self._on_cam_command(value)
        else:
            self.values[key] = value

    # ------------------------------------------------------------------------------ PDOs
    def _check_pdo_write(self, index, subindex, value) -> None:
        """Refuse mappings the drive cannot pack (CiA 301 abort codes)."""
        is_mapping = 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF
        if not is_mapping:
            return
        transmit = index >= 0x1A00
        if subindex != 0:
            if subindex <= self._stored(index, 0):  # an entry of the mapping in use
                self._mapped_object(value, transmit)
            return
        if value > 8:
            raise SdoAbortedError(ABORT_PDO_LENGTH)
        bits = 0
        for sub in range(1, value + 1):
            entry = self._stored(index, sub)
            obj = self._mapped_object(entry, transmit)
            bits += len(obj)
        if bits > 64:
            raise SdoAbortedError(ABORT_PDO_LENGTH)

    def _mapped_object(self, entry: int, transmit: bool) -> ODVariable:
        target, sub, length = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
        try:
            obj = self.node._find_object(target, sub)
        except SdoAbortedError:
            raise SdoAbortedError(ABORT_CANNOT_MAP) from None
        readable_ok = obj.readable if transmit else obj.writable
        if (not obj.pdo_mappable or not readable_ok or obj.data_type not in _STRUCT_CODES
                or len(obj) != length):
            raise SdoAbortedError(ABORT_CANNOT_MAP)
        return obj

    def _build_pdos(self) -> None:
        """Compile the PDO communication and mapping objects into packers and subscriptions."""
        for cob_id in getattr(self, "_rpdo_subscriptions", ()):
            self.network.unsubscribe(cob_id, self._on_rpdo)
        self.rpdos: dict[int, _Pdo] = {}
        self.tpdos: list[_Pdo] = []
        for transmit, comm_base, map_base in ((False, 0x1400, 0x1600), (True, 0x1800, 0x1A00)):
            for number in range(4):
                cob = self._stored(comm_base + number, 1)
                if cob & 0x80000000:
                    continue
                trans_type = self._stored(comm_base + number, 2)
                count = self._stored(map_base + number, 0)
                keys, codes = [], "<"
                for sub in range(1, count + 1):
                    entry = self._stored(map_base + number, sub)
                    obj = self._mapped_object(entry, transmit)
                    keys.append((obj.index, obj.subindex))
                    codes += _STRUCT_CODES[obj.data_type]
                pdo = _Pdo(number + 1, cob & 0x7FF, trans_type, tuple(keys), struct.Struct(codes))
                if transmit:
                    self.tpdos.append(pdo)
                else:
                    self.rpdos[pdo.cob_id] = pdo
        for pdo in self.tpdos + list(self.rpdos.values()):
            for key in pdo.keys:
                self.values.setdefault(key, self._stored(*key))
        self._rpdo_subscriptions = tuple(self.rpdos)
        for cob_id in self._rpdo_subscriptions:
            self.network.subscribe(cob_id, self._on_rpdo)
        self._sync_tpdos = [p for p in self.tpdos if p.trans_type <= 240]
        self._event_tpdos = [p for p in self.tpdos if p.trans_type >= 254]
        self._latched: dict[int, bytes] = {}
        sync_cob = self._stored(0x1005) & 0x7FF
        if getattr(self, "_sync_cob", None) is not None:
            self.network.unsubscribe(self._sync_cob, self._on_sync)
        self._sync_cob = sync_cob
        self.network.subscribe(sync_cob, self._on_sync)
        self._pdo_dirty = False

    def _on_rpdo(self, can_id, data, timestamp) -> None:
        if self.nmt_state != OPERATIONAL:
            return
        pdo = self.rpdos.get(can_id)
        if pdo is None:
            return
        if len(data) < pdo.length:
            self._emcy(EMCY_PDO_LENGTH, ERROR_REGISTER_COMMUNICATION)
            return
        if pdo.trans_type <= 240:
            self._latched[can_id] = bytes(data)
        else:
            self._apply_rpdo(pdo, data)
            self._send_event_tpdos()

    def _apply_rpdo(self, pdo: _Pdo, data) -> None:
        values = self.values
        for key, value in zip(pdo.keys, pdo.codec.unpack_from(data)):
            if key[0] in (0x6040, 0x6060, 0x2004) or key == (0x2001, 1):
                try:
                    self._set_value(key, value)
                except SdoAbortedError:
                    pass  # a PDO has no answer: an invalid value is ignored
            else:
                values[key] = value

    def _send_event_tpdos(self) -> None:
        if self.nmt_state != OPERATIONAL:
            return
        for pdo in self._event_tpdos:
            data = pdo.codec.pack(*[self.values[key] for key in pdo.keys])
            if data != pdo.last:
                pdo.last = data
                self.network.send_message(pdo.cob_id, data)

    # ------------------------------------------------------------------------------- NMT
    def boot(self) -> None:
        """Power on: initialise, send the boot-up message, enter PRE-OPERATIONAL."""
        self.nmt_state = INITIALISING
        self.network.send_message(0x700 + self.node_id, bytes([0]))
        self.nmt_state = PRE_OPERATIONAL
        self._next_heartbeat = self._now() + self._heartbeat_period_s

    def _on_nmt(self, can_id, data, timestamp) -> None:
        if len(data) < 2 or data[1] not in (0, self.node_id):
            return
        command = NMT_COMMANDS.get(data[0])
        if command is None:
            return
        state, reset = command
        if reset == "application":
            self._reset_application()
        elif reset == "communication":
            self._reset_communication()
        if reset is not None:
            self.boot()
        else:
            self.nmt_state = state
            if state != OPERATIONAL:
                self._latched.clear()
            else:
                self._send_event_tpdos()

    def _on_sdo_request(self, can_id, data, timestamp) -> None:
        if self.nmt_state in (PRE_OPERATIONAL, OPERATIONAL):
            self.node.sdo.on_request(can_id, data, timestamp)
            if self._pdo_dirty:  # a PDO parameter was written: takes effect now
                self._build_pdos()
            self._send_event_tpdos()

    def _service_heartbeat(self) -> None:
        period = self._heartbeat_period_s
        if period <= 0.0 or self.nmt_state == INITIALISING:
            return
        now = self._now()
        if now + 1e-12 >= self._next_heartbeat:
            self.network.send_message(0x700 + self.node_id, bytes([self.nmt_state]))
            self._next_heartbeat += period
            if self._next_heartbeat <= now:  # fell far behind (wall clock): resynchronise
                self._next_heartbeat = now + period

    def _reset_communication(self) -> None:
        for index in list(self.node.data_store):
            if 0x1000 <= index <= 0x1FFF:
                del self.node.data_store[index]
        heartbeat = self._heartbeat_ms_override
        if heartbeat is not None:
            self._store(0x1017, 0, heartbeat)
        self._heartbeat_period_s = self._stored(0x1017) / 1000.0
        self._next_heartbeat = math.inf
        self._build_pdos()

    def _reset_application(self) -> None:
        """Power-on values: the live objects, the 402 state, the cam tables."""
        position = self.axis.position_counts if self.axis is not None else self._initial_counts
        for index in list(self.node.data_store):
            if index >= 0x2000:
                del self.node.data_store[index]
        self.values = {key: self._default(*key) for key in PROCESS_OBJECTS}
        self.values[(0x2001, 4)] = "no error"
        if self.mechanics.motor_torque_limit is not None:
            self.values[(0x6076, 0)] = max(1, round(self.mechanics.motor_torque_limit * 1000.0))
        self._active_table = self._pending_table = None
        self._active_blob = self._pending_blob = None
        self._master_unwrapped = None
        self._fe_since = None
        self._last_controlword = 0
        self._make_axis(position)
        self._hold_counts = self.axis.position_counts
        self._reset_communication()
        self.state = SWITCH_ON_DISABLED  # transition 1 is automatic
        self._update_statusword()

    def _make_axis(self, position_counts: int, cycle_s: float | None = None) -> None:
        """(Re)build the servo axis at ``position_counts`` for an interpolation period."""
        from hil_sim.control import ServoAxis
        kwargs = {}
        if self.counts_per_motor_rad is not None:
            kwargs["counts_per_motor_rad"] = self.counts_per_motor_rad
        if cycle_s is None:
            cycle_s = interpolation_period_s(self._stored(0x60C2, 1), self._stored(0x60C2, 2))
        self.axis = ServoAxis(self.mechanics, self.gains, cycle_s=cycle_s,
                              substeps=self.substeps, model=self.model,
                              excitation_hz=self.excitation_hz,
                              initial_counts=int(position_counts), **kwargs)
        self.values[(0x6064, 0)] = _wrap_int32(self.axis.position_counts)
        self.values[(0x60F4, 0)] = 0

    # ------------------------------------------------------------------------------ 402
    def _on_controlword(self, controlword: int) -> None:
        previous, self._last_controlword = self._last_controlword, controlword
        if controlword & CW_FAULT_RESET:
            if not previous & CW_FAULT_RESET and self.state == FAULT:
                self._fault_reset()
            return
        for name, mask, value in COMMANDS:
            if controlword & mask == value:
                new_state = TRANSITIONS.get((self.state, name))
                if new_state is not None:
                    self._enter(new_state)
                return

    def _enter(self, new_state: str) -> None:
        if new_state == OPERATION_ENABLED and self.state != QUICK_STOP_ACTIVE:
            # CSP starts from where the motor is: no jump when the master's first target lags.
            position = _wrap_int32(self.axis.position_counts)
            self.values[(0x607A, 0)] = position
            self.values[(0x60B1, 0)] = 0
            self._master_unwrapped = None
        if new_state in (QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE):
            self._hold_counts = self.axis.position_counts
        self.state = new_state
        self._fe_since = None
        self._update_statusword()

    def _fault(self, code: int, register: int) -> None:
        """Enter FAULT REACTION ACTIVE, set 0x603F / 0x1001 and send the EMCY."""
        if self.state in (FAULT, FAULT_REACTION_ACTIVE):
            return
        self.values[(0x603F, 0)] = code
        self.values[(0x1001, 0)] |= register
        self._enter(FAULT_REACTION_ACTIVE)
        self._emcy(code, self.values[(0x1001, 0)])

    def _fault_reset(self) -> None:
        self.values[(0x603F, 0)] = 0
        self.values[(0x1001, 0)] = 0
        self._enter(SWITCH_ON_DISABLED)
        self._emcy(0x0000, 0)

    def _emcy(self, code: int, register: int) -> None:
        """Send an EMCY (not while STOPPED, CiA 301)."""
        if self.nmt_state in (PRE_OPERATIONAL, OPERATIONAL):
            cob = self._stored(0x1014) & 0x7FF
            self.network.send_message(cob, struct.pack("<HB5s", code, register, b""))

    def _update_statusword(self) -> None:
        word = STATUSWORD[self.state] | SW_REMOTE
        if self.state == OPERATION_ENABLED and self.values[(0x6061, 0)] == CYCLIC_SYNCHRONOUS_POSITION:
            word |= SW_FOLLOWING_COMMAND
        if self._fe_since is not None:
            word |= SW_FOLLOWING_ERROR
        self.values[(0x6041, 0)] = word

    # -------------------------------------------------------------------------- the cam
    def _download_refused(self, index: int, code: int, message: str) -> None:
        if index == 0x2000:
            self._refuse(code, message)

    def _refuse(self, code: int, message: str) -> None:
        values = self.values
        values[(0x2001, 3)] = code
        values[(0x2001, 4)] = message.encode("ascii", "replace").decode("ascii")
        values[(0x2001, 2)] |= CAM_STATUS_LAST_DOWNLOAD_REFUSED

    def _verify_download(self, blob: bytes) -> None:
        """Verify a complete download of 0x2000 into the pending slot, or refuse it."""
        import ecam
        try:
            table = ecam.CamTable.from_bytes(blob)
        except TableFormatError as exc:
            self._refuse(ABORT_CANNOT_STORE, str(exc))
            raise SdoAbortedError(ABORT_CANNOT_STORE) from None
        self._pending_table = table
        self._pending_blob = blob
        values = self.values
        values[(0x2005, 0)] = table.crc32
        values[(0x2001, 2)] = (values[(0x2001, 2)] | CAM_STATUS_PENDING) & ~CAM_STATUS_LAST_DOWNLOAD_REFUSED
        values[(0x2001, 3)] = 0
        values[(0x2001, 4)] = "no error"

    def _on_cam_command(self, command: int) -> None:
        values = self.values
        if command == CAM_COMMAND_ACTIVATE:
            if self._pending_table is None:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            # The swap is one assignment between two cycles: atomic for the control loop.
            self._active_table, self._active_blob = self._pending_table, self._pending_blob
            self._pending_table = self._pending_blob = None
            self._master_unwrapped = None
            values[(0x2002, 0)] = self._active_table.crc32
            values[(0x2005, 0)] = 0
            values[(0x2001, 2)] = (values[(0x2001, 2)] | CAM_STATUS_ACTIVE) & ~CAM_STATUS_PENDING
        elif command == CAM_COMMAND_DISCARD:
            self._pending_table = self._pending_blob = None
            values[(0x2005, 0)] = 0
            values[(0x2001, 2)] &= ~CAM_STATUS_PENDING
        elif command != 0:
            raise SdoAbortedError(ABORT_INVALID_VALUE)
        values[(0x2001, 1)] = command

    @property
    def active_table(self):
        """The cam table the drive runs (None before the first activation)."""
        return self._active_table

    @property
    def pending_table(self):
        """The verified table waiting for activation (None if none)."""
        return self._pending_table

    def _cam_target(self) -> tuple[int, float]:
        """Target and velocity offset from the active cam at the master position 0x2003."""
        raw = self.values[(0x2003, 0)]
        previous = self._master_unwrapped
        if previous is None:
            master = raw
            previous = raw
        else:
            master = previous + _wrap_int32(raw - _wrap_int32(previous))
        self._master_unwrapped = master
        # two scalar lookups take the table's pure-integer path (no numpy overhead per cycle)
        _, slope = self._active_table.lookup((previous + master) // 2, with_slope=True)
        velocity = slope * (master - previous) / (65536.0 * self.cycle_s)
        return self._active_table.lookup(master), velocity

    # ----------------------------------------------------------------------------- cycle
    def _on_sync(self, can_id, data, timestamp) -> None:
        self.run_cycle(synchronous=True)

    def free_run(self) -> None:
        """Run one interpolation period without a SYNC (the SYNC was lost): the control loop
        keeps its own timer, synchronous RPDOs stay latched and no synchronous TPDO is sent."""
        self.run_cycle(synchronous=False)

    def run_cycle(self, synchronous: bool = True) -> None:
        """One interpolation period: latch RPDOs, run the axis, publish, send TPDOs."""
        values = self.values
        if synchronous and self._latched:
            for cob_id, data in self._latched.items():
                self._apply_rpdo(self.rpdos[cob_id], data)
            self._latched.clear()
        state = self.state
        axis = self.axis
        if state in ENERGIZED:
            if state == OPERATION_ENABLED and values[(0x6061, 0)] == CYCLIC_SYNCHRONOUS_POSITION:
                if values[(0x2004, 0)] == 1 and self._active_table is not None:
                    target, velocity = self._cam_target()
                    values[(0x607A, 0)] = _wrap_int32(target)
                    values[(0x60B1, 0)] = _saturate_int32(round(velocity))
                else:
                    target, velocity = values[(0x607A, 0)], values[(0x60B1, 0)]
            elif state == OPERATION_ENABLED:
                target, velocity = values[(0x607A, 0)], 0.0  # no mode: hold the last target
            else:
                target, velocity = self._hold_counts, 0.0
            start = time.perf_counter()
            axis.cycle(target, velocity)
            self.axis_wall_s += time.perf_counter() - start
            plant = axis.plant
            following_error = axis.following_error_counts
            values[(0x6064, 0)] = _wrap_int32(axis.position_counts)
            values[(0x60F4, 0)] = _wrap_int32(following_error)
            values[(0x606C, 0)] = _wrap_int32(round(plant.motor_speed * axis.counts_per_motor_rad))
            torque = round(plant.torque * 1e6 / values[(0x6076, 0)])
            values[(0x6077, 0)] = min(max(torque, -32768), 32767)
            self._check_following_error(following_error)
            if state == FAULT_REACTION_ACTIVE:
                self._enter(FAULT)  # transition 14: the reaction (hold, then off) is done
        else:
            values[(0x606C, 0)] = 0
            values[(0x6077, 0)] = 0
        self.cycles += 1
        self.time_s = self.cycles * self.cycle_s
        self._service_heartbeat()
        if synchronous and self.nmt_state == OPERATIONAL:
            for pdo in self._sync_tpdos:
                pdo.syncs += 1
                if pdo.trans_type == 0 or pdo.syncs >= pdo.trans_type:
                    pdo.syncs = 0
                    data = pdo.codec.pack(*[values[key] for key in pdo.keys])
                    if pdo.trans_type == 0 and data == pdo.last:
                        continue
                    pdo.last = data
                    self.network.send_message(pdo.cob_id, data)
        if self._event_tpdos:
            self._send_event_tpdos()

    def _check_following_error(self, following_error: int) -> None:
        window = self.values[(0x6065, 0)]
        beyond = window != 0xFFFFFFFF and abs(following_error) > window
        was = self._fe_since is not None
        if not beyond:
            if was:
                self._fe_since = None
                self._update_statusword()
            return
        if not was:
            self._fe_since = self.time_s
            self._update_statusword()
        timeout_s = self.values[(0x6066, 0)] / 1000.0
        if self.state == OPERATION_ENABLED and self.time_s - self._fe_since >= timeout_s - 1e-12:
            self._fault(EMCY_FOLLOWING_ERROR, ERROR_REGISTER_GENERIC | ERROR_REGISTER_PROFILE)

    # -------------------------------------------------------------------------- running
    def process(self) -> int:
        """Handle every frame waiting on the bus, in order (lock-step use); return the count."""
        with self._lock:
            return pump(self.bus, self.network)

    def start(self) -> None:
        """Boot and handle frames in a thread of its own until :meth:`stop` (external masters)."""
        if self._thread is not None:
            raise RuntimeError("the drive is already running")
        self._wall_clock = True
        self._running = True
        with self._lock:
            self.boot()
        self._thread = threading.Thread(target=self._serve, name=f"VirtualDrive-{self.node_id}",
                                        daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while self._running:
            try:
                msg = self.bus.recv(timeout=0.01)
            except can.CanError:
                break
            with self._lock:
                if msg is not None and not (msg.is_error_frame or msg.is_remote_frame):
                    try:
                        self.network.notify(msg.arbitration_id, msg.data, msg.timestamp)
                    except Exception:  # a bad frame must not stop the drive
                        logger.exception("frame 0x%03X", msg.arbitration_id)
                self._service_heartbeat()

    def stop(self) -> None:
        """Stop the thread of :meth:`start` and release the bus if the drive opened it."""
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self.close()

    def close(self) -> None:
        """Release the bus if the drive opened it."""
        if self._own_bus and self.bus is not None:
            self.bus.shutdown()
            self.bus = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
