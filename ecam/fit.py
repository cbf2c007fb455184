r"""Cams from points: a quintic smoothing spline through a point table, its deviation certified.

Given points ``(x_i, y_i)`` (master, slave, user units) with weights ``w_i``, :func:`fit_points`
returns the function ``f`` that minimizes

.. math::

    \sum_i w_i \, (y_i - f(x_i))^2 + \lambda \int f'''(x)^2 \, dx

over the master range (over one period, ``f`` periodic, for a periodic cam). The minimizer is a
spline of degree 2m - 1 = 5 for this penalty on the m = 3rd derivative (Schoenberg 1964; Reinsch
1967 for m = 2; Wahba, *Spline Models for Observational Data*, SIAM 1990, ch. 1): a quintic with
continuous position, velocity, acceleration, jerk and snap (C4), the jerk's square integral the
roughness it trades against the deviation. Periodic cams use periodic B-splines, so all of that
holds across the seam; a net-stroke cam fits ``y - N x / P`` periodically (the ramp has no jerk,
so the penalty is the same) and adds the ramp back.

**Basis and knots.** ``f`` is a quintic B-spline (de Boor, *A Practical Guide to Splines*, 1978:
the recurrences for the values and derivatives of the B-splines, BSPLVB, and for the derivative's
coefficients). Up to ``MAX_KNOTS`` distinct master positions the knots are the data sites: the
exact smoothing spline. Beyond, a penalized regression spline (O'Sullivan 1986) on
``MAX_KNOTS`` intervals placed where the points need them: half equidistribute the points, half
equidistribute ``|f^(6)|^(1/6)`` of a pilot fit, de Boor's rule for the knots of an order-6 spline
(NEWNOT, *A Practical Guide*, ch. XII), so intervals shrink where the shape bends fastest. When
a tolerance is not met, knots are added inside the intervals whose points miss it.

**Solving for every lambda at once.** With ``G = B^T W B`` (the weighted Gram matrix of the
basis at the points) and ``Omega`` (the penalty's Gram matrix of third derivatives, exact by
3-point Gauss-Legendre per interval), the coefficients solve ``(G + lambda Omega) c = B^T W y``.
Following Demmler and Reinsch (1975), one Cholesky factor ``L L^T = G + c0 Omega`` and one
symmetric eigen-decomposition ``L^-1 Omega L^-T = U diag(m) U^T`` give ``c(lambda) = L^-T U
diag(1 / (1 + (lambda - c0) m)) U^T L^-1 B^T W y`` and the hat matrix's trace
``sum (1 - c0 m) / (1 + (lambda - c0) m)`` for any lambda in O(K^2): the search over lambda costs
no further factorization. ``c0 = tr G / tr Omega`` balances the two, so ``L`` is well conditioned
(B-splines are a well-conditioned basis: de Boor 1976).

**Choosing lambda.** With a tolerance: the smoothest fit (largest lambda, smallest peak jerk over
the candidates) whose largest deviation from the points is at most the tolerance -- a grid of
lambda over 28 decades, then bisection at the edge of the feasible ones. Without: generalized
cross-validation (Craven and Wahba 1979), the lambda that minimizes ``n RSS_w / (n - tr H)^2``.
The result says which was used.

**The cam.** The spline is written as one ``law = "spline"`` segment (:mod:`ecam.spline`): its
knots and, per knot, position and derivatives 1..5 from the right, each derivative taken from the
derivative spline's own coefficients, so that both sides of a knot agree to rounding in every
derivative. The deviation certified is that of this cam, evaluated as the compiler evaluates it,
at every given point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .errors import InputError
from .profile import CamProfile, Segment
from .spline import spline_law

__all__ = ["fit_points", "FitResult", "MAX_KNOTS", "MAX_FIT_POINTS", "MIN_FIT_POINTS"]

DEGREE = 5
MIN_FIT_POINTS = 6
MAX_FIT_POINTS = 2_000_000
# Knot intervals of the fit: the data sites up to this many, else placed (module docstring). The
# cost is one K^3 factorization per knot set plus O(K^2 + n) per lambda tried.
MAX_KNOTS = 600
# Knot intervals a tolerance may ask for, refinement included.
MAX_REFINED_KNOTS = 1600
# log10(lambda / c0) tried: 28 decades, two steps a decade.
_GRID = np.arange(-12.0, 16.0001, 0.5)
# A step: one interval rising this share of the slave range at least ...
STEP_SHARE = 0.05
# ... this many times steeper than the intervals on either side.
STEP_STEEPNESS = 10.0
# Duplicate master positions are averaged unless their slave values spread more than this share
# of the slave range: then they are a step.
DUPLICATE_SPREAD = 0.01
ORDER_NAMES = ("position", "velocity", "acceleration", "jerk")
# 3-point Gauss-Legendre rule on [-1, 1] (exact for degree 5; the penalty's integrand, a product
# of two quadratics, has degree 4): nodes 0, +-sqrt(3/5), weights 8/9, 5/9 (Abramowitz and Stegun,
# Handbook of Mathematical Functions, table 25.4).
_GAUSS_NODES = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])
_GAUSS_WEIGHTS = np.array([5 / 9, 8 / 9, 5 / 9])


@dataclass(frozen=True)
class FitResult:
    """A fitted cam and its certificate.

    Attributes
    ----------
    profile : CamProfile
        The cam: one ``law = "spline"`` segment from master 0 (the first point) over the period
        (periodic) or the points' range.
    smoothing : str
        ``"tolerance"`` (the smoothest fit within it) or ``"gcv"`` (generalized cross-validation).
    certificate : dict
        The JSON certificate (:meth:`FitResult.certificate` documents its fields).
    """

    profile: CamProfile
    smoothing: str
    certificate: dict = field(repr=False)
    residuals: np.ndarray = field(repr=False)
    master: np.ndarray = field(repr=False)
    slave: np.ndarray = field(repr=False)

    @property
    def max_deviation(self) -> float:
        """Largest |fit - point| over the points (slave units)."""
        return self.certificate["max_deviation"]

    @property
    def rms_deviation(self) -> float:
        """Root mean square of fit - point (slave units)."""
        return self.certificate["rms_deviation"]

    def report_text(self) -> str:
        """The certificate as a few lines of text."""
        c = self.certificate
        unit, munit = c["slave_unit"], c["master_unit"]
        how = (f"the smoothest within the tolerance {c['tolerance']:.6g} {unit}" if c["smoothing"] == "tolerance"
               else "generalized cross-validation (no tolerance given)")
        lines = [
            f"fit of {c['points']} points ({c['points_read']} read"
            + (f", {c['duplicates_averaged']} duplicate master positions averaged" if c["duplicates_averaged"] else "")
            + f"): quintic smoothing spline, C4"
            + (", periodic" if c["periodic"] else "")
            + (f", net stroke {c['net_stroke']:+.6g} {unit}" if c["net_stroke"] else ""),
            f"  smoothing: {how}; lambda {c['lambda']:.4g}, {c['effective_parameters']:.1f} effective parameters, "
            f"{c['knots']} knot intervals ({c['knot_placement']})",
            f"  master period {c['master_period']:.10g} {munit}"
            + (f", declared steps at {', '.join(f'{v:.6g}' for v in c['steps'])} {munit} (one segment per "
               "stretch)" if c["steps"] else "")
            + (f", from master {c['master_offset']:.10g} {munit} of the table" if c["master_offset"] else ""),
            f"  max deviation {c['max_deviation']:.4g} {unit} at master {c['max_deviation_at']:.6g} {munit} "
            f"(row {c['max_deviation_row']}); rms {c['rms_deviation']:.4g} {unit}",
            f"  {'':14s} {'fit':>12s} {'points (finite differences)':>28s}",
        ]
        for name in ORDER_NAMES[1:]:
            fit, raw = c["peaks"][name]["fit"], c["peaks"][name]["points"]
            lines.append(f"  peak {name:9s} {fit:12.5g} {raw:28.5g}   {unit}/{munit}^{ORDER_NAMES.index(name)}")
        lines.append(f"  continuity: {c['continuity']}")
        return "\n".join(lines)


def fit_points(master, slave, weights=None, *, tolerance=None, periodic: bool = False, net_stroke=None,
               period=None, name: str = "fit", master_unit: str = "deg", slave_unit: str = "mm",
               max_knots: int = MAX_KNOTS, steps=None) -> FitResult:
    """Fit a cam to a point table: a quintic smoothing spline (C4: jerk continuous), certified.

    Parameters
    ----------
    master, slave : array_like
        The points, master positions in increasing order (equal ones are averaged), user units.
    weights : array_like, optional
        Per point, >= 0 (e.g. 1 / variance); default 1.
    tolerance : float, optional
        Largest allowed |fit - point| (slave units): the smoothest fit (smallest peak jerk) within
        it. Default: generalized cross-validation.
    periodic : bool
        Fit a cam that repeats: C4 across the seam too.
    net_stroke : float, optional
        A periodic cam's slave advance per period (slave units); implies ``periodic``.
    period : float, optional
        A periodic cam's master period. Default: last master minus first (the last point repeats
        the first, one period on, as ecam's exports and most CAD tables write it; it is averaged
        with the first).
    name, master_unit, slave_unit : str
        Of the cam.
    max_knots : int
        Knot intervals beyond which the knots are placed rather than at every point.
    steps : sequence of float, optional
        Master positions where the table is declared to step: each stretch between them is
        fitted on its own (C4 inside), so the cam has one spline segment per stretch and the
        position may jump at the steps (``ecam check`` reports it). Of several points at a step,
        the first ends the stretch before it. Not with a net stroke. Default: none, and a step in
        the points is refused.

    Returns
    -------
    FitResult
        ``profile`` (the cam), ``smoothing`` ("tolerance" or "gcv"), ``certificate``.

    Raises
    ------
    InputError
        Bad points (NaN, too few, decreasing master), a step in the points, a tolerance below
        what the spline can reach: one line naming the field, the value and the limit.
    """
    x, y, w, rows = _points(master, slave, weights)
    read = x.size
    given_x, given_y = x, y
    if net_stroke is not None:
        net_stroke = validate.number("net_stroke", validate.plain(net_stroke))
        periodic = True
    net = net_stroke or 0.0
    validate.boolean("periodic", periodic)
    max_knots = validate.integer("max_knots", validate.plain(max_knots), minimum=MIN_FIT_POINTS,
                                 maximum=MAX_REFINED_KNOTS)
    span_range = float(np.ptp(y)) or 1.0
    if tolerance is not None:
        tolerance = validate.positive("tolerance", validate.plain(tolerance))
    x0 = float(x[0])
    if periodic:
        length = float(x[-1] - x0) if period is None else validate.positive("period", validate.plain(period))
        if not length > 0:
            raise validate.fail("master", "a single position", "a range > 0")
        if x[-1] - x0 > length * (1 + 1e-12):
            raise validate.fail("period", length, f"at least the points' range ({float(x[-1] - x0):.10g})")
        turns = np.floor((x - x0) / length + 1e-12)
        y = y - turns * net
        x = x - turns * length  # the last point, one period on, lands on the first
    else:
        length = float(x[-1] - x0)
    steps = _steps(steps, x0, length, net, periodic)
    pieces = []
    averaged = 0
    edges = [x0, *steps, x0 + length]
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        inside = _stretch(x, lo, hi, k == 0, k == len(edges) - 2)
        px, py, pw, slack, merged = _merge_duplicates(x[inside], y[inside], w[inside], span_range)
        averaged += merged
        where = f" between the steps at {lo:.10g} and {hi:.10g}" if steps else ""
        if px.size < MIN_FIT_POINTS:
            raise validate.fail("points", px.size, f"at least {MIN_FIT_POINTS} distinct master positions{where}")
        smooth = periodic and not steps
        _refuse_steps(px, py, span_range, smooth, length, net)
        pieces.append(_fit_stretch(px, py, pw, slack, lo, hi, smooth, net, tolerance, max_knots, slave_unit))
    # the cam's master starts at the first point; each segment where the one before ends (as a
    # cam file places them: start + the last knot)
    segments, master = [], 0.0
    for piece in pieces:
        law, start = piece["law"], piece["start"]
        segments.append(Segment(master, master + law.span, start, start + law.end_position, law, name))
        master = segments[-1].master_end
    profile = CamProfile(tuple(segments), master, periodic, name=name, master_unit=master_unit,
                         slave_unit=slave_unit, net_stroke=net if periodic and net else None)
    lam = pieces[0]["lambda"]
    system_k = sum(piece["knots"] for piece in pieces)
    placement = pieces[0]["placement"]
    effective = sum(piece["effective"] for piece in pieces)

    # the certificate: the cam as written, at every given point (a periodic cam unrolls by its
    # net stroke, so a last point one period on is compared as it stands)
    at = given_x - x0
    if not periodic:
        at = np.clip(at, 0.0, length)
    residuals = profile(at) - given_y
    k = int(np.argmax(np.abs(residuals)))
    peaks = {}
    for order in (1, 2, 3):
        peaks[ORDER_NAMES[order]] = {"fit": profile.peak(order), "points": _difference_peak(x, y, order, steps)}
    report = profile.check()
    continuity = ("position, velocity, acceleration and jerk continuous" + (" across the seam" if periodic else "")
                  if report.continuous(3) else
                  "; ".join(f"{ORDER_NAMES[d.order]} jumps {d.jump:+.3g} at {d.master:.6g}" for d in
                            report.discontinuities[:3]))
    certificate = {
        "points_read": int(read),
        "points": int(x.size - averaged),
        "duplicates_averaged": int(averaged),
        "periodic": bool(periodic),
        "net_stroke": float(net),
        "master_period": length,
        "master_offset": x0,
        "master_unit": master_unit,
        "slave_unit": slave_unit,
        "smoothing": "gcv" if tolerance is None else "tolerance",
        "tolerance": tolerance,
        "lambda": float(lam),
        "effective_parameters": float(effective),
        "knots": int(system_k),
        "knot_placement": placement,
        "steps": [float(v) for v in steps],
        "degree": DEGREE,
        "max_deviation": float(abs(residuals[k])),
        "max_deviation_at": float(given_x[k]),
        "max_deviation_row": int(rows[k]),
        "rms_deviation": float(np.sqrt(np.mean(residuals**2))),
        "peaks": peaks,
        "continuity": continuity,
        "check_ok": bool(report.continuous(3)),
    }
    return FitResult(profile, certificate["smoothing"], certificate, residuals, given_x, given_y)


def _fit_stretch(x, y, w, slack, lo, hi, periodic, net, tolerance, max_knots, slave_unit) -> dict:
    """The spline of one stretch [lo, hi] of master positions (the whole period when periodic):
    its law, start position, smoothing and knots."""
    length = hi - lo
    u = (x - lo) / length
    ramp = net * u if periodic else 0.0
    g = y - ramp
    center = float((g.max() + g.min()) / 2)
    yscale = float(np.ptp(g)) or 1.0
    target = (g - center) / yscale
    w = w / w.mean()
    slack = slack / yscale

    placement = "at the points"
    if x.size <= max_knots + (0 if periodic else 1):
        tau = np.concatenate([[0.0], u, [1.0]])
    else:
        placement = "placed: half by the points, half by the shape"
        tau = _quantile_knots(u, max_knots, periodic)
        pilot = _System(u, target, w, tau, periodic, slack)
        lam = pilot.gcv(refine=0)[0]
        tau = _shape_knots(u, pilot, pilot.coefficients(lam), max_knots, periodic)
    system = _System(u, target, w, tau, periodic, slack)
    tol_n = None if tolerance is None else tolerance / yscale
    for _ in range(8):  # knot refinement for a tolerance a coarse knot set cannot meet
        if tol_n is None:
            lam, _ = system.gcv()
            break
        lam = system.smoothest_within(tol_n)
        if lam is not None:
            break
        finer = system.refine(tol_n, MAX_REFINED_KNOTS)
        if finer is None:
            break
        placement = "refined where the tolerance was missed"
        system = _System(u, target, w, finer, periodic, slack)
    else:
        lam = system.smoothest_within(tol_n)
    if lam is None:
        best = system.least_deviation() * yscale
        raise validate.fail("tolerance", tolerance, f"at least {best:.3g} {slave_unit}, the smallest largest "
                            f"deviation a quintic spline on {system.K} knot intervals reaches here")
    coef = system.coefficients(lam)
    law, start = _spline(system, coef, length, yscale, center, net, periodic, x - lo)
    return {"law": law, "start": start, "lambda": lam * length**5, "effective": system.trace(lam), "knots": system.K,
            "placement": placement}


def _steps(steps, x0, length, net, periodic) -> list[float]:
    """Declared steps: master positions strictly inside the points' range, increasing."""
    if steps is None:
        return []
    if isinstance(steps, (str, bytes)) or not hasattr(steps, "__iter__"):
        raise validate.fail("steps", steps, "a list of master positions")
    out = []
    for i, value in enumerate(steps):
        value = validate.number(f"steps[{i}]", validate.plain(value))
        if not x0 < value < x0 + length:
            raise validate.fail(f"steps[{i}]", value, f"inside the points' master range ({x0:.10g} .. "
                                f"{x0 + length:.10g})")
        if out and not value > out[-1]:
            raise validate.fail(f"steps[{i}]", value, f"greater than steps[{i - 1}] ({out[-1]:.10g})")
        out.append(float(value))
    if out and net:
        raise validate.fail("steps", out, "absent with a net stroke (each stretch is fitted on its own, so the "
                            "period's advance would not be the net stroke exactly)")
    return out


def _stretch(x, lo, hi, first, last) -> np.ndarray:
    """The points of [lo, hi]: those at a step belong to the stretch after it, except that of
    several points at one step the first ends the stretch before (the table steps between them)."""
    inside = (x >= lo) & (x < hi) if not last else (x >= lo) & (x <= hi)
    if not first:  # points at lo: all but the first of them (it ended the stretch before)
        at = np.flatnonzero(x == lo)
        if at.size > 1:
            inside[at[0]] = False
    at = np.flatnonzero(x == hi)
    if not last and at.size > 1:
        inside[at[0]] = True
    return inside


# -- the points --------------------------------------------------------------------------------------
def _points(master, slave, weights):
    arrays = []
    for field_name, values in (("master", master), ("slave", slave), ("weights", weights)):
        if values is None:
            arrays.append(None)
            continue
        try:
            array = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            raise validate.fail(field_name, values, "a list of numbers") from None
        if array.ndim != 1:
            raise validate.fail(field_name, f"an array of shape {array.shape}", "a list of numbers (one column)")
        if array.size > MAX_FIT_POINTS:
            raise validate.fail(field_name, f"{array.size} points", f"at most {MAX_FIT_POINTS}")
        bad = ~np.isfinite(array)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise validate.fail(f"{field_name}[{i}]", float(array[i]), "a finite number")
        arrays.append(array)
    x, y, w = arrays
    if y.size != x.size:
        raise validate.fail("slave", f"{y.size} values", f"{x.size} values, one per master position")
    if w is None:
        w = np.ones(x.size)
    elif w.size != x.size:
        raise validate.fail("weights", f"{w.size} values", f"{x.size} values, one per master position")
    elif (w < 0).any():
        i = int(np.flatnonzero(w < 0)[0])
        raise validate.fail(f"weights[{i}]", float(w[i]), ">= 0")
    if x.size < MIN_FIT_POINTS:
        raise validate.fail("points", x.size, f"at least {MIN_FIT_POINTS}")
    down = np.flatnonzero(np.diff(x) < 0)
    if down.size:
        i = int(down[0]) + 1
        raise validate.fail(f"master[{i}]", float(x[i]), f">= master[{i - 1}] ({x[i - 1]:.10g}): the points in "
                            "increasing master order")
    keep = w > 0
    if keep.sum() < MIN_FIT_POINTS:
        raise validate.fail("weights", f"{int(keep.sum())} positive", f"at least {MIN_FIT_POINTS} positive")
    return x[keep], y[keep], w[keep], np.flatnonzero(keep)


def _merge_duplicates(x, y, w, span_range):
    """Points at the same master position become one, their weighted mean (weights summed); a
    spread above DUPLICATE_SPREAD of the slave range is a step, refused."""
    order = np.argsort(x, kind="stable")
    x, y, w = x[order], y[order], w[order]
    first = np.concatenate([[True], x[1:] != x[:-1]])
    if first.all():
        return x, y, w, np.zeros(x.size), 0
    group = np.cumsum(first) - 1
    weight = np.bincount(group, weights=w)
    mean = np.bincount(group, weights=w * y) / weight
    low = np.full(weight.size, np.inf)
    high = np.full(weight.size, -np.inf)
    np.minimum.at(low, group, y)
    np.maximum.at(high, group, y)
    spread = high - low
    bad = np.flatnonzero(spread > DUPLICATE_SPREAD * span_range)
    if bad.size:
        i = int(bad[0])
        raise InputError(f"slave: {low[i]:.6g} and {high[i]:.6g} at the same master {x[first][i]:.10g} should "
                         f"differ by at most {DUPLICATE_SPREAD:g} of the slave range ({DUPLICATE_SPREAD * span_range:.3g}) "
                         "to be averaged: a step, which a cam cannot follow")
    # the largest distance from the mean to a point it stands for: a deviation from the mean
    # plus this bounds the deviation from every one of them
    slack = np.zeros(weight.size)
    np.maximum.at(slack, group, np.abs(y - mean[group]))
    return x[first], mean, weight, slack, int(x.size - weight.size)


def _refuse_steps(x, y, span_range, periodic, length, net):
    """One interval that rises STEP_SHARE of the range, STEP_STEEPNESS times steeper than both
    neighbours: a step in the points (a jump a smooth cam would ring around), refused."""
    xs, ys = x, y
    if periodic:  # the seam's interval too, the first point one period on
        xs, ys = np.append(x, x[0] + length), np.append(y, y[0] + net)
    dy = np.diff(ys)
    slope = np.abs(dy / np.diff(xs))
    if periodic:
        before, after = np.roll(slope, 1), np.roll(slope, -1)
    else:
        before = np.concatenate([[0.0], slope[:-1]])
        after = np.concatenate([slope[1:], [0.0]])
    neighbours = np.maximum(before, after)
    steep = (np.abs(dy) > STEP_SHARE * span_range) & (slope > STEP_STEEPNESS * neighbours)
    if steep.any():
        i = int(np.flatnonzero(steep)[0])
        raise InputError(f"slave: steps by {dy[i]:+.6g} between master {xs[i]:.10g} and {xs[i + 1]:.10g} "
                         f"(rows {i} and {(i + 1) % x.size}), {slope[i] / max(neighbours[i], 1e-300):.3g} times "
                         f"steeper than either side, should be smooth: a cam cannot follow a step (correct the "
                         f"table, or declare it, steps=[{xs[i + 1]:.10g}] / --step {xs[i + 1]:.10g}, to fit either "
                         "side on its own)")


def _difference_peak(x, y, order: int, steps=()) -> float:
    """Largest |order-th divided difference| x order! of the points: the raw points' own
    velocity, acceleration or jerk (distinct master positions only; not across a declared step)."""
    keep = np.concatenate([[True], np.diff(x) > 0])
    x, y = x[keep], y[keep]
    best = 0.0
    for part in np.split(np.arange(x.size), np.searchsorted(x, steps)):
        values, xs = y[part].astype(float), x[part].astype(float)
        for k in range(1, order + 1):
            values = np.diff(values) / (xs[k:] - xs[:-k])
        if values.size:
            best = max(best, float(np.abs(values).max() * math.factorial(order)))
    return best


# -- knots -----------------------------------------------------------------------------------------
def _quantile_knots(u, count, periodic):
    """``count`` intervals with (about) as many points each."""
    if periodic:
        picks = u[np.round(np.arange(count) * (u.size / count)).astype(int)]
        tau = np.append(np.unique(np.append(picks, 0.0)), 1.0)
    else:
        tau = np.unique(u[np.round(np.linspace(0, u.size - 1, count + 1)).astype(int)])
        tau[0], tau[-1] = 0.0, 1.0
    return tau


def _shape_knots(u, system, coef, count, periodic):
    """de Boor's NEWNOT for order 6, blended with the points: equidistribute half the points'
    share and half of ``|f^(6)|^(1/6)`` (estimated from the jumps of the 5th derivative)."""
    tau = system.tau
    crackle = system.crackle(coef)  # per interval
    jumps = np.abs(np.diff(np.concatenate([crackle[-1:], crackle, crackle[:1]]) if periodic
                           else np.concatenate([crackle[:1], crackle, crackle[-1:]])))
    h = np.diff(tau)
    sixth = (jumps[:-1] + jumps[1:]) / (2 * np.maximum(h, 1e-300))  # |f^(6)| per interval
    shape = sixth ** (1 / 6) * h
    density = np.histogram(u, bins=tau)[0].astype(float)
    cumulative = 0.5 * np.cumsum(density) / density.sum() + 0.5 * np.cumsum(shape) / max(shape.sum(), 1e-300)
    cumulative = np.concatenate([[0.0], cumulative])
    cumulative[-1] = 1.0
    targets = np.linspace(0.0, 1.0, count + 1)
    new = np.interp(targets, cumulative, tau)
    new = np.unique(np.concatenate([new, [0.0, 1.0]]))
    return new[(new >= 0.0) & (new <= 1.0)]


# -- B-splines -------------------------------------------------------------------------------------
def _bsplines(t, i, x, nu):
    """Values of derivative ``nu`` of the 6 quintic B-splines nonzero on [t[i], t[i+1]) at x (one
    row per point, B_{i-5} .. B_i): de Boor's BSPLVB to degree 5 - nu, then the derivative
    recurrence (de Boor 1978, ch. X)."""
    m = x.size
    low = DEGREE - nu
    b = np.zeros((m, DEGREE + 1))
    b[:, 0] = 1.0
    right = np.empty((m, DEGREE))
    left = np.empty((m, DEGREE))
    for j in range(low):
        right[:, j] = t[i + 1 + j] - x
        left[:, j] = x - t[i - j]
        saved = np.zeros(m)
        for r in range(j + 1):
            term = b[:, r] / (right[:, r] + left[:, j - r])
            b[:, r] = saved + right[:, r] * term
            saved = left[:, j - r] * term
        b[:, j + 1] = saved
    for d in range(low + 1, DEGREE + 1):
        new = np.zeros((m, d + 1))
        for r in range(d + 1):
            jj = i - d + r
            if r >= 1:
                denominator = t[jj + d] - t[jj]
                new[:, r] += np.divide(b[:, r - 1], denominator, out=np.zeros(m), where=denominator > 0)
            if r <= d - 1:
                denominator = t[jj + d + 1] - t[jj + 1]
                new[:, r] -= np.divide(b[:, r], denominator, out=np.zeros(m), where=denominator > 0)
        b[:, : d + 1] = d * new
    return b


class _System:
    """The normal equations of one knot set, solved for any lambda by a banded Cholesky factor
    (module docstring)."""

    def __init__(self, u, y, w, tau, periodic, slack):
        # Knots on multiples of 2^-52: a periodic basis repeats them one period on (tau + 1) and
        # before (tau - 1), which is then exact, so both sides of the seam are computed from the
        # same numbers and agree in every derivative as any inner knot does.
        tau = np.unique(np.round(np.asarray(tau) * 2.0**52) / 2.0**52)
        self.u, self.y, self.w, self.tau, self.periodic, self.slack = u, y, w, tau, periodic, slack
        K = self.K = tau.size - 1
        if periodic:
            self.t = np.concatenate([tau[K - DEGREE:K] - 1.0, tau, tau[1:DEGREE + 1] + 1.0])
            self.size = K
        else:
            self.t = np.concatenate([np.zeros(DEGREE), tau, np.ones(DEGREE)])
            self.size = K + DEGREE
        self.cols, self.vals = self._rows(u, 0)
        n = self.size
        self.G = self._gram(self.cols, self.vals, w)
        self.r = np.bincount(self.cols.ravel(), weights=(self.vals * (w * y)[:, None]).ravel(), minlength=n)
        nodes, weights = _GAUSS_NODES, _GAUSS_WEIGHTS
        h = np.diff(tau)
        xq = (tau[:-1, None] + h[:, None] * (nodes[None, :] + 1) / 2).ravel()
        wq = (h[:, None] * weights[None, :] / 2).ravel()
        cols3, vals3 = self._rows(xq, 3, interval=np.repeat(np.arange(K), 3))
        self.omega = self._gram(cols3, vals3, wq)
        self.c0 = float(np.trace(self.G) / np.trace(self.omega))
        self.lam_min = self.c0 * 10.0 ** _GRID[0]
        # where the jerk is sampled for its peak: each interval's ends and 3 points inside
        xs = (tau[:-1, None] + h[:, None] * np.linspace(0, 1, 5)[None, :-1]).ravel()
        self.jerk_rows = self._rows(np.append(xs, 1.0), 3,
                                    interval=np.append(np.repeat(np.arange(K), 4), K - 1))
        self._solved: dict = {}

    def _rows(self, x, nu, interval=None):
        if interval is None:
            interval = np.clip(np.searchsorted(self.tau, x, side="right") - 1, 0, self.K - 1)
        vals = _bsplines(self.t, interval + DEGREE, x, nu)
        cols = interval[:, None] + np.arange(DEGREE + 1)[None, :]
        if self.periodic:
            cols = cols % self.K
        return cols, vals

    def _gram(self, cols, vals, w):
        n = self.size
        flat = (cols[:, :, None] * n + cols[:, None, :]).ravel()
        products = (vals[:, :, None] * vals[:, None, :] * w[:, None, None]).ravel()
        return np.bincount(flat, weights=products, minlength=n * n).reshape(n, n)

    def factor(self, lam) -> "_Factor":
        return _Factor(self.G + lam * self.omega, DEGREE, self.periodic)

    def coefficients(self, lam):
        if lam not in self._solved:
            factor = self.factor(lam)
            self._solved = {lam: (factor, factor.solve(self.r))}  # the last one only: memory
        return self._solved[lam][1]

    def fitted(self, coef):
        return (self.vals * coef[self.cols]).sum(axis=1)

    def max_deviation(self, coef):
        return float((np.abs(self.fitted(coef) - self.y) + self.slack).max())

    def trace(self, lam):
        """tr H = tr(A^-1 G): the entries of A^-1 = Z^T Z (Z = L^-1) where G has entries."""
        self.coefficients(lam)
        z = self._solved[lam][0].inverse_factor()
        n, total = self.size, 0.0
        for d in range(DEGREE + 1):
            shifted = np.roll(np.arange(n), -d)
            diagonal = self.G[np.arange(n), shifted]  # G[i, i + d] (cyclically)
            if not self.periodic:
                diagonal = np.where(np.arange(n) + d < n, diagonal, 0.0)
            products = (z * z[:, shifted]).sum(axis=0)
            total += (1.0 if d == 0 else 2.0) * float((diagonal * products).sum())
        return total

    def peak_jerk(self, coef):
        cols, vals = self.jerk_rows
        return float(np.abs((vals * coef[cols]).sum(axis=1)).max())

    def crackle(self, coef):
        """The 5th derivative on each interval (constant there)."""
        mid = (self.tau[:-1] + self.tau[1:]) / 2
        cols, vals = self._rows(mid, 5, interval=np.arange(self.K))
        return (vals * coef[cols]).sum(axis=1)

    def gcv_score(self, s):
        lam = self.c0 * 10.0**s
        try:
            residual = self.fitted(self.coefficients(lam)) - self.y
        except _Singular:
            return math.inf
        n = self.u.size
        dof = n - self.trace(lam)
        # GCV needs a residual degree of freedom: below one, as the fit nears interpolation (knots
        # at the points), n - tr H and the residuals are rounding noise (tr H carries about 1e-4
        # of error near n) and their ratio picks an interpolant of the noise.
        if dof < 1.0:
            return math.inf
        return n * float(np.sum(self.w * residual**2)) / dof**2

    def gcv(self, refine: int = 16):
        """The lambda of least GCV score: every decade, then golden-section search around the best."""
        grid = _GRID[::2]
        scores = [self.gcv_score(s) for s in grid]
        k = int(np.argmin(scores))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        golden = (math.sqrt(5) - 1) / 2
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        fa, fb = self.gcv_score(a), self.gcv_score(b)
        for _ in range(refine):
            if fa <= fb:
                hi, b, fb = b, a, fa
                a = hi - golden * (hi - lo)
                fa = self.gcv_score(a)
            else:
                lo, a, fa = a, b, fb
                b = lo + golden * (hi - lo)
                fb = self.gcv_score(b)
        best = min((scores[k], grid[k]), (fa, a), (fb, b))
        return self.c0 * 10.0 ** best[1], best[0]

    def _deviation(self, s):
        try:
            coef = self.coefficients(self.c0 * 10.0**s)
        except _Singular:
            return math.inf, None
        return self.max_deviation(coef), coef

    def smoothest_within(self, tol):
        """The lambda of smallest peak jerk whose largest deviation is at most ``tol`` (normalized),
        or None when none on the grid is."""
        feasible = []
        for s in _GRID:
            deviation, coef = self._deviation(s)
            if deviation <= tol:
                feasible.append((self.peak_jerk(coef), s))
        if not feasible:
            return None
        jerk, s = min(feasible)
        step = _GRID[1] - _GRID[0]
        lo, hi = s, s + step
        if hi <= _GRID[-1] and self._deviation(hi)[0] > tol:
            for _ in range(20):  # the edge of the feasible lambdas, from the feasible side
                mid = (lo + hi) / 2
                if self._deviation(mid)[0] <= tol:
                    lo = mid
                else:
                    hi = mid
            if self.peak_jerk(self._deviation(lo)[1]) <= jerk:
                s = lo
        return self.c0 * 10.0**s

    def least_deviation(self):
        return min(self._deviation(s)[0] for s in _GRID[:8])

    def refine(self, tol, limit):
        """A finer knot set: each interval holding a point the least smoothing misses by more than
        ``tol`` split in two; None when that would pass ``limit`` intervals or adds nothing."""
        deviation, coef = self._deviation(_GRID[0])
        if coef is None:
            return None
        residual = np.abs(self.fitted(coef) - self.y) + self.slack
        interval = np.clip(np.searchsorted(self.tau, self.u[residual > tol], side="right") - 1, 0, self.K - 1)
        split = np.unique(interval)
        if split.size == 0 or self.K + split.size > limit:
            return None
        middles = (self.tau[split] + self.tau[split + 1]) / 2
        return np.unique(np.concatenate([self.tau, middles]))

    def derivative_rows(self, coef):
        """At each knot but the last, f and its derivatives 1..5 from the right (normalized units),
        each from its own derivative spline's coefficients (de Boor 1978, ch. X)."""
        t, K = self.t, self.K
        extended = coef[np.arange(K + DEGREE) % K] if self.periodic else coef.copy()
        rows = np.empty((K, DEGREE + 1))
        interval = np.arange(K) + DEGREE  # the knot span right of each knot
        x = self.tau[:-1]
        current = extended
        for nu in range(DEGREE + 1):
            q = DEGREE - nu  # the degree of the nu-th derivative spline
            b = _values(t, interval, x, q)
            index = interval[:, None] - q + np.arange(q + 1)[None, :]
            rows[:, nu] = (b * current[index]).sum(axis=1)
            if nu < DEGREE:
                nxt = np.zeros_like(current)
                j = np.arange(1, current.size)
                width = t[j + q] - t[j]
                nxt[1:] = np.divide(q * (current[1:] - current[:-1]), width, out=np.zeros(j.size),
                                    where=width > 0)
                current = nxt
        return rows


class _Singular(ArithmeticError):
    """A pivot of the Cholesky factor is not positive: lambda too small for the points."""


class _Factor:
    """Cholesky factor L L^T = A of a symmetric positive definite matrix with half-bandwidth p,
    plus, for a periodic basis, entries in the corners: then the last p rows of L fill in (an
    arrow), every other row keeps the band. O(K p^2) to factor, O(K p) per solve; no pivoting is
    needed (A is positive definite), so the factor is backward stable."""

    def __init__(self, a, p, periodic):
        n = a.shape[0]
        self.n, self.p = n, p
        tail = self.tail = n - p if periodic and n > 2 * p else n
        index = np.arange(n)[:, None] - p + np.arange(p)[None, :]
        band_a = np.where(index >= 0, a[np.arange(n)[:, None], np.maximum(index, 0)], 0.0).tolist()
        diag_a = np.diag(a).tolist()
        band = [[0.0] * p for _ in range(n)]
        diag = [0.0] * n
        for i in range(tail):
            row, given = band[i], band_a[i]
            for d in range(p):
                j = i - p + d
                if j < 0:
                    continue
                other = band[j]
                total = given[d]
                for k in range(max(i - p, 0), j):  # both rows' band: k in [i - p, j - 1]
                    total -= row[k - i + p] * other[k - j + p]
                row[d] = total / diag[j]
            pivot = diag_a[i] - sum(v * v for v in row)
            if not pivot > 0:
                raise _Singular()
            diag[i] = math.sqrt(pivot)
        tail_rows = []
        for i in range(tail, n):
            row = a[i, :i].tolist()
            for j in range(i):
                total = row[j]
                if j < tail:
                    other = band[j]
                    for k in range(max(j - p, 0), j):
                        total -= row[k] * other[k - j + p]
                else:
                    other = tail_rows[j - tail]
                    for k in range(j):
                        total -= row[k] * other[k]
                row[j] = total / diag[j]
            pivot = diag_a[i] - sum(v * v for v in row)
            if not pivot > 0:
                raise _Singular()
            diag[i] = math.sqrt(pivot)
            tail_rows.append(row)
        self.band = np.array(band)
        self.diag = np.array(diag)
        self.tail_rows = np.zeros((n - tail, n))
        for r, row in enumerate(tail_rows):
            self.tail_rows[r, : len(row)] = row

    def forward(self, b):
        """L^-1 b (b: a vector or a matrix of columns)."""
        x = np.array(b, dtype=float)
        p, band, diag = self.p, self.band, self.diag
        for i in range(self.tail):
            lo = max(i - p, 0)
            if i > lo:
                x[i] -= _dot(band[i, lo - i + p:], x[lo:i])
            x[i] /= diag[i]
        for r, i in enumerate(range(self.tail, self.n)):
            x[i] -= _dot(self.tail_rows[r, :i], x[:i])
            x[i] /= diag[i]
        return x

    def backward(self, b):
        """L^-T b."""
        x = np.array(b, dtype=float)
        p, band, diag, tail = self.p, self.band, self.diag, self.tail
        for r in range(self.n - tail - 1, -1, -1):
            i = tail + r
            x[i] -= _dot(self.tail_rows[r + 1:, i], x[i + 1:])
            x[i] /= diag[i]
        for i in range(tail - 1, -1, -1):
            hi = min(i + p, tail - 1)
            if hi > i:
                # L[k, i] for k in (i, hi]: band row k, column offset i - k + p
                ks = np.arange(i + 1, hi + 1)
                x[i] -= _dot(band[ks, i - ks + p], x[i + 1:hi + 1])
            if tail < self.n:
                x[i] -= _dot(self.tail_rows[:, i], x[tail:])
            x[i] /= diag[i]
        return x

    def solve(self, b):
        return self.backward(self.forward(b))

    def inverse_factor(self):
        """L^-1 as a dense matrix."""
        return self.forward(np.eye(self.n))


def _dot(weights, block):
    """sum_k weights[k] * block[k] (block: a vector or rows), elementwise in a fixed order: no
    BLAS, whose kernels differ between CPUs, so a fit is the same bits on every machine."""
    return (weights.reshape((-1,) + (1,) * (block.ndim - 1)) * block).sum(axis=0)


def _values(t, i, x, q):
    """The q + 1 B-splines of degree q nonzero on [t[i], t[i+1]) at x (BSPLVB)."""
    m = x.size
    b = np.zeros((m, q + 1))
    b[:, 0] = 1.0
    right = np.empty((m, max(q, 1)))
    left = np.empty((m, max(q, 1)))
    for j in range(q):
        right[:, j] = t[i + 1 + j] - x
        left[:, j] = x - t[i - j]
        saved = np.zeros(m)
        for r in range(j + 1):
            term = b[:, r] / (right[:, r] + left[:, j - r])
            b[:, r] = saved + right[:, r] * term
            saved = left[:, j - r] * term
        b[:, j + 1] = saved
    return b


def _spline(system, coef, length, yscale, center, net, periodic, sites):
    """The fitted spline in user units: its law and its start position."""
    rows = system.derivative_rows(coef)
    knots = system.tau * length
    # Knots at the points are written as the points' master positions (1.0, not the
    # 0.9999999999999964 the basis's 2^-52 grid leaves): that moves a knot by under 1e-13 of the
    # span, far inside what the check tells from a jump.
    nearest = np.clip(np.searchsorted(sites, knots), 1, max(sites.size - 1, 1))
    for candidate in (sites[nearest - 1], sites[np.minimum(nearest, sites.size - 1)]):
        knots = np.where(np.abs(candidate - knots) <= 1e-13 * length, candidate, knots)
    knots[0], knots[-1] = 0.0, length
    if not np.all(np.diff(knots) > 0):
        knots = system.tau * length
        knots[0], knots[-1] = 0.0, length
    user = np.empty_like(rows)
    user[:, 0] = yscale * (rows[:, 0] - rows[0, 0]) + (net * system.tau[:-1] if periodic else 0.0)
    for nu in range(1, DEGREE + 1):
        user[:, nu] = yscale * rows[:, nu] / length**nu
    if periodic and net:
        user[:, 1] += net / length
    user[0, 0] = 0.0
    law = spline_law(knots.tolist(), user.tolist())
    return law, center + yscale * rows[0, 0]
