"""Bus timing and fault injection for the lock-step rig.

The python-can ``virtual`` interface delivers every frame at once and in order: it has no
bitrate. This module puts the timing back as bookkeeping, and the faults as a plan.

* :func:`frame_bits` is the worst-case length of one CAN 2.0A data frame on the wire.
* :class:`BusLoad` adds up the bits of every frame sent in a bus cycle and flags the cycles
  whose frames do not fit into ``bitrate * cycle_s`` bits.
* :class:`FaultInjector` decides, frame by frame, whether a frame is delivered, dropped or
  delayed by whole cycles, and draws the SYNC jitter, from one seeded
  ``numpy.random.default_rng``: the same seed and the same frame sequence give the same faults.
  It and the plan it applies (:class:`Faults`, ``FRAME_KINDS``) live in :mod:`hil_sim.faults`,
  which loads no CAN stack, and are re-exported here.

And how frames move in lock-step: :func:`open_virtual_bus` (python-can's virtual interface,
keeping simulated timestamps), :class:`SimNetwork` (a canopen Network without a notifier
thread, stamping frames with a clock of its own) and :func:`pump` (hand every waiting frame to
``network.notify`` at a point the caller chooses).
"""

from __future__ import annotations

import collections
import math
import queue
import time

import can
import canopen
import numpy as np
from can.interfaces.virtual import VirtualBus, channels_lock

from ecam.validate import integer, plain, positive
from hil_sim.faults import (  # noqa: F401 - re-exported: the rig's bus names in one place
    DELIVER, DROP, FRAME_KINDS, MAX_SYNC_JITTER_S, FaultInjector, Faults,
)

#: Bits of an 11-bit-identifier data frame outside the data field, before stuffing:
#: SOF 1, identifier 11, RTR 1, IDE 1, r0 1, DLC 4, CRC 15, CRC delimiter 1, ACK slot 1,
#: ACK delimiter 1, EOF 7, plus the 3-bit intermission before the next frame.
FRAME_OVERHEAD_BITS = 47
#: Bits exposed to bit stuffing without the data field: SOF through the CRC sequence
#: (1 + 11 + 1 + 1 + 1 + 4 + 15).
STUFFED_OVERHEAD_BITS = 34

def frame_bits(data_length: int, *, stuffing: bool = True) -> int:
    """Bits one CAN 2.0A (11-bit identifier) data frame occupies on the bus.

    Parameters
    ----------
    data_length : int
        Data bytes, 0..8.
    stuffing : bool
        Count the worst-case stuff bits (default) or none.

    Returns
    -------
    int
        ``47 + 8 n + floor((34 + 8 n - 1) / 4)`` with stuffing, ``47 + 8 n`` without.

    Notes
    -----
    After five equal bits the transmitter inserts one complementary bit. In the worst case the
    first stuff bit comes after five bits and each further one after four more (the stuff bit
    itself starts the next run), so ``g`` stuffed-region bits carry at most ``floor((g - 1) / 4)``
    stuff bits (Davis, Burns, Bril, Lukkien: "Controller Area Network (CAN) schedulability
    analysis: refuted, revisited and revised", Real-Time Systems 35, 2007). The stuffed region
    is SOF to the end of the CRC: ``g = 34 + 8 n``. An 8-byte frame is 135 bits, a SYNC 55.
    """
    integer("data_length", data_length, minimum=0, maximum=8)
    bits = FRAME_OVERHEAD_BITS + 8 * data_length
    if stuffing:
        bits += (STUFFED_OVERHEAD_BITS + 8 * data_length - 1) // 4
    return bits


class BusLoad:
    """Per-cycle bit budget of a bus at a given bitrate.

    Parameters
    ----------
    bitrate : int
        Bits per second, > 0.
    cycle_s : float
        Bus cycle (SYNC period) [s], > 0.

    Notes
    -----
    Call :meth:`add_frame` for every frame on the bus (both directions) and :meth:`end_cycle`
    once per cycle. A cycle overruns when its frames need more bits than
    ``floor(bitrate * cycle_s)``: on a real bus the last frames would slip into the next
    cycle and arrive after the SYNC they were meant for.

    Acyclic frames (the SDO writes of a drive-side event: a table download, the cam slot's
    commands) are queued with :meth:`queue_frame` instead: their COB-IDs (0x580/0x600 + node,
    CiA 301's pre-defined connection set) lose every arbitration to the SYNC (0x080) and the
    PDOs (0x180..0x57F), and an SDO client sends one transfer after another, so they go in
    order into the bits each cycle leaves below its budget, as many whole frames as fit, and
    wait for the next cycle otherwise. They are counted apart from the cyclic load
    (:meth:`summary`'s ``event_sdo``), whose peak the load limit judges.
    """

    def __init__(self, bitrate: int, cycle_s: float) -> None:
        self.bitrate = integer("bitrate", plain(bitrate), minimum=1)
        self.cycle_s = positive("cycle_s", plain(cycle_s))
        self.budget_bits = math.floor(self.bitrate * self.cycle_s + 1e-9)
        self._bits_by_length = [frame_bits(n) for n in range(9)]
        self._cycle_bits = 0
        self._cycle_frames = 0
        self.cycle_bits: list[int] = []
        self.frames = 0
        self.bits = 0
        self._queue: collections.deque = collections.deque()  # (bits, tag) waiting
        self.acyclic: dict = {}  # tag -> [frames, bits, first cycle, last cycle or None]
        self._waiting: dict = {}  # tag -> its frames still queued
        self.acyclic_peak_bits = 0  # the busiest cycle's bits, acyclic frames included

    def queue_frame(self, data_length: int, tag) -> None:
        """Queue one acyclic frame of ``data_length`` bytes, counted under ``tag``."""
        bits = self._bits_by_length[data_length]
        self._queue.append((bits, tag))
        entry = self.acyclic.setdefault(tag, [0, 0, len(self.cycle_bits), None])
        entry[0] += 1
        entry[1] += bits
        entry[3] = None  # not all sent until the queue has taken this one
        self._waiting[tag] = self._waiting.get(tag, 0) + 1

    def _drain(self) -> None:
        """Send queued acyclic frames in the bits this cycle leaves."""
        used = self._cycle_bits
        cycle = len(self.cycle_bits)
        queue = self._queue
        while queue and used + queue[0][0] <= self.budget_bits:
            bits, tag = queue.popleft()
            used += bits
            self._waiting[tag] -= 1
            if not self._waiting[tag]:
                self.acyclic[tag][3] = cycle
        self.acyclic_peak_bits = max(self.acyclic_peak_bits, used)

    def add_frame(self, data_length: int) -> None:
        """Count one frame of ``data_length`` bytes in the current cycle."""
        self._cycle_bits += self._bits_by_length[data_length]
        self._cycle_frames += 1

    def end_cycle(self) -> None:
        """Close the current cycle."""
        if self._queue:
            self._drain()
        self.cycle_bits.append(self._cycle_bits)
        self.frames += self._cycle_frames
        self.bits += self._cycle_bits
        self._cycle_bits = 0
        self._cycle_frames = 0

    def summary(self) -> dict:
        """Peak and mean load in percent of the budget, overrunning cycles and the first one.

        Returns
        -------
        dict
            ``bitrate``, ``budget_bits`` (per cycle), ``peak_bits``, ``peak_percent``,
            ``mean_percent``, ``overrun_cycles``, ``first_overrun_cycle`` (None if none),
            ``frames``, ``cycles``.
        """
        bits = np.asarray(self.cycle_bits, dtype=np.int64)
        cycles = int(bits.size)
        peak = int(bits.max()) if cycles else 0
        over = np.flatnonzero(bits > self.budget_bits)
        return {
            "bitrate": self.bitrate,
            "budget_bits": self.budget_bits,
            "peak_bits": peak,
            "peak_percent": 100.0 * peak / self.budget_bits if self.budget_bits else math.inf,
            "mean_percent": (100.0 * float(bits.mean()) / self.budget_bits
                             if cycles and self.budget_bits else 0.0),
            "overrun_cycles": int(over.size),
            "first_overrun_cycle": int(over[0]) if over.size else None,
            "frames": self.frames,
            "cycles": cycles,
            **({"event_sdo": self._acyclic_summary()} if self.acyclic else {}),
        }

    def _acyclic_summary(self) -> dict:
        """The queued frames: per tag (node, event) frames, bits, the cycle queued and the cycle
        the last went out (None: still waiting at the end); the busiest cycle with them."""
        return {"transfers": [{"node": tag[0], "event": tag[1], "frames": frames, "bits": bits,
                               "queued_cycle": first, "sent_cycle": last}
                              for tag, (frames, bits, first, last) in self.acyclic.items()],
                "pending_frames": len(self._queue),
                "peak_bits": max(self.acyclic_peak_bits, max(self.cycle_bits, default=0))}


def arbitrate(frames: list, budget_bits: int, used_bits: int) -> tuple[list, list]:
    """Which frames of one bus cycle get on the bus before the next SYNC.

    Parameters
    ----------
    frames : list of (cob_id, data_length, item)
        The frames waiting after the cycle's SYNC (and after ``used_bits``).
    budget_bits : int
        Bits of one cycle at the bitrate.
    used_bits : int
        Bits already on the bus in this cycle (the SYNC, frames carried over from the last).

    Returns
    -------
    on_time, late : list, list
        The frames in the order they go, and those that do not fit: CAN arbitration lets the
        lowest COB-ID win whenever the bus falls idle, so the frames go lowest COB-ID first and
        the first that would end past the budget is late with every frame after it (they go
        out after the next SYNC).
    """
    on_time, late = [], []
    for frame in sorted(frames, key=lambda f: f[0]):
        used_bits += frame_bits(frame[1])
        (on_time if used_bits <= budget_bits and not late else late).append(frame)
    return on_time, late


# ----------------------------------------------------------------------------------------------
# Moving frames in lock-step.

class LockstepVirtualBus(VirtualBus):
    """python-can's virtual bus made cheaper per frame, for the rig's hot path.

    * :meth:`VirtualBus.send` deep-copies the message for every receiver (about 4 us of the
      7 us a frame costs on this machine); a frame is immutable here, so one plain
      :class:`can.Message` shared by every receiver does.
    * The receive queue is a :class:`queue.SimpleQueue` (C, no condition variables) instead
      of a :class:`queue.Queue`; it has the same ``put``/``get`` calls the other virtual buses
      use on it.
    * A poll (``recv(timeout=0)``) on an empty queue returns at once.

    It joins the same channels as any other virtual bus in the process, so an ordinary
    ``can.Bus(interface="virtual", ...)`` talks to it. It relies on python-can 4's virtual bus
    internals (a channel is a list of receive queues, ``channels_lock``), and python-can is
    pinned below 5.
    """

    def __init__(self, channel="channel-0", receive_own_messages=False, **kwargs) -> None:
        super().__init__(channel=channel, receive_own_messages=receive_own_messages, **kwargs)
        with channels_lock:
            fast = queue.SimpleQueue()
            self.channel[self.channel.index(self.queue)] = fast
            self.queue = fast

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if timeout == 0 and self._filters is None:
            self._check_if_open()
            try:
                return self.queue.get_nowait()
            except queue.Empty:
                return None
        return super().recv(timeout)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        timestamp = msg.timestamp if self.preserve_timestamps else time.time()
        data = bytes(msg.data)

        def copy(is_rx: bool) -> can.Message:
            return can.Message(
                timestamp=timestamp, arbitration_id=msg.arbitration_id,
                is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                is_error_frame=msg.is_error_frame, dlc=msg.dlc, data=data,
                channel=self.channel_id, is_rx=is_rx, check=False)

        # Every other receiver gets the same received frame (nobody mutates one), so a frame to
        # n nodes builds one message, not n.
        received = None
        for bus_queue in self.channel:
            if bus_queue is self.queue:
                if self.receive_own_messages:
                    bus_queue.put(copy(False), block=True, timeout=timeout)
                continue
            if received is None:
                received = copy(True)
            bus_queue.put(received, block=True, timeout=timeout)



def open_virtual_bus(channel: str) -> can.BusABC:
    """A virtual bus on ``channel`` that keeps the senders' (simulated) timestamps."""
    return LockstepVirtualBus(channel=channel, receive_own_messages=False,
                              preserve_timestamps=True)


class SimNetwork(canopen.Network):
    """A canopen Network that stamps every frame it sends with a clock of its own.

    Parameters
    ----------
    bus : can.BusABC
        The bus to send on. No notifier thread is started: frames are fed to :meth:`notify`
        by whoever owns the network (see :func:`pump`).
    clock : callable
        Returns the timestamp [s] for a frame being sent (simulated or wall time).
    """

    def __init__(self, bus: can.BusABC, clock) -> None:
        super().__init__(bus)
        self.clock = clock

    def send_message(self, can_id: int, data, remote: bool = False) -> None:
        """Send one 11-bit frame stamped with ``clock()``."""
        msg = can.Message(arbitration_id=can_id, data=bytes(data), is_extended_id=False,
                          is_remote_frame=remote, timestamp=self.clock(), check=False)
        with self.send_lock:
            self.bus.send(msg)


def pump(bus: can.BusABC, network: canopen.Network) -> int:
    """Feed every frame waiting on ``bus`` to ``network.notify``, in order; return how many."""
    count = 0
    recv = bus.recv
    notify = network.notify
    while True:
        msg = recv(timeout=0)
        if msg is None:
            return count
        count += 1
        if not (msg.is_error_frame or msg.is_remote_frame):
            notify(msg.arbitration_id, msg.data, msg.timestamp)
