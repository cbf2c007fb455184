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

from hil_sim.bus import frame_bits

#: The CANopen bit rates (CiA 301, 7.2: bit timing; 10 kbit/s .. 1 Mbit/s) [bit/s].
STANDARD_BITRATES = (10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000)


def axis_bits(data_lengths) -> int:
    """Bits one axis puts on the bus each SYNC period: its frames' ``data_lengths``."""
    return sum(frame_bits(n) for n in data_lengths)


def size_bus(axes: dict, bitrate: int, cycle_s: float, load_percent: float) -> dict:
    """The bus a machine needs and what would still fit.

    Parameters
    ----------
    axes : dict of str to list of int
        Each axis's name and the data lengths of its cyclic frames per SYNC period.
    bitrate : int
        The bus's bit rate [bit/s].
    cycle_s : float
        The SYNC period [s].
    load_percent : float
        The load limit [% of the period's bits].

    Returns
    -------
    dict
        ``bits_per_cycle`` (SYNC and every axis), ``budget_bits`` (the limit's share of the
        period), ``load_percent`` (the cyclic traffic's share of the period), ``fits``,
        ``min_cycle_s`` (at this bit rate), ``min_bitrate`` (at this period, and
        ``min_standard_bitrate``: the lowest CiA 301 rate that fits, None if none), and
        ``more_axes``: per axis, how many more axes like it fit (0 when none or over budget).
    """
    share = load_percent / 100.0
    bits = {name: axis_bits(lengths) for name, lengths in axes.items()}
    used = frame_bits(0) + sum(bits.values())
    period_bits = bitrate * cycle_s
    budget = math.floor(period_bits * share + 1e-9)
    min_bitrate = used / (cycle_s * share) if share > 0 else math.inf
    standard = next((b for b in STANDARD_BITRATES if b >= min_bitrate - 1e-9), None)
    return {
        "bits_per_cycle": used,
        "budget_bits": budget,
        "load_percent": 100.0 * used / period_bits,
        "limit_percent": load_percent,
        "fits": used <= budget,
        "min_cycle_s": used / (bitrate * share) if share > 0 else math.inf,
        "min_bitrate": min_bitrate,
        "min_standard_bitrate": standard,
        "axis_bits": bits,
        "more_axes": {name: max(0, (budget - used) // b) if b else None
                      for name, b in bits.items()},
    }
