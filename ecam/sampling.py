"""Samples of uncertain parameters: distributions and designs for robustness sweeps.

A sweep varies some numeric fields of a machine within their manufacturing spread (a coupling
within +-15 % of its catalogue stiffness, a backlash that grows with wear) and asks how many
machines built that way pass. This module is the sampling half of it, numpy only:

* :class:`Distribution`: ``normal`` (mean, std), ``uniform`` (low, high) or ``triangular`` (low,
  mode, high), optionally truncated to ``[minimum, maximum]``, either absolute or ``relative`` to
  a nominal value (a factor: ``mean = 1.0, std = 0.15`` is +-15 % at one sigma). Its
  :meth:`Distribution.quantile` maps a point of the unit interval to a value (the inverse CDF),
  so every design below is drawn on the unit hypercube and then mapped, field by field.
* :func:`design`: ``latin_hypercube`` (the default: every field's range cut into as many strata
  as samples, each stratum drawn once, McKay, Beckman & Conover, Technometrics 21(2), 1979),
  ``monte_carlo`` (independent draws), ``grid`` (one or two fields: the quantiles at the
  midpoints of equal-probability cells, so a uniform field is swept evenly) and ``sobol``
  (Saltelli's design for Sobol' indices, from SALib, only where the ``sweep`` extra is
  installed).

Reproducibility: every design is a function of the seed, the method, the sample count and the
distributions only. Each sample also gets a seed of its own (:func:`sample_seeds`, numpy's
``SeedSequence(seed).spawn``), which a Monte Carlo draw uses, so sample ``i`` of a Monte Carlo
sweep is drawn from its own seed whatever the others are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .validate import boolean, choice, fail, integer, number

#: Distribution kinds and the parameters each takes (besides relative, minimum, maximum).
DISTRIBUTIONS = {"normal": ("mean", "std"), "uniform": ("low", "high"),
                 "triangular": ("low", "mode", "high")}
#: Sampling designs; the first is the default.
METHODS = ("latin_hypercube", "monte_carlo", "grid", "sobol")
#: Every field a distribution table may hold.
DISTRIBUTION_FIELDS = ("distribution", "mean", "std", "low", "mode", "high", "relative",
                       "minimum", "maximum")
#: The smallest probability a truncated distribution may keep: below it the truncation bounds
#: lie so far in a tail that the samples would all pile up on one bound.
MIN_KEPT_PROBABILITY = 1e-9
#: Most samples one design may have (a million rig runs is days on one machine).
MAX_SAMPLES = 1_000_000
_EDGE = 1e-12  # unit points are kept inside (0, 1): a normal's quantile at 0 or 1 is infinite


# --- the normal distribution, numpy only ------------------------------------------------------
# Acklam's rational approximation of the normal quantile (relative error < 1.15e-9), refined by
# one step of Halley's method on the CDF computed with math.erfc, which brings it to full double
# precision (P. J. Acklam, "An algorithm for computing the inverse normal cumulative distribution
# function", 2003; the refinement step is the one given there).
_A = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
      1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
_B = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
      6.680131188771972e+01, -1.328068155288572e+01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
      -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
      3.754408661907416e+00)
_P_LOW = 0.02425
_erfc = np.frompyfunc(math.erfc, 1, 1)


def normal_cdf(x) -> np.ndarray:
    """Standard normal CDF, Phi(x) = erfc(-x / sqrt(2)) / 2, elementwise."""
    x = np.asarray(x, dtype=float)
    return 0.5 * np.asarray(_erfc(-x / math.sqrt(2.0)), dtype=float)


def normal_quantile(p) -> np.ndarray:
    """Standard normal quantile (inverse CDF) of probabilities ``p`` in (0, 1), elementwise.

    Acklam's approximation refined by a Halley step: within a few units in the last place of
    the exact quantile over (1e-300, 1 - 1e-16).
    """
    p = np.asarray(p, dtype=float)
    if np.any(~((p > 0.0) & (p < 1.0))):
        raise InputError("p: probabilities should lie strictly between 0 and 1")
    x = np.empty_like(p)
    low, high = p < _P_LOW, p > 1.0 - _P_LOW
    middle = ~(low | high)
    q = p[middle] - 0.5
    r = q * q
    x[middle] = (((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q / (
        ((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0)
    for mask, sign, tail in ((low, 1.0, p[low]), (high, -1.0, 1.0 - p[high])):
        q = np.sqrt(-2.0 * np.log(tail))
        x[mask] = sign * (((((_C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q
                          + _C[5]) / ((((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0)
    # Halley: e = Phi(x) - p, u = e sqrt(2 pi) exp(x^2 / 2), x -= u / (1 + x u / 2). The upper
    # tail is refined on its complement (1 - p is exact there, Phi(x) near 1 is not).
    upper = x > 0.0
    error = np.where(upper, (1.0 - p) - normal_cdf(-x), normal_cdf(x) - p)
    u = error * math.sqrt(2.0 * math.pi) * np.exp(0.5 * x * x)
    return x - u / (1.0 + 0.5 * x * u)


# --- distributions ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Distribution:
    """One uncertain field: its distribution, absolute or relative to a nominal value.

    Parameters
    ----------
    kind : {"normal", "uniform", "triangular"}
    mean, std : float
        ``normal``: mean and standard deviation (> 0).
    low, mode, high : float
        ``uniform``: low < high; ``triangular``: low <= mode <= high, low < high.
    relative : bool
        The values are factors on the nominal value (``mean = 1.0, std = 0.15``: +-15 % at one
        sigma); else absolute values in the field's own unit.
    minimum, maximum : float, optional
        Truncation bounds (in the same terms: factors when relative): the distribution
        conditioned on lying within them.

    Raises
    ------
    InputError
        A missing or out-of-range parameter, or truncation bounds that keep less than
        :data:`MIN_KEPT_PROBABILITY` of the distribution; the message names the parameter.
    """

    kind: str
    mean: float | None = None
    std: float | None = None
    low: float | None = None
    mode: float | None = None
    high: float | None = None
    relative: bool = False
    minimum: float | None = None
    maximum: float | None = None

    def __post_init__(self) -> None:
        choice("distribution", self.kind, DISTRIBUTIONS)
        boolean("relative", self.relative)
        wanted = DISTRIBUTIONS[self.kind]
        for name in ("mean", "std", "low", "mode", "high"):
            value = getattr(self, name)
            if name not in wanted:
                if value is not None:
                    raise fail(name, value, f"left out: a {self.kind} distribution takes "
                                            f"{', '.join(wanted)}")
                continue
            if value is None:
                raise InputError(f"{name}: missing; expected a number (a {self.kind} "
                                 f"distribution takes {', '.join(wanted)})")
            object.__setattr__(self, name, number(name, value))
        for name in ("minimum", "maximum"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, number(name, getattr(self, name)))
        if self.kind == "normal":
            number("std", self.std, minimum=0.0, strict=True)
        elif self.high <= self.low:
            raise fail("high", self.high, f"> low ({self.low:g})")
        if self.kind == "triangular" and not self.low <= self.mode <= self.high:
            raise fail("mode", self.mode, f"within [low, high] = [{self.low:g}, {self.high:g}]")
        if (self.minimum is not None and self.maximum is not None
                and self.maximum <= self.minimum):
            raise fail("maximum", self.maximum, f"> minimum ({self.minimum:g})")
        kept = float(np.diff(self._cdf(np.array(self._bounds())))[0])
        if not kept >= MIN_KEPT_PROBABILITY:
            bounds = f"[{self._bounds()[0]:g}, {self._bounds()[1]:g}]"
            raise InputError(f"minimum, maximum: {bounds} should keep some of the {self.kind} "
                             f"distribution (they keep a probability of {kept:.3g})")

    def _bounds(self) -> tuple[float, float]:
        low = -math.inf if self.minimum is None else self.minimum
        high = math.inf if self.maximum is None else self.maximum
        return low, high

    def _cdf(self, x: np.ndarray) -> np.ndarray:
        """The untruncated CDF, in the distribution's own terms (factors when relative)."""
        if self.kind == "normal":
            with np.errstate(invalid="ignore"):
                z = (x - self.mean) / self.std
            return normal_cdf(np.clip(z, -40.0, 40.0))
        if self.kind == "uniform":
            return np.clip((x - self.low) / (self.high - self.low), 0.0, 1.0)
        low, mode, high = self.low, self.mode, self.high
        x = np.clip(x, low, high)
        span = high - low
        # Each branch only where it applies: a mode at an end has no rising (or falling) side.
        rising = (x - low) ** 2 / (span * (mode - low)) if mode > low else np.zeros_like(x)
        falling = 1.0 - (high - x) ** 2 / (span * (high - mode)) if high > mode else np.ones_like(x)
        return np.where(x <= mode, rising, falling)

    def _quantile(self, p: np.ndarray) -> np.ndarray:
        """The untruncated inverse CDF of ``p`` in (0, 1)."""
        if self.kind == "normal":
            return self.mean + self.std * normal_quantile(p)
        if self.kind == "uniform":
            return self.low + p * (self.high - self.low)
        # Triangular inverse CDF, split at the mode's probability (low < high is checked).
        low, mode, high = self.low, self.mode, self.high
        split = (mode - low) / (high - low)
        rising = low + np.sqrt(p * (high - low) * (mode - low))
        falling = high - np.sqrt((1.0 - p) * (high - low) * (high - mode))
        return np.where(p < split, rising, falling)

    def quantile(self, unit, nominal: float | None = None) -> np.ndarray:
        """Values at the points ``unit`` of (0, 1): the inverse CDF of the truncated
        distribution, times ``nominal`` when the distribution is relative.

        Parameters
        ----------
        unit : array_like
            Points of the unit interval (0 and 1 are moved just inside it).
        nominal : float, optional
            The field's nominal value; required when ``relative``.
        """
        if self.relative and nominal is None:
            raise InputError("nominal: missing; a relative distribution needs the nominal value")
        unit = np.clip(np.asarray(unit, dtype=float), _EDGE, 1.0 - _EDGE)
        below, above = self._cdf(np.array(self._bounds()))
        probability = np.clip(below + unit * (above - below), _EDGE, 1.0 - _EDGE)
        values = np.clip(self._quantile(probability), *self._bounds())
        return values * nominal if self.relative else values

    def to_dict(self) -> dict:
        """The distribution as the table a scene's ``[sweep.vary]`` holds."""
        out = {"distribution": self.kind}
        for name in (*DISTRIBUTIONS[self.kind], "minimum", "maximum"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        out["relative"] = self.relative
        return out


# --- designs ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Design:
    """A sampling design mapped onto its fields.

    Attributes
    ----------
    method : str
        One of :data:`METHODS`.
    names : tuple of str
        The fields, in column order.
    unit : numpy.ndarray
        (samples, fields) points of the unit hypercube, read-only.
    values : numpy.ndarray
        (samples, fields) the fields' values, read-only.
    seeds : tuple of int
        Each sample's own seed (:func:`sample_seeds`).
    base_samples : int or None
        ``sobol``: Saltelli's N (a power of two; the design has N (fields + 2) rows).
    """

    method: str
    names: tuple[str, ...]
    unit: np.ndarray
    values: np.ndarray
    seeds: tuple[int, ...]
    base_samples: int | None = None

    @property
    def samples(self) -> int:
        """Rows of the design."""
        return int(self.values.shape[0])

    def sample(self, index: int) -> dict:
        """Sample ``index`` as {field: value}."""
        return {name: float(v) for name, v in zip(self.names, self.values[index])}


def sample_seeds(seed: int, samples: int) -> tuple[int, ...]:
    """One 63-bit seed per sample, spawned from ``seed`` (``numpy.random.SeedSequence``): sample
    ``i``'s seed does not depend on how many samples there are."""
    children = np.random.SeedSequence(seed).spawn(samples)
    return tuple(int(c.generate_state(2, np.uint64)[0] >> np.uint64(1)) for c in children)


def sobol_base_samples(samples: int, fields: int) -> int:
    """Saltelli's N for at most ``samples`` rows of ``fields`` fields: the largest power of two
    with N (fields + 2) <= samples (first-order and total indices; Saltelli et al., Computer
    Physics Communications 181(2), 2010, the design SALib draws)."""
    n = 1 << max(0, int(math.floor(math.log2(max(samples // (fields + 2), 1)))))
    if n * (fields + 2) > samples or n < 2:
        raise fail("samples", samples, f">= {2 * (fields + 2)} for a Sobol' design of {fields} "
                                       f"field(s) (N (fields + 2) rows with N >= 2)")
    return n


def unit_design(method: str, samples: int, fields: int, seed: int) -> tuple[np.ndarray, int | None]:
    """The design's points on the unit hypercube, (rows, fields), and Saltelli's N for
    ``sobol`` (None otherwise). ``grid`` and ``sobol`` may give fewer rows than ``samples``
    (a whole grid; whole Saltelli blocks)."""
    method = choice("method", method, METHODS)
    samples = integer("samples", samples, minimum=1, maximum=MAX_SAMPLES)
    fields = integer("fields", fields, minimum=1, maximum=1000)
    seed = integer("seed", seed, minimum=0, maximum=2**63 - 1)
    if method == "monte_carlo":
        seeds = sample_seeds(seed, samples)
        return np.array([np.random.default_rng(s).random(fields) for s in seeds]), None
    if method == "latin_hypercube":
        rng = np.random.default_rng(seed)
        strata = np.column_stack([rng.permutation(samples) for _ in range(fields)])
        return (strata + rng.random((samples, fields))) / samples, None
    if method == "grid":
        if fields > 2:
            raise fail("method", method, f"used with one or two fields (a grid of {fields} "
                                         "fields grows too fast: use latin_hypercube)")
        per_field = samples if fields == 1 else math.isqrt(samples)
        if per_field < 2:
            raise fail("samples", samples, f">= {2 ** fields} for a grid of {fields} field(s)")
        axis = (np.arange(per_field) + 0.5) / per_field
        mesh = np.meshgrid(*([axis] * fields), indexing="ij")
        return np.column_stack([m.ravel() for m in mesh]), None
    base = sobol_base_samples(samples, fields)
    try:
        from SALib.sample import sobol as salib_sobol
    except ImportError:
        raise InputError("method: 'sobol' needs SALib: pip install 'ecam[sweep]'") from None
    problem = {"num_vars": fields, "names": [f"x{i}" for i in range(fields)],
               "bounds": [[0.0, 1.0]] * fields}
    points = salib_sobol.sample(problem, base, calc_second_order=False, scramble=True, seed=seed)
    return np.asarray(points, dtype=float), base


def design(method: str, distributions: dict, samples: int, seed: int,
           nominal: dict | None = None) -> Design:
    """A design of ``samples`` rows over the ``distributions``.

    Parameters
    ----------
    method : {"latin_hypercube", "monte_carlo", "grid", "sobol"}
    distributions : dict of str to Distribution
        The fields, in order.
    samples : int
        Rows wanted (``grid`` and ``sobol`` round down, see :func:`unit_design`).
    seed : int
        0 .. 2^63 - 1.
    nominal : dict of str to float, optional
        The nominal value of each relative field.

    Returns
    -------
    Design
    """
    if not distributions:
        raise InputError("distributions: {} should name at least one field")
    names = tuple(distributions)
    unit, base = unit_design(method, samples, len(names), seed)
    nominal = nominal or {}
    columns = [distributions[name].quantile(unit[:, j], nominal.get(name))
               for j, name in enumerate(names)]
    values = np.column_stack(columns)
    unit.setflags(write=False)
    values.setflags(write=False)
    return Design(method=method, names=names, unit=unit, values=values,
                  seeds=sample_seeds(seed, unit.shape[0]), base_samples=base)
