"""The sweep's core: distributions and designs (ecam.sampling), statistics (ecam.statistics).

Oracles: scipy.stats for the quantiles and Spearman's rho, Newcombe's worked examples for the
Wilson interval, the Ishigami function's analytic Sobol' indices.
"""

import math

import numpy as np
import pytest
from scipy import stats

from ecam.errors import InputError
from ecam.sampling import Distribution, design, normal_quantile, sample_seeds, unit_design
from ecam.statistics import (max_speed_at_yield, rank_sensitivity, sobol_sensitivity, spearman,
                             wilson_interval)


def test_normal_quantile_matches_scipy_to_full_precision():
    p = np.concatenate([[1e-300, 1e-30, 1e-8, 0.02425, 0.5, 1 - 0.02425, 1 - 1e-12],
                        np.random.default_rng(0).random(2000)])
    exact = stats.norm.ppf(p)
    assert np.allclose(normal_quantile(p), exact, rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("kwargs, frozen", [
    (dict(kind="normal", mean=2.0, std=0.3), stats.norm(2.0, 0.3)),
    (dict(kind="normal", mean=1.0, std=0.15, minimum=0.8, maximum=1.1),
     stats.truncnorm((0.8 - 1.0) / 0.15, (1.1 - 1.0) / 0.15, loc=1.0, scale=0.15)),
    (dict(kind="uniform", low=-1.0, high=3.0), stats.uniform(-1.0, 4.0)),
    (dict(kind="triangular", low=0.9, mode=1.0, high=1.3), stats.triang(0.25, 0.9, 0.4)),
    (dict(kind="triangular", low=0.0, mode=0.0, high=2.0), stats.triang(0.0, 0.0, 2.0)),
    (dict(kind="triangular", low=0.0, mode=2.0, high=2.0), stats.triang(1.0, 0.0, 2.0)),
])
def test_quantiles_are_the_inverse_cdf(kwargs, frozen):
    u = np.linspace(0.001, 0.999, 101)
    assert np.allclose(Distribution(**kwargs).quantile(u), frozen.ppf(u), rtol=1e-12, atol=1e-12)


def test_truncated_uniform_and_relative_scale():
    d = Distribution("uniform", low=0.0, high=10.0, minimum=2.0, maximum=4.0, relative=True)
    u = np.linspace(0.0, 1.0, 5)
    assert np.allclose(d.quantile(u, nominal=3.0), 3.0 * np.array([2.0, 2.5, 3.0, 3.5, 4.0]))
    with pytest.raises(InputError, match="nominal"):
        d.quantile(u)


@pytest.mark.parametrize("kwargs, message", [
    (dict(kind="normal", mean=1.0), r"^std: missing"),
    (dict(kind="normal", mean=1.0, std=0.0), r"^std: 0 should be > 0"),
    (dict(kind="normal", mean=1.0, std=0.1, low=0.0), r"^low: 0 should be left out"),
    (dict(kind="uniform", low=1.0, high=1.0), r"^high: 1 should be > low \(1\)"),
    (dict(kind="triangular", low=0.0, mode=2.0, high=1.0), r"^mode: 2 should be within"),
    (dict(kind="lognormal", mean=1.0), r"^distribution: 'lognormal' should be one of"),
    (dict(kind="normal", mean=0.0, std=1.0, minimum=40.0), r"^minimum, maximum: .* keep"),
    (dict(kind="uniform", low=0.0, high=1.0, minimum=2.0), r"^minimum, maximum: .* keep"),
    (dict(kind="normal", mean=0.0, std=1.0, minimum=1.0, maximum=0.5), r"^maximum: 0.5 should be > minimum"),
    (dict(kind="normal", mean=math.inf, std=1.0), r"^mean: inf should be finite"),
])
def test_bad_distributions_are_one_line_naming_the_parameter(kwargs, message):
    with pytest.raises(InputError, match=message) as caught:
        Distribution(**kwargs)
    assert "\n" not in str(caught.value)


def test_latin_hypercube_puts_one_sample_in_every_stratum_of_every_field():
    unit, _ = unit_design("latin_hypercube", 50, 3, seed=7)
    assert unit.shape == (50, 3)
    for column in unit.T:
        assert sorted(np.floor(column * 50).astype(int)) == list(range(50))


def test_designs_are_reproducible_and_monte_carlo_samples_stand_alone():
    d = {"a": Distribution("normal", mean=1.0, std=0.1, relative=True),
         "b": Distribution("uniform", low=0.0, high=1.0)}
    for method in ("latin_hypercube", "monte_carlo", "grid", "sobol"):
        first = design(method, d, 64, 11, {"a": 5.0})
        again = design(method, d, 64, 11, {"a": 5.0})
        assert np.array_equal(first.values, again.values), method
        assert not first.values.flags.writeable
    # a Monte Carlo sample is drawn from its own seed: the same whatever the sample count
    small, large = design("monte_carlo", d, 5, 11, {"a": 5.0}), design("monte_carlo", d, 40, 11, {"a": 5.0})
    assert np.array_equal(small.values, large.values[:5])
    assert sample_seeds(11, 5) == sample_seeds(11, 40)[:5] and len(set(sample_seeds(11, 40))) == 40


def test_grid_and_sobol_sizes():
    unit, _ = unit_design("grid", 10, 2, seed=0)  # 3 x 3: whole rows of the grid
    assert unit.shape == (9, 2) and sorted(set(unit[:, 0])) == pytest.approx([1 / 6, 1 / 2, 5 / 6])
    unit, base = unit_design("sobol", 100, 3, seed=0)  # N (d + 2) rows, N a power of two
    assert base == 16 and unit.shape == (80, 3)
    with pytest.raises(InputError, match="grid"):
        unit_design("grid", 100, 3, seed=0)
    with pytest.raises(InputError, match=r"^samples: 5 should be >= 8"):
        unit_design("sobol", 5, 2, seed=0)


def test_wilson_interval_matches_newcombes_worked_examples():
    # R. G. Newcombe, "Two-sided confidence intervals for the single proportion: comparison of
    # seven methods", Statistics in Medicine 17 (1998) 857-872, Table II, method 3 (score).
    for (successes, trials), expected in {(81, 263): (0.2553, 0.3662), (15, 148): (0.0624, 0.1605),
                                          (0, 20): (0.0, 0.1611), (1, 29): (0.0061, 0.1718)}.items():
        assert wilson_interval(successes, trials) == pytest.approx(expected, abs=5e-5)
    # every sample passed: the failure rate's upper bound is z^2 / (n + z^2)
    z = stats.norm.ppf(0.975)
    assert wilson_interval(100, 100)[0] == pytest.approx(100 / (100 + z * z), rel=1e-12)


def test_spearman_matches_scipy_with_ties():
    rng = np.random.default_rng(3)
    x = rng.integers(0, 8, 40).astype(float)
    y = x ** 2 + rng.random(40)
    y[:5] = y[5]
    assert spearman(x, y) == pytest.approx(stats.spearmanr(x, y).statistic, rel=1e-12)
    assert spearman([1, 1, 1], [1, 2, 3]) is None
    ranking = rank_sensitivity(["noise", "driver"], np.column_stack([rng.random(40), x]), y)
    assert [r["name"] for r in ranking] == ["driver", "noise"]
    assert ranking[0]["spearman"] == pytest.approx(stats.spearmanr(x, y).statistic, rel=1e-12)


def test_sobol_indices_of_the_ishigami_function():
    # Ishigami & Homma (1990), a = 7, b = 0.1 over [-pi, pi]^3; the analytic variances:
    # V = a^2/8 + b pi^4/5 + b^2 pi^8/18 + 1/2, V1 = (1 + b pi^4/5)^2 / 2, V2 = a^2/8, V3 = 0,
    # and the total of x1 and x3 share V13 = b^2 pi^8 (1/18 - 1/50).
    a, b = 7.0, 0.1
    v = a * a / 8 + b * math.pi ** 4 / 5 + b * b * math.pi ** 8 / 18 + 0.5
    v1, v2, v13 = 0.5 * (1 + b * math.pi ** 4 / 5) ** 2, a * a / 8, b * b * math.pi ** 8 * (1 / 18 - 1 / 50)
    field = Distribution("uniform", low=-math.pi, high=math.pi)
    d = design("sobol", {"x1": field, "x2": field, "x3": field}, 2 ** 13 * 5, seed=1)
    x1, x2, x3 = d.values.T
    y = np.sin(x1) + a * np.sin(x2) ** 2 + b * x3 ** 4 * np.sin(x1)
    found = {row["name"]: row for row in sobol_sensitivity(d.names, y, seed=1)}
    assert found["x1"]["S1"] == pytest.approx(v1 / v, abs=0.03)
    assert found["x2"]["S1"] == pytest.approx(v2 / v, abs=0.03)
    assert found["x3"]["S1"] == pytest.approx(0.0, abs=0.03)
    assert found["x1"]["ST"] == pytest.approx((v1 + v13) / v, abs=0.03)
    assert found["x3"]["ST"] == pytest.approx(v13 / v, abs=0.03)


def test_max_speed_at_yield_takes_the_confident_speed_and_brackets_it():
    speeds = [300.0, 360.0, 420.0, 480.0]
    result = max_speed_at_yield(speeds, passed=[200, 200, 190, 100], trials=[200] * 4, required=0.9)
    # 190/200 = 95 %: Wilson's lower bound 91.0 % >= 90 %; 100/200 is not
    assert result == {"required": 0.9, "speed": 420.0, "speed_estimate": 420.0, "next_speed": 480.0}
    result = max_speed_at_yield(speeds, passed=[20, 19, 10, 0], trials=[20] * 4, required=0.95)
    # 20/20 has a lower bound of 83.9 %: nothing is confidently at 95 % with 20 samples
    assert result["speed"] is None and result["speed_estimate"] == 360.0 and result["next_speed"] == 300.0
