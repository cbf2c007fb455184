"""SDO: the drive's SDO server, its canopen node, access to the object values canopen stores,
and the abort codes the drive answers with.

The server is written here (canopen's :class:`~canopen.sdo.SdoServer` lends only its class and
its local ``upload``/``download``): canopen 2.4's server lets ``struct.error`` escape on a short
frame, answers a segment request outside a transfer with a general error naming whatever object
was addressed last, never times a transfer out and does not enforce a download's indicated size.
It implements the CiA 301 SDO protocols expedited and segmented (section 7.2.4.3), with the
behaviour of a real server on every frame a client may send:

* every request gets one answer at most: the response, or an abort (0x80) naming the object of
  the transfer it ends, or 0000:00 where the frame named none (never an earlier transfer's);
* a frame too short for what its command specifier announces is answered as lely-core's server
  answers it (``src/co/ssdo.c``: no command byte or a segment shorter than its size field
  0x05040001, an initiate frame without a whole index 0x06020000, without a sub-index
  0x06090011); a segmented download initiate that announces a size and does not carry it is
  aborted with 0x05040001 too (lely-core reads the missing bytes as zeros);
  CANopenNode instead ignores every frame whose length is not 8 (``301/CO_SDOserver.c``), which
  leaves the client to time out;
* a segment request without a transfer in progress, an initiate request during one and an
  unknown command specifier (block transfers included: this server implements none) abort with
  0x05040001, and end the transfer in progress (as lely-core does);
* a segment whose toggle bit did not alternate aborts with 0x05030000;
* a segmented transfer the client does not continue within :data:`SDO_TIMEOUT_S` aborts with
  0x05040000 (CANopenNode's default server time-out, 1000 ms);
* a download longer or shorter than its object's data type aborts with 0x06070012 / 0x06070013,
  one whose segments do not add up to the indicated size with 0x06070010;
* an abort from the client ends the transfer without an answer;
* an exception in the drive while it serves a request (a defect, never the frame's doing) is
  logged and answered with 0x08000000; it never leaves the handler.

A download that ends in an abort before it reached its object calls ``on_refused(index,
abort_code, message)``, so the drive-side cam can record why a table download failed.

canopen 2.4 internals this relies on (canopen is pinned below 2.5): ``LocalNode._write_callbacks``
and ``LocalNode._find_object``.
"""

from __future__ import annotations

import logging
import struct

import canopen
from canopen.objectdictionary import NUMBER_TYPES, ODVariable
from canopen.sdo import SdoAbortedError, SdoServer

from ecam.table_spec import MAX_POINTS
from hil_sim.drive.objects import CAM_TABLE_DOWNLOAD, ObjectKey

logger = logging.getLogger(__name__)

#: SDO abort codes (CiA 301, table "SDO abort codes").
ABORT_TOGGLE = 0x05030000  # toggle bit not alternated
ABORT_TIMEOUT = 0x05040000  # SDO protocol timed out
ABORT_COMMAND_SPECIFIER = 0x05040001  # client/server command specifier not valid or unknown
ABORT_READ_WRITE_ONLY = 0x06010001
ABORT_WRITE_READ_ONLY = 0x06010002
ABORT_NO_OBJECT = 0x06020000  # object does not exist in the object dictionary
ABORT_CANNOT_MAP = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_LENGTH = 0x06070010  # data type does not match, length of service parameter does not match
ABORT_LENGTH_TOO_HIGH = 0x06070012
ABORT_LENGTH_TOO_LOW = 0x06070013
ABORT_NO_SUBINDEX = 0x06090011
ABORT_INVALID_VALUE = 0x06090030  # invalid value for parameter (download only)
ABORT_VALUE_TOO_HIGH = 0x06090031
ABORT_VALUE_TOO_LOW = 0x06090032
ABORT_GENERAL = 0x08000000
ABORT_CANNOT_STORE = 0x08000020
ABORT_DEVICE_STATE = 0x08000022
ABORT_NO_DATA = 0x08000024

#: Server time-out of a segmented transfer [s] (on the drive's clock: simulated in lock-step).
SDO_TIMEOUT_S = 1.0

#: Longest download the drive takes into a DOMAIN (0x2000): the largest cam table a blob can
#: carry (firmware_tables/FORMAT.md: a 64-byte header and up to 3 words per point).
MAX_DOMAIN_BYTES = 64 + 4 * 3 * MAX_POINTS

# CiA 301 SDO command byte: client command specifier (bits 7..5) and flags.
_CCS_DOWNLOAD_SEGMENT, _CCS_INITIATE_DOWNLOAD, _CCS_INITIATE_UPLOAD = 0, 1, 2
_CCS_UPLOAD_SEGMENT, _CCS_ABORT, _CCS_BLOCK_UPLOAD, _CCS_BLOCK_DOWNLOAD = 3, 4, 5, 6
_EXPEDITED, _SIZE_INDICATED, _TOGGLE, _LAST_SEGMENT = 0x02, 0x01, 0x10, 0x01
# Server command specifiers of the responses.
_SCS_UPLOAD_SEGMENT, _SCS_DOWNLOAD_SEGMENT, _SCS_INITIATE_UPLOAD = 0x00, 0x20, 0x40
_SCS_INITIATE_DOWNLOAD, _SCS_ABORT = 0x60, 0x80

_IDLE, _DOWNLOADING, _UPLOADING = "idle", "download", "upload"

#: What the cam status 0x2001:04 says of a download the server refused.
_ABORT_REASONS = {
    ABORT_TOGGLE: "toggle bit not alternated",
    ABORT_TIMEOUT: "SDO protocol timed out",
    ABORT_COMMAND_SPECIFIER: "command specifier not valid or unknown",
    ABORT_WRITE_READ_ONLY: "object is read only",
    ABORT_NO_OBJECT: "object does not exist",
    ABORT_NO_SUBINDEX: "sub-index does not exist",
    ABORT_LENGTH: "length does not match",
    ABORT_LENGTH_TOO_HIGH: "length too high",
    ABORT_LENGTH_TOO_LOW: "length too low",
    ABORT_GENERAL: "general error",
}


class DriveSdoServer(SdoServer):
    """The drive's SDO server (see the module docstring).

    Parameters
    ----------
    rx_cobid, tx_cobid : int
        COB-IDs of the requests and of the responses.
    node : DriveNode
        The object dictionary and its data.
    on_refused : callable
        ``on_refused(index, abort_code, message)`` when a download ends in an abort before it
        reached its object.
    clock : callable
        The drive's time now [s], for the transfer time-out.
    """

    def __init__(self, rx_cobid, tx_cobid, node, on_refused, clock) -> None:
        super().__init__(rx_cobid, tx_cobid, node)
        self._on_refused = on_refused
        self._clock = clock
        self.timeout_s = SDO_TIMEOUT_S
        self._state = _IDLE
        self._index = self._subindex = 0
        self._buffer: bytearray | None = None
        self._toggle = 0
        self._expected_size: int | None = None  # a segmented download's indicated size
        self._max_size = 0  # the most bytes the object of a segmented download takes
        self._last_activity = 0.0
        # A download was initiated and its data has not reached the object: an abort now is a
        # refusal the object never saw (reported through on_refused).
        self._download_pending = False

    @property
    def transfer(self) -> str:
        """The segmented transfer in progress: ``"idle"``, ``"download"`` or ``"upload"``."""
        return self._state

    # -------------------------------------------------------------------------- framing
    def on_request(self, can_id, data, timestamp) -> None:
        """Network callback for the request COB-ID: answer one frame (never raises)."""
        try:
            self._serve(bytes(data))
        except SdoAbortedError as exc:
            self._abort(exc.code)
        except Exception:  # noqa: BLE001 - a defect of the drive must not stop its SDO server
            logger.exception("SDO request %s", bytes(data).hex(" "))
            self._abort(ABORT_GENERAL)

    def service(self) -> None:
        """Abort a segmented transfer the client left for longer than :attr:`timeout_s`
        (called on the drive's clock: at each cycle, and when a free-running drive is idle)."""
        if self._state != _IDLE and self._clock() - self._last_activity > self.timeout_s:
            self._abort(ABORT_TIMEOUT, f"SDO time-out: the client sent no segment for "
                                       f"{self.timeout_s:g} s")

    def _serve(self, frame: bytes) -> None:
        if not frame:
            raise SdoAbortedError(ABORT_COMMAND_SPECIFIER)
        command = frame[0]
        ccs = command >> 5
        if ccs == _CCS_ABORT:
            self._client_abort(frame)
            return
        if self._state == _DOWNLOADING and ccs == _CCS_DOWNLOAD_SEGMENT:
            self._download_segment(command, frame)
        elif self._state == _UPLOADING and ccs == _CCS_UPLOAD_SEGMENT:
            self._upload_segment(command)
        elif self._state == _IDLE and ccs == _CCS_INITIATE_DOWNLOAD:
            self._initiate_download(command, frame)
        elif self._state == _IDLE and ccs == _CCS_INITIATE_UPLOAD:
            self._initiate_upload(frame)
        else:
            if self._state == _IDLE and _is_block_initiate(command) and len(frame) >= 4:
                # a block transfer names its object: the abort names it too
                _, self._index, self._subindex = struct.unpack_from("<BHB", frame)
            raise SdoAbortedError(ABORT_COMMAND_SPECIFIER)

    def _address(self, frame: bytes):
        """The object an initiate request names (lely-core's aborts for a short frame)."""
        if len(frame) < 3:
            raise SdoAbortedError(ABORT_NO_OBJECT)
        self._index, = struct.unpack_from("<H", frame, 1)
        if len(frame) < 4:
            raise SdoAbortedError(ABORT_NO_SUBINDEX)
        self._subindex = frame[3]
        return self._node._find_object(self._index, self._subindex)

    def _respond(self, response: bytes) -> None:
        self.network.send_message(self.tx_cobid, response)

    def _respond_initiate(self, command: int, payload: bytes = b"") -> None:
        self._respond(struct.pack("<BHB", command, self._index, self._subindex)
                      + payload.ljust(4, b"\0"))

    def _abort(self, code: int, message: str | None = None) -> None:
        """Send an abort naming the object of the transfer it ends; the server is then idle."""
        self._respond(struct.pack("<BHBI", _SCS_ABORT, self._index, self._subindex, code))
        if self._download_pending:
            reason = _ABORT_REASONS.get(code, "refused")
            self._refused(code, message or f"download refused: {reason} (0x{code:08X})")
        self._idle()

    def abort(self, abort_code=ABORT_GENERAL):
        """canopen's name for :meth:`_abort`."""
        self._abort(abort_code)

    def reset(self) -> None:
        """An NMT reset (node or communication): the transfer in progress ends without an
        answer (the boot-up that follows tells the client), a download that had not reached its
        object is reported refused, and the next segment is a request outside a transfer."""
        if self._download_pending:
            self._refused(ABORT_DEVICE_STATE, "download ended by an NMT reset before its last "
                                              "segment")
        self._idle()

    def _refused(self, code: int, message: str) -> None:
        self._on_refused(self._index, code, message)

    def _idle(self) -> None:
        self._state = _IDLE
        self._index = self._subindex = 0
        self._buffer = None
        self._expected_size = None
        self._toggle = 0
        self._download_pending = False

    def _client_abort(self, frame: bytes) -> None:
        """CiA 301: an abort is not answered; it ends the transfer in progress."""
        if len(frame) >= 8:
            self.last_received_error, = struct.unpack_from("<I", frame, 4)
        if self._download_pending:
            code = self.last_received_error
            self._refused(code, f"download aborted by the client with code 0x{code:08X}")
        self._idle()

    # ------------------------------------------------------------------------- download
    def _initiate_download(self, command: int, frame: bytes) -> None:
        if len(frame) >= 3:
            self._download_pending = True
        obj = self._address(frame)
        if not obj.writable:
            raise SdoAbortedError(ABORT_WRITE_READ_ONLY)
        if command & _EXPEDITED:
            if command & _SIZE_INDICATED:
                size = 4 - ((command >> 2) & 0x3)
                if len(frame) < 4 + size:
                    raise SdoAbortedError(ABORT_COMMAND_SPECIFIER)
                data = frame[4:4 + size]
            else:  # size not indicated: the object's own length, as far as the frame has it
                data = frame[4:8]
                if obj.data_type in NUMBER_TYPES:
                    data = data[:len(obj) // 8]
            self._write(obj, data)
            self._respond_initiate(_SCS_INITIATE_DOWNLOAD)
            self._idle()
            return
        max_size = _max_length(obj)
        self._expected_size = None
        if command & _SIZE_INDICATED:
            if len(frame) < 8:
                raise SdoAbortedError(ABORT_COMMAND_SPECIFIER)
            size, = struct.unpack_from("<I", frame, 4)
            _check_length(obj, size)
            self._expected_size = size
        self._state = _DOWNLOADING
        self._buffer = bytearray()
        self._max_size = max_size
        self._toggle = 0
        self._last_activity = self._clock()
        self._respond_initiate(_SCS_INITIATE_DOWNLOAD)

    def _download_segment(self, command: int, frame: bytes) -> None:
        if command & _TOGGLE != self._toggle:
            raise SdoAbortedError(ABORT_TOGGLE)
        size = 7 - ((command >> 1) & 0x7)
        if len(frame) < 1 + size:
            raise SdoAbortedError(ABORT_COMMAND_SPECIFIER)
        buffer = self._buffer
        buffer.extend(frame[1:1 + size])
        if self._expected_size is not None and len(buffer) > self._expected_size:
            self._abort(ABORT_LENGTH_TOO_HIGH, f"download longer than the indicated "
                                               f"{self._expected_size} bytes")
            return
        if len(buffer) > self._max_size:
            raise SdoAbortedError(ABORT_LENGTH_TOO_HIGH)
        self._last_activity = self._clock()
        response = bytes([_SCS_DOWNLOAD_SEGMENT | self._toggle]) + bytes(7)
        self._toggle ^= _TOGGLE
        if not command & _LAST_SEGMENT:
            self._respond(response)
            return
        if self._expected_size is not None and len(buffer) != self._expected_size:
            self._abort(ABORT_LENGTH, f"download length {len(buffer)} should be the indicated "
                                      f"{self._expected_size} bytes")
            return
        obj = self._node._find_object(self._index, self._subindex)
        self._write(obj, bytes(buffer))
        self._respond(response)
        self._idle()

    def _write(self, obj: ODVariable, data: bytes) -> None:
        _check_length(obj, len(data))
        self._download_pending = False  # the object answers for the data: a refusal is its own
        self._state = _IDLE
        self._node.set_data(obj.index, obj.subindex, data, check_writable=True)

    # --------------------------------------------------------------------------- upload
    def _initiate_upload(self, frame: bytes) -> None:
        obj = self._address(frame)
        if not obj.readable:
            raise SdoAbortedError(ABORT_READ_WRITE_ONLY)
        try:
            data = self._node.get_data(obj.index, obj.subindex, check_readable=True)
        except SdoAbortedError as exc:
            if exc.code == 0x060A0023:  # canopen: "resource not available", nothing stored
                raise SdoAbortedError(ABORT_NO_DATA) from None
            raise
        size = len(data)
        if size == 0:
            raise SdoAbortedError(ABORT_NO_DATA)
        if size <= 4:
            command = _SCS_INITIATE_UPLOAD | _EXPEDITED | _SIZE_INDICATED | ((4 - size) << 2)
            self._respond_initiate(command, data)
            self._idle()
            return
        self._state = _UPLOADING
        self._buffer = bytearray(data)
        self._toggle = 0
        self._last_activity = self._clock()
        self._respond_initiate(_SCS_INITIATE_UPLOAD | _SIZE_INDICATED, struct.pack("<I", size))

    def _upload_segment(self, command: int) -> None:
        if command & _TOGGLE != self._toggle:
            raise SdoAbortedError(ABORT_TOGGLE)
        chunk = bytes(self._buffer[:7])
        del self._buffer[:7]
        last = not self._buffer
        response = (_SCS_UPLOAD_SEGMENT | self._toggle | ((7 - len(chunk)) << 1)
                    | (_LAST_SEGMENT if last else 0))
        self._toggle ^= _TOGGLE
        self._last_activity = self._clock()
        self._respond(bytes([response]) + chunk.ljust(7, b"\0"))
        if last:
            self._idle()


def _is_block_initiate(command: int) -> bool:
    """A block upload or download initiate request (CiA 301: these carry index and sub-index)."""
    ccs = command >> 5
    return ((ccs == _CCS_BLOCK_DOWNLOAD and command & 0x01 == 0)
            or (ccs == _CCS_BLOCK_UPLOAD and command & 0x03 == 0))


def _max_length(obj: ODVariable) -> int:
    """The most bytes the object takes."""
    if obj.data_type in NUMBER_TYPES:
        return len(obj) // 8
    return MAX_DOMAIN_BYTES


def _check_length(obj: ODVariable, size: int) -> None:
    """CiA 301: a number takes exactly its data type's bytes; a string or domain a bounded length."""
    if size > _max_length(obj):
        raise SdoAbortedError(ABORT_LENGTH_TOO_HIGH)
    if obj.data_type in NUMBER_TYPES and size < len(obj) // 8:
        raise SdoAbortedError(ABORT_LENGTH_TOO_LOW)


def check_range(obj: ODVariable, value) -> None:
    """A written number within its EDS limits (LowLimit/HighLimit): CiA 301 aborts 0x06090032
    (value too low) and 0x06090031 (value too high) otherwise."""
    if obj.min is not None and value < obj.min:
        raise SdoAbortedError(ABORT_VALUE_TOO_LOW)
    if obj.max is not None and value > obj.max:
        raise SdoAbortedError(ABORT_VALUE_TOO_HIGH)


class DriveNode(canopen.LocalNode):
    """canopen's LocalNode, except that a cam blob written to 0x2000 is not kept a second time
    in the data store (the drive holds it in its pending slot), and that a sub-index other than
    0 of a plain variable does not exist (canopen's lookup ignores it)."""

    def set_data(self, index, subindex, data, check_writable=False):
        super().set_data(index, subindex, data, check_writable=check_writable)
        if index == CAM_TABLE_DOWNLOAD.index:
            self.data_store[index].pop(subindex, None)

    def _find_object(self, index, subindex):
        obj = super()._find_object(index, subindex)
        if obj.subindex != subindex:  # CiA 301: a VAR has sub-index 0 only
            raise SdoAbortedError(ABORT_NO_SUBINDEX)
        return obj


class StoredObjects:
    """The objects canopen keeps in the node's data store (those the drive does not keep live),
    read and written as decoded values."""

    def __init__(self, node: canopen.LocalNode) -> None:
        self.node = node

    def find(self, key: ObjectKey):
        """The object's dictionary entry; aborts (0x06020000 / 0x06090011) if there is none."""
        return self.node._find_object(*key)

    def stored(self, key: ObjectKey):
        """Decoded value of an object kept in canopen's data store (EDS default if unset)."""
        obj = self.node._find_object(*key)
        return obj.decode_raw(self.node.get_data(*key))

    def store(self, key: ObjectKey, value) -> None:
        obj = self.node._find_object(*key)
        self.node.data_store.setdefault(key[0], {})[key[1]] = obj.encode_raw(value)

    def default(self, key: ObjectKey):
        obj = self.node._find_object(*key)
        return obj.value if obj.value is not None else obj.default

    def forget(self, area: range) -> None:
        """Drop every stored value of the indexes in ``area``: they read as EDS defaults again."""
        data_store = self.node.data_store
        for index in list(data_store):
            if index in area:
                del data_store[index]
