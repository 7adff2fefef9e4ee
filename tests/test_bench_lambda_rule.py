"""benchmarks/lambda_rule.py: its scale-free lambdas and the choice of a rule's constant."""

from __future__ import annotations

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.scores import likelihood


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("lambda_rule")


def fields(scale: float = 1.0) -> list[dict[str, np.ndarray]]:
    rng = np.random.default_rng(3)
    result = []
    for _ in range(4):
        costs = np.concatenate([[0.0], rng.exponential(0.05, size=40)]) * scale
        result.append({"costs": costs, "captured": costs < 0.05 * scale, "successful": costs < 0.02 * scale})
    return result


def test_the_effective_sample_size_rule_hits_its_fraction(bench) -> None:
    costs = fields()[0]["costs"]
    lam = bench.ess_lambda(costs, 0.3)
    weights = likelihood(costs, lam)
    assert 1.0 / np.sum(weights**2) == pytest.approx(0.3 * costs.size, rel=1e-3)


@pytest.mark.parametrize("rule", ["median", "quantile10", "ess", "dataset_median"])
def test_every_rule_is_scale_free(bench, rule: str) -> None:
    small, large = fields(), fields(scale=1000.0)
    lams_small = bench.frame_lambdas(small, rule, 0.3 if rule == "ess" else 2.0)
    lams_large = bench.frame_lambdas(large, rule, 0.3 if rule == "ess" else 2.0)
    np.testing.assert_allclose(lams_small, lams_large * 1000.0, rtol=1e-6)
    for a, b, lam_a, lam_b in zip(small, large, lams_small, lams_large, strict=True):
        assert bench.region_mass(a, "captured", lam_a) == pytest.approx(bench.region_mass(b, "captured", lam_b))


def test_the_median_rule_is_kappa_over_the_median_cost_of_the_nodes_beyond_the_root(bench) -> None:
    entry = fields()[0]
    assert bench.frame_lambdas([entry], "median", 4.0)[0] == pytest.approx(4.0 / np.median(entry["costs"][1:]))


def test_a_rules_constant_is_chosen_on_one_seed_and_checked_on_the_other(bench, monkeypatch) -> None:
    monkeypatch.setattr(bench, "RULES", {"median": (1.0, 2.0)})

    def row(calibrated: float, one: float, two: float) -> dict:
        return {
            "calibrated": {"mean": calibrated},
            "hand_set": {"mean": calibrated - 0.05},
            "derived": None,
            "rules": {"median:1": {"mean": one}, "median:2": {"mean": two}},
        }

    results = {
        "a": {"11": row(0.9, 0.89, 0.85), "12": row(0.9, 0.80, 0.899)},
        "b": {"11": row(0.8, 0.79, 0.78), "12": row(0.8, 0.79, 0.70)},
    }
    selection = bench.select(results, "11", "12")
    assert selection["median"]["chosen"] == "median:1"
    assert selection["median"]["worst_gap_choose"] == pytest.approx(0.01)
    assert selection["median"]["worst_gap_check"] == pytest.approx(0.10)
    assert selection["hand_set"]["worst_gap_check"] == pytest.approx(0.05)
    assert selection["derived"]["gaps_check"] == {"a": None, "b": None}
