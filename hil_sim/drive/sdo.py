"""SDO: the drive's SDO server, its canopen node, access to the object values canopen stores,
and the abort codes the drive answers with.

canopen 2.4 internals this relies on (canopen is pinned below 2.5): the SDO server's transfer
state (``_buffer``, ``_index``), ``LocalNode._write_callbacks`` and ``LocalNode._find_object``.
"""

from __future__ import annotations

import struct

import canopen
from canopen.sdo import SdoAbortedError, SdoServer
from canopen.sdo.constants import (EXPEDITED, NO_MORE_DATA, SIZE_SPECIFIED,
                                   ABORT_LENGTH_NOT_MATCHED)

from hil_sim.drive.objects import CAM_TABLE_DOWNLOAD, ObjectKey

#: SDO abort codes used by the drive (CiA 301).
ABORT_COMMAND_SPECIFIER = 0x05040001  # command specifier not valid or unknown
ABORT_INVALID_VALUE = 0x06090030
ABORT_CANNOT_MAP = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_GENERAL = 0x08000000
ABORT_CANNOT_STORE = 0x08000020
ABORT_DEVICE_STATE = 0x08000022


class DriveSdoServer(SdoServer):
    """canopen's SDO server, plus: the indicated size of a segmented download is enforced, an
    abort from the client drops the partial buffer, and the drive hears about both through
    ``on_refused(index, abort_code, message)``."""

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
            raise SdoAbortedError(ABORT_COMMAND_SPECIFIER)  # segment without an initiated download
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

    def abort(self, abort_code=ABORT_GENERAL):
        # canopen packs the index of the transfer; a stray segment comes before any.
        self._index = self._index or 0
        self._subindex = self._subindex or 0
        super().abort(abort_code)

    def request_aborted(self, data):
        super().request_aborted(data)
        if self._buffer is not None:
            self._buffer = None
            code = self.last_received_error
            self._on_refused(self._index, code,
                             f"download aborted by the client with code 0x{code:08X}")


class DriveNode(canopen.LocalNode):
    """canopen's LocalNode, except that a cam blob written to 0x2000 is not kept a second time
    in the data store (the drive holds it in its pending slot)."""

    def set_data(self, index, subindex, data, check_writable=False):
        super().set_data(index, subindex, data, check_writable=check_writable)
        if index == CAM_TABLE_DOWNLOAD.index:
            self.data_store[index].pop(subindex, None)


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
