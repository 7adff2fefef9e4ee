"""Region primitives against hand-computed cases: inside, outside, on the boundary, moving frames."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.errors import InvalidParameterError
from energy_margin.tasks.base import MeasurableRegion, all_inside
from energy_margin.tasks.regions import (
    REGION_TYPES,
    AllOf,
    AnyOf,
    AtLeast,
    BoxRegion,
    CylinderRegion,
    NotIn,
    SpeedRegion,
    build_region,
    distance_region,
    height_region,
)


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_world_box_inside_outside_boundary() -> None:
    box = BoxRegion([1.0, 0.0, 0.0], [0.5, 0.2, 0.1])
    points = np.array([[1.0, 0.0, 0.0], [1.5, 0.0, 0.0], [1.6, 0.0, 0.0], [1.0, 0.3, 0.0]])
    assert box.contains(points).tolist() == [True, True, False, False]
    # Centre: 0.1 from the nearest (z) face; on the x face: 0; 0.1 beyond it; 0.1 beyond the y face.
    np.testing.assert_allclose(box.signed_distance(points), [0.1, 0.0, -0.1, -0.1], atol=1e-12)
    # Beyond a corner: the Euclidean distance to it.
    np.testing.assert_allclose(box.signed_distance(np.array([1.8, 0.6, 0.0])), -0.5, atol=1e-12)


def test_box_in_a_rotated_moving_body_frame() -> None:
    # A body at (2, 1, 0) turned 90 degrees about z: its local x is the world y.
    box = BoxRegion([0.3, 0.0, 0.0], [0.1, 0.05, 0.05], origin=np.array([2.0, 1.0, 0.0]), rotation=_rot_z(np.pi / 2))
    inside_world = np.array([2.0, 1.3, 0.0])  # local (0.3, 0, 0)
    outside_world = np.array([2.3, 1.0, 0.0])  # local (0, -0.3, 0)
    assert box.contains(np.stack([inside_world, outside_world])).tolist() == [True, False]
    # The same body after moving by (+1, 0, 0): the box moves with it.
    moved = BoxRegion([0.3, 0.0, 0.0], [0.1, 0.05, 0.05], origin=np.array([3.0, 1.0, 0.0]), rotation=_rot_z(np.pi / 2))
    assert not moved.contains(inside_world)
    assert moved.contains(inside_world + np.array([1.0, 0.0, 0.0]))


def test_cylinder() -> None:
    cylinder = CylinderRegion([0.0, 0.0, 0.0], 0.5, 0.2)
    points = np.array([[0.3, 0.4, 0.0], [0.3, 0.4, 0.2], [0.6, 0.0, 0.0], [0.0, 0.0, 0.25], [0.1, 0.0, 0.0]])
    assert cylinder.contains(points).tolist() == [True, True, False, False, True]
    np.testing.assert_allclose(cylinder.signed_distance(points), [0.0, 0.0, -0.1, -0.05, 0.2], atol=1e-12)


def test_height_and_distance() -> None:
    height = height_region(0.1, 0.0, 0.5)
    points = np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.35], [0.0, 0.0, 0.7], [0.0, 0.0, 0.05]])
    assert height.contains(points).tolist() == [True, True, False, False]
    np.testing.assert_allclose(height.signed_distance(points), [0.0, 0.25, -0.1, -0.05], atol=1e-12)
    distance = distance_region(np.array([1.0, 1.0, 0.0]), 0.0, 0.5)
    points = np.array([[1.3, 1.4, 0.0], [1.0, 1.0, 0.6], [1.0, 1.1, 0.0]])
    assert distance.contains(points).tolist() == [True, False, True]
    np.testing.assert_allclose(distance.signed_distance(points), [0.0, -0.1, 0.1], atol=1e-12)


def test_speed_uses_velocities_and_rest_is_inside() -> None:
    speed = SpeedRegion(0.5, 1.0)
    positions = np.zeros((3, 3))
    velocities = np.array([[0.3, 0.4, 0, 0, 0, 0], [0.3, 0.41, 0, 0, 0, 0], [0, 0, 0, 0, 0, 1.2]], dtype=float)
    assert speed.contains(positions, velocities).tolist() == [True, False, False]
    assert speed.contains(positions).tolist() == [True, True, True]
    assert np.all(np.isinf(speed.signed_distance(positions)))


def test_all_any_not() -> None:
    left = BoxRegion([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    right = BoxRegion([1.5, 0.0, 0.0], [1.0, 1.0, 1.0])
    points = np.array([[0.8, 0.0, 0.0], [-0.8, 0.0, 0.0], [2.2, 0.0, 0.0], [5.0, 0.0, 0.0]])
    assert AllOf([left, right]).contains(points).tolist() == [True, False, False, False]
    assert AnyOf([left, right]).contains(points).tolist() == [True, True, True, False]
    assert NotIn(left).contains(points).tolist() == [False, False, True, True]
    np.testing.assert_allclose(AllOf([left, right]).signed_distance(points[:1]), [0.2])
    np.testing.assert_allclose(AnyOf([left, right]).signed_distance(points[3:]), [-2.5])
    np.testing.assert_allclose(NotIn(left).signed_distance(points[:1]), [-0.2])
    assert isinstance(NotIn(AllOf([left, SpeedRegion(1.0)])), MeasurableRegion)


def test_every_object_and_at_least_k() -> None:
    box = BoxRegion([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    # Two states of three objects: two inside in the first, one in the second.
    states = np.array(
        [
            [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [3.0, 0.0, 0.0]],
            [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]],
        ]
    )
    assert all_inside(box, states).tolist() == [False, False]
    assert all_inside(AtLeast(2, box), states).tolist() == [True, False]
    assert all_inside(AtLeast(1, box), states).tolist() == [True, True]
    assert all_inside(AtLeast(3, box), states).tolist() == [False, False]
    # The distance baseline's min over objects is the 2nd-largest object distance.
    np.testing.assert_allclose(np.min(AtLeast(2, box).signed_distance(states), axis=-1), [0.5, -1.0])
    with pytest.raises(InvalidParameterError, match=r"^count must be a positive integer, got 0$"):
        AtLeast(0, box)


def test_build_region_from_tables_with_a_body_frame() -> None:
    def lookup(kind: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        assert (kind, name) == ("body", "pusher")
        return np.array([0.0, 1.0, 0.0]), np.eye(3)

    table = {
        "type": "all",
        "of": [
            {"type": "box", "body": "pusher", "center": (0.0, 0.2, 0.0), "half_size": (0.1, 0.1, 0.1)},
            {"type": "not", "region": {"type": "height", "min": 0.5}},
        ],
    }
    region = build_region(table, lookup)
    points = np.array([[0.0, 1.2, 0.0], [0.0, 1.2, 0.6], [0.0, 0.2, 0.0]])
    assert region.contains(points).tolist() == [True, False, False]
    assert {"box", "cylinder", "height", "distance", "speed", "all", "any", "not"} <= set(REGION_TYPES)
