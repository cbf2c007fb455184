"""Bus timing and fault injection for the lock-step rig.

The python-can ``virtual`` interface delivers every frame at once and in order: it has no
bitrate. This module puts the timing back as bookkeeping, and the faults as a plan.

* :func:`frame_bits` is the worst-case length of one CAN 2.0A data frame on the wire.
* :class:`BusLoad` adds up the bits of every frame sent in a bus cycle and flags the cycles
  whose frames do not fit into ``bitrate * cycle_s`` bits.
* :class:`FaultInjector` decides, frame by frame, whether a frame is delivered, dropped or
  delayed by whole cycles, and draws the SYNC jitter, from one seeded
  ``numpy.random.default_rng``: the same seed and the same frame sequence give the same faults.

And how frames move in lock-step: :func:`open_virtual_bus` (python-can's virtual interface,
keeping simulated timestamps), :class:`SimNetwork` (a canopen Network without a notifier
thread, stamping frames with a clock of its own) and :func:`pump` (hand every waiting frame to
``network.notify`` at a point the caller chooses).
"""

from __future__ import annotations

import math
import queue
import time
from dataclasses import dataclass, field

import can
import canopen
import numpy as np
from can.interfaces.virtual import VirtualBus, channels_lock

from ecam.validate import choice, fail, integer, number, plain, positive

#: Bits of an 11-bit-identifier data frame outside the data field, before stuffing:
#: SOF 1, identifier 11, RTR 1, IDE 1, r0 1, DLC 4, CRC 15, CRC delimiter 1, ACK slot 1,
#: ACK delimiter 1, EOF 7, plus the 3-bit intermission before the next frame.
FRAME_OVERHEAD_BITS = 47
#: Bits exposed to bit stuffing without the data field: SOF through the CRC sequence
#: (1 + 11 + 1 + 1 + 1 + 4 + 15).
STUFFED_OVERHEAD_BITS = 34

#: Frame kinds the fault injector knows (SYNC, PDOs from the controller, PDOs from the drive).
FRAME_KINDS = ("sync", "rpdo", "tpdo")
#: Largest SYNC jitter a fault plan may ask for [s]: a tenth of a second, far beyond any bus
#: cycle (at most 0.255 s, the 0x60C2 format), so every draw stays a small offset.
MAX_SYNC_JITTER_S = 0.1


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

    def add_frame(self, data_length: int) -> None:
        """Count one frame of ``data_length`` bytes in the current cycle."""
        self._cycle_bits += self._bits_by_length[data_length]
        self._cycle_frames += 1

    def end_cycle(self) -> None:
        """Close the current cycle."""
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
        }


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


@dataclass(frozen=True)
class Faults:
    """What goes wrong on the bus, reproducibly.

    Parameters
    ----------
    seed : int
        Seed of ``numpy.random.default_rng``; same seed, same faults.
    kinds : tuple of str
        Frame kinds the random drops and delays apply to, from ``("sync", "rpdo", "tpdo")``.
    drop_probability : float
        Probability that a frame of those kinds is lost, 0..1.
    drop : tuple of (int, str)
        Frames always lost: (cycle, kind) pairs.
    delay_probability : float
        Probability that a frame of those kinds (SYNC excepted) arrives whole cycles late.
    delay_cycles : int
        A delayed frame arrives 1..delay_cycles cycles late (uniform), >= 1.
    sync_jitter_s : float
        The controller's SYNC instants move by a uniform draw in [-jitter, +jitter] [s],
        0..MAX_SYNC_JITTER_S; the set points it sends are sampled at the jittered instant.

    Raises
    ------
    InputError
        A value out of range; the message names the parameter (``drop[1].frame``), the value
        and what was expected.
    """

    seed: int = 0
    kinds: tuple[str, ...] = ("rpdo", "tpdo")
    drop_probability: float = 0.0
    drop: tuple[tuple[int, str], ...] = ()
    delay_probability: float = 0.0
    delay_cycles: int = 1
    sync_jitter_s: float = 0.0

    def __post_init__(self) -> None:
        def store(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        store("seed", integer("seed", plain(self.seed), minimum=0))
        kinds = _sequence("kinds", self.kinds, f"a list of {', '.join(FRAME_KINDS)}")
        store("kinds", tuple(choice(f"kinds[{i}]", kind, FRAME_KINDS)
                             for i, kind in enumerate(kinds)))
        for name in ("drop_probability", "delay_probability"):
            store(name, number(name, plain(getattr(self, name)), minimum=0.0, maximum=1.0))
        drops = []
        for i, entry in enumerate(_sequence("drop", self.drop, "a list of (cycle, frame) pairs")):
            if not isinstance(entry, tuple) or len(entry) != 2:
                raise fail(f"drop[{i}]", entry, f"a pair (cycle >= 0, frame: one of "
                           f"{', '.join(FRAME_KINDS)})")
            drops.append((integer(f"drop[{i}].cycle", plain(entry[0]), minimum=0),
                          choice(f"drop[{i}].frame", entry[1], FRAME_KINDS)))
        store("drop", tuple(drops))
        store("delay_cycles", integer("delay_cycles", plain(self.delay_cycles), minimum=1))
        store("sync_jitter_s", number("sync_jitter_s", plain(self.sync_jitter_s), minimum=0.0,
                                      maximum=MAX_SYNC_JITTER_S))

    @property
    def active(self) -> bool:
        """True if any fault is configured."""
        return bool(self.drop_probability or self.drop or self.delay_probability or self.sync_jitter_s)


def _sequence(field: str, value, expected: str) -> tuple:
    """A tuple or list as a tuple (a string is refused: it is no list of names)."""
    if not isinstance(value, (tuple, list)):
        raise fail(field, value, expected)
    return tuple(value)


#: What :meth:`FaultInjector.decide` returns for a frame delivered on time.
DELIVER = 0
#: What :meth:`FaultInjector.decide` returns for a lost frame; a positive value is a delay in cycles.
DROP = -1


@dataclass
class FaultInjector:
    """Applies a :class:`Faults` plan frame by frame.

    The random draws happen in the order the rig asks, which is fixed by the scene (the rig is
    lock-step), so a run is reproducible. Counters of what was done are kept for the report.
    """

    faults: Faults
    cycle_s: float
    dropped: dict = field(default_factory=lambda: {kind: 0 for kind in FRAME_KINDS})
    delayed: dict = field(default_factory=lambda: {kind: 0 for kind in FRAME_KINDS})

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.faults.seed)
        self._explicit = set(self.faults.drop)
        self._random_kinds = frozenset(self.faults.kinds)

    def sync_offsets(self, cycles: int) -> np.ndarray:
        """SYNC jitter of ``cycles`` cycles [s] (zeros when none is configured).

        Drawn once, up front, from a generator of its own (seeded from the plan's seed), so the
        jitter does not depend on how many frame decisions came before.
        """
        jitter = self.faults.sync_jitter_s
        if not jitter:
            return np.zeros(cycles)
        rng = np.random.default_rng([self.faults.seed, 1])
        return rng.uniform(-jitter, jitter, cycles)

    def decide(self, cycle: int, kind: str) -> int:
        """Fate of one frame: :data:`DELIVER`, :data:`DROP`, or a delay in whole cycles (> 0)."""
        faults = self.faults
        if (cycle, kind) in self._explicit:
            self.dropped[kind] += 1
            return DROP
        if kind not in self._random_kinds:
            return DELIVER
        if faults.drop_probability and self._rng.random() < faults.drop_probability:
            self.dropped[kind] += 1
            return DROP
        if kind != "sync" and faults.delay_probability and self._rng.random() < faults.delay_probability:
            self.delayed[kind] += 1
            return int(self._rng.integers(1, faults.delay_cycles + 1))
        return DELIVER

    def summary(self) -> dict:
        """Counts of dropped and delayed frames by kind."""
        return {"dropped": dict(self.dropped), "delayed": dict(self.delayed),
                "sync_jitter_s": self.faults.sync_jitter_s, "seed": self.faults.seed}


# ----------------------------------------------------------------------------------------------
# Moving frames in lock-step.

class LockstepVirtualBus(VirtualBus):
    """python-can's virtual bus made cheaper per frame, for the rig's hot path.

    * :meth:`VirtualBus.send` deep-copies the message for every receiver (about 4 us of the
      7 us a frame costs on this machine); a frame is immutable here, so one plain
      :class:`can.Message` per receiver does.
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
        for bus_queue in self.channel:
            if bus_queue is self.queue and not self.receive_own_messages:
                continue
            bus_queue.put(can.Message(
                timestamp=timestamp, arbitration_id=msg.arbitration_id,
                is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                is_error_frame=msg.is_error_frame, dlc=msg.dlc, data=data,
                channel=self.channel_id, is_rx=bus_queue is not self.queue, check=False),
                block=True, timeout=timeout)



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
