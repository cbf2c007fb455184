"""The cam-table compiler: CamProfile + format -> CamTable with a certified error.

Steps: sample the profile's position and derivatives at the table points (the average of the
two one-sided values where a derivative jumps), choose fixed-point shifts as fine as the int64
budget allows (proving no intermediate can overflow), then certify: predict the error from the
profile's derivatives and measure the integer lookup against the analytic profile.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace
from fractions import Fraction

import numpy as np

from .certificate import FINAL_ROUNDING_COUNTS, Certificate, Measurement
from .errors import InputError, TableFormatError
from .profile import CamProfile
from .table import (
    HEADER_BYTES, KINDS, MAX_NET_DENOMINATOR, MAX_RAMP, MAX_STEP_COUNTS, MAX_WORK_BITS, SLOPE_BITS, CamTable,
    TableFormat, divisors, narrow_horner, overflow_proof,
)
from .table_spec import MAX_POINTS, TableSpec, parse_tolerance

__all__ = ["compile_table", "MAX_POINTS", "TableSpec", "candidate_intervals", "parse_tolerance",
           "net_stroke_fraction"]

DENSE_LIMIT = 2**22  # certify on every master count up to this period
# A net-stroke table is also measured across the seam of these periods (and the one before each),
# and at the first and last period whose masters and positions fit int64.
WRAP_PERIODS = (1, 2, 10**6, 10**9)
WRAP_WINDOW = 4096  # master counts either side of each seam
WRAP_SPREAD = 1024  # and this many spread over the period
_INT32_MAX = 2**31 - 1
# A net stroke whose stored positions would keep fewer fraction bits than this (their rounding above
# 2^-11 counts) is stored relative to its ramp (format version 3; FORMAT.md step 8).
RAMP_BELOW_BITS = 10
_INT64_LIMIT = 2.0**63 * (1 - 1e-9)  # float bounds carry a relative margin
# max over tau of |f - p| = h^(n+1) * max|f^(n+1)| * _ERROR_CONSTANT[n]
_ERROR_CONSTANT = {1: 1 / 8, 3: 1 / 384, 5: 1 / 46080}


def compile_table(
    profile: CamProfile,
    spec: TableSpec | None = None,
    *,
    interp: str | None = None,
    points: int | None = None,
    tolerance=None,
    master_counts: int | None = None,
    slave_counts_per_unit: float | None = None,
    horner_bits: int | None = None,
    interpolation_tolerance=None,
    certify: bool = True,
    progress=None,
) -> CamTable:
    """Compile a profile into a fixed-point table with a certified error.

    Parameters
    ----------
    profile : CamProfile
    spec : TableSpec, optional
        All table settings at once; or give them one by one below (the cam file's ``[table]``
        fills in what is not given, see :meth:`TableSpec.resolve`).
    interp : {'linear', 'cubic', 'quintic', 'auto'}
        Interpolation kind; 'auto' picks the kind and point count that meet ``tolerance`` with the
        fewest bytes. Default: the cam file's ``[table]`` setting, else 'cubic'.
    points : int, optional
        Stored points (intervals + 1); ``points - 1`` must divide ``master_counts``.
    tolerance : float or str, optional
        Largest allowed error: a number in slave units, or a string like ``"2 counts"``.
    interpolation_tolerance : float or str, optional
        With ``tolerance``: the largest error the table may add to the final rounding's 1/2 count
        (same forms), so that the measured error stays near the 1/2 count; default: none (the
        tolerance alone sizes the table). See :class:`TableSpec`.
    master_counts : int
        Master period in encoder counts, 2..2^31.
    slave_counts_per_unit : float
        Slave counts per slave user unit; every table position must fit int32.
    horner_bits : {64, 32}, optional
        32: the finest format whose expanded form runs in 32-bit words (see
        :class:`TableSpec`); default 64.
    certify : bool
        Measure the error of the integer lookup (default). Without it the report has the
        prediction only.
    progress : callable, optional
        ``progress(done, total)`` during certification.

    Returns
    -------
    CamTable
        With ``table.certificate`` (:class:`ecam.Certificate`) and ``table.report``, the
        certificate as the documented dictionary (see the README).

    Raises
    ------
    InputError, TableFormatError
        One line naming the field, the value and the limit.
    """
    if not isinstance(profile, CamProfile):
        raise InputError(f"profile {type(profile).__name__} should be a CamProfile (see ecam.load_cam)")
    overrides = dict(interp=interp, points=points, tolerance=tolerance, master_counts=master_counts,
                     slave_counts_per_unit=slave_counts_per_unit, horner_bits=horner_bits,
                     interpolation_tolerance=interpolation_tolerance)
    if spec is None:
        spec = TableSpec.resolve(profile.table, **overrides)
    elif any(value is not None for value in overrides.values()):
        given = ", ".join(k for k, v in overrides.items() if v is not None)
        raise InputError(f"spec and {given}: give the settings either in the TableSpec or as arguments")
    elif not isinstance(spec, TableSpec):
        raise InputError(f"spec {type(spec).__name__} should be an ecam.TableSpec")
    master_counts, scale = spec.master_counts, spec.slave_counts_per_unit
    low, high = profile.slave_range
    for value in (low, high):
        if abs(value * scale) > _INT32_MAX - 1:
            raise InputError(
                f"slave position {value:g} {profile.slave_unit} x slave_counts_per_unit {scale:g} = "
                f"{value * scale:.6g} counts overflows int32 (limit {_INT32_MAX})"
            )
    job = _Job(profile, master_counts, scale, narrow=spec.horner_bits == 32)
    if abs(job.net) >= 2**31:
        raise InputError(f"net stroke {profile.net_stroke:+g} {profile.slave_unit} x slave_counts_per_unit {scale:g} "
                         f"= {float(job.net):.6g} counts per period should be below 2^31 counts")
    if spec.points is not None:
        points = spec.points
        intervals = points - 1
        if master_counts % intervals:
            better = min(divisors(master_counts), key=lambda d: (abs(d - intervals), d))
            raise InputError(
                f"points {points} gives {intervals} intervals, which do not divide master_counts "
                f"{master_counts}; use points = k + 1 for a divisor k of {master_counts}, e.g. {better + 1}"
            )
        return job.build(KINDS[spec.interp], intervals, certify=certify, progress=progress)
    kinds = list(KINDS.values()) if spec.interp == "auto" else [KINDS[spec.interp]]
    return job.search(kinds, spec.tolerance_counts(profile.slave_unit),
                      spec.interpolation_tolerance_counts(profile.slave_unit), certify=certify, progress=progress)


def net_stroke_fraction(net_stroke: float, slave_counts_per_unit: float) -> tuple[Fraction, float]:
    """The net stroke per period in slave counts as the table stores it: a fraction N/D, D < 2^32.

    The cam's net stroke in counts is taken as the two numbers are written (their shortest
    decimal forms: 360.0 deg x 1000.0001 counts/deg = 360000.036 = 90000009/250 exactly), except
    where that product is float rounding away from a much simpler fraction: both numbers are
    float64, each within 2^-52 (relative) of the value meant, so a fraction within 2^-50 of the
    product whose denominator is far below what a coincidence gives (at most 2^-10 / sqrt of
    that distance; an integer always qualifies) is the value meant, and is stored. So a drum of
    2^26 counts per revolution written as 360 deg x 186413.51111111112 counts/deg (2^26 / 360 in
    float64, whose decimal product is 67108864.0000000032) stores 67108864/1, whose rounding adds
    nothing to a lookup, rather than 20971520000000001/312500000, whose rounding of k N/D adds
    up to half a count. Otherwise, when the decimal product's denominator is below 2^32 it is
    stored as is, and the lookup never drifts from it; else the closest fraction with such a
    denominator is stored (0.3333333333333333 becomes 1/3). The difference from the decimal
    product is the residual (second value, counts per period) that the certificate reports.
    """
    exact = Fraction(repr(float(net_stroke))) * Fraction(repr(float(slave_counts_per_unit)))
    width = abs(exact) * Fraction(1, 2**50)
    if width:
        simple = _simplest_between(exact - width, exact + width)
        if simple.denominator <= max(1.0, 2.0**-10 / math.sqrt(width)) and simple.denominator <= MAX_NET_DENOMINATOR:
            return simple, float(abs(simple - exact))
    stored = exact if exact.denominator <= MAX_NET_DENOMINATOR else exact.limit_denominator(MAX_NET_DENOMINATOR)
    return stored, float(abs(stored - exact))


def _simplest_between(low: Fraction, high: Fraction) -> Fraction:
    """The fraction with the smallest denominator in [low, high] (the smallest magnitude among
    integers), by continued fractions."""
    if low <= 0 <= high:
        return Fraction(0)
    if high < 0:
        return -_simplest_between(-high, -low)
    whole = math.floor(low)
    if whole == low or whole + 1 <= high:
        return Fraction(math.ceil(low))
    return whole + 1 / _simplest_between(1 / (high - whole), 1 / (low - whole))


def candidate_intervals(profile: CamProfile, master_counts: int, degree: int) -> list[int]:
    """Interval counts allowed for a table, smallest first: divisors of ``master_counts`` that
    put every joint where a derivative up to ``degree`` jumps on a table point (all divisors if
    some joint does not fall on a whole master count)."""
    return _Job(profile, master_counts, 1.0).intervals(degree)


# --------------------------------------------------------------------------------------------


class _Job:
    """One profile at one counts scaling; builds and certifies tables for several formats."""

    def __init__(self, profile: CamProfile, master_counts: int, scale: float, narrow: bool = False):
        self.profile = profile
        self.narrow = narrow
        self.M = master_counts
        self.S = scale
        self.unit = profile.master_period / master_counts  # master user units per count
        self._jumps = None
        self._bounds = {}
        self.net, self.net_residual = net_stroke_fraction(profile.net_stroke or 0.0, scale)

    # derivatives in counts ----------------------------------------------------------------------
    def derivative(self, counts: np.ndarray, order: int, side: str = "right") -> np.ndarray:
        x = counts * self.unit
        if not self.profile.periodic:
            x = np.clip(x, 0.0, self.profile.master_period)
        return self.profile(x, order, side=side) * self.S * self.unit**order

    def bound(self, order: int) -> float:
        if order not in self._bounds:
            self._bounds[order] = self.profile.derivative_bound(order) * self.S * self.unit**order
        return self._bounds[order]

    def jumps(self):
        """(count position, order, size) of every derivative jump up to order 5, in counts."""
        if self._jumps is None:
            self._jumps = [
                (d.master / self.unit, d.order, d.jump * self.S * self.unit**d.order)
                for d in self.profile.jumps(max_order=5)
            ]
        return self._jumps

    def intervals(self, degree: int) -> list[int]:
        positions = sorted({where for where, order, _ in self.jumps() if order <= degree})
        g = self.M
        for where in positions:
            nearest = round(where)
            if abs(where - nearest) > 1e-6:
                return divisors(self.M)  # cannot align: every divisor; the certificate shows the cost
            g = math.gcd(g, nearest % self.M)
        # h must divide g (and M); intervals = M / h
        return sorted(self.M // h for h in divisors(g) if h <= MAX_STEP_COUNTS)

    # search -------------------------------------------------------------------------------------
    def search(self, degrees, tol_counts, interp_tol_counts=None, *, certify, progress):
        """The fewest bytes whose certified bound meets ``tol_counts`` and, when given, the final
        rounding's 1/2 count plus ``interp_tol_counts`` (the bound less that 1/2 count, all the
        table adds to it, within ``interp_tol_counts``)."""
        target = tol_counts
        if interp_tol_counts is not None:
            target = min(tol_counts, FINAL_ROUNDING_COUNTS + interp_tol_counts)
        best = None
        floor_seen = math.inf
        floor_built = False  # whether floor_seen is a built table's bound, or only a prediction
        for degree in degrees:
            for intervals in self.intervals(degree):
                if intervals + 1 > MAX_POINTS:
                    break
                # the final rounding alone costs 1/2 count: a lower bound of the certified error
                predicted = self.predict_interpolation(degree, intervals) + FINAL_ROUNDING_COUNTS
                if predicted > target:
                    if predicted < floor_seen:
                        floor_seen, floor_built = predicted, False
                    continue
                nbytes = HEADER_BYTES + (intervals + 1) * 4 * ((degree + 1) // 2)
                if best is not None and nbytes >= best[0]:
                    break  # more intervals only cost more bytes
                try:
                    table = self.build(degree, intervals, certify=False)
                except TableFormatError:
                    continue  # this size has no valid format (e.g. a step past 2^30); try the next
                if table.certificate.predicted_error_counts <= target:
                    best = (nbytes, table)
                    break
                if table.certificate.predicted_error_counts < floor_seen:
                    floor_seen, floor_built = table.certificate.predicted_error_counts, True
        # a floor no table was built for is the interpolation's prediction alone: the stored
        # data's rounding and the arithmetic would add to it, so it is a lower bound
        floor_kind = ("" if floor_built
                      else ", at least (the interpolation's prediction alone: that table was not built)")
        if best is None and target < tol_counts:
            raise TableFormatError(
                f"interpolation_tolerance {interp_tol_counts:.4g} counts ({interp_tol_counts / self.S:.4g} "
                f"{self.profile.slave_unit}) cannot be met within {MAX_POINTS} points; the best bound found "
                f"is {floor_seen - FINAL_ROUNDING_COUNTS:.6g} counts above the final rounding's 1/2 count{floor_kind}"
            )
        if best is None:
            raise TableFormatError(
                f"tolerance {tol_counts:.4g} counts ({tol_counts / self.S:.4g} {self.profile.slave_unit}) cannot be "
                f"met within {MAX_POINTS} points; the best bound found is {floor_seen:.6g} counts "
                f"(the final rounding to whole counts alone costs 1/2 count){floor_kind}"
            )
        _, table = best
        if certify:  # the winner was built uncertified; measure it rather than build it again
            data = self.point_data(table.format.degree, table.points - 1)
            certificate = table.certificate.measured(self.measure(table, data, progress))
        else:
            certificate = table.certificate
        return replace(table, certificate=certificate.for_tolerance(tol_counts, interp_tol_counts))

    # prediction ---------------------------------------------------------------------------------
    def predict_interpolation(self, degree: int, intervals: int) -> float:
        """Bound of |f - p| before quantization, in counts: the smooth term
        c_n h^(n+1) max|f^(n+1)| plus, per interval, the cost of every derivative jump of
        order <= n that is not exactly representable there."""
        h = self.M / intervals
        smooth = _ERROR_CONSTANT[degree] * h ** (degree + 1) * self.bound(degree + 1)
        per_interval: dict[int, float] = {}
        for where, order, size in self.jumps():
            if order > degree or (self.profile.periodic and abs(where) < 1e-9):
                continue  # the seam is stored one-sided at both ends: no cost
            position = (where / h) % intervals if self.profile.periodic else where / h
            i = math.floor(position + 1e-9)
            offset = position - i
            if abs(offset) < 1e-9 or abs(offset - 1) < 1e-9:
                offset = 0.0
                touched = [(i - 1, 1.0), (i, 0.0)]  # the jump sits on a table point
            else:
                touched = [(i, offset)]
            for index, at in touched:
                if self.profile.periodic:
                    index %= intervals
                elif not 0 <= index < intervals:
                    continue
                cost = _jump_cost(degree, order, at, h) * abs(size)
                per_interval[index] = per_interval.get(index, 0.0) + cost
        return smooth + max(per_interval.values(), default=0.0)

    # building -----------------------------------------------------------------------------------
    def point_data(self, degree: int, intervals: int):
        """Float position, h*slope and h^2*curvature/2 at each point (average of the one-sided
        values where a derivative jumps)."""
        h = self.M // intervals
        counts = np.arange(intervals + 1, dtype=np.float64) * h
        values = []
        for order in range((degree + 1) // 2):
            right = self.derivative(counts, order, "right")
            left = self.derivative(counts, order, "left")
            # The first point only starts an interval and the last only ends one (a periodic
            # lookup wraps before it would cross the seam), so both take one-sided values: a
            # seam jump, or a net stroke per cycle, is then stored exactly.
            left[0], right[-1] = right[0], left[-1]
            values.append((left + right) / 2 * h**order / math.factorial(order))
        return values

    def build(self, degree: int, intervals: int, *, certify: bool = True, progress=None) -> CamTable:
        h = self.M // intervals
        if h > MAX_STEP_COUNTS:
            raise TableFormatError(f"step {h} counts (master_counts / intervals) should be <= {MAX_STEP_COUNTS}")
        data = self.point_data(degree, intervals)
        if np.abs(data[0]).max() + 0.5 > _INT32_MAX:
            raise TableFormatError(f"table position {np.abs(data[0]).max():.0f} counts overflows int32")
        fmt, positions, slopes, curvatures = _choose_format(degree, self.profile.periodic, h, intervals, data,
                                                            self.net, self.narrow)
        table = CamTable(fmt, positions, slopes, curvatures)
        return replace(table, certificate=self.certificate(table, data, certify, progress))

    # certificate --------------------------------------------------------------------------------
    def certificate(self, table: CamTable, data, certify: bool, progress) -> Certificate:
        f = table.format
        degree, h = f.degree, f.step_counts
        intervals = f.points - 1
        interp_bound = self.predict_interpolation(degree, intervals)
        quant = _quantization_bound(table)
        # the analytic profile is evaluated in float64: allow 64 ulp of the largest position
        low, high = self.profile.slave_range
        float_margin = 1e-6 + 64 * 2.0**-52 * max(abs(low), abs(high)) * self.S
        predicted = interp_bound + quant + float_margin
        off_grid = sorted({
            round(where * self.unit, 9) for where, order, _ in self.jumps()
            if order <= degree and abs(where / h - round(where / h)) > 1e-6
        })
        certificate = Certificate(
            slave_counts_per_unit=self.S,
            slave_unit=self.profile.slave_unit,
            master_unit=self.profile.master_unit,
            predicted_interpolation_counts=interp_bound,
            quantization_counts=quant,
            predicted_error_counts=predicted,
            joints_off_points=tuple(off_grid),
            net_stroke_units=self.profile.net_stroke or 0.0,
            net_stroke_residual_counts=self.net_residual,
            points=f.points,
        )
        return certificate.measured(self.measure(table, data, progress)) if certify else certificate

    def measure(self, table: CamTable, data, progress) -> Measurement:
        """Evaluate the integer lookup against the analytic profile: every master count when the
        period is at most DENSE_LIMIT, otherwise an even sample plus every joint and point."""
        M, h = self.M, table.format.step_counts
        last = M if not table.periodic else M - 1
        if M <= DENSE_LIMIT:
            grid = None
            total, how = last + 1, "every master count"
        else:
            sample = np.linspace(0, last, DENSE_LIMIT).round().astype(np.int64)
            extra = [np.arange(0, M + 1, h, dtype=np.int64)]
            for where, _, _ in self.jumps():
                base = int(math.floor(where))
                extra.append(np.arange(base - 2, base + 3, dtype=np.int64))
            grid = _sorted_unique(np.clip(np.concatenate([sample] + extra), 0, last))
            total, how = grid.size, f"{grid.size} master counts: an even sample, every table point and joint"
        worst = {"err": -1.0, "at": 0, "slope": 0.0, "float": 0.0}
        chunk = 1 << 20
        for start in range(0, total, chunk):
            counts = np.arange(start, min(start + chunk, total), dtype=np.int64) if grid is None else grid[start:start + chunk]
            exact = self.derivative(counts.astype(np.float64), 0)
            position, slope = table.lookup(counts, with_slope=True)
            error = np.abs(position - exact)
            i = int(np.argmax(error))
            if error[i] > worst["err"]:
                worst.update(err=float(error[i]), at=int(counts[i]))
            exact_slope = self.derivative(counts.astype(np.float64), 1)
            worst["slope"] = max(worst["slope"], float(np.abs(slope / 2.0**SLOPE_BITS - exact_slope).max()))
            worst["float"] = max(worst["float"], float(np.abs(_float_interpolant(table, data, counts) - exact).max()))
            if progress:
                progress(min(start + chunk, total), total)
        wrap = {}
        if table.net_stroke:
            wrap = self.measure_wrap(table)
            if wrap["wrap_max_error_counts"] > worst["err"]:
                worst.update(err=wrap["wrap_max_error_counts"], at=wrap["wrap_max_error_at_master_counts"])
        return Measurement(
            evaluated=how,
            evaluated_counts=int(total),
            max_error_counts=worst["err"],
            max_error_at_master_counts=worst["at"],
            max_error_at_master=worst["at"] * self.unit,
            interpolation_error_counts=worst["float"],
            max_slope_error_counts_per_count=worst["slope"],
            **wrap,
        )

    def wrap_periods(self) -> list[int]:
        """The periods k (master counts k*M .. k*M + M - 1) a net-stroke table is measured in:
        those of WRAP_PERIODS, their negatives, the one before each (so each seam is crossed),
        and the first and last whole period whose masters fit int64 and whose positions fit it
        with 2^32 to spare (beyond, the lookup is taken modulo 2^64: FORMAT.md step 7)."""
        M, net = self.M, abs(self.net)
        by_position = math.floor((2**63 - 2**32) / (net + 1))
        high = min((2**63 - M) // M, by_position)
        low = -min(2**63 // M, by_position)
        wanted = {k for base in WRAP_PERIODS for k in (base, -base)} | {low + 1, high}
        periods = {p for k in wanted for p in (k - 1, k)}
        return sorted(p for p in periods if low <= p <= high)

    def measure_wrap(self, table: CamTable) -> dict:
        """The lookup of a net-stroke table against the profile plus k net strokes (the table's
        own N/D, exactly), across the seams of :meth:`wrap_periods` and spread over them."""
        M = self.M
        window = min(M // 2, WRAP_WINDOW)
        local = np.unique(np.concatenate([
            np.arange(0, window), np.arange(M - window, M),
            np.linspace(0, M - 1, WRAP_SPREAD).round().astype(np.int64)])).astype(np.int64)
        exact = self.derivative(local.astype(np.float64), 0)
        num, den = self.net.numerator, self.net.denominator
        worst, at, periods = -1.0, 0, self.wrap_periods()
        for k in periods:
            masters = np.int64(k) * np.int64(M) + local
            whole, rest = divmod(k * num, den)  # k N/D = whole + rest/D, exactly
            got = table.lookup(masters) - np.int64(whole)  # both fit int64 (wrap_periods): exact
            error = np.abs(got.astype(np.float64) - rest / den - exact)
            i = int(np.argmax(error))
            if error[i] > worst:
                worst, at = float(error[i]), int(masters[i])
        inner = [k for k in WRAP_PERIODS if k in periods and -k in periods]
        shown = ", ".join(f"+-{k:g}" for k in inner)
        return {
            "wrap_evaluated": f"{len(periods) * local.size} master counts: {local.size} in each of the periods "
                              f"{shown}, the first and last inside int64 ({periods[1]}, {periods[-1]}) and the one "
                              f"before each ({window} either side of its seam, the rest spread over it)",
            "wrap_evaluated_counts": len(periods) * int(local.size),
            "wrap_max_error_counts": worst,
            "wrap_max_error_at_master_counts": at,
        }


def _sorted_unique(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` by a sort: numpy 2.4's hashing unique takes seconds on the millions
    of master counts of a cam with many joints (5 per jump), a sort a fraction of that."""
    values = np.sort(values)
    return values[np.concatenate([[True], values[1:] != values[:-1]])] if values.size else values


# fixed-point format --------------------------------------------------------------------------


def _ramp(periodic, h, intervals, data, net: Fraction):
    """S, the whole slave counts per master count of a net stroke's ramp, when the table stores
    its data relative to it (format version 3), else 0: when the absolute positions would keep
    fewer than RAMP_BELOW_BITS fraction bits in int32 (a large stroke: 2^26 counts per cut keeps
    5) and S is not 0. The ramp S m is a line, so the Hermite data of the cam minus the ramp are
    the positions minus S i h, the slopes minus S h, the curvatures as they are."""
    if not periodic or net == 0 or _fit_bits(data[0]) >= RAMP_BELOW_BITS:
        return 0
    ramp = math.floor(net / (h * intervals))
    return ramp if 0 < abs(ramp) <= MAX_RAMP else 0


def _choose_format(degree, periodic, h, intervals, data, net: Fraction = Fraction(0), narrow: bool = False):
    """Pick position/tau/work/slope/curvature bits as fine as the int64 budget allows; prove it.
    With ``narrow``, as fine as keeps the expanded form's Horner values in 32-bit words
    (:func:`ecam.table.narrow_horner`). A large net stroke stores its data relative to its ramp
    (:func:`_ramp`, format version 3)."""
    pow2 = h & (h - 1) == 0
    ramp = _ramp(periodic, h, intervals, data, net)
    if ramp:
        data = [data[0] - float(ramp * h) * np.arange(intervals + 1, dtype=np.float64),
                *(data[1] - float(ramp * h) for _ in data[1:2]), *data[2:]]
    position_fit = min(30, _fit_bits(data[0]))
    need = (h - 1).bit_length()
    tau_options = [need] if pow2 else list(range(min(30, need + 16), need - 1, -1))
    last_error = None
    for tau_bits in tau_options:
        tau_recip = -(-(1 << (32 + tau_bits)) // h)
        work_options = range(position_fit, -1, -1) if degree == 1 else range(MAX_WORK_BITS, -1, -1)
        for work_bits in work_options:
            position_bits = min(position_fit, work_bits)
            positions = np.round(data[0] * 2.0**position_bits)
            slopes = curvatures = None
            slope_bits = curvature_bits = 0
            if degree >= 3:
                slope_bits = min(work_bits, _fit_bits(data[1]))
                slopes = np.round(data[1] * 2.0**slope_bits)
                if np.abs(slopes).max() > _INT32_MAX:
                    raise TableFormatError(f"table slope {np.abs(data[1]).max():.4g} counts per step overflows int32")
            if degree == 5:
                curvature_bits = min(work_bits, _fit_bits(data[2]))
                curvatures = np.round(data[2] * 2.0**curvature_bits)
                if np.abs(curvatures).max() > _INT32_MAX:
                    raise TableFormatError(f"table curvature {np.abs(data[2]).max():.4g} counts per step^2 overflows int32")
            ok, why, preshift = overflow_proof(degree, positions, slopes, curvatures, position_bits, slope_bits,
                                       curvature_bits, work_bits, tau_bits, tau_recip, abs(ramp) << SLOPE_BITS)
            if ok:
                fmt = TableFormat(degree, periodic, intervals + 1, h * intervals, h, need if pow2 else -1,
                                  tau_bits, work_bits, slope_bits, curvature_bits, preshift, tau_recip,
                                  position_bits, net.numerator, net.denominator, bool(ramp))
                if narrow and not narrow_horner(CamTable(fmt, positions, slopes, curvatures)):
                    last_error = ("no format keeps the expanded form's Horner values in 32-bit words "
                                  f"(work_bits down to {work_bits}): horner_bits 32 needs a smaller stroke in counts")
                    continue
                return (
                    fmt,
                    positions.astype(np.int32),
                    None if slopes is None else slopes.astype(np.int32),
                    None if curvatures is None else curvatures.astype(np.int32),
                )
            last_error = why
    raise TableFormatError(f"no fixed-point format avoids overflow: {last_error}")


def _fit_bits(values) -> int:
    """Largest q <= MAX_WORK_BITS with round(max|values| * 2^q) inside int32."""
    peak = float(np.abs(values).max())
    if peak * 2.0**MAX_WORK_BITS < _INT32_MAX - 1:  # zero, tiny or denormal: every bit fits
        return MAX_WORK_BITS
    q = math.floor(math.log2((_INT32_MAX - 1) / peak))
    return max(0, min(MAX_WORK_BITS, q))


# error accounting ----------------------------------------------------------------------------


def _basis(degree: int, tau: np.ndarray):
    """Hermite basis on [0, 1] for data (y, h y', h^2 y''/2) at both ends: lists for end 0, 1."""
    t = tau
    if degree == 1:
        return [[1 - t], [t]]
    if degree == 3:
        return [[1 - 3 * t**2 + 2 * t**3, t - 2 * t**2 + t**3], [3 * t**2 - 2 * t**3, -(t**2) + t**3]]
    t3, t4, t5 = t**3, t**4, t**5
    return [
        [1 - 10 * t3 + 15 * t4 - 6 * t5, t - 6 * t3 + 8 * t4 - 3 * t5, t**2 - 3 * t3 + 3 * t4 - t5],
        [10 * t3 - 15 * t4 + 6 * t5, -4 * t3 + 7 * t4 - 3 * t5, t3 - 2 * t4 + t5],
    ]


_FINE = np.linspace(0.0, 1.0, 4001)


def _basis_peak(degree: int, order: int) -> float:
    """max over tau of |B_order,0| + |B_order,1| (the weight of a data error of that order)."""
    b = _basis(degree, _FINE)
    return float((np.abs(b[0][order]) + np.abs(b[1][order])).max())


# A jump's cost depends on the format and where it sits in its interval only; most joints of a
# cam of many segments sit on table points (at 0 or 1), so the 4001-point evaluation is shared.
@functools.lru_cache(maxsize=4096)
def _jump_cost(degree: int, order: int, at: float, h: float) -> float:
    """Max interpolation error, per unit jump, of psi(x) = (x - x_j)_+^order / order! with x_j
    at fraction ``at`` of an interval of length h (data at x_j take the average of both sides)."""
    t = _FINE
    x = (t - at) * h
    psi = np.where(x > 0, x, 0.0) ** order / math.factorial(order)
    if order == 0:
        psi = np.where(x > 0, 1.0, np.where(x == 0, 0.5, 0.0))
    stored = (degree + 1) // 2
    ends = []
    for end in (0.0, 1.0):
        xe = (end - at) * h
        row = []
        for d in range(stored):
            if xe > 0:
                value = xe ** (order - d) / math.factorial(order - d) if d <= order else 0.0
            elif xe == 0:
                value = 0.5 if d == order else 0.0
            else:
                value = 0.0
            row.append(value * h**d / math.factorial(d))
        ends.append(row)
    b = _basis(degree, t)
    interp = sum(b[e][d] * ends[e][d] for e in range(2) for d in range(stored))
    return float(np.abs(psi - interp).max()) * 1.01 + 1e-12


def _quantization_bound(table: CamTable) -> float:
    """Bound, in counts, of everything integer arithmetic adds to the interpolation error:
    stored position rounding (1/2), slope and curvature rounding, Horner floors, tau rounding
    (non-power-of-two steps), the final rounding (1/2) and, for a net stroke of a fraction of a
    count per period, its rounding (1/2)."""
    f = table.format
    bound = 0.5 * 2.0**-f.position_bits + (0.5 if f.work_bits else 1.0)  # W = 0: the last shift floors
    if f.net_stroke_den > 1:
        bound += 0.5
    if f.degree >= 3:
        bound += 0.5 * 2.0**-f.slope_bits * _basis_peak(f.degree, 1)
    if f.degree == 5:
        bound += 0.5 * 2.0**-f.curvature_bits * _basis_peak(f.degree, 2)
    bound += f.degree * 2.0**-f.work_bits
    if f.step_shift < 0:
        rows = table.coefficient_rows()
        # |dp/dtau| <= sum k |c_k|, in counts per unit tau
        dpdtau = sum(k * np.abs(rows[k].astype(np.float64)) for k in range(1, f.degree + 1)).max() / 2.0**f.work_bits
        dtau = 2.0**-f.tau_bits * (1 + f.step_counts / 2.0**32)
        bound += dpdtau * dtau
    return bound


def _float_interpolant(table: CamTable, data, counts: np.ndarray) -> np.ndarray:
    """The same Hermite interpolant in float64 on unquantized data: the error before
    quantization."""
    f = table.format
    m = np.mod(counts, f.master_counts) if f.periodic else np.clip(counts, 0, f.master_counts)
    i = np.minimum(m // f.step_counts, f.points - 2)
    tau = (m - i * f.step_counts) / f.step_counts
    b = _basis(f.degree, tau)
    out = np.zeros(counts.shape)
    for d, values in enumerate(data):
        out += b[0][d] * values[i] + b[1][d] * values[i + 1]
    return out
