"""The error certificate of a compiled table: what the compiler proved and what it measured.

A :class:`Certificate` is built with its table and never changes. It holds only what the table
cannot tell by itself (the bound, the measurement, the units); :meth:`Certificate.report` joins it
with the table's own facts (kind, points, step, CRC) into the dictionary that ``ecam compile
--json``, the JSON export and the README document. Those keys are a contract: they do not change.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction

# Every lookup rounds a real position to whole counts (FORMAT.md step 5): up to 1/2 count whatever the table.
FINAL_ROUNDING_COUNTS = 0.5


@dataclass(frozen=True)
class Measurement:
    """The integer lookup against the analytic profile, in slave counts.

    Attributes
    ----------
    evaluated : str
        Which master counts were evaluated ("every master count", or a sample and why).
    evaluated_counts : int
        How many.
    max_error_counts : float
        Largest |lookup - profile| found.
    max_error_at_master_counts : int
        Where (master counts), and ``max_error_at_master`` the same in master units.
    max_error_at_master : float
    interpolation_error_counts : float
        Largest error of the same interpolant in float64, before any rounding.
    max_slope_error_counts_per_count : float
        Largest error of the slope the lookup returns, in slave counts per master count.
    wrap_evaluated : str
        For a table with a net stroke: which master counts across the seam and at far periods
        were evaluated ("" otherwise: without a net stroke the lookup depends on the master
        modulo the period alone, so one period says everything).
    wrap_evaluated_counts : int
    wrap_max_error_counts : float or None
        Largest |lookup - (profile + k * net stroke)| there, the table's net stroke taken as
        stored (exact); ``max_error_counts`` includes it.
    wrap_max_error_at_master_counts : int or None
    """

    evaluated: str
    evaluated_counts: int
    max_error_counts: float
    max_error_at_master_counts: int
    max_error_at_master: float
    interpolation_error_counts: float
    max_slope_error_counts_per_count: float
    wrap_evaluated: str = ""
    wrap_evaluated_counts: int = 0
    wrap_max_error_counts: float | None = None
    wrap_max_error_at_master_counts: int | None = None

    def __post_init__(self):
        # Python numbers, not the numpy scalars the measurement computes them as (see Certificate).
        for name in ("max_error_counts", "max_error_at_master", "interpolation_error_counts",
                     "max_slope_error_counts_per_count", "wrap_max_error_counts"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, float(value))
        for name in ("evaluated_counts", "max_error_at_master_counts", "wrap_evaluated_counts",
                     "wrap_max_error_at_master_counts"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, int(value))


@dataclass(frozen=True)
class Certificate:
    """What a table is guaranteed to do: a predicted bound, and (when certified) a measurement.

    Attributes
    ----------
    slave_counts_per_unit : float
        The scale the table was compiled at.
    slave_unit, master_unit : str
        The profile's units, for messages.
    predicted_interpolation_counts : float
        Bound of the interpolation error before quantization.
    quantization_counts : float
        Bound of the rounding of stored values and of the arithmetic.
    predicted_error_counts : float
        The certified bound: both of the above plus a float64 margin. ``measured <= predicted``.
    joints_off_points : tuple of float
        Master positions of derivative jumps that do not fall on a table point.
    measurement : Measurement or None
        None for a table compiled with ``certify=False``.
    tolerance_counts : float or None
        The tolerance the table was chosen for, when it was compiled to one.
    net_stroke_units : float
        The cam's net stroke per period in slave units (0 for none).
    net_stroke_residual_counts : float
        |stored net stroke - the cam's| in counts per period: 0 when the cam's net stroke
        (net_stroke x slave_counts_per_unit, as decimals) is stored exactly, else the difference
        (see :func:`ecam.compile.net_stroke_fraction`); k periods away it adds k times this.
    points : int or None
        Stored points of the table the certificate speaks for (``report['points']``); None only
        for a certificate built by hand without it.
    interpolation_tolerance_counts : float or None
        The interpolation tolerance the table was chosen for (``ecam.TableSpec``), when given:
        the bound less the final rounding's 1/2 count is at most this.
    """

    slave_counts_per_unit: float
    slave_unit: str
    master_unit: str
    predicted_interpolation_counts: float
    quantization_counts: float
    predicted_error_counts: float
    joints_off_points: tuple[float, ...] = ()
    measurement: Measurement | None = None
    tolerance_counts: float | None = None
    net_stroke_units: float = 0.0
    net_stroke_residual_counts: float = 0.0
    points: int | None = None
    interpolation_tolerance_counts: float | None = None

    def __post_init__(self):
        # The compiler computes these in numpy: stored as Python floats, so the repr is plain and
        # equality is a float's (the JSON written from them is the same either way).
        for name in ("slave_counts_per_unit", "predicted_interpolation_counts", "quantization_counts",
                     "predicted_error_counts", "net_stroke_units", "net_stroke_residual_counts"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "joints_off_points", tuple(float(x) for x in self.joints_off_points))
        for name in ("tolerance_counts", "interpolation_tolerance_counts"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, float(getattr(self, name)))
        if self.points is not None:
            object.__setattr__(self, "points", int(self.points))

    @property
    def predicted_error_units(self) -> float:
        """The certified bound :attr:`predicted_error_counts` in slave user units."""
        return self.predicted_error_counts / self.slave_counts_per_unit

    @property
    def max_error_counts(self) -> float | None:
        """The measured error, or None when the table was not certified."""
        return None if self.measurement is None else self.measurement.max_error_counts

    def measured(self, measurement: Measurement) -> "Certificate":
        """This certificate with ``measurement`` (the lookup evaluated against the profile).

        Parameters
        ----------
        measurement : Measurement

        Returns
        -------
        Certificate
            A new certificate; this one is unchanged (it is frozen).
        """
        return replace(self, measurement=measurement)

    def for_tolerance(self, tolerance_counts: float, interpolation_tolerance_counts: float | None = None
                      ) -> "Certificate":
        """This certificate, recording the tolerance the table was chosen for.

        Parameters
        ----------
        tolerance_counts : float
            The tolerance in slave counts (``tolerance_counts`` and ``tolerance_units`` in
            :meth:`report`).
        interpolation_tolerance_counts : float, optional
            The interpolation tolerance in slave counts, when one was given
            (``interpolation_tolerance_counts`` in :meth:`report`, with the bound's two parts).

        Returns
        -------
        Certificate
            A new certificate; this one is unchanged (it is frozen).
        """
        return replace(self, tolerance_counts=float(tolerance_counts),
                       interpolation_tolerance_counts=interpolation_tolerance_counts)

    def report(self, table) -> dict:
        """The certificate as the documented dictionary (``table.report``), joined with ``table``'s
        own facts."""
        f = table.format
        out = {
            "interp": f.interp,
            "degree": f.degree,
            "points": f.points,
            "intervals": f.points - 1,
            "step_counts": f.step_counts,
            "master_counts": f.master_counts,
            "slave_counts_per_unit": self.slave_counts_per_unit,
            "periodic": f.periodic,
            "bytes": table.nbytes,
            "crc32": table.crc32,
            "format": {
                "position_bits": f.position_bits, "step_shift": f.step_shift, "tau_bits": f.tau_bits,
                "work_bits": f.work_bits, "slope_bits": f.slope_bits, "curvature_bits": f.curvature_bits,
                "slope_preshift": f.slope_preshift, "tau_recip": f.tau_recip,
            },
            "predicted_interpolation_counts": self.predicted_interpolation_counts,
            "quantization_counts": self.quantization_counts,
            "predicted_error_counts": self.predicted_error_counts,
            "predicted_error_units": self.predicted_error_units,
            "joints_off_points": list(self.joints_off_points),
            "slave_unit": self.slave_unit,
            "master_unit": self.master_unit,
        }
        m = self.measurement
        if m is not None:
            out.update({
                "evaluated": m.evaluated,
                "evaluated_counts": m.evaluated_counts,
                "max_error_counts": m.max_error_counts,
                "max_error_units": m.max_error_counts / self.slave_counts_per_unit,
                "max_error_at_master_counts": m.max_error_at_master_counts,
                "max_error_at_master": m.max_error_at_master,
                "interpolation_error_counts": m.interpolation_error_counts,
                "max_slope_error_counts_per_count": m.max_slope_error_counts_per_count,
            })
        if self.tolerance_counts is not None:
            out["tolerance_counts"] = self.tolerance_counts
            out["tolerance_units"] = self.tolerance_counts / self.slave_counts_per_unit
        if self.interpolation_tolerance_counts is not None:
            # Only tables compiled to an interpolation tolerance have these keys (the other
            # reports are unchanged): the bound's two parts, each against its own tolerance.
            out.update({
                "interpolation_tolerance_counts": self.interpolation_tolerance_counts,
                "interpolation_tolerance_units": self.interpolation_tolerance_counts / self.slave_counts_per_unit,
                "final_rounding_counts": FINAL_ROUNDING_COUNTS,
                "predicted_above_rounding_counts": self.predicted_error_counts - FINAL_ROUNDING_COUNTS,
            })
        net: Fraction = f.net_stroke
        if net:  # only tables with a net stroke have these keys (the others' reports are unchanged)
            out.update({
                "net_stroke_units": self.net_stroke_units,
                "net_stroke_counts": float(net),
                "net_stroke_fraction": [net.numerator, net.denominator],
                "net_stroke_exact": self.net_stroke_residual_counts == 0,
                "net_stroke_residual_counts": self.net_stroke_residual_counts,
                "format_version": table.format_version,
            })
            if m is not None and m.wrap_max_error_counts is not None:
                out.update({
                    "wrap_evaluated": m.wrap_evaluated,
                    "wrap_evaluated_counts": m.wrap_evaluated_counts,
                    "wrap_max_error_counts": m.wrap_max_error_counts,
                    "wrap_max_error_at_master_counts": m.wrap_max_error_at_master_counts,
                })
        return out
