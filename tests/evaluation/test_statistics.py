from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from energy_margin.errors import InvalidParameterError
from energy_margin.evaluation.statistics import Z_95, rank, spearman, spearman_rho, wilson_interval


@pytest.mark.parametrize(
    ("successes", "trials", "expected"),
    [
        # Published 95 % Wilson intervals (e.g. Newcombe 1998, Table I; Brown, Cai & DasGupta 2001).
        (0, 10, (0.0, 0.2775)),
        (5, 10, (0.2366, 0.7634)),
        (10, 10, (0.7225, 1.0)),
        (81, 263, (0.2553, 0.3662)),
        (15, 148, (0.0624, 0.1605)),
    ],
)
def test_wilson_interval_known_values(successes: int, trials: int, expected: tuple[float, float]) -> None:
    low, high = wilson_interval(successes, trials)
    assert low == pytest.approx(expected[0], abs=5e-5)
    assert high == pytest.approx(expected[1], abs=5e-5)


@pytest.mark.parametrize(("successes", "trials"), [(1, 7), (3, 20), (12, 20), (29, 30)])
def test_wilson_bounds_solve_the_score_equation(successes: int, trials: int) -> None:
    # The Wilson bounds are the p where the score statistic |p_hat - p| / sqrt(p (1 - p) / n) equals z.
    p_hat = successes / trials
    for bound in wilson_interval(successes, trials):
        assert abs(p_hat - bound) / math.sqrt(bound * (1 - bound) / trials) == pytest.approx(Z_95, rel=1e-9)


def test_wilson_interval_rejects_bad_counts() -> None:
    with pytest.raises(InvalidParameterError, match="trials"):
        wilson_interval(0, 0)
    with pytest.raises(InvalidParameterError, match="successes"):
        wilson_interval(4, 3)
    with pytest.raises(InvalidParameterError, match="successes"):
        wilson_interval(-1, 3)


def test_rank_averages_ties() -> None:
    assert rank(np.array([10.0, 30.0, 20.0, 30.0, 10.0])).tolist() == [1.5, 4.5, 3.0, 4.5, 1.5]


def test_spearman_on_known_ranks() -> None:
    assert spearman_rho(np.array([1, 2, 3, 4, 5]), np.array([2, 4, 6, 8, 10])) == pytest.approx(1.0)
    assert spearman_rho(np.array([1, 2, 3, 4, 5]), np.array([5, 4, 3, 2, 1])) == pytest.approx(-1.0)
    # 1 - 6 sum(d^2) / (n (n^2 - 1)) with d = (0, 0, 1, -1, 0): 1 - 12 / 120.
    assert spearman_rho(np.array([1, 2, 3, 4, 5]), np.array([1, 2, 4, 3, 5])) == pytest.approx(0.9)
    assert spearman_rho(np.array([1, 2, 3]), np.array([7, 7, 7])) is None
    # Perfect order of 5 items: 2 of the 120 orderings reach |rho| = 1.
    result = spearman(np.arange(5.0), np.arange(5.0) ** 2)
    assert result.exact and result.p_value == pytest.approx(2 / 120)


@pytest.mark.parametrize("seed", range(3))
def test_spearman_matches_scipy_with_ties(seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = np.round(rng.random(6), 1)
    y = np.round(x + rng.normal(0, 0.3, 6), 1)
    result = spearman(x, y)
    assert result.rho == pytest.approx(stats.spearmanr(x, y).statistic)
    # The exact permutation p-value, enumerated independently here.
    observed = abs(stats.spearmanr(x, y).statistic)
    null = [abs(stats.spearmanr(x, y[list(order)]).statistic) for order in itertools.permutations(range(6))]
    assert result.p_value == pytest.approx(np.mean(np.array(null) >= observed - 1e-12))


def test_spearman_random_permutations_beyond_exact() -> None:
    rng = np.random.default_rng(0)
    x = rng.random(12)
    y = x + rng.normal(0, 0.1, 12)
    first = spearman(x, y, permutations=3000, seed=1)
    assert not first.exact and first.p_value is not None and first.p_value < 0.01
    assert spearman(x, y, permutations=3000, seed=1) == first
    # Away from the tails the permutation p-value agrees with scipy's t approximation.
    unrelated = rng.random(12)
    result = spearman(x, unrelated, permutations=20000, seed=2)
    reference = stats.spearmanr(x, unrelated)
    assert reference.pvalue > 0.05 and result.p_value == pytest.approx(reference.pvalue, abs=0.03)
