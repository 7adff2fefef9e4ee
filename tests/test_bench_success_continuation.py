"""benchmarks/success_continuation.py: its paired intervals agree with its APs."""

from __future__ import annotations

import numpy as np
import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("success_continuation")


class _Dataset:
    """What the paired intervals read of a dataset: its size and success labels."""

    def __init__(self, labels: np.ndarray, n_frames: int) -> None:
        self.labels, self.n_frames, self.n_trajectories = labels, n_frames, len(labels)

    def success_labels(self) -> np.ndarray:
        return self.labels

    def capture_labels(self, window: int) -> np.ndarray:
        raise AssertionError("no capture question is asked")


def grids(seed: int, labels: np.ndarray, frames: int = 10) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(rng.uniform(0, 1, (len(labels), frames)) * 0.6 + 0.4 * labels[:, None], 0, 1)


def test_paired_differences_are_those_of_the_benchmarks_aps(bench) -> None:
    labels = np.array([1, 0, 1, 1, 0, 0, 1, 0, 1, 0] * 2)
    success = {0: grids(1, labels), 16: grids(2, labels)}
    distance = grids(3, labels)
    found = bench.paired(_Dataset(labels, 10), success, distance)
    tree, continued, baseline = (bench._early_aps(labels, grid) for grid in (success[0], success[16], distance))
    for question in ("first3", "first5", "last3"):
        entry = found["continuation_16_minus_tree"]
        assert entry[question] == pytest.approx(continued[question] - tree[question], abs=1e-12)
        assert entry[f"{question}_low"] <= entry[question] <= entry[f"{question}_high"]
        against = found["continuation_16_minus_distance"]
        assert against[question] == pytest.approx(continued[question] - baseline[question], abs=1e-12)
        assert found["tree_minus_distance"][question] == pytest.approx(tree[question] - baseline[question], abs=1e-12)


def test_a_scorer_against_itself_is_exactly_level(bench) -> None:
    labels = np.array([1, 0] * 8)
    grid = grids(4, labels, frames=5)
    found = bench.paired(_Dataset(labels, 10), {0: grid, 8: grid.copy()}, None)
    assert set(found) == {"continuation_8_minus_tree"}
    entry = found["continuation_8_minus_tree"]
    assert "last3" not in entry  # five frames scored: early success only
    assert [entry[key] for key in ("first3", "first3_low", "first3_high", "first5_low", "first5_high")] == [0] * 5


def test_the_rows_say_each_paired_difference_in_a_word(bench) -> None:
    measured = {
        "methods": {"tree": {"first3": 0.5}},
        "baselines": {},
        "paired": {
            "continuation_16_minus_tree": {"first3": 0.2, "first3_low": 0.05, "first3_high": 0.3},
            "tree_minus_distance": {"first3": -0.1, "first3_low": -0.2, "first3_high": 0.01},
        },
    }
    found = bench.rows({"scenes": {"pushing": {"12": measured}}, "selection_seed": 11})
    assert found[0]["use"] == "check"
    assert found[0]["continuation_16_minus_tree_first3_word"] == "ahead"
    assert found[0]["tree_minus_distance_first3_word"] == "level"
    assert found[0]["continuation_16_minus_tree_first3_low"] == 0.05
