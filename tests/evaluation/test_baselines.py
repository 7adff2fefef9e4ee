from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from energy_margin.data.dataset import load_dataset
from energy_margin.evaluation.baselines import distance_scores
from energy_margin.tasks import PushingTask, ScoopingTask
from energy_margin.tasks.base import MeasurableRegion
from energy_margin.tasks.pushing import PushingConfig, SweptRegion, WallBand
from energy_margin.tasks.scooping import BoxesAboveTable, ScoopingConfig


def test_wall_band_signed_distance() -> None:
    band = WallBand(PushingConfig())  # y in [1.45, 1.65], workspace [-0.1, 2.1]
    points = np.array([[1.0, 1.55, 0.0], [1.0, 1.45, 0.0], [1.0, 1.65, 0.0], [1.0, 1.25, 0.0], [1.0, 1.7, 0.0]])
    np.testing.assert_allclose(band.signed_distance(points), [0.1, 0.0, 0.0, -0.2, -0.05], atol=1e-12)
    assert isinstance(band, MeasurableRegion)


def test_disc_signed_distance() -> None:
    region = SweptRegion(PushingConfig(), np.array([1.0, 1.0]), np.zeros(3))  # disc of radius 0.6
    assert region.is_disc
    points = np.array([[1.0, 1.0, 0.0], [1.6, 1.0, 0.0], [1.0, 1.9, 0.0]])
    np.testing.assert_allclose(region.signed_distance(points), [0.6, 0.0, -0.3], atol=1e-12)


def test_band_signed_distance_straight_motion() -> None:
    # Straight push along +y at 0.5 m/s: a band of half width 0.4 around x = 1, from 0.06 m behind
    # the pusher to 0.5 m ahead of it.
    region = SweptRegion(PushingConfig(), np.array([1.0, 0.5]), np.array([0.0, 0.5, 0.0]))
    assert not region.is_disc
    points = np.array([[1.0, 0.75, 0.0], [1.4, 0.75, 0.0], [1.5, 0.75, 0.0], [1.0, 1.1, 0.0], [1.0, 0.3, 0.0]])
    distance = region.signed_distance(points)
    np.testing.assert_allclose(distance[:3], [0.25, 0.0, -0.1], atol=1e-4)  # radius 1000 m: nearly straight
    assert distance[3] == pytest.approx(-0.1, abs=1e-3)  # 0.1 m beyond the swept end
    assert distance[4] == pytest.approx(-0.14, abs=1e-3)  # 0.14 m behind the margin


def test_boxes_above_table_signed_distance() -> None:
    config = ScoopingConfig()
    region = BoxesAboveTable(config, config.success_height)
    low = region.min_z
    points = np.array([[0.0, 0.0, low + 0.01], [0.0, 0.0, low], [0.0, 0.0, low - 0.02], [region.half_x + 0.01, 0, 1]])
    np.testing.assert_allclose(region.signed_distance(points), [0.01, 0.0, -0.02, -0.01], atol=1e-12)


pushing_regions = [
    WallBand(PushingConfig()),
    SweptRegion(PushingConfig(), np.array([1.0, 1.0]), np.zeros(3)),
    SweptRegion(PushingConfig(), np.array([1.0, 0.5]), np.array([0.3, 0.5, 0.4])),
    BoxesAboveTable(ScoopingConfig(), 0.0005),
]


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-0.3, 2.3),
    y=st.floats(-0.3, 2.3),
    z=st.floats(-0.05, 0.2),
    which=st.integers(0, len(pushing_regions) - 1),
)
def test_sign_agrees_with_contains(x: float, y: float, z: float, which: int) -> None:
    region = pushing_regions[which]
    if isinstance(region, BoxesAboveTable):
        x, y = x / 20 - 0.05, y / 50 - 0.02
    point = np.array([[x, y, z]])
    distance = float(region.signed_distance(point)[0])
    inside = bool(region.contains(point)[0])
    if abs(distance) > 1e-9:
        assert inside == (distance > 0)


def test_distance_scores_and_evaluate(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    scores = distance_scores(dataset)
    assert scores is not None
    capture, success = scores
    assert capture.shape == success.shape == (2, 3)
    # The sign of the capture heuristic is the current-state capture label.
    np.testing.assert_array_equal(capture > 0, dataset.arrays["captured"])
    assert isinstance(PushingTask().success_region(), MeasurableRegion)
    assert isinstance(ScoopingTask().success_region(), MeasurableRegion)
