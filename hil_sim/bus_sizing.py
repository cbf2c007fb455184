"""How much of a bus a machine needs: the bits of its cyclic frames per SYNC period with
worst-case bit stuffing (:func:`hil_sim.bus.frame_bits`), the cycle time and bit rate it needs
within a load limit, and how many more axes of each kind would fit.

The cyclic traffic of a SYNC period is the SYNC and, per axis, its set-point RPDOs and the
TPDOs its drive sends on every SYNC. For example one 6-byte RPDO and one 6-byte TPDO per axis
(115 bits each) and the SYNC (55 bits) at 80 % of a 1 Mbit/s bus carry 3 axes at 1 ms, 6 at
2 ms and 13 at 4 ms (issue 22's figures, derived from the same frame lengths).
"""

from __future__ import annotations

import math

import numpy as np

from hil_sim.bus import frame_bits

#: The CANopen bit rates (CiA 301, 7.2: bit timing; 10 kbit/s .. 1 Mbit/s) [bit/s].
STANDARD_BITRATES = (10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000)


#: Longest cycle of SYNC periods over which the frames' pattern repeats that the sizing lays out
#: (the least common multiple of the transmission types); beyond it every frame is taken to go
#: on the same SYNC (the unspread worst case).
MAX_PATTERN_SYNCS = 100_000


#: CiA 301 SDO: an expedited transfer carries up to 4 data bytes in its initiate request; a
#: segmented one 7 per segment; a block transfer's blocks hold up to 127 segments (blksize).
SDO_EXPEDITED_BYTES = 4
SDO_SEGMENT_BYTES = 7
SDO_BLOCK_SEGMENTS = 127
#: Every SDO frame carries 8 data bytes (CiA 301: unused bytes are sent, reserved).
SDO_FRAME_BYTES = 8


def sdo_download_frames(data_bytes: int, block: bool = False) -> int:
    """Frames on the bus, both ways, of one SDO download of ``data_bytes`` (CiA 301, as the
    canopen package's client sends it): expedited up to 4 bytes (request and response);
    segmented beyond (initiate request and response, then a request and a response per 7
    bytes); ``block``: initiate request and response, one frame per 7 bytes, the server's
    acknowledgement after each block of up to 127 segments, end request and response."""
    if data_bytes <= SDO_EXPEDITED_BYTES and not block:
        return 2
    segments = math.ceil(data_bytes / SDO_SEGMENT_BYTES)
    if block:
        return 2 + segments + math.ceil(segments / SDO_BLOCK_SEGMENTS) + 2
    return 2 + 2 * segments


def frame_timing(frame) -> tuple[int, int, int]:
    """``(data_length, every, phase)`` of a frame given as a data length (sent on every SYNC)
    or as ``(data_length, every, phase)``: on the SYNCs whose number modulo ``every`` is
    ``phase`` (:attr:`hil_sim.sync_schedule.TpdoTiming.phase`)."""
    if isinstance(frame, int):
        return frame, 1, 0
    length, every, phase = frame
    return int(length), int(every), int(phase) % int(every)


def axis_bits(data_lengths) -> int:
    """Bits one axis puts on the bus in a SYNC period where all its frames go: its frames'
    data lengths (or timings, :func:`frame_timing`)."""
    return sum(frame_bits(frame_timing(n)[0]) for n in data_lengths)


class _Pattern:
    """The bits of each SYNC period over one repetition of the frames' pattern."""

    def __init__(self, frames: list, fixed_bits: int) -> None:
        everys = {every for _, every, _ in frames}
        self.length = math.lcm(*everys) if everys else 1
        self.exact = self.length <= MAX_PATTERN_SYNCS
        self.slots = np.full(self.length if self.exact else 1, fixed_bits, dtype=np.int64)
        for frame in frames:
            self.add(frame)

    def add(self, frame) -> None:
        length, every, phase = frame
        if not self.exact:
            self.slots += frame_bits(length)
            return
        if self.length % every:  # a new period: lay the pattern out again, longer
            self.length = math.lcm(self.length, every)
            if self.length > MAX_PATTERN_SYNCS:
                self.exact = False
                self.slots = np.array([self.slots.max()], dtype=np.int64)
                self.add(frame)
                return
            self.slots = np.tile(self.slots, self.length // self.slots.size)
        self.slots[phase::every] += frame_bits(length)

    @property
    def peak(self) -> int:
        return int(self.slots.max())


def size_bus(axes: dict, bitrate: int, cycle_s: float, load_percent: float, *,
             shared=(), sync_counter: bool = False, max_axes: int = 127) -> dict:
    """The bus a machine needs and what would still fit.

    Parameters
    ----------
    axes : dict of str to list
        Each axis's name and its cyclic frames: a data length (on every SYNC) or ``(data_length,
        every, phase)`` (:func:`frame_timing`: a TPDO of transmission type ``every``).
    bitrate : int
        The bus's bit rate [bit/s].
    cycle_s : float
        The SYNC period [s].
    load_percent : float
        The load limit [% of the period's bits].
    shared : sequence
        Frames the machine sends once per SYNC for several axes (the master position every
        drive-side axis consumes), as in ``axes``: counted once.
    sync_counter : bool
        The SYNC carries the CiA 301 counter (0x1019 > 0): one data byte.
    max_axes : int
        At most this many axes on the bus (CiA 301: node ids 1..127).

    Returns
    -------
    dict
        ``bits_per_cycle`` (the busiest SYNC period's: the SYNC, the shared frames and every
        axis's frames that go on it), ``unspread_bits_per_cycle`` (without spreading: a SYNC
        without the counter, so every TPDO goes on the same SYNC, each n-th), ``mean_bits_per_cycle``,
        ``spread`` (whether the start values lower the peak), ``budget_bits`` (the limit's share
        of the period), ``load_percent`` and ``unspread_load_percent`` (shares of the period),
        ``fits``, ``min_cycle_s`` (at this bit rate), ``min_bitrate`` (at this period, and
        ``min_standard_bitrate``: the lowest CiA 301 rate that fits, None if none),
        ``axis_bits``, ``shared_bits``, and ``more_axes``: per axis, how many more axes like it
        fit (each further one's TPDOs started on the SYNC that keeps the peak lowest when the
        SYNC counter is on; 0 when none or over budget).
    """
    share = load_percent / 100.0
    timed = {name: [frame_timing(f) for f in frames] for name, frames in axes.items()}
    shared = [frame_timing(f) for f in shared]
    sync = frame_bits(1 if sync_counter else 0)
    fixed = sync + sum(frame_bits(length) for length, _, _ in shared)
    bits = {name: sum(frame_bits(length) for length, _, _ in frames)
            for name, frames in timed.items()}
    pattern = _Pattern([f for frames in timed.values() for f in frames], fixed)
    used = pattern.peak
    # without spreading: no counter in the SYNC, every TPDO on the n-th SYNC after OPERATIONAL
    unspread = fixed - sync + frame_bits(0) + sum(bits.values())
    mean = fixed + sum(frame_bits(length) / every for frames in timed.values()
                       for length, every, _ in frames)
    period_bits = bitrate * cycle_s
    budget = math.floor(period_bits * share + 1e-9)
    min_bitrate = used / (cycle_s * share) if share > 0 else math.inf
    standard = next((b for b in STANDARD_BITRATES if b >= min_bitrate - 1e-9), None)
    room = max(0, max_axes - len(axes))
    return {
        "bits_per_cycle": used,
        "unspread_bits_per_cycle": unspread,
        "mean_bits_per_cycle": mean,
        "spread": used < unspread,
        "budget_bits": budget,
        "load_percent": 100.0 * used / period_bits,
        "unspread_load_percent": 100.0 * unspread / period_bits,
        "limit_percent": load_percent,
        "fits": used <= budget,
        "min_cycle_s": used / (bitrate * share) if share > 0 else math.inf,
        "min_bitrate": min_bitrate,
        "min_standard_bitrate": standard,
        "axis_bits": bits,
        "shared_bits": sum(frame_bits(length) for length, _, _ in shared),
        "sync_bits": sync,
        "more_axes": {name: _more_axes(pattern, frames, budget, sync_counter, room)
                      for name, frames in timed.items()},
    }


def _more_axes(pattern: _Pattern, frames: list, budget: int, sync_counter: bool,
               room: int) -> int:
    """How many copies of an axis's frames still fit under ``budget``. With the SYNC counter
    each copy gets the SYNC start value that keeps the peak lowest, one for all its TPDOs (as
    ``[drive] tpdo_sync_start``): a frame of every n-th SYNC then goes on phase start mod n."""
    trial = _copy(pattern)
    cycle = math.lcm(*(every for _, every, _ in frames)) if frames else 1
    starts = range(cycle) if sync_counter and cycle > 1 else (None,)
    added = 0
    while added < room:
        best = None
        for start in starts:
            candidate = _copy(trial)
            for length, every, phase in frames:
                candidate.add((length, every, phase if start is None or every == 1
                               else start % every))
            if best is None or candidate.peak < best.peak:
                best = candidate
        if best.peak > budget:
            return added
        trial = best
        added += 1
    return added


def _copy(pattern: _Pattern) -> _Pattern:
    out = _Pattern([], 0)
    out.length, out.exact, out.slots = pattern.length, pattern.exact, pattern.slots.copy()
    return out


def spreading_text(sizing: dict) -> str:
    """The sizing's spreading and sharing in words ("" when the machine uses neither): the
    busiest SYNC period with and without spreading, and the shared master position."""
    parts = []
    if sizing["unspread_bits_per_cycle"] != sizing["bits_per_cycle"]:
        parts.append(f"busiest SYNC period {sizing['bits_per_cycle']} bits "
                     f"({sizing['load_percent']:.3g} %) with the TPDOs spread by the SYNC counter, "
                     f"{sizing['unspread_bits_per_cycle']} bits "
                     f"({sizing['unspread_load_percent']:.3g} %) without")
    if sizing["shared_bits"]:
        parts.append(f"the master position goes once for every drive-side axis "
                     f"({sizing['shared_bits']} bits per SYNC period)")
    return "; ".join(parts)
