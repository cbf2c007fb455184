"""What table to compile: a :class:`TableSpec`, validated once, whoever wrote it (the Python API,
a cam file's ``[table]``, a scene's ``[cam]``, the command line)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .errors import InputError
from .table import INTERPOLATIONS, MAX_MASTER_COUNTS

__all__ = ["TableSpec", "parse_tolerance", "HORNER_BITS", "MAX_POINTS", "MIN_COUNTS_PER_UNIT", "MAX_COUNTS_PER_UNIT"]

MAX_POINTS = 2**22 + 1
# Counts per slave unit: below a micro-count per unit no table position is meaningful; above 1e12
# (a picometre per count on a metre axis) no encoder exists and int32 positions could not hold a
# millimetre of stroke.
MIN_COUNTS_PER_UNIT = 1e-6
MAX_COUNTS_PER_UNIT = 1e12
DEFAULT_INTERP = "cubic"
DEFAULT_MASTER_COUNTS = 2**16
DEFAULT_COUNTS_PER_UNIT = 1000.0
HORNER_BITS = (64, 32)


_COUNT_WORDS = ("counts", "count", "lsb")


def parse_tolerance(tolerance, field: str = "tolerance", slave_unit: str | None = None) -> tuple[float, bool]:
    """A tolerance as (value, in_counts).

    A number is in slave units; a string is a number and an optional unit: ``"2 counts"`` (also
    ``count``, ``lsb``), ``"0.001"`` or ``"0.001 deg"`` when ``deg`` is the cam's slave unit.
    Without ``slave_unit`` any unit word is accepted here and checked when the cam is known.
    """
    value, in_counts = tolerance, False
    if isinstance(tolerance, str):
        number, _, unit = tolerance.strip().partition(" ")
        unit = unit.strip()
        in_counts = unit.lower() in _COUNT_WORDS
        try:
            value = float(number)
        except ValueError:
            value = None
        if unit and not in_counts and slave_unit is not None and unit != slave_unit:
            raise validate.fail(field, tolerance, f"in the cam's slave unit ({slave_unit}) or in counts")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
        raise validate.fail(field, tolerance, "a number > 0 in slave units or a string like '2 counts' or "
                            "'0.01 mm' (the cam's slave unit)")
    if value > validate.MAX_MAGNITUDE:  # in counts (x slave_counts_per_unit <= 1e12) it must stay finite
        raise validate.fail(field, tolerance, f"at most {validate.MAX_MAGNITUDE:g}")
    return float(value), in_counts


def _plain_int(value):
    return int(value) if isinstance(value, np.integer) else value


@dataclass(frozen=True)
class TableSpec:
    """The settings of one table.

    Attributes
    ----------
    interp : {'linear', 'cubic', 'quintic', 'auto'}
        Interpolation kind; ``auto`` picks the kind and size that meet ``tolerance`` in the fewest
        bytes.
    points : int or None
        Stored points (intervals + 1), 2..MAX_POINTS; ``points - 1`` must divide ``master_counts``.
    tolerance : float, str or None
        Largest allowed error: slave units, or a string such as ``"2 counts"``. Exactly one of
        ``points`` and ``tolerance`` is given.
    master_counts : int
        Master period in encoder counts, 2..2^31.
    slave_counts_per_unit : float
        Slave counts per slave unit, 1e-6..1e12.
    horner_bits : {64, 32}
        64 (default): the finest fixed-point format int64 allows. 32: the finest whose expanded
        form (``ecam_poly_init``, FORMAT.md "Expanded form") keeps every Horner value inside
        32-bit words, so that ``ecam_poly_position`` runs its narrow kernels (one 32x32 multiply
        per degree: the cheapest lookup on 32-bit cores); it has fewer work bits, and the
        certificate says what that costs, which grows with the stroke in counts (FORMAT.md).
    interpolation_tolerance : float, str or None
        With ``tolerance``: the largest error the table may add to the final rounding's 1/2
        count (interpolation, stored data, arithmetic): slave units or a string such as ``"0.05
        counts"``. The certified bound then meets both: it is at most ``tolerance`` and at most
        1/2 count + ``interpolation_tolerance``. None (default): the tolerance alone sizes the
        table, and the interpolation may take all of it above the 1/2 count (see
        docs/table_formats.md, "One count on a 26-bit drum").
    """

    interp: str = DEFAULT_INTERP
    points: int | None = None
    tolerance: float | str | None = None
    master_counts: int = DEFAULT_MASTER_COUNTS
    slave_counts_per_unit: float = DEFAULT_COUNTS_PER_UNIT
    horner_bits: int = 64
    interpolation_tolerance: float | str | None = None

    def __post_init__(self):
        validate.choice("interp", self.interp, INTERPOLATIONS)
        if isinstance(self.horner_bits, bool) or _plain_int(self.horner_bits) not in HORNER_BITS:
            raise validate.fail("horner_bits", self.horner_bits, "64 or 32")
        object.__setattr__(self, "horner_bits", int(self.horner_bits))
        object.__setattr__(self, "master_counts", validate.integer(
            "master_counts", _plain_int(self.master_counts), minimum=2, maximum=MAX_MASTER_COUNTS))
        object.__setattr__(self, "slave_counts_per_unit", validate.number(
            "slave_counts_per_unit", self.slave_counts_per_unit, minimum=MIN_COUNTS_PER_UNIT,
            maximum=MAX_COUNTS_PER_UNIT))
        if self.points is not None and self.tolerance is not None:
            raise validate.fail("points", _plain_int(self.points),
                                "absent when a tolerance is given: give either points or tolerance, not both")
        if self.points is None and self.tolerance is None:
            raise InputError("points and tolerance are both missing: give one (--points / --tolerance, "
                             "or points / tolerance in the cam file's [table])")
        if self.points is not None:
            object.__setattr__(self, "points", validate.integer(
                "points", _plain_int(self.points), minimum=2, maximum=MAX_POINTS))
        else:
            parse_tolerance(self.tolerance)
        if self.interp == "auto" and self.tolerance is None:
            raise validate.fail("interp", self.interp, "given a tolerance, not points (it picks the point count)")
        if self.interpolation_tolerance is not None:
            if self.tolerance is None:
                raise validate.fail("interpolation_tolerance", self.interpolation_tolerance,
                                    "absent when points are given: it sizes the table with the tolerance")
            parse_tolerance(self.interpolation_tolerance, "interpolation_tolerance")

    def tolerance_counts(self, slave_unit: str | None = None) -> float | None:
        """The tolerance in slave counts (None for a table of fixed size); ``slave_unit`` checks
        a tolerance written with a unit word, such as ``"0.001 deg"``."""
        if self.tolerance is None:
            return None
        value, in_counts = parse_tolerance(self.tolerance, slave_unit=slave_unit)
        return value if in_counts else value * self.slave_counts_per_unit

    def interpolation_tolerance_counts(self, slave_unit: str | None = None) -> float | None:
        """The interpolation tolerance in slave counts (None when not given), as
        :meth:`tolerance_counts`."""
        if self.interpolation_tolerance is None:
            return None
        value, in_counts = parse_tolerance(self.interpolation_tolerance, "interpolation_tolerance",
                                           slave_unit=slave_unit)
        return value if in_counts else value * self.slave_counts_per_unit

    @classmethod
    def resolve(cls, defaults: Mapping, *, interp=None, points=None, tolerance=None, master_counts=None,
                slave_counts_per_unit=None, horner_bits=None, interpolation_tolerance=None) -> "TableSpec":
        """The spec from explicit settings over ``defaults`` (a cam file's ``[table]``).

        Points and tolerance travel together: giving either one replaces both of the defaults',
        and the defaults' ``interpolation_tolerance`` with them (it refines the defaults'
        tolerance; give it again with an explicit tolerance).
        A default ``interp = "auto"`` with explicit ``points`` becomes ``cubic``, since ``auto``
        chooses the size that explicit points fix.
        """
        if interp is None:
            interp = defaults.get("interp", DEFAULT_INTERP)
            if interp == "auto" and points is not None:
                interp = DEFAULT_INTERP
        if points is None and tolerance is None:
            points, tolerance = defaults.get("points"), defaults.get("tolerance")
            if interpolation_tolerance is None:
                interpolation_tolerance = defaults.get("interpolation_tolerance")
        return cls(
            interp=interp, points=points, tolerance=tolerance,
            master_counts=defaults.get("master_counts", DEFAULT_MASTER_COUNTS) if master_counts is None
            else master_counts,
            slave_counts_per_unit=defaults.get("slave_counts_per_unit", DEFAULT_COUNTS_PER_UNIT)
            if slave_counts_per_unit is None else slave_counts_per_unit,
            horner_bits=defaults.get("horner_bits", 64) if horner_bits is None else horner_bits,
            interpolation_tolerance=interpolation_tolerance,
        )
