"""A CAN bus between processes on one machine that does not hand a sender its own frames back.

python-can's ``udp_multicast`` interface joins processes over IP multicast, but every frame a bus
sends comes back to that same bus (multicast loopback), although python-can's API promises that a
bus does not receive its own messages unless ``receive_own_messages`` is set. A CANopen master
trips over this: python ``canopen`` takes two receptions of its own RPDO for a periodic PDO
(``PdoMap.on_message`` sets ``period``), and ``BaseNode402`` then stops transmitting the
controlword, so the state machine stalls in READY TO SWITCH ON.

:class:`EchoFreeUdpMulticastBus` speaks the same wire format (msgpack frames on the same groups
and port, so plain ``udp_multicast`` nodes still hear it) and drops exactly its own frames: each
frame it sends carries the bus's own tag in the ``channel`` field of the packed message, and a
received frame with that tag is the echo. It is registered with python-can as the interface
``ecam_udp``, so any python-can program, an unmodified canopen master included, selects it with
``interface="ecam_udp"``.

Its socket has a receive buffer of :data:`RECEIVE_BUFFER_BYTES` instead of the system default
(Linux: 208 KiB, about 256 frames, since each datagram is charged its kernel buffer, about 830
bytes on loopback). A drive's socket also takes its own frames back (multicast loopback is what
reaches the other processes), some 4000 datagrams a second at a 1 kHz SYNC, so a drive process
the scheduler leaves waiting for 65 ms lost SYNCs and set points (measured: 117 dropped in a
1000-cycle run on a loaded machine), and a lost SYNC is an interpolation period the drive never
runs. The kernel caps the request at ``net.core.rmem_max`` (212992 bytes unless the system
raises it: ``sysctl -w net.core.rmem_max=4194304``); a process with CAP_NET_ADMIN (root) sets it
past that cap.

It also survives a datagram that is not a frame. python-can's ``udp_multicast`` raises
``CanOperationError`` from ``recv`` for anything on the group's port that does not unpack into a
valid message (another program's datagram, a truncated one), and a node whose receive loop
stops at the first error goes deaf for good. Here such a datagram is dropped (counted in
:attr:`EchoFreeUdpMulticastBus.dropped`, logged once); only a failure of the socket itself
is raised.
"""

from __future__ import annotations

import itertools
import logging
import os
import socket
import time
from copy import copy

import can
from can.interfaces.udp_multicast import UdpMulticastBus

__all__ = ["EchoFreeUdpMulticastBus", "DEFAULT_GROUP", "RECEIVE_BUFFER_BYTES"]

logger = logging.getLogger(__name__)

# IPv4: routable on a loopback-only network namespace with one route (224.0.0.0/4 dev lo), where
# python-can's IPv6 default group needs more set-up.
DEFAULT_GROUP = UdpMulticastBus.DEFAULT_GROUP_IPv4
_BUS_NUMBERS = itertools.count()
#: The socket's receive buffer [bytes] asked for: 4 MiB, which the kernel doubles for its
#: bookkeeping: some 10 000 datagrams, 2.5 s of a drive's traffic at a 1 kHz SYNC (see the
#: module docstring).
RECEIVE_BUFFER_BYTES = 4 * 1024 * 1024


class EchoFreeUdpMulticastBus(UdpMulticastBus):
    """``udp_multicast`` without the sender's own frames (see the module docstring).

    Parameters are those of :class:`can.interfaces.udp_multicast.UdpMulticastBus`; ``channel``
    defaults to the IPv4 group :data:`DEFAULT_GROUP`.
    """

    def __init__(self, channel: str = DEFAULT_GROUP, *args, **kwargs) -> None:
        super().__init__(channel, *args, **kwargs)
        # fileno() is python-can's public handle on the socket; fromfd duplicates it, and an
        # option set on the duplicate is set on the one socket both name.
        with socket.fromfd(self.fileno(), socket.AF_INET, socket.SOCK_DGRAM) as sock:
            _enlarge_receive_buffer(sock)
        self._tag = f"ecam-udp:{os.getpid()}:{next(_BUS_NUMBERS)}:{id(self):x}"
        self.channel_info = f"{channel} (echo-free)"
        #: Datagrams on the group's port that were not frames, dropped.
        self.dropped = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        tagged = copy(msg)
        tagged.channel = self._tag
        super().send(tagged, timeout)

    def _recv_internal(self, timeout: float | None):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                msg, filtered = super()._recv_internal(remaining)
            except can.CanOperationError as exc:
                # The socket failed (its OSError is the cause): raise. Otherwise the datagram
                # did not unpack into a frame: drop it and go on listening.
                if exc.__cause__ is None or isinstance(exc.__cause__, OSError):
                    raise
                self._drop(exc.__cause__)
                msg, filtered = None, False
            else:
                if msg is None or msg.channel != self._tag:
                    return msg, filtered
            if deadline is not None and remaining == 0.0:
                return None, False

    def _drop(self, reason: BaseException) -> None:
        self.dropped += 1
        if self.dropped == 1:
            logger.warning("%s: dropped a datagram that is not a python-can frame (%s: %s); "
                           "further ones are counted, not logged", self.channel_info,
                           type(reason).__name__, reason)


def _enlarge_receive_buffer(sock: socket.socket) -> None:
    """Ask for :data:`RECEIVE_BUFFER_BYTES` of receive buffer: past ``net.core.rmem_max`` where
    the process may (SO_RCVBUFFORCE, CAP_NET_ADMIN), else up to that cap (SO_RCVBUF, which the
    kernel clamps without an error). Linux socket(7)."""
    force = getattr(socket, "SO_RCVBUFFORCE", None)
    if force is not None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, force, RECEIVE_BUFFER_BYTES)
            return
        except OSError:
            pass  # not permitted: the capped request below
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
