"""Which master counts put a cam's joints on table points.

A joint where a derivative jumps costs accuracy unless it is a table point (the interpolant
smears the corner over the interval around it). A table's points sit every ``step`` counts of a
period of ``master_counts``, so a joint at master position ``x`` of a period ``P`` is a point when
``x / P * master_counts`` is a whole multiple of the step. This module finds the master counts
nearest the ones asked for that put every joint on a whole count, and the table sizes that then
put them on points: what ``ecam compile`` suggests when it lists joints off the points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from .table import MAX_MASTER_COUNTS

__all__ = ["JointGrid", "joint_grid"]

# Joint positions are user numbers (15.0, 61.875 deg): their share of the period is read as the
# nearest fraction with a denominator up to this; a joint that is no such fraction gets no hint.
MAX_DENOMINATOR = 10**6


@dataclass(frozen=True)
class JointGrid:
    """Master counts that put every joint on a whole count, and the tables that put them on points.

    Attributes
    ----------
    master_counts : int
        The master period in counts: the multiple of ``multiple`` nearest the counts asked for.
    multiple : int
        Every master count that is a multiple of this puts every joint on a whole count.
    smallest_points : int
        The smallest table with every joint on a point at ``master_counts``; any table of
        ``k * (smallest_points - 1) + 1`` points (``k`` dividing ``master_counts / (smallest_points - 1)``)
        has them on points too.
    """

    master_counts: int
    multiple: int
    smallest_points: int


def joint_grid(master_period: float, joints, master_counts: int) -> JointGrid | None:
    """The joint grid nearest ``master_counts``, or None when no master count up to 2^31 has it.

    Parameters
    ----------
    master_period : float
        The cam's period [master units].
    joints : iterable of float
        Master positions of the joints to put on points [master units].
    master_counts : int
        The master counts asked for.
    """
    shares = []
    for joint in joints:
        share = Fraction(float(joint) / float(master_period)).limit_denominator(MAX_DENOMINATOR) % 1
        # A few ulp: a decimal joint (15.0, 61.875) over a decimal period gives its fraction to
        # the last bit; an irrational share's best fraction stays far above that.
        if abs(float(share) - (float(joint) / float(master_period)) % 1) > 1e-15:
            return None
        shares.append(share)
    if not shares:
        return None
    multiple = math.lcm(*(share.denominator for share in shares))
    if multiple > MAX_MASTER_COUNTS:
        return None
    counts = max(multiple, min(MAX_MASTER_COUNTS // multiple * multiple,
                               round(master_counts / multiple) * multiple))
    step = math.gcd(counts, *(int(share * counts) for share in shares))
    return JointGrid(master_counts=counts, multiple=multiple, smallest_points=counts // step + 1)
