from __future__ import annotations

import math

import numpy as np
import pytest

from energy_margin.analysis.scores import likelihood, region_score, trajectory_success_score, trajectory_weights
from energy_margin.errors import InvalidParameterError

LN2 = math.log(2.0)


@pytest.mark.parametrize("lam", [0.5, 5.0, 1e4])
def test_likelihood_by_hand(lam: float) -> None:
    # exp(-lam * ln2 / lam) = 1/2: weights 1 and 1/2.
    np.testing.assert_allclose(likelihood(np.array([0.0, LN2 / lam]), lam), [2 / 3, 1 / 3], rtol=1e-12)
    np.testing.assert_allclose(
        likelihood(np.array([LN2 / lam, 0.0, 2 * LN2 / lam]), lam), [2 / 7, 4 / 7, 1 / 7], rtol=1e-12
    )


def test_likelihood_is_shift_invariant() -> None:
    lam = 5.0
    np.testing.assert_allclose(likelihood(np.array([1e6, 1e6 + LN2 / lam]), lam), [2 / 3, 1 / 3], rtol=1e-8)


@pytest.mark.parametrize("lam", [5.0, 1e3, 1e6])
def test_likelihood_is_stable_for_huge_costs_and_lambda(lam: float) -> None:
    costs = np.array([0.0, 1e6, 3e5, 1e6, 12.0])
    result = likelihood(costs, lam)
    assert np.all(np.isfinite(result))
    assert result.sum() == pytest.approx(1.0, abs=1e-12)
    assert result[0] == pytest.approx(1.0, abs=1e-12)  # the root (cost 0) takes all the mass
    assert np.all(result >= 0)


def test_likelihood_without_a_zero_cost_node() -> None:
    result = likelihood(np.array([1e6, 2e6, 1e6 + 1.0]), 1e6)
    assert np.all(np.isfinite(result))
    np.testing.assert_allclose(result, [1.0, 0.0, 0.0], atol=1e-12)


def test_zero_lambda_is_uniform() -> None:
    np.testing.assert_array_equal(likelihood(np.array([0.0, 3.0, 1e6, 7.0]), 0.0), [0.25] * 4)


@pytest.mark.parametrize(
    ("costs", "lam", "message"),
    [
        (np.array([]), 1.0, "non-empty 1-D"),
        (np.zeros((2, 2)), 1.0, "non-empty 1-D"),
        (np.array([0.0, np.nan]), 1.0, "costs must be finite"),
        (np.array([0.0, np.inf]), 1.0, "costs must be finite"),
        (np.array([0.0, 1.0]), -1.0, "lam must be a finite number >= 0, got -1.0"),
        (np.array([0.0, 1.0]), float("nan"), "lam must be a finite number >= 0, got nan"),
        (np.array([0.0, 1.0]), float("inf"), "lam must be a finite number >= 0, got inf"),
    ],
)
def test_likelihood_rejects_bad_input(costs: np.ndarray, lam: float, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        likelihood(costs, lam)


def test_region_score_by_hand() -> None:
    lam = 2.0
    costs = np.array([0.0, LN2 / lam, LN2 / lam, 2 * LN2 / lam])  # weights 1, 1/2, 1/2, 1/4
    total = 2.25
    assert region_score(costs, np.array([True, False, False, False]), lam) == pytest.approx(1 / total)
    assert region_score(costs, np.array([False, True, True, False]), lam) == pytest.approx(1 / total)
    assert region_score(costs, np.array([False, False, False, True]), lam) == pytest.approx(0.25 / total)
    assert region_score(costs, np.ones(4, dtype=bool), lam) == pytest.approx(1.0)
    assert region_score(costs, np.zeros(4, dtype=bool), lam) == 0.0
    # Lists of 0/1 work as masks.
    assert region_score(costs, [0, 1, 1, 0], lam) == pytest.approx(1 / total)


def test_region_score_rejects_a_mismatched_mask() -> None:
    with pytest.raises(InvalidParameterError, match="inside must have shape"):
        region_score(np.zeros(3), np.ones(4, dtype=bool), 1.0)
    with pytest.raises(InvalidParameterError, match="lam must be"):
        region_score(np.zeros(3), np.ones(3, dtype=bool), -2.0)


def test_linear_weights_by_hand() -> None:
    np.testing.assert_allclose(trajectory_weights(5, last=3), [0, 0, 1 / 6, 2 / 6, 3 / 6])
    np.testing.assert_allclose(trajectory_weights(3, last=3), [1 / 6, 2 / 6, 3 / 6])
    np.testing.assert_allclose(trajectory_weights(4, last=1), [0, 0, 0, 1])
    # A window longer than the trajectory covers every frame.
    np.testing.assert_allclose(trajectory_weights(2, last=10), [1 / 3, 2 / 3])


def test_uniform_weights_by_hand() -> None:
    np.testing.assert_allclose(trajectory_weights(5, last=3, scheme="uniform"), [0, 0, 1 / 3, 1 / 3, 1 / 3])
    np.testing.assert_allclose(trajectory_weights(2, last=5, scheme="uniform"), [0.5, 0.5])


def test_trajectory_weights_reject_bad_input() -> None:
    with pytest.raises(InvalidParameterError, match="last must be a positive integer, got 0"):
        trajectory_weights(5, last=0)
    with pytest.raises(InvalidParameterError, match="scheme must be"):
        trajectory_weights(5, last=2, scheme="exponential")


def test_trajectory_success_score_by_hand() -> None:
    frames = np.array([[0.0, 0.0, 0.5, 1.0, 1.0], [1.0, 1.0, 1.0, 0.0, 0.0], [0.2, 0.2, 0.2, 0.2, 0.2]])
    np.testing.assert_allclose(trajectory_success_score(frames, last=3), [(0.5 + 2 + 3) / 6, 1 / 6, 0.2], rtol=1e-12)
    np.testing.assert_allclose(
        trajectory_success_score(frames, last=3, scheme="uniform"), [2.5 / 3, 1 / 3, 0.2], rtol=1e-12
    )
    np.testing.assert_allclose(trajectory_success_score(frames, last=1), [1.0, 0.0, 0.2])
    assert trajectory_success_score(frames, last=2).shape == (3,)


def test_region_score_never_exceeds_one() -> None:
    rng = np.random.default_rng(0)
    for _ in range(100):
        costs = rng.uniform(0.0, 0.01, 31)
        costs[0] = 0.0
        assert region_score(costs, np.ones(31, dtype=bool), 5.0) <= 1.0
