"""Where the drive-side cam sits on its axes: the coordinates of an ``MC_CamIn`` in integers.

PLCopen's ``MC_CamIn`` (Function Blocks for Motion Control, TC2, v2.0, 2011) couples a slave to a
master through a cam with a master and a slave offset and scaling, and places the cam absolutely or
relatively on each axis (``StartMode``; ``MC_CamTableSelect.MasterAbsolute`` / ``SlaveAbsolute``).
CODESYS SoftMotion writes the master side as ``X = MasterScaling * MasterPosition + MasterOffset``
("MC_CamIn.MasterOffset, MC_CamIn.MasterScaling"), Beckhoff the slave side as
``SlaveScaling * CAM(X) + SlaveOffset`` (``ST_CamScalingData``, tf5050_tc3_nc_camming/1003864075).
The controller-side path of the rig applies them in floating point (:class:`hil_sim.events._Piece`);
the drive keeps them in the integers a drive's interrupt can afford, written by SDO into 0x2001
and taken when a table is activated (with 0x2001:05):

* the table is looked up at ``X = round(N_m (master - zero) / D_m) + MasterOffset`` [table master
  counts], zero = 0 (master absolute) or the activation's master position (relative);
* the slave is ``base + SlaveOffset + round(N_s CAM(X) / D_s)`` [slave counts], base = 0 (slave
  absolute) or the running cam's position at the activation (relative).

**Scaling is a ratio of two UNSIGNED32**, numerator and denominator (0x2001:09/0A master,
0x2001:0B/0C slave), as CiA 402 gives its own ratios (0x6091 gear ratio, 0x6092 feed constant:
numerator and divisor sub-indices, CiA 402-2 / IEC 61800-7-201): every rational scaling (2/3, a
gearbox's 37/12) is exact, the product ``a N`` fits int64 for a master within 2^31 counts of its
zero, and the result is the same bits on every target. Rounding is half up, the rule of the
table's own lookup, taken from the floored quotient and its remainder (``q = floor(a N / D)``, plus
one where ``2 (a N - q D) >= D``): the textbook ``floor((2 a N + D) / 2 D)`` doubles the product
and overflows int64 for ``|a| >= 2^30`` with a numerator near 2^32. A ratio of 1 (N = D) takes the unscaled path, SwitchPair's
(:mod:`ecam.table_pair`) arithmetic exactly: ``X = master - (zero - MasterOffset)``, slave
``CAM(X) + SlaveOffset + base``.
"""

from __future__ import annotations

from dataclasses import dataclass

from fractions import Fraction

__all__ = ["Coupling", "round_ratio", "scaling_ratio"]

#: The largest term of a scaling ratio: UNSIGNED32.
MAX_RATIO_TERM = 2**32 - 1


def scaling_ratio(scaling: float) -> tuple[int, int]:
    """A positive scaling as (numerator, denominator), the nearest fraction whose terms fit
    UNSIGNED32 (exact for a float that is such a fraction: 0.5, 2, 1.25)."""
    fraction = Fraction(scaling)
    limit = MAX_RATIO_TERM if scaling <= 1.0 else max(1, int(MAX_RATIO_TERM / scaling))
    fraction = fraction.limit_denominator(limit)
    return fraction.numerator, fraction.denominator


def round_ratio(value: int, numerator: int, denominator: int) -> int:
    """``value x numerator / denominator`` rounded half up, in exact integers, every
    intermediate within int64 for ``|value| < 2^31`` and UNSIGNED32 terms (module docstring)."""
    quotient, remainder = divmod(value * numerator, denominator)  # floor; 0 <= remainder < D
    return quotient + (2 * remainder >= denominator)


@dataclass(frozen=True)
class Coupling:
    """One activation's coordinates (module docstring); the defaults are the identity.

    Attributes
    ----------
    zero : int
        Master position where the table's master 0 is before the offset [master counts].
    master_offset : int
        ``MasterOffset`` [table master counts].
    master_ratio : tuple of int
        ``MasterScaling`` as (numerator, denominator).
    base : int
        Slave position added [slave counts] (the running cam's, slave relative).
    slave_offset : int
        ``SlaveOffset`` [slave counts].
    slave_ratio : tuple of int
        ``SlaveScaling`` as (numerator, denominator).
    """

    zero: int = 0
    master_offset: int = 0
    master_ratio: tuple = (1, 1)
    base: int = 0
    slave_offset: int = 0
    slave_ratio: tuple = (1, 1)

    @property
    def origin(self) -> int:
        """The unscaled path's master origin: X = master - origin."""
        return self.zero - self.master_offset

    @property
    def slave_base(self) -> int:
        """What is added to the (scaled) cam: base + SlaveOffset."""
        return self.base + self.slave_offset

    @property
    def scaled(self) -> bool:
        """A master or slave ratio other than 1."""
        return self.master_ratio[0] != self.master_ratio[1] or self.slave_ratio[0] != self.slave_ratio[1]

    @property
    def velocity_ratio(self) -> float:
        """Slave scaling x master scaling: what the cam's slope is multiplied by."""
        return (self.master_ratio[0] * self.slave_ratio[0]) / (self.master_ratio[1] * self.slave_ratio[1])

    def x(self, master: int) -> int:
        """The table's master coordinate at ``master`` [counts]."""
        n, d = self.master_ratio
        if n == d:
            return master - self.origin
        return round_ratio(master - self.zero, n, d) + self.master_offset

    def master_at(self, x: int) -> int:
        """The master position [counts] where the table's coordinate is ``x`` (rounded)."""
        n, d = self.master_ratio
        if n == d:
            return x + self.origin
        return self.zero + round_ratio(x - self.master_offset, d, n)

    def y(self, position: int) -> int:
        """The slave [counts] for the table's position ``position`` [counts]."""
        n, d = self.slave_ratio
        if n == d:
            return position + self.slave_base
        return round_ratio(position, n, d) + self.slave_base
