"""INTEGER32 (CiA 301 data type 0x0004), the type of the positions and velocities on the bus.

A position wraps like a modular counter (two's complement): a CiA 402 drive's position actual
value 0x6064 and target 0x607A roll over from 2^31 - 1 to -2^31, and the difference of two
wrapped positions, wrapped again, is the true step as long as it is below 2^31 counts. A
velocity that leaves its type has no meaningful wrap (a sign flip would command full speed
backwards): it saturates.

One module for the drive, the controller and the rig, scalars and numpy arrays alike; it
imports nothing of the rig, so every layer of it can use it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["INT32_MIN", "INT32_MAX", "wrap_int32", "saturate_int32", "wrap_int32_array",
           "saturate_int32_array"]

INT32_MIN = -(1 << 31)
INT32_MAX = (1 << 31) - 1
_SPAN = 1 << 32


def wrap_int32(value: int) -> int:
    """Two's complement wrap of an integer to INTEGER32 (a position on the bus)."""
    return (value - INT32_MIN) % _SPAN + INT32_MIN


def saturate_int32(value: int) -> int:
    """Clamp an integer to INTEGER32 (a velocity on the bus, e.g. 0x60B1 velocity offset)."""
    return max(INT32_MIN, min(INT32_MAX, value))


def wrap_int32_array(values) -> np.ndarray:
    """:func:`wrap_int32` of every element, as int64 (exact for int64 inputs within
    ``2^63 - 2^31``, which positions in counts are)."""
    return (np.asarray(values, dtype=np.int64) - INT32_MIN) % _SPAN + INT32_MIN


def saturate_int32_array(values) -> np.ndarray:
    """:func:`saturate_int32` of every element, as int64; whole-valued floats (``numpy.rint``
    of a velocity) are clamped first, so values past int64 saturate too."""
    return np.clip(values, INT32_MIN, INT32_MAX).astype(np.int64)
