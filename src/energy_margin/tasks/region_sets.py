"""Regions composed of regions, and quantifiers over the objects of a state.

:class:`AllOf`, :class:`AnyOf` and :class:`NotIn` combine regions per object; :class:`AtLeast`
holds for every object of a state when at least k objects of it are inside its region. Each passes
orientations on to a part that uses them (a ``contact`` region).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from energy_margin.errors import InvalidParameterError, check_positive_int

__all__ = ["AllOf", "AnyOf", "AtLeast", "NotIn"]


def _contains(
    region: Any, positions: np.ndarray, velocities: np.ndarray | None, quaternions: np.ndarray | None
) -> np.ndarray:
    """``region.contains``, with the orientations when the region uses them."""
    if quaternions is not None and getattr(region, "uses_orientation", False):
        result: np.ndarray = region.contains(positions, velocities, quaternions=quaternions)
        return result
    result = region.contains(positions, velocities)
    return result


class AllOf:
    """Inside every one of ``parts``."""

    def __init__(self, parts: list[Any]) -> None:
        """Build it from at least one region."""
        if not parts:
            raise InvalidParameterError("parts", "must hold at least one region")
        self.parts = parts
        self.uses_orientation = any(getattr(part, "uses_orientation", False) for part in parts)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The smallest of the parts' signed distances (m), shape (...)."""
        return np.min([part.signed_distance(positions) for part in self.parts], axis=0)

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Inside every part, shape (...)."""
        return np.all([_contains(part, positions, velocities, quaternions) for part in self.parts], axis=0)


class AnyOf(AllOf):
    """Inside at least one of ``parts``."""

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The largest of the parts' signed distances (m), shape (...)."""
        return np.max([part.signed_distance(positions) for part in self.parts], axis=0)

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Inside some part, shape (...)."""
        return np.any([_contains(part, positions, velocities, quaternions) for part in self.parts], axis=0)


class NotIn:
    """Outside ``region``."""

    def __init__(self, region: Any) -> None:
        """Build the complement of ``region``."""
        self.region = region
        self.uses_orientation = bool(getattr(region, "uses_orientation", False))

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The region's signed distance, negated (m), shape (...)."""
        return -self.region.signed_distance(positions)

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Outside the region, shape (...)."""
        return ~_contains(self.region, positions, velocities, quaternions)


class AtLeast:
    """At least ``count`` objects of a state inside ``region``: the same answer for each object.

    ``contains`` returns, for every object of a state (last axis), whether ``count`` or more of
    that state's objects are inside, so "every object in this region" (``all_inside``) reads
    "at least ``count`` objects in ``region``".
    """

    def __init__(self, count: int, region: Any) -> None:
        """Build it (``count`` >= 1)."""
        self.count = check_positive_int("count", count)
        self.region = region
        self.uses_orientation = bool(getattr(region, "uses_orientation", False))

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The ``count``-th largest object distance of each state, for each object (m), shape (..., n)."""
        distances = self.region.signed_distance(positions)
        n = distances.shape[-1]
        if self.count > n:
            return np.full_like(distances, -np.inf)
        kth = -np.sort(-distances, axis=-1)[..., self.count - 1]
        return np.broadcast_to(kth[..., None], distances.shape).copy()

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Whether at least ``count`` objects of each state are inside, for each object, shape (..., n)."""
        inside = _contains(self.region, positions, velocities, quaternions)
        enough = np.sum(inside, axis=-1) >= self.count
        return np.broadcast_to(enough[..., None], inside.shape).copy()
