"""Which SYNC a synchronous TPDO goes out on (CiA 301), as arithmetic: the rig's bus-free path
samples what a controller would receive with it, and the bus sizing spreads the load with it.
No CAN stack here.

CiA 301 v4.2.0 7.5.2.37 (TPDO communication parameter 1800h..19FFh): transmission type n
(1..240) sends the TPDO on every n-th SYNC; 7.5.2.22 (1019h, synchronous counter overflow
value): 0, the SYNC has no data; 2..240, it carries a one-byte counter, 1 on the first SYNC and
back to 1 after the overflow value; sub-index 06h of the TPDO communication parameter (SYNC
start value, 0..240): with the counter on and a start value s > 0, the SYNC whose counter is s
counts as the first one, so the first transmission is on it. Without either the first goes on
the n-th SYNC after the node entered OPERATIONAL (CANopenNode's CO_TPDO_process does the same).
In the rig every drive is OPERATIONAL before the first SYNC of the run, whose counter is 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: How a machine sends its drive-side axes' master position: one RPDO per axis, or one PDO on one
#: COB-ID that every drive-side drive consumes (CiA 301 lets any number of RPDOs consume a COB-ID).
MASTER_POSITION_PDOS = ("per_axis", "shared")
#: CiA 301 7.5.2.37: transmission types 1..240 are synchronous and cyclic.
MAX_TRANSMISSION_TYPE = 240
#: CiA 301 7.5.2.22: the counter runs up to 2..240 (1 and 241..255 are reserved).
MAX_SYNC_COUNTER_OVERFLOW = 240


@dataclass(frozen=True)
class TpdoTiming:
    """When a drive's synchronous TPDOs go out.

    Attributes
    ----------
    every : int
        The transmission type n, 1..240: every n-th SYNC.
    start : int
        The SYNC start value, 0..240 (0: not used).
    overflow : int
        The SYNC counter overflow value 0x1019 of the network, 0 or 2..240 (0: no counter).
    """

    every: int = 1
    start: int = 0
    overflow: int = 0

    @classmethod
    def of(cls, scene) -> "TpdoTiming":
        """A scene's (``drive.tpdo_transmission_type``, ``drive.tpdo_sync_start``,
        ``bus.sync_counter_overflow``)."""
        return cls(scene.drive.tpdo_transmission_type, scene.drive.tpdo_sync_start,
                   scene.bus.sync_counter_overflow)

    @property
    def every_sync(self) -> bool:
        """On every SYNC from the first (type 1 without a start value)."""
        return self.first_sync == 1 and self.every == 1

    @property
    def uses_start(self) -> bool:
        """The start value is in force (CiA 301 ignores it without the counter)."""
        return bool(self.overflow and self.start)

    @property
    def phase(self) -> int:
        """The SYNC numbers (1 = the first) it goes on are ``phase`` modulo ``every``."""
        return self.start % self.every if self.uses_start else 0

    @property
    def first_sync(self) -> int:
        """The number of the first SYNC it goes on (1 = the run's first)."""
        return self.start if self.uses_start else self.every

    def cycles(self, count: int) -> np.ndarray:
        """A mask over the run's cycles ``0..count-1`` (cycle k runs on SYNC k + 1): True where
        the TPDO goes out."""
        sync = np.arange(1, count + 1)
        first = self.first_sync
        return (sync >= first) & ((sync - first) % self.every == 0)


def check_sync_start(top, drive, bus) -> None:
    """A scene's ``drive.tpdo_sync_start`` against its ``bus.sync_counter_overflow``: a start
    value needs the counter (CiA 301 ignores it without one: the user meant to spread and would
    not) and no more than the overflow value (the counter never reaches a larger one, so the
    TPDOs would never go). ``top`` is the scene's :class:`ecam.validate.Fields`."""
    start, overflow = drive.tpdo_sync_start, bus.sync_counter_overflow
    if start and not overflow:
        raise top.error(f"drive.tpdo_sync_start: {start} should be 0 without a SYNC counter "
                        "(give bus.sync_counter_overflow 2..240: CiA 301 ignores the start value "
                        "without it)")
    if start > overflow:
        raise top.error(f"drive.tpdo_sync_start: {start} should be <= bus.sync_counter_overflow "
                        f"({overflow}): the SYNC counter never reaches it")
