"""What every vendor export shares: the consumer's interpolant, the error bound predicted from the
cam's derivatives, the error measured against the cam, point placement, and the certificate.

Every consumer interpolation ecam exports to -- straight lines, a cubic with tangents from the
neighbours, a cubic spline, one quintic per interval through X/Y/V/A -- is, on each interval, a
polynomial fixed by its values and first derivatives at the two ends: a Hermite polynomial. A
format module works out those end data exactly as its consumer does (from the numbers it writes,
rounding included) and hands them over as a :class:`Hermite`; everything else is done once, here:

* **predicted bound**, per interval ``[a, b]`` of width ``h``, in slave user units::

      C_n h^(n+1) max|f^(n+1)|                  the cam against the ideal Hermite polynomial
    + sum over derivative jumps inside (a, b)   a jump of order m <= n costs |jump| h^m psi_nm
    + max_t sum_k |delta_k| h^k |B_k(t)|        the consumer's end data against the cam's
    + output rounding                           when the consumer outputs whole counts

  with ``C_1 = 1/8``, ``C_3 = 1/384``, ``C_5 = 1/46080`` (the Peano bounds of Hermite
  interpolation), ``max|f^(n+1)|`` bounded on that interval only (:meth:`Cam.bounds`, sampled
  with a Lipschitz margin as :meth:`ecam.CamProfile.derivative_bound` does), ``psi_nm`` the
  interpolation error of the truncated power ``(x - x_j)_+^m / m!``, and
  ``delta_k`` the difference between the k-th derivative the consumer uses at an end and the
  cam's one-sided derivative there (``B_k`` the Hermite basis functions). Each term is an upper
  bound, so the sum is one.
* **measured error**: the consumer's interpolant against the cam on a dense grid in every interval
  plus each interval's extremum (a golden-section search around the largest sample); for consumers
  that only see whole master counts and output whole counts, at every master count.

A tolerance is met when the predicted bound is within it (the measurement is always below the
bound; the tests hold both).
"""

from __future__ import annotations

import functools
import math
import zlib
from dataclasses import dataclass, field
from decimal import Decimal

import numpy as np

from ..errors import InputError, TableFormatError
from ..linear import inverse_exact, matmul
from ..profile import CamProfile
from ..table import divisors
from ..table_spec import TableSpec, parse_tolerance
from ..validate import integer
from .batched import linspaces
from .stretches import Stretches, settle

__all__ = [
    "EXPORT_VERSION", "Cam", "Hermite", "Reading", "ExportCertificate", "VendorExport", "certify", "predicted",
    "greedy_knots", "equidistributed", "spread_knots", "place_local", "fewest", "knot_data", "positional",
    "divisors", "unreachable", "table_counts", "joint_masters", "hermite_points",
]

# max over tau of |f - p| = h^(n+1) max|f^(n+1)| * _SMOOTH[n] for the Hermite polynomial of degree n
_SMOOTH = {1: 1 / 8, 3: 1 / 384, 5: 1 / 46080}
_T = np.linspace(0.0, 1.0, 257)        # where basis weights are sampled (polynomials of degree <= 5)
_T_FINE = np.linspace(0.0, 1.0, 4001)  # where a truncated power's error is sampled
_SAMPLE_MARGIN = 1.01                  # sampled maxima of smooth polynomials, with a relative margin
DENSE_PER_INTERVAL = 64                # measured samples per interval, before the extremum search
EVERY_COUNT_LIMIT = 2**22              # integer consumers: every master count up to this period
# Written in the files that take comments, with a content CRC-32 instead of a date: raise it when
# the same cam and settings would give different points.
EXPORT_VERSION = 2


# -- the cam over one period -------------------------------------------------------------------------
def table_counts(profile: CamProfile, *, master_counts=None, slave_counts_per_unit=None) -> TableSpec:
    """The cam's counts, given or from its cam file's ``[table]``, checked by :class:`ecam.TableSpec`
    exactly as for ecam's own tables (same defaults, limits and messages).

    Only ``master_counts`` and ``slave_counts_per_unit`` of the result mean anything: a vendor
    export chooses its own size and interpolation, so the spec is resolved with a stand-in one
    (linear, 2 points) and the cam file's ``interp``, ``points`` and ``tolerance`` are not read.
    """
    return TableSpec.resolve(profile.table or {}, interp="linear", points=2, master_counts=master_counts,
                             slave_counts_per_unit=slave_counts_per_unit)


class Cam:
    """A cam profile over one master period ``[0, P]``, unwrapped: at ``P`` it takes the left limit,
    so a net-stroke cam ends at ``y(0) + net stroke``.

    Also carries the cam's counts (``slave_counts_per_unit``, ``master_counts``) for reports in
    counts and for the formats that store counts.
    """

    def __init__(self, profile: CamProfile, *, master_counts=None, slave_counts_per_unit=None):
        if not isinstance(profile, CamProfile):
            raise InputError(f"profile: {type(profile).__name__} should be a CamProfile (see ecam.load_cam)")
        self.profile = profile
        self.period = float(profile.master_period)
        counts = table_counts(profile, master_counts=master_counts, slave_counts_per_unit=slave_counts_per_unit)
        self.master_counts = counts.master_counts
        self.scale = counts.slave_counts_per_unit
        self.jumps = tuple(
            (float(d.master), int(d.order), float(d.jump)) for d in profile.jumps(max_order=5)
            if 0.0 < d.master < self.period
        )
        # The same jumps as arrays, and their positions sorted (equal ones in report order): an
        # interval finds the jumps inside it by bisection, not by reading them all -- the greedy
        # placement asks for thousands of intervals, and a cam may have 10^5 jumps.
        self.jump_at = np.array([where for where, _, _ in self.jumps], dtype=float)
        self.jump_order = np.array([order for _, order, _ in self.jumps], dtype=np.int64)
        self.jump_size = np.array([size for _, _, size in self.jumps], dtype=float)
        self._jump_rank = np.argsort(self.jump_at, kind="stable")
        self._jump_sorted = self.jump_at[self._jump_rank]
        self._envelopes: dict = {}
        self._stretches: dict = {}  # equidistributed's weights, by (order, forced knots, floor)
        self._check_seam()

    @property
    def name(self) -> str:
        return self.profile.name

    @property
    def periodic(self) -> bool:
        return self.profile.periodic

    @functools.cached_property
    def net_stroke(self) -> float:
        """Slave advance per master period, as the cam file declares it (0 when it declares none)."""
        return float(self.profile.net_stroke or 0.0)

    def _check_seam(self) -> None:
        """A periodic cam must end where it starts, or one net stroke on (the profile has checked that
        a declared net stroke is what the segments add up to). An undeclared step at the seam is the
        accidental gap ``ecam check`` reports: no controller table is exported for it."""
        if not self.periodic:
            return
        end = float(self.profile(self.period, 0, side="left"))
        start = float(self.profile(0.0, 0, side="right"))
        step = end - start - self.net_stroke
        low, high = self.profile.slave_range
        if abs(step) > 1e-9 * max(1.0, abs(low), abs(high), abs(self.net_stroke)):
            unit = self.profile.slave_unit
            raise InputError(
                f"position: jumps by {-step:+.6g} {unit} at the seam (master {self.period:g} -> 0) and should "
                f"continue; if the slave is meant to advance by {end - start:+.6g} {unit} every period, say so "
                f"in the cam file: net_stroke = {end - start!r}")

    @functools.cached_property
    def stroke(self) -> float:
        low, high = self.profile.slave_range
        return high - low

    @functools.cached_property
    def peak(self) -> float:
        """Largest |slave position| over the period (for float round-off margins)."""
        low, high = self.profile.slave_range
        return max(abs(low), abs(high), abs(low + self.net_stroke), abs(high + self.net_stroke))

    def __call__(self, master, order: int = 0, side: str = "right") -> np.ndarray:
        """d^order y / dx^order at ``master`` in [0, P] (user units); at P the left limit."""
        x = np.atleast_1d(np.asarray(master, dtype=float))
        out = self.profile(np.minimum(x, self.period), order, side=side)
        end = x >= self.period
        if end.any():
            out = np.where(end, self.profile(self.period, order, side="left"), out)
        return out

    def bounds(self, order: int, lo, hi) -> np.ndarray:
        """Upper bounds of |d^order y/dx^order| on the intervals [lo[i], hi[i]], vectorized.

        From an envelope built once per order: the period is cut at every joint and law break, each
        piece into cells of at most P / 2^14 (16 at least); a cell's bound is the larger of
        |f^(order)| at its two ends plus half its width times the piece's largest |f^(order+1)|
        (sampled, with a 1 % margin, as :meth:`ecam.CamProfile.derivative_bound` does). An interval
        takes the largest bound of the cells it touches (a sparse table answers each in O(1))."""
        left_edges, right_edges, table = self._envelope(order)
        lo = np.atleast_1d(np.asarray(lo, dtype=float))
        hi = np.atleast_1d(np.asarray(hi, dtype=float))
        first = np.clip(np.searchsorted(right_edges, lo, side="right"), 0, right_edges.size - 1)
        last = np.clip(np.searchsorted(left_edges, hi, side="left") - 1, first, left_edges.size - 1)
        span = last - first + 1
        level = np.floor(np.log2(span)).astype(int)
        out = np.empty(lo.size)
        for k in np.unique(level):
            mask = level == k
            out[mask] = np.maximum(table[k][first[mask]], table[k][last[mask] - (1 << k) + 1])
        return out

    def _envelope(self, order: int):
        if order not in self._envelopes:
            cuts = np.array(sorted({0.0, self.period,
                                    *(b for b, _, _ in self.profile.breaks() if 0.0 < b < self.period)}))
            p0, p1 = cuts[:-1], cuts[1:]
            width = self.period / 2**14
            count = np.array([max(16, math.ceil(c)) for c in ((p1 - p0) / width).tolist()], dtype=np.int64)
            nodes, piece, last = linspaces(p0, p1, count)
            # every piece at once: its nodes from the right, its end from the left (one call each)
            values = np.empty(nodes.size)
            slopes = np.empty(nodes.size)
            values[~last] = self(nodes[~last], order, "right")
            values[last] = self(nodes[last], order, "left")
            slopes[~last] = self(nodes[~last], order + 1, "right")
            slopes[last] = self(nodes[last], order + 1, "left")
            values, slopes = np.abs(values), np.abs(slopes)
            first = np.flatnonzero(np.concatenate([[True], last[:-1]]))  # each piece's first node
            steepest = np.maximum.reduceat(slopes, first)
            step = (p1 - p0) / count
            margin = steepest * step / 2 * _SAMPLE_MARGIN
            cell = ~last[:-1]  # a cell from every node but a piece's last one to the next node
            base = np.maximum(values[:-1], values[1:])[cell] + margin[piece[:-1][cell]]
            table = [base]
            while (1 << len(table)) <= base.size:
                previous, half = table[-1], 1 << (len(table) - 1)
                table.append(np.maximum(previous[:-half], previous[half:]))
            self._envelopes[order] = (nodes[:-1][cell], nodes[1:][cell], table)
        return self._envelopes[order]

    def breaks(self, max_order: int) -> list[float]:
        """0, P and every master position strictly inside where a derivative of order <= max_order jumps."""
        inner = sorted({x for x, order, _ in self.jumps if order <= max_order})
        return [0.0, *inner, self.period]


def knot_data(cam: Cam, x: np.ndarray, values: int, *, sides: bool = False):
    """The cam's derivatives 0..values-1 at knots ``x`` (shape (len(x), values)): the mean of the two
    one-sided values where a derivative jumps, one-sided at 0 (right) and P (left). With ``sides``
    also the one-sided values themselves: (data, right limits, left limits)."""
    x = np.asarray(x, dtype=float)
    out, rights, lefts = (np.empty((x.size, values)) for _ in range(3))
    for order in range(values):
        right = cam(x, order, "right")
        left = cam(x, order, "left")
        mean = (left + right) / 2
        mean = np.where(x <= 0.0, right, np.where(x >= cam.period, left, mean))
        # float noise around a true zero (a dwell's acceleration) is written as 0
        noise = 1e-13 * max(cam.stroke, abs(cam.net_stroke), 1e-300) / cam.period**order
        out[:, order] = np.where(np.abs(mean) <= noise, 0.0, mean)
        rights[:, order], lefts[:, order] = right, left
    return (out, rights, lefts) if sides else out


# -- Hermite form --------------------------------------------------------------------------------------
@functools.cache
def _hermite_inverse(degree: int) -> np.ndarray:
    """Matrix from end data (d^k p/dt^k at t = 0 for k < r, then at t = 1) to the coefficients of
    p(t) = sum c_j t^j on [0, 1]."""
    r = (degree + 1) // 2
    system = np.zeros((degree + 1, degree + 1))
    for k in range(r):
        system[k, k] = math.factorial(k)
        for j in range(k, degree + 1):
            system[r + k, j] = math.factorial(j) / math.factorial(j - k)
    return inverse_exact(system.tolist())


@functools.cache
def _basis_on(degree: int, grid_size: int) -> np.ndarray:
    """|B_{end,k}(t)| on a grid of t: shape (2 * r, grid_size), ends then orders."""
    t = np.linspace(0.0, 1.0, grid_size)
    powers = t[None, :] ** np.arange(degree + 1)[:, None]
    return np.abs(matmul(_hermite_inverse(degree).T, powers))


@dataclass(frozen=True)
class Hermite:
    """A consumer's interpolant: on interval i = [x[i], x[i+1]] the polynomial of ``degree`` whose
    derivatives d^k y/dx^k, k < (degree + 1) / 2, are ``left[i, k]`` at x[i] and ``right[i, k]`` at
    x[i+1] (slave user units per master unit^k)."""

    x: np.ndarray
    degree: int
    left: np.ndarray
    right: np.ndarray

    @classmethod
    def continuous(cls, x, degree: int, data) -> "Hermite":
        """One set of end data per knot, shared by the intervals on both sides."""
        data = np.asarray(data, dtype=float).reshape(len(x), -1)
        return cls(np.asarray(x, dtype=float), degree, data[:-1], data[1:])

    @property
    def widths(self) -> np.ndarray:
        return np.diff(self.x)

    @functools.cached_property
    def coefficients(self) -> np.ndarray:
        """c[i, j]: p_i(t) = sum_j c[i, j] t^j with t = (x - x[i]) / h_i."""
        h = self.widths[:, None]
        r = (self.degree + 1) // 2
        scale = h ** np.arange(r)[None, :]
        data = np.concatenate([self.left * scale, self.right * scale], axis=1)
        return matmul(data, _hermite_inverse(self.degree).T)

    def at(self, interval: np.ndarray, t: np.ndarray) -> np.ndarray:
        """p_interval(t), vectorized."""
        c = self.coefficients[interval]
        out = c[..., -1]
        for j in range(self.degree - 1, -1, -1):
            out = out * t + c[..., j]
        return out

    def __call__(self, master) -> np.ndarray:
        x = np.asarray(master, dtype=float)
        i = np.clip(np.searchsorted(self.x, x, side="right") - 1, 0, len(self.x) - 2)
        return self.at(i, (x - self.x[i]) / self.widths[i])


# -- the predicted bound ------------------------------------------------------------------------------
@functools.cache
def _psi_cost(degree: int, order: int, at: float) -> float:
    """Largest |psi - H psi| on [0, 1] for psi(t) = (t - at)_+^order / order! (a unit jump of
    derivative ``order`` at ``at``), H psi its Hermite polynomial from one-sided end data. Scale by
    h^order for an interval of width h."""
    t = _T_FINE
    if order == 0:
        psi = (t > at).astype(float)
    else:
        psi = np.where(t > at, t - at, 0.0) ** order / math.factorial(order)
    r = (degree + 1) // 2
    data = np.zeros(2 * r)
    for k in range(r):  # at t = 0 psi vanishes with its derivatives; at t = 1 the left limits
        if k <= order:
            data[r + k] = (1.0 - at) ** (order - k) / math.factorial(order - k)
    powers = t[None, :] ** np.arange(degree + 1)[:, None]
    interpolant = matmul(matmul(_hermite_inverse(degree), data), powers)
    return float(np.abs(psi - interpolant).max()) * _SAMPLE_MARGIN + 1e-12


def interval_bounds(cam: Cam, hermite: Hermite, *, extra: float = 0.0, inside=None) -> np.ndarray:
    """Predicted bound of |consumer - cam| on every interval, slave user units (module docstring).
    ``extra`` (units) is added to each, for rounding the consumer applies to its output. ``inside``
    may carry the cam's one-sided derivatives at the intervals' ends, (at a from the right, at b from
    the left), each shaped like ``hermite.left``, when the caller has them already."""
    return _bounds(cam, hermite.degree, hermite.x[:-1], hermite.x[1:], hermite.left, hermite.right,
                   extra=extra, inside=inside)


def _bounds(cam: Cam, n: int, a, b, left, right, *, extra: float = 0.0, inside=None) -> np.ndarray:
    """:func:`interval_bounds` of the Hermite polynomials of degree ``n`` on intervals [a[i], b[i]]
    with end data ``left[i]`` and ``right[i]``; the intervals need not be adjacent (the greedy
    placement weighs many candidate intervals from one knot at once). Each interval's bound is
    computed element by element, so it is the same number however many are asked together."""
    r = (n + 1) // 2
    h = b - a
    smooth = _SMOOTH[n] * h ** (n + 1) * cam.bounds(n + 1, a, b)
    jumps = _jump_costs(cam, n, a, b, h)
    if inside is None:
        inside = (np.stack([cam(a, k, "right") for k in range(r)], axis=1),
                  np.stack([cam(b, k, "left") for k in range(r)], axis=1))
    scale = h[:, None] ** np.arange(r)
    delta = np.concatenate([(left - inside[0]) * scale, (right - inside[1]) * scale], axis=1)
    # row by row the same numbers, a block of intervals at a time: the product is 257 samples
    # per interval (2 kB), gigabytes at once for a million points (issue 28, item 3)
    basis = _basis_on(n, _T.size)
    data = np.concatenate([matmul(np.abs(delta[start:start + _DENSE_BLOCK]), basis).max(axis=1)
                           for start in range(0, max(1, delta.shape[0]), _DENSE_BLOCK)]) * _SAMPLE_MARGIN
    # the cam and the consumer both evaluate in float64: a few ulp of the largest position
    roundoff = 64 * 2.0**-52 * (cam.peak + 1.0)
    return smooth + jumps + data + roundoff + extra


def _jump_costs(cam: Cam, n: int, a, b, h) -> np.ndarray:
    """Per interval, the sum over the cam's jumps of order <= n strictly inside it of |jump| h^order
    psi (module docstring), added in the order of ``cam.jumps``. The jumps inside come from two
    bisections per interval in the sorted positions: the cost is in the jumps that are inside, not
    in all the cam's jumps for every interval (which made the greedy placement quadratic)."""
    out = np.zeros(a.size)
    first = np.searchsorted(cam._jump_sorted, a, side="right")
    count = np.maximum(0, np.searchsorted(cam._jump_sorted, b, side="left") - first)
    if not count.any():  # the common case: knots on the jumps
        return out
    interval = np.repeat(np.arange(a.size), count)
    rank = np.arange(interval.size) - np.repeat(np.cumsum(count) - count, count) + np.repeat(first, count)
    k = cam._jump_rank[rank]
    report = np.lexsort((k, interval))  # each interval's jumps in the cam's order
    interval, k = interval[report], k[report]
    keep = cam.jump_order[k] <= n
    interval, k = interval[keep], k[keep]
    order, size = cam.jump_order[k], cam.jump_size[k]
    at = (cam.jump_at[k] - a[interval]) / h[interval]
    cost = np.array([_psi_cost(n, o, round(u, 12)) for o, u in zip(order.tolist(), at.tolist())])
    # h^order by the C library's pow, one element at a time, as the per-jump code computed it: on
    # AVX-512 CPUs numpy's array power runs a vector pow (SVML) whose last bit differs from pow()
    widths = np.array([w ** o for w, o in zip(h[interval].tolist(), order.tolist())])
    np.add.at(out, interval, np.abs(size) * widths * cost)
    return out


# -- the measured error -------------------------------------------------------------------------------
#: Intervals whose dense samples measure_float holds at once (a few MB whatever the table's size).
_DENSE_BLOCK = 4096


def measure_float(cam: Cam, hermite: Hermite, per_interval: int = DENSE_PER_INTERVAL):
    """Largest |consumer - cam| (user units) for a consumer that evaluates its interpolant at any
    master position: ``per_interval`` + 1 samples in every interval, then a golden-section search for
    the extremum around each interval's largest sample. Returns (error, master, interval)."""
    n_int = hermite.x.size - 1
    t = np.arange(per_interval + 1) / per_interval
    # The dense samples a block of intervals at a time: all at once they took some 8 kB per
    # interval, gigabytes at a million points (issue 28, item 3); each sample is computed alone,
    # so the blocks give the very same numbers.
    largest = np.empty(n_int)
    best = np.empty(n_int, dtype=np.int64)
    for start in range(0, n_int, _DENSE_BLOCK):
        block = np.arange(start, min(n_int, start + _DENSE_BLOCK))
        i = np.repeat(block, t.size)
        tt = np.tile(t, block.size)
        x = hermite.x[i] + tt * hermite.widths[i]
        exact = np.where(tt >= 1.0, cam(x, 0, "left"), cam(x, 0, "right"))
        error = np.abs(hermite.at(i, tt) - exact).reshape(block.size, t.size)
        best[block] = error.argmax(axis=1)
        largest[block] = error.max(axis=1)
    lo = np.clip((best - 1) / per_interval, 0.0, 1.0)
    hi = np.clip((best + 1) / per_interval, 0.0, 1.0)
    intervals = np.arange(n_int)

    def err(tau):
        xs = hermite.x[intervals] + tau * hermite.widths[intervals]
        return np.abs(hermite.at(intervals, tau) - cam(xs, 0, "right"))

    golden = (math.sqrt(5) - 1) / 2
    c, d = hi - golden * (hi - lo), lo + golden * (hi - lo)
    fc, fd = err(c), err(d)
    for _ in range(40):  # the bracket shrinks to 0.618^40 of two samples' spacing
        left = fc > fd  # the maximum is in [lo, d]: d becomes the inner point c was
        hi = np.where(left, d, hi)
        lo = np.where(left, lo, c)
        probe = np.where(left, hi - golden * (hi - lo), lo + golden * (hi - lo))
        value = err(probe)
        c, d, fc, fd = (np.where(left, probe, d), np.where(left, c, probe),
                        np.where(left, value, fd), np.where(left, fc, value))
    refined = np.maximum(fc, fd)
    refined_t = np.where(fc >= fd, c, d)
    per = np.maximum(largest, refined)
    where_t = np.where(refined > largest, refined_t, t[best])
    k = int(per.argmax())
    master = float(hermite.x[k] + where_t[k] * hermite.widths[k])
    return float(per[k]), master, k


def measure_counts(cam: Cam, output, *, master_counts: int):
    """Largest |consumer - cam| in slave counts for a consumer that sees whole master counts:
    ``output(counts)`` gives its slave position in counts. Every master count of one period when
    the period is at most EVERY_COUNT_LIMIT counts, else an even sample with every table point.
    Returns (error_counts, master_count, how)."""
    last = master_counts - 1 if cam.periodic else master_counts
    if master_counts <= EVERY_COUNT_LIMIT:
        grid = None
        total, how = last + 1, "every master count"
    else:
        grid = np.unique(np.linspace(0, last, EVERY_COUNT_LIMIT).round().astype(np.int64))
        total, how = grid.size, f"{grid.size} master counts, evenly spread (the period has {master_counts})"
    worst, at = -1.0, 0
    chunk = 1 << 20
    for start in range(0, total, chunk):
        counts = (np.arange(start, min(start + chunk, total), dtype=np.int64) if grid is None
                  else grid[start:start + chunk])
        exact = cam(counts * (cam.period / master_counts), 0, "right") * cam.scale
        error = np.abs(output(counts) - exact)
        j = int(error.argmax())
        if error[j] > worst:
            worst, at = float(error[j]), int(counts[j])
    return worst, at, how


# -- readings and the certificate ---------------------------------------------------------------------
@dataclass(frozen=True)
class Reading:
    """One way to read the consumer's documentation.

    ``hermite`` is its interpolant over master user units. A consumer that sees whole master counts
    and outputs whole slave counts gives ``output(master_counts) -> slave counts`` and the most its
    rounding can add, ``output_rounding_counts``."""

    name: str
    hermite: Hermite
    output: object = None
    output_rounding_counts: float = 0.0


@dataclass(frozen=True)
class ExportCertificate:
    """The error of one export under its consumer's interpolation, in slave user units.

    Not :class:`ecam.Certificate`, which certifies ecam's own fixed-point table under its
    integer lookup.

    ``readings`` holds (name, predicted, measured) for every plausible reading of the consumer's
    documentation; the certificate's bound and measured error are the largest over them, and
    ``worst_reading`` names the one measured worst."""

    predicted_error_units: float
    max_error_units: float
    max_error_at_master: float
    max_error_interval: int
    evaluated: str
    slave_counts_per_unit: float
    slave_unit: str
    master_unit: str
    readings: tuple = ()
    worst_reading: str = ""
    tolerance_units: float | None = None

    @property
    def predicted_error_counts(self) -> float:
        """The predicted bound in slave counts."""
        return self.predicted_error_units * self.slave_counts_per_unit

    @property
    def max_error_counts(self) -> float:
        """The measured error in slave counts."""
        return self.max_error_units * self.slave_counts_per_unit

    def to_dict(self) -> dict:
        """The certificate as the keys of ``ecam export --json`` (errors in units and counts,
        every reading, the tolerance when one was asked for)."""
        out = {
            "predicted_error_units": self.predicted_error_units,
            "predicted_error_counts": self.predicted_error_counts,
            "max_error_units": self.max_error_units,
            "max_error_counts": self.max_error_counts,
            "max_error_at_master": self.max_error_at_master,
            "max_error_interval": self.max_error_interval,
            "evaluated": self.evaluated,
            "slave_counts_per_unit": self.slave_counts_per_unit,
            "slave_unit": self.slave_unit,
            "master_unit": self.master_unit,
            "readings": [{"reading": name, "predicted_error_units": p, "max_error_units": m}
                         for name, p, m in self.readings],
            "worst_reading": self.worst_reading,
        }
        if self.tolerance_units is not None:
            out["tolerance_units"] = self.tolerance_units
            out["tolerance_counts"] = self.tolerance_units * self.slave_counts_per_unit
        return out


def predicted(cam: Cam, reading: Reading) -> float:
    """The predicted bound of one reading (units)."""
    return float(interval_bounds(cam, reading.hermite, extra=reading.output_rounding_counts / cam.scale).max())


def certify(cam: Cam, readings, tolerance_units: float | None = None) -> ExportCertificate:
    """Predict and measure every reading. The certificate holds the largest bound and the largest
    measured error over the readings (``worst_reading`` is the one measured worst)."""
    rows = []
    worst = None
    for reading in readings:
        bound = predicted(cam, reading)
        if reading.output is not None:
            error_counts, at_count, how = measure_counts(cam, reading.output, master_counts=cam.master_counts)
            error = error_counts / cam.scale
            master = at_count * cam.period / cam.master_counts
            interval = int(np.clip(np.searchsorted(reading.hermite.x, master, side="right") - 1,
                                   0, reading.hermite.x.size - 2))
        else:
            error, master, interval = measure_float(cam, reading.hermite)
            how = f"{DENSE_PER_INTERVAL + 1} master positions in every interval and each interval's extremum"
        rows.append((reading.name, bound, error))
        if worst is None or error > worst[1]:
            worst = (reading.name, error, master, interval, how)
    name, error, master, interval, how = worst
    several = len(rows) > 1
    return ExportCertificate(
        predicted_error_units=max(bound for _, bound, _ in rows), max_error_units=error,
        max_error_at_master=master, max_error_interval=interval, evaluated=how, slave_counts_per_unit=cam.scale,
        slave_unit=cam.profile.slave_unit, master_unit=cam.profile.master_unit,
        readings=tuple(rows) if several else (), worst_reading=name if several else "",
        tolerance_units=tolerance_units,
    )


# -- point placement ----------------------------------------------------------------------------------
def greedy_knots(bound, grid: int, forced, budget: float, *, min_step: int = 1, most: int | None = None,
                 bounds=None):
    """Fewest knots on the grid 0..grid whose every interval's bound is within ``budget``.

    ``bound(i, j)`` is the predicted bound of the interval between grid indices i < j; it must not
    decrease when the interval grows (so the greediest reach from each knot is optimal). ``forced``
    are grid indices that must be knots (0 and ``grid`` included). Knots are at least ``min_step``
    apart. Returns the knot indices, or None when even ``min_step`` misses the budget somewhere or
    more than ``most`` knots would be needed.

    ``bounds(i, js)``, optional, gives ``bound(i, j)`` for every j of an array at once, to the
    same numbers. The search then asks it, whenever it needs a bound it has not got, for that one
    together with those it may need next from the same knot (the next doublings, the bisection
    below the current bracket): a knot costs one or two calls instead of one per probe, and the
    knots are the same.
    """
    knots = [forced[0]]
    guess = min_step
    for start, end in zip(forced[:-1], forced[1:]):
        if end - start < min_step:
            return None
        i = start
        while i < end:
            known: dict = {}  # bound(i, j) by j

            def ok(j, ahead=lambda: ()):
                if not (j == end or j <= end - min_step):
                    return False
                if j not in known:
                    if bounds is None:
                        known[j] = bound(i, j)
                    else:
                        wanted = sorted({k for k in (j, *ahead()) if i < k <= end and k not in known})
                        values = bounds(i, np.array(wanted, dtype=np.int64))
                        known.update(zip(wanted, (float(v) for v in values)))
                return known[j] <= budget

            first = min(end, i + max(guess, min_step))  # the reach tried first: the last step's
            if ok(end, lambda: [i + min_step, first, *_doublings(i, first, end, 3),
                                *_bisections(i + min_step, first, 5),
                                *_bisections(first, min(end, first + (first - i)), 5)]):
                knots.append(end)
                break
            low = i + min_step
            if low > end or not ok(low):
                return None
            high = first
            if ok(high):  # grow until the bound fails
                low = high
                while True:
                    high = min(end, low + (low - i))
                    if not ok(high, lambda: [*_doublings(i, high, end, 3), *_bisections(low, high, 4)]):
                        break
                    low = high
                    if high == end:
                        break
            while high - low > 1:
                mid = (low + high) // 2
                if ok(mid, lambda: _bisections(low, high, 5)):
                    low = mid
                else:
                    high = mid
            guess = low - i
            knots.append(low)
            i = low
            if most is not None and len(knots) > most:
                return None
    return knots


def _doublings(i: int, reach: int, end: int, count: int) -> list[int]:
    """The next ``count`` reaches of :func:`greedy_knots`' growth from knot i past ``reach``."""
    out = []
    for _ in range(count):
        reach = min(end, reach + (reach - i))
        out.append(reach)
    return out


def _bisections(low: int, high: int, depth: int) -> list[int]:
    """Every probe a bisection of (low, high) may make in its next ``depth`` steps."""
    out, brackets = [], [(low, high)]
    for _ in range(depth):
        narrower = []
        for lo, hi in brackets:
            if hi - lo > 1:
                mid = (lo + hi) // 2
                out.append(mid)
                narrower += [(lo, mid), (mid, hi)]
        brackets = narrower
    return out


def equidistributed(cam: Cam, intervals: int, order: int, forced, grid: int, floor: float = 1e-3,
                    end_intervals: int = 1) -> np.ndarray:
    """``intervals`` intervals placed where |d^order y/dx^order|^(1/order) is large (the error of an
    interpolation of that order then shares out evenly), with ``forced`` master positions as knots;
    snapped to the grid of ``grid`` steps per period. ``floor`` (a fraction of the mean density) is
    added everywhere, so no interval grows without bound where the derivative vanishes (a dwell).
    The first and last stretches between forced knots get at least ``end_intervals`` intervals.
    Returns sorted unique knot grid indices.

    Each stretch between forced knots is cut into 4096 cells weighed by the density at their
    middle; the intervals are shared out by weight (largest remainder), and each stretch's knots
    cut its cumulative weight evenly. The weights are computed once per cam, order, forced knots
    and floor (:class:`.stretches.Stretches`): a search over the count pays only the sharing out.
    """
    forced = tuple(sorted(set(forced)))
    key = (order, forced, floor)
    if key not in cam._stretches:
        cam._stretches[key] = Stretches(cam, order, forced, floor)
    stretches = cam._stretches[key]
    totals = stretches.totals
    base = np.ones(totals.size, dtype=int)
    base[0] = max(base[0], end_intervals)
    base[-1] = max(base[-1], end_intervals)
    total = max(intervals, int(base.sum()))
    desired = totals / totals.sum() * total
    counts = settle(np.maximum(base, np.floor(desired).astype(int)), base, desired, total)
    knots = stretches.knots(counts)
    return np.unique(np.round(knots / cam.period * grid).astype(np.int64))


def place_local(cam: Cam, degree: int, *, grid: int, tolerance, points, limit: int, what: str,
                file_points=lambda knots: knots, min_step: int = 1, quantum: float = 0.0,
                rounding: float = 0.0) -> np.ndarray:
    """Knots (grid indices 0..grid over one period) for a consumer whose interval depends on its two
    ends only (straight lines, or Hermite polynomials through the cam's own derivatives).

    With a tolerance: the fewest knots whose every interval's predicted bound is within it (greedy
    from the start; every derivative jump of order <= degree is a knot). With ``points``: that many,
    placed by :func:`equidistributed`. ``quantum`` is the step of the stored positions (user units;
    rounding costs half of it), ``rounding`` what the consumer's own output rounding adds (units).
    ``file_points(knots)`` says how many points the file holds for that many knots.
    """
    r = (degree + 1) // 2
    forced = sorted({int(round(x / cam.period * grid)) for x in cam.breaks(degree)})
    cache: dict = {}

    def data(indices):  # (stored data, right limits, left limits) at grid indices, one row each
        missing = sorted({k for k in indices.tolist() if k not in cache})
        if missing:
            at = np.array(missing, dtype=np.int64)
            stored, right, left = knot_data(cam, at * cam.period / grid, r, sides=True)
            cache.update((k, (stored[n], right[n], left[n])) for n, k in enumerate(missing))
        rows = [cache[k] for k in indices.tolist()]
        return tuple(np.array([row[part] for row in rows]) for part in range(3))

    stored_rounding = quantum / 2 * _SAMPLE_MARGIN + rounding  # the most rounding adds (units)

    def bounds(i, js):  # the bounds of the intervals from grid index i to each of js, at once
        (stored_i, right_i, _), (stored_j, _, left_j) = data(np.array([i])), data(js)
        start = np.full(js.size, i) * (cam.period / grid)
        return _bounds(cam, degree, start, js * (cam.period / grid), np.repeat(stored_i, js.size, axis=0),
                       stored_j, extra=stored_rounding, inside=(np.repeat(right_i, js.size, axis=0), left_j))

    def bound(i, j):
        return float(bounds(i, np.array([j], dtype=np.int64))[0])

    def spread(count):  # every joint is a knot here: a dwell's ends bound the error tightly
        return spread_knots(cam, count, degree + 1, cam.breaks(5), grid, min_step=min_step)

    if points is not None:
        knots = next((count for count in range(points + 1, 1, -1) if file_points(count) == points), None)
        if knots is None:
            raise InputError(f"points: {points} should be at least {file_points(2)}")
        # Before the placement, which tries up to 40 spreads of that many knots (minutes at a
        # million) before it finds that the grid has no room for them.
        if knots > grid // min_step + 1:
            raise InputError(f"points: {points} should be at most {file_points(grid // min_step + 1)}: "
                             f"{knots} knots {min_step} master count(s) apart do not fit a period of {grid} "
                             "counts (give more --master-counts or fewer points)")
        return spread(knots)
    most = min(limit + 1, grid // min_step + 1)  # no more knots than the grid holds
    while file_points(most) > limit:
        most -= 1
    knots = greedy_knots(bound, grid, forced, tolerance, min_step=min_step, most=most, bounds=bounds)
    if knots is not None and file_points(len(knots)) <= limit:
        return np.array(knots)
    # Over the limit (or a step below the minimum spacing somewhere): spreading the points by the
    # error may still meet the tolerance within the limit; if not, that spread's bound is the best
    # error ecam reaches.

    def spread_bound(count):
        try:
            spread_at = spread(count)
        except InputError:
            return math.inf, None
        x = spread_at * (cam.period / grid)
        hermite = Hermite.continuous(x, degree, knot_data(cam, x, r))
        return float(interval_bounds(cam, hermite, extra=stored_rounding).max()), spread_at

    best, _ = spread_bound(most)
    while not math.isfinite(best) and most > 2:
        # that many knots do not fit the grid where the error wants them (a cam whose rises are
        # shorter than the limit in whole master counts): the best error is that of the most that do
        most = max(2, most - max(1, most // 16))
        best, _ = spread_bound(most)
    if best > tolerance:
        raise unreachable(what, tolerance, best, limit, cam, file_points(most))
    low, high = 1, most  # spread_bound(high) meets the tolerance; bisect for the fewest
    while high - low > 1:
        mid = (low + high) // 2
        if spread_bound(mid)[0] <= tolerance:
            high = mid
        else:
            low = mid
    return spread_bound(high)[1]


def joint_masters(cam: Cam, knots: np.ndarray, grid: int, values: int) -> tuple[np.ndarray, list[float]]:
    """Master positions (user units) of knots on a grid of ``grid`` steps per period, with each joint
    of the cam that the grid rounds to a knot put back where it is, when the ``values`` derivatives a
    point carries (0 .. values - 1) are continuous there.

    Placement works on whole master counts; a consumer that reads the master position as a real
    number (CODESYS ``dX``, the CSV's master column) then gets the joint itself as a point
    (``120.0``, not the count grid's ``120.00091552734375`` at 131072 counts per 360 deg), with the
    cam's own values there: a dwell's end at the dwell's height and velocity 0. A joint is within
    half a count of its knot, so the points stay in order; where two joints round to one knot, the
    nearer one is placed.

    A joint where a carried derivative jumps (a harmonic rise's acceleration against a dwell) stays
    on its count: a point carries one value of each derivative, and at the joint either side's value
    is wrong for the other side's whole interval, while a count beside the joint lies inside one side
    (the placement puts a point on the count on the other side when the bound needs it). Returns
    the positions and those joints (off the grid, not moved).
    """
    on_grid = np.asarray(knots, dtype=np.int64) * (cam.period / grid)
    master = on_grid.copy()
    where = {int(k): n for n, k in enumerate(np.asarray(knots).tolist())}
    jumping = set(cam.breaks(values - 1))
    kept = []
    for x in cam.breaks(5):
        n = where.get(int(round(x / cam.period * grid)))
        if n is None or x == on_grid[n]:
            continue
        if x in jumping:
            kept.append(x)
        elif master[n] == on_grid[n] or abs(x - on_grid[n]) < abs(master[n] - on_grid[n]):
            master[n] = x
    return master, kept


def hermite_points(cam: Cam, knots: np.ndarray, grid: int, degree: int, reading: str, tolerance):
    """The rows a point-list consumer reads (master and the cam's derivatives ``0..(degree-1)/2``, as
    the shortest decimals of their float64s), their master positions and their certificate, with the
    joints at their real positions where :func:`joint_masters` puts them there.

    Returns ``(rows, master, certificate, note)``; ``note`` (else ``""``) names the joints left on
    whole master counts, and why. The placement's bound holds on the count grid: should moving the
    joints take the bound over ``tolerance``, every point stays on the grid, and the note says so.
    """
    values = (degree + 1) // 2

    def build(master):
        data = knot_data(cam, master, values)
        # The file holds the shortest decimal of each float64: the consumer reads the very same numbers.
        rows = [[positional(v) for v in (x, *row)] for x, row in zip(master, data)]
        hermite = Hermite.continuous(np.array([float(r[0]) for r in rows]), degree,
                                     np.array([[float(v) for v in r[1:]] for r in rows]))
        return rows, master, certify(cam, [Reading(reading, hermite)], tolerance)

    munit, counts = cam.profile.master_unit, f"whole master counts ({grid} per period)"
    on_grid = np.asarray(knots, dtype=np.int64) * (cam.period / grid)
    real, kept = joint_masters(cam, knots, grid, values)
    carried = ", ".join(("slave", "velocity", "acceleration")[:values])
    note = (f"the joints at {', '.join(f'{x:.6g}' for x in kept)} {munit} are points on {counts}, beside "
            f"the joint: a value a point carries ({carried}) jumps there, and a point holds one value of "
            "each") if kept else ""
    if np.array_equal(real, on_grid):
        return (*build(on_grid), note)
    built = build(real)
    if tolerance is None or built[2].predicted_error_units <= tolerance:
        return (*built, note)
    moved = [float(x) for x, g in zip(real, on_grid) if x != g]
    return (*build(on_grid),
            f"the joints at {', '.join(f'{x:.6g}' for x in moved + kept)} {munit} are points on {counts}: at "
            f"their real positions the predicted bound would be {built[2].predicted_error_units:.6g} "
            f"{cam.profile.slave_unit}, above the tolerance")


def spread_knots(cam: Cam, count: int, order: int, forced, grid: int, *, min_step: int = 1, **placement) -> np.ndarray:
    """Exactly ``count`` knots (grid indices, 0 and ``grid`` included) by :func:`equidistributed`,
    at least ``min_step`` apart. Raises InputError when that many cannot be placed (fewer than the
    joints that must be knots, or more than the grid holds)."""
    if min_step == 1 and count == grid + 1:  # every grid point
        return np.arange(grid + 1, dtype=np.int64)
    impossible = False
    if min_step == 1:
        # Every spread keeps each stretch's end (the forced knots after 0) as a knot, and no two knots
        # merge: fewer knots than those ends never come out, however the intervals are shared.
        ends = {int(round(x / cam.period * grid)) for x in sorted(set(forced))[1:]}
        impossible = count < len(ends)
    intervals = count - 1
    for _ in range(0 if impossible else 40):
        knots = equidistributed(cam, max(1, intervals), order, forced, grid, **placement)
        kept = [int(knots[0])]
        for k in knots[1:]:
            if k - kept[-1] >= min_step:
                kept.append(int(k))
            elif k == grid:
                kept[-1] = int(k) if len(kept) > 1 else kept[-1]
        if kept[-1] != grid:
            kept.append(grid)
        if len(kept) == count:
            return np.array(kept, dtype=np.int64)
        step = count - len(kept)
        if intervals + step < 1:
            break
        intervals += step
    raise InputError(f"points: {count} knots should leave room for every joint of the cam as a point, "
                     f"{min_step} grid steps apart (try a few more or fewer)")


def fewest(counts, ok):
    """The first count in ``counts`` (ascending) for which ``ok(count)`` holds, or None. Every count
    up to 64 is tried in turn (errors of global interpolants are not monotone in the count there);
    beyond, steps of about 3 % bracket the first success and a bisection narrows the bracket."""
    counts = list(counts)
    previous = None
    index = 0
    while index < len(counts):
        count = counts[index]
        if ok(count):
            if previous is None or count - previous <= 1:
                return count
            low, high = previous, count  # ok(low) failed, ok(high) holds
            while high - low > 1:
                mid = (low + high) // 2
                if ok(mid):
                    high = mid
                else:
                    low = mid
            return high
        previous = count
        index += 1 if count < 64 else max(1, int(count * 0.03))
    return None


# -- the export ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class VendorExport:
    """A cam table for one consumer: the file's text and its certificate.

    Attributes
    ----------
    format, interpolation : str
        The format name (``ecam.export.VENDOR_FORMATS``) and the consumer's interpolation.
    points : int
        Points (rows, table entries) in the file: what the consumer's limit counts.
    limit : int
        The consumer's point limit.
    content : str
        The file, ready to write.
    suffix : str
        The usual file name ending.
    certificate : ExportCertificate
    master : ndarray
        Master position of every point, user units.
    notes : tuple of str
        What to set on the controller, and what the documentation leaves open.
    """

    format: str
    interpolation: str
    points: int
    limit: int
    content: str
    suffix: str
    certificate: ExportCertificate
    master: np.ndarray = field(repr=False)
    notes: tuple = ()

    @property
    def crc32(self) -> int:
        return zlib.crc32(self.content.encode("utf-8"))

    def summary(self) -> dict:
        """The export as a JSON-ready dictionary (``ecam export --json``, without ``file``)."""
        out = {"format": self.format, "interpolation": self.interpolation, "points": self.points,
               "point_limit": self.limit, "crc32": self.crc32, "bytes": len(self.content.encode("utf-8"))}
        out.update(self.certificate.to_dict())
        out["notes"] = list(self.notes)
        return out

    def report_text(self, name: str) -> str:
        c = self.certificate
        unit, munit = c.slave_unit, c.master_unit
        lines = [
            f"{name} -> {self.format}: {self.interpolation}, {self.points} points (limit {self.limit})",
            f"  predicted bound {c.predicted_error_units:.4g} {unit} = {c.predicted_error_counts:.4g} counts; "
            f"measured max {c.max_error_units:.4g} {unit} = {c.max_error_counts:.4g} counts "
            f"at master {c.max_error_at_master:.6g} {munit} ({c.evaluated})",
        ]
        for reading, bound, error in c.readings:
            mark = "  <- measured worst" if reading == c.worst_reading else ""
            lines.append(f"  reading '{reading}': bound {bound:.4g} {unit}, measured {error:.4g} {unit}{mark}")
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines)


def tolerance_units(tolerance, cam: Cam) -> float:
    """A tolerance (slave units, or a string such as '2 counts' or '0.01 mm' in the cam's slave unit)
    in slave user units."""
    value, in_counts = parse_tolerance(tolerance, slave_unit=cam.profile.slave_unit)
    return value / cam.scale if in_counts else value


def unreachable(what: str, tolerance: float, best: float, limit: int, cam: Cam, at_points: int) -> TableFormatError:
    """The one-line error for a tolerance no table within the consumer's limit meets."""
    unit = cam.profile.slave_unit
    return TableFormatError(
        f"tolerance: {tolerance:.4g} {unit} ({tolerance * cam.scale:.4g} counts) should be at least "
        f"{best:.4g} {unit} ({best * cam.scale:.4g} counts), the smallest error ecam reaches with {what} "
        f"within its limit of {limit} points (at {at_points} points)")


def positional(value: float) -> str:
    """The shortest decimal that reads back as the same float64, without an exponent
    (``1e-05`` -> ``0.00001``), and with a decimal point."""
    value = float(value)
    if not math.isfinite(value):
        raise InputError(f"value: {value!r} should be finite")
    if value == 0.0:
        return "0.0"
    text = format(Decimal(repr(value)), "f")
    return text if "." in text else text + ".0"


def content_crc(text: str) -> int:
    return zlib.crc32(text.encode("utf-8"))


def check_points(points, minimum: int, limit: int) -> int:
    return integer("points", points, minimum=minimum, maximum=limit)
