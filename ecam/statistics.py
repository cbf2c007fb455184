"""Statistics of a robustness sweep: yield with its confidence interval, rank-correlation and
Sobol' sensitivity, the worst sample, and the fastest speed that reaches a required yield.

numpy only, except :func:`sobol_sensitivity`, which calls SALib (the ``sweep`` extra).

The yield's interval is Wilson's score interval (E. B. Wilson, "Probable inference, the law of
succession, and statistical inference", JASA 22(158), 1927, pp. 209-212), recommended over the
Wald interval and over the conservative Clopper-Pearson interval by Brown, Cai & DasGupta
("Interval estimation for a binomial proportion", Statistical Science 16(2), 2001, pp. 101-133):
it keeps its coverage near the nominal level for yields close to 1, where a sweep's usually
are, and it is never empty nor outside [0, 1] (0 failures in n samples still gives an upper
bound on the failure rate of z^2 / (n + z^2)).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .sampling import normal_quantile
from .validate import integer, number


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson's score interval for a binomial proportion.

    Parameters
    ----------
    successes, trials : int
        0 <= successes <= trials, trials >= 1.
    confidence : float
        Two-sided confidence level, 0 < confidence < 1.

    Returns
    -------
    (low, high) : tuple of float
        ``(p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)`` with ``p = successes /
        trials`` and ``z`` the normal quantile at ``1 - (1 - confidence) / 2``.
    """
    trials = integer("trials", trials, minimum=1)
    successes = integer("successes", successes, minimum=0, maximum=trials)
    confidence = number("confidence", confidence, minimum=0.0, strict=True)
    if confidence >= 1.0:
        raise InputError(f"confidence: {confidence:g} should be < 1")
    z = float(normal_quantile(1.0 - (1.0 - confidence) / 2.0))
    p = successes / trials
    z2n = z * z / trials
    centre = (p + z2n / 2.0) / (1.0 + z2n)
    half = z * math.sqrt(p * (1.0 - p) / trials + z2n / (4.0 * trials)) / (1.0 + z2n)
    # The exact ends at 0 and n successes (the formula gives them up to rounding).
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high


def proportion(successes: int, trials: int, confidence: float = 0.95) -> dict:
    """``{"value", "interval", "successes", "trials"}``: a proportion and its Wilson interval
    (``value`` and ``interval`` None when there are no trials)."""
    if trials == 0:
        return {"value": None, "interval": None, "successes": 0, "trials": 0}
    return {"value": successes / trials, "interval": list(wilson_interval(successes, trials, confidence)),
            "successes": successes, "trials": trials}


def ranks(values) -> np.ndarray:
    """Ranks 1..n of ``values``, ties given their average rank (as Spearman's rho needs)."""
    values = np.asarray(values, dtype=float)
    order = np.argsort(values, kind="stable")
    ranked = np.empty(len(values))
    ranked[order] = np.arange(1, len(values) + 1, dtype=float)
    sorted_values = values[order]
    starts = np.flatnonzero(np.r_[True, sorted_values[1:] != sorted_values[:-1]])
    ends = np.r_[starts[1:], len(values)]
    for start, end in zip(starts, ends):
        if end - start > 1:
            ranked[order[start:end]] = 0.5 * (start + 1 + end)
    return ranked


def spearman(x, y) -> float | None:
    """Spearman's rank correlation of ``x`` and ``y`` (Pearson's correlation of their average
    ranks); None when either is constant or there are fewer than 3 pairs."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if len(x) != len(y):
        raise InputError(f"y: {len(y)} values should be as many as x's {len(x)}")
    if len(x) < 3:
        return None
    rx, ry = ranks(x) - (len(x) + 1) / 2.0, ranks(y) - (len(y) + 1) / 2.0
    # elementwise products and numpy's pairwise sum, not a BLAS dot: the same bits everywhere
    norm = math.sqrt(float(np.sum(rx * rx)) * float(np.sum(ry * ry)))
    return None if norm == 0.0 else float(np.sum(rx * ry)) / norm


def rank_sensitivity(names, values, output) -> list[dict]:
    """Which fields drive an output: Spearman's rho of each column of ``values`` (samples,
    fields) against ``output`` (samples,), largest magnitude first (None last).

    Returns
    -------
    list of dict
        ``{"name", "spearman"}`` per field.
    """
    values = np.asarray(values, dtype=float)
    rows = [{"name": name, "spearman": spearman(values[:, j], output)}
            for j, name in enumerate(names)]
    return sorted(rows, key=lambda r: (r["spearman"] is None, -abs(r["spearman"] or 0.0)))


def sobol_sensitivity(names, output, seed: int = 0, confidence: float = 0.95) -> list[dict]:
    """First-order and total Sobol' indices of ``output`` over a Saltelli design (the rows of
    :func:`ecam.sampling.design` with method ``sobol``, in order), by SALib's estimator
    (Saltelli et al. 2010, Jansen 1999), with bootstrap confidence half-widths.

    Returns
    -------
    list of dict
        ``{"name", "S1", "S1_conf", "ST", "ST_conf"}`` per field, largest ``ST`` first.

    Raises
    ------
    InputError
        SALib is not installed, or the output is not finite.
    """
    output = np.asarray(output, dtype=float)
    if not np.all(np.isfinite(output)):
        raise InputError("output: Sobol' indices need a finite output for every sample")
    try:
        from SALib.analyze import sobol as salib_sobol
    except ImportError:
        raise InputError("Sobol' indices need SALib: pip install 'ecam[sweep]'") from None
    names = list(names)
    problem = {"num_vars": len(names), "names": names, "bounds": [[0.0, 1.0]] * len(names)}
    with np.errstate(all="ignore"):  # a constant output gives 0/0: reported as None below
        result = salib_sobol.analyze(problem, output, calc_second_order=False,
                                     conf_level=confidence, seed=seed)

    def finite(value):
        return float(value) if np.isfinite(value) else None

    rows = [{"name": name, "S1": finite(result["S1"][j]), "S1_conf": finite(result["S1_conf"][j]),
             "ST": finite(result["ST"][j]), "ST_conf": finite(result["ST_conf"][j])}
            for j, name in enumerate(names)]
    return sorted(rows, key=lambda r: (r["ST"] is None, -(r["ST"] or 0.0)))


def max_speed_at_yield(speeds, passed, trials, required: float,
                       confidence: float = 0.95) -> dict:
    """The fastest of the judged speeds whose yield reaches ``required``.

    Parameters
    ----------
    speeds : sequence of float
        The judged speeds (any order; magnitudes are compared).
    passed, trials : sequence of int
        Samples that passed, and samples run, at each speed.
    required : float
        The required yield, 0 < required <= 1.
    confidence : float
        The Wilson interval's level.

    Returns
    -------
    dict
        ``required``; ``speed``: the fastest speed whose yield's lower confidence bound reaches
        ``required`` (the answer one can rely on at that confidence; None when none does);
        ``speed_estimate``: the fastest whose observed yield reaches it; ``next_speed``: the
        slowest judged speed above ``speed`` that does not reach it with confidence (the answer
        lies between ``speed`` and ``next_speed``: that bracket is the speed's uncertainty,
        together with the yield's interval at each).

    Notes
    -----
    Assumes a machine that passes at a speed passes at every slower one (as
    :func:`hil_sim.find_max_speed` does), so the yield falls with the speed; each speed is judged
    on its own samples, without smoothing between speeds.
    """
    required = number("required", required, minimum=0.0, strict=True, maximum=1.0)
    order = sorted(range(len(speeds)), key=lambda i: abs(speeds[i]))
    confident = [i for i in order if trials[i] > 0
                 and wilson_interval(passed[i], trials[i], confidence)[0] >= required]
    observed = [i for i in order if trials[i] > 0 and passed[i] / trials[i] >= required]
    best = confident[-1] if confident else None
    above = [i for i in order if best is None or abs(speeds[i]) > abs(speeds[best])]
    above = [i for i in above if i not in confident]
    return {"required": required,
            "speed": None if best is None else float(speeds[best]),
            "speed_estimate": float(speeds[observed[-1]]) if observed else None,
            "next_speed": float(speeds[above[0]]) if above else None}
