"""What a received CAN frame must be before any CANopen code sees it.

python-can hands a receiver whatever the transport delivered: over ``udp_multicast`` a frame is
a msgpack map that any process on the network writes, and python-can's own check
(``can.Message(check=True)``) compares the identifier with 0x7FF but never asks whether it is an
integer at all: ``arbitration_id = 128.0`` or NaN passes it, and canopen's network then fails on
it inside its callbacks (issue 28, item 1: one such datagram stopped the drive). A classic CAN
data frame (ISO 11898-1) is an 11- or 29-bit integer identifier, flags that are true or false,
and 0..8 data bytes whose count is its DLC; :func:`frame_problem` says what a frame has that is
not that, and receivers drop and count such frames where they enter (the drive's runner, the
echo-free UDP bus).
"""

from __future__ import annotations

import math

__all__ = ["frame_problem", "STANDARD_ID_MAX", "EXTENDED_ID_MAX", "MAX_DATA_BYTES"]

#: ISO 11898-1: an 11-bit (base format) and a 29-bit (extended format) identifier.
STANDARD_ID_MAX = 0x7FF
EXTENDED_ID_MAX = 0x1FFFFFFF
#: ISO 11898-1 classic CAN: at most 8 data bytes (DLC 9..15 also mean 8; python-can keeps the
#: byte count in ``dlc``). CANopen (CiA 301) runs on classic frames.
MAX_DATA_BYTES = 8

_FLAGS = ("is_extended_id", "is_remote_frame", "is_error_frame", "is_fd")


def frame_problem(msg) -> str | None:
    """Why ``msg`` is not a well-formed classic CAN frame, or None if it is.

    Parameters
    ----------
    msg : can.Message
        As a transport delivered it (its attributes may hold anything).

    Returns
    -------
    str or None
        One short phrase (``"arbitration_id 128.0 is not an integer"``), values shown by
        ``repr`` and cut, so a log line stays one line.
    """
    for flag in _FLAGS:
        value = getattr(msg, flag, None)
        if type(value) is not bool:
            return f"{flag} {_shown(value)} is not true or false"
    if msg.is_fd:
        return "a CAN FD frame (CANopen CiA 301 runs on classic CAN)"
    can_id = getattr(msg, "arbitration_id", None)
    if type(can_id) is not int:  # bool, float, NaN, str: none is an identifier
        return f"arbitration_id {_shown(can_id)} is not an integer"
    limit = EXTENDED_ID_MAX if msg.is_extended_id else STANDARD_ID_MAX
    if not 0 <= can_id <= limit:
        return f"arbitration_id {can_id} is outside 0..0x{limit:X}"
    data = getattr(msg, "data", None)
    if not isinstance(data, (bytes, bytearray)):
        return f"data {_shown(data)} is not bytes"
    dlc = getattr(msg, "dlc", None)
    if type(dlc) is not int:
        return f"dlc {_shown(dlc)} is not an integer"
    if msg.is_remote_frame:
        if data or not 0 <= dlc <= MAX_DATA_BYTES:
            return f"a remote frame with dlc {dlc} and {len(data)} data bytes"
    elif len(data) > MAX_DATA_BYTES or dlc != len(data):
        return f"dlc {dlc} with {len(data)} data bytes (0..{MAX_DATA_BYTES}, equal)"
    timestamp = getattr(msg, "timestamp", None)
    if type(timestamp) not in (int, float) or not math.isfinite(timestamp):
        return f"timestamp {_shown(timestamp)} is not a finite number"
    return None


def _shown(value) -> str:
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a hostile object's repr must not escape either
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 40 else text[:37] + "..."
