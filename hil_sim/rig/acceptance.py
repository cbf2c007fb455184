"""The acceptance filter of a virtual drive's CAN controller, for a machine on one virtual
channel: a frame whose identifier none of the drive's CANopen handlers listens to is not queued
for it, as a real drive's controller drops it in hardware before its firmware sees it
(ISO 11898-1 acceptance filtering).

Why: on one channel every node receives every frame, so N drives each handled every node's
frames (validated, looked up, dropped): a machine of N axes cost N^2 frame deliveries, and the
six-axis shipped line's CANopen loop about 1.15 times its axes run alone. Filtered, each drive
handles its own frames (its RPDOs, SDO, NMT and the SYNC) and the loop costs about the sum of
its axes (measured: ``ecam bench``, ``machine_scaling``; docs/machine.md).

The filter reads the drive's subscriptions when a frame arrives, so a COB-ID the controller
configures by SDO during the set-up (a PDO's 0x1400 entry) is accepted from then on. A frame
whose identifier is not an integer is passed on: the drive's runner drops and counts it.
"""

from __future__ import annotations

from can.interfaces.virtual import channels_lock


class AcceptanceQueue:
    """A receive queue that takes only frames the drive subscribes to (the others are not
    queued); ``get_nowait`` and ``get`` as the queue it wraps."""

    __slots__ = ("queue", "subscribers", "rejected")

    def __init__(self, queue, subscribers: dict) -> None:
        self.queue = queue
        self.subscribers = subscribers
        #: Frames not queued: no handler of the drive listens to their identifier.
        self.rejected = 0

    def put(self, msg, block: bool = True, timeout: float | None = None) -> None:
        can_id = msg.arbitration_id
        if type(can_id) is int and can_id not in self.subscribers:
            self.rejected += 1
            return
        self.queue.put(msg, block, timeout)

    def get_nowait(self):
        return self.queue.get_nowait()

    def get(self, block: bool = True, timeout: float | None = None):
        return self.queue.get(block, timeout)

    def empty(self) -> bool:
        return self.queue.empty()

    def qsize(self) -> int:
        return self.queue.qsize()


def filter_frames(drive) -> AcceptanceQueue:
    """Put an acceptance filter on ``drive``'s virtual bus (a :class:`VirtualDrive` on a
    python-can ``virtual`` channel, as :func:`hil_sim.bus.open_virtual_bus` opens it): its
    receive queue on the channel is replaced by one that takes only the identifiers the drive's
    CANopen network subscribes to. Returns the new queue."""
    bus = drive.bus
    with channels_lock:  # python-can's virtual bus: a channel is a list of receive queues
        accepting = AcceptanceQueue(bus.queue, drive.network.subscribers)
        bus.channel[bus.channel.index(bus.queue)] = accepting
        bus.queue = accepting
    return accepting
