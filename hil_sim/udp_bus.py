"""A CAN bus between processes on one machine that does not hand a sender its own frames back.

python-can's ``udp_multicast`` interface joins processes over IP multicast, but every frame a bus
sends comes back to that same bus (multicast loopback), although python-can's API promises that a
bus does not receive its own messages unless ``receive_own_messages`` is set. A CANopen master
trips over this: python ``canopen`` takes two receptions of its own RPDO for a periodic PDO
(``PdoMap.on_message`` sets ``period``), and ``BaseNode402`` then stops transmitting the
controlword, so the state machine stalls in READY TO SWITCH ON.

:class:`EchoFreeUdpMulticastBus` speaks the same wire format (msgpack frames on the same groups
and port, so plain ``udp_multicast`` nodes still hear it) and drops exactly its own frames. It
tells them by something a peer cannot forge: it sends from a socket of its own, bound to an
ephemeral port no other socket can bind while it is open (no ``SO_REUSEPORT`` on it), and a
datagram whose source address is that socket's is its own echo. (Before issue 28 a tag in the
packed ``channel`` field marked the echo, and any process that copied the tag silenced the
frames it sent.) It is registered with python-can as the interface ``ecam_udp``, so any
python-can program, an unmodified canopen master included, selects it with
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
stops at the first error goes deaf for good; and it passes on messages that unpack but are no
CAN frame (an ``arbitration_id`` of 128.0 or NaN, issue 28). Here every such datagram is
dropped (counted in :attr:`EchoFreeUdpMulticastBus.dropped`, logged once;
:func:`hil_sim.frames.frame_problem` says what a frame must be); only a failure of the socket
itself is raised.
"""

from __future__ import annotations

import logging
import socket
import struct
import time

import can
from can.interfaces.udp_multicast import UdpMulticastBus
from can.interfaces.udp_multicast.utils import pack_message, unpack_message

from hil_sim.frames import frame_problem

__all__ = ["EchoFreeUdpMulticastBus", "DEFAULT_GROUP", "RECEIVE_BUFFER_BYTES"]

logger = logging.getLogger(__name__)

# IPv4: routable on a loopback-only network namespace with one route (224.0.0.0/4 dev lo), where
# python-can's IPv6 default group needs more set-up.
DEFAULT_GROUP = UdpMulticastBus.DEFAULT_GROUP_IPv4
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
        try:
            super().__init__(channel, *args, **kwargs)
        except BaseException:
            # Half built, nothing to shut down: without this python-can's __del__ logs a stray
            # "was not properly shut down" under the caller's one-line error.
            self._is_shutdown = True
            raise
        # fileno() is python-can's public handle on the socket; fromfd duplicates it, and an
        # option set on the duplicate is set on the one socket both name.
        with socket.fromfd(self.fileno(), socket.AF_INET, socket.SOCK_DGRAM) as sock:
            _enlarge_receive_buffer(sock)
        multicast = self._multicast  # python-can's socket pair: receive here, send on our own
        self._sender, self._own_address = _open_sender(multicast.group, multicast.port,
                                                      multicast.ip_version, multicast.hop_limit)
        self._send_timeout: float | None = None
        self.channel_info = f"{channel} (echo-free)"
        #: Datagrams on the group's port that were not frames, dropped.
        self.dropped = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.is_fd and self._can_protocol is not can.CanProtocol.CAN_FD:
            raise can.CanOperationError("cannot send FD message over bus with CAN FD disabled")
        data = pack_message(msg)
        if timeout != self._send_timeout:
            self._send_timeout = timeout
            self._sender.settimeout(timeout)
        try:
            if self._sender.send(data) < len(data):
                raise TimeoutError
        except TimeoutError:
            raise can.CanTimeoutError() from None
        except OSError as error:
            raise can.CanOperationError("failed to send via socket") from error

    def _recv_internal(self, timeout: float | None):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            received = self._multicast.recv(remaining)  # raises only when the socket fails
            if received is not None:
                data, sender, timestamp = received
                if tuple(sender[:2]) != self._own_address:  # else our own echo
                    msg = self._frame(data, timestamp)
                    if msg is not None:
                        return msg, False
            if deadline is not None and remaining == 0.0:
                return None, False

    def _frame(self, data: bytes, timestamp: float) -> can.Message | None:
        """The frame a datagram carries, or None (dropped) if it carries none."""
        try:
            msg = unpack_message(data, replace={"timestamp": timestamp}, check=True)
        except Exception as exc:  # noqa: BLE001 - msgpack and Message raise anything on garbage
            self._drop(f"{type(exc).__name__}: {exc}")
            return None
        problem = frame_problem(msg)
        if problem is not None:
            self._drop(problem)
            return None
        return msg

    def _drop(self, reason: str) -> None:
        self.dropped += 1
        if self.dropped == 1:
            logger.warning("%s: dropped a datagram that is not a CAN frame (%s); further ones are "
                           "counted, not logged", self.channel_info, reason[:200])

    def shutdown(self) -> None:
        super().shutdown()
        self._sender.close()


def _open_sender(group: str, port: int, ip_version: int, hop_limit: int):
    """A socket that sends to the group from an ephemeral port of its own, and its address as
    receivers see it (the source of every datagram it sends): ``(socket, (host, port))``."""
    family = socket.AF_INET if ip_version == 4 else socket.AF_INET6
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        hops = struct.pack("@I", hop_limit)  # as python-can sets it on its own socket
        if family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, hops)
        else:
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_HOPS, hops)
        # connect() picks the source address and port the kernel sends from (and binds them)
        sock.connect((group, port))
        return sock, tuple(sock.getsockname()[:2])
    except OSError as error:
        sock.close()
        raise can.CanInitializationError("could not open the sending socket") from error


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
