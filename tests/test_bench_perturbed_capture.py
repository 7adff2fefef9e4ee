"""benchmarks/perturbed_capture.py: the perturbed frames' capture test, its ranges, the ellipse's odds."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.world.ellipsoid import Ellipsoid


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("perturbed_capture")


class HalfPlane:
    """Every position with x >= 0: a region whose odds and edge distances are known."""

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        return np.asarray(positions)[..., 0] >= 0.0

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        return np.asarray(positions, dtype=float)[..., 0]


def _circle(x: float) -> Ellipsoid:
    return Ellipsoid(center=np.array([x, 0.0]), radii=np.array([1.0, 1.0]), rotation=np.eye(2))


def test_a_span_is_the_smallest_and_largest_copy_in_copy_order(bench: ModuleType) -> None:
    assert bench.span([0.7, 0.6, 0.9]) == {"min": 0.6, "max": 0.9, "values": [0.7, 0.6, 0.9]}


def test_a_copy_row_counts_positives_kept_and_negatives_gained(bench: ModuleType) -> None:
    true = np.array([[True, True, True, True], [False, False, False, False]])
    own = np.array([[True, True, True, False], [True, False, False, False]])
    row = bench.copy_row(true, own)
    assert row["still_captured"] == pytest.approx(0.75)
    assert row["negatives_captured"] == pytest.approx(0.25)
    # The yes/no test as a score: precision 3/4 at recall 3/4, then 4/8 at recall 1.
    assert row["test_ap"] == pytest.approx(0.75 * 0.75 + 0.25 * 0.5)


def test_a_perfect_test_has_ap_one_and_a_constant_one_the_positive_rate(bench: ModuleType) -> None:
    true = np.array([True, False, True, False, False])
    assert bench.copy_row(true, true)["test_ap"] == pytest.approx(1.0)
    assert bench.copy_row(true, np.ones(5, bool))["test_ap"] == pytest.approx(0.4)


def test_copy_spans_range_every_field_over_the_copies(bench: ModuleType) -> None:
    rows = [
        {"copy": 1, "still_captured": 0.9, "negatives_captured": 0.2, "test_ap": 0.8},
        {"copy": 2, "still_captured": 0.7, "negatives_captured": 0.3, "test_ap": 0.6},
    ]
    spans = bench.copy_spans(rows)
    assert spans["still_captured"] == {"min": 0.7, "max": 0.9, "values": [0.9, 0.7]}
    assert spans["negatives_captured"]["max"] == 0.3
    assert spans["test_ap"]["min"] == 0.6


def test_the_odds_of_an_all_inside_draw_are_those_of_n_independent_centres(bench: ModuleType) -> None:
    rng = np.random.default_rng(0)
    # A circle centred on the half plane's edge: each centre inside with probability 1/2.
    odds = bench.all_inside_odds(HalfPlane(), _circle(0.0), np.zeros(2), 20_000, rng)
    assert odds == pytest.approx(0.25, abs=0.01)
    assert bench.all_inside_odds(HalfPlane(), _circle(2.0), np.zeros(3), 100, rng) == 1.0
    assert bench.all_inside_odds(HalfPlane(), _circle(-2.0), np.zeros(3), 100, rng) == 0.0


def test_the_odds_are_seeded(bench: ModuleType) -> None:
    draws = [bench.all_inside_odds(HalfPlane(), _circle(0.3), np.zeros(4), 500, np.random.default_rng(7)) for _ in "ab"]
    assert draws[0] == draws[1]


def test_the_nearest_edge_is_the_smallest_signed_distance(bench: ModuleType) -> None:
    positions = np.array([[0.3, 5.0, 0.0], [0.1, -1.0, 0.0], [0.7, 0.0, 0.0]])
    assert bench.nearest_edge(HalfPlane(), positions) == pytest.approx(0.1)


def test_the_odds_summary_splits_positive_and_negative_frames(bench: ModuleType) -> None:
    odds = np.array([[0.9, 0.8], [0.1, 0.3]])
    labels = np.array([[True, True], [False, False]])
    edge = np.array([[0.05, 0.07], [-0.01, -0.02]])
    summary = bench.odds_summary(odds, labels, edge)
    assert summary == {
        "odds_positive": pytest.approx(0.85),
        "odds_negative": pytest.approx(0.2),
        "edge_median_cm": pytest.approx(6.0),
        "positive_rate": 0.5,
    }
