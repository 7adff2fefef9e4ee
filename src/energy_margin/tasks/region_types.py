"""Regions of object states: the :class:`Region` protocol, its measurable and drawable kinds, and membership tests.

A task's capture and success regions (:mod:`energy_margin.tasks.regions` holds the built-in ones)
answer which object states lie inside; :func:`all_inside` asks it for every object of a state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from energy_margin.errors import check_choice

__all__ = [
    "DrawableRegion",
    "FrameRegions",
    "MeasurableRegion",
    "Region",
    "RegionShape",
    "all_inside",
]


class Region(Protocol):
    """A region of object states: centre-of-mass positions and, where it matters, velocities."""

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each object state lies inside.

        Args:
            positions: shape (..., 3), metres, world frame.
            velocities: linear then angular velocities, shape (..., 6), m/s and rad/s, world
                frame; ``None`` when unknown (a region that needs them then treats the objects
                as at rest).

        Returns:
            Boolean array of shape (...).

        """
        ...


@runtime_checkable
class MeasurableRegion(Region, Protocol):
    """A region that also tells how far object positions are from its boundary."""

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of each position (..., 3) to the boundary: > 0 inside, < 0 outside, 0 on it."""
        ...


class FrameRegions:
    """One region per frame, measured row by row: the default of :meth:`Task.capture_regions`.

    Args:
        regions: the region of each of F frames.
    """

    def __init__(self, regions: Sequence[Region]) -> None:
        self.regions = list(regions)
        # all_inside passes orientations on when some frame's region tests them (a contact test).
        self.uses_orientation = any(getattr(region, "uses_orientation", False) for region in self.regions)

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Whether row f of positions (F, ..., 3) lies in frame f's region; shape (F, ...).

        ``quaternions`` (F, ..., 4) go to the regions that test orientations.
        """
        rows = []
        for f, region in enumerate(self.regions):
            velocity = None if velocities is None else velocities[f]
            if quaternions is not None and getattr(region, "uses_orientation", False):
                rows.append(region.contains(positions[f], velocity, quaternions=quaternions[f]))  # type: ignore[call-arg]
            else:
                rows.append(region.contains(positions[f], velocity))
        return np.stack(rows)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of row f of positions (F, ..., 3) to frame f's region; 0 where it measures none."""
        return np.stack(
            [
                np.asarray(region.signed_distance(positions[f]), dtype=float)
                if isinstance(region, MeasurableRegion)
                else np.zeros(np.shape(positions[f])[:-1])
                for f, region in enumerate(self.regions)
            ]
        )


@dataclass(frozen=True)
class RegionShape:
    """One solid of a region's drawing (pictures only: :meth:`Region.contains` decides membership).

    Attributes:
        kind: ``"box"`` or ``"cylinder"`` (axis along world z).
        centre: centre of the solid, shape (3,), m, world frame.
        half_size: box half extents (x, y, z) before the yaw, or cylinder (radius, half height, 0), m.
        yaw: rotation about world z, rad.

    """

    kind: str
    centre: tuple[float, float, float]
    half_size: tuple[float, float, float]
    yaw: float = 0.0

    def __post_init__(self) -> None:
        check_choice("kind", self.kind, ("box", "cylinder"))

    def contains(self, positions: np.ndarray) -> np.ndarray:
        """Whether each position (..., 3), m, lies in the solid; shape (...)."""
        relative = np.asarray(positions, dtype=float) - np.asarray(self.centre)
        cos, sin = np.cos(self.yaw), np.sin(self.yaw)
        local_x = cos * relative[..., 0] + sin * relative[..., 1]
        local_y = -sin * relative[..., 0] + cos * relative[..., 1]
        within_z = np.abs(relative[..., 2]) <= self.half_size[2 if self.kind == "box" else 1]
        if self.kind == "cylinder":
            return (np.hypot(local_x, local_y) <= self.half_size[0]) & within_z
        return (np.abs(local_x) <= self.half_size[0]) & (np.abs(local_y) <= self.half_size[1]) & within_z


@runtime_checkable
class DrawableRegion(Region, Protocol):
    """A region that can be drawn as a union of solids (renders, interactive views)."""

    def shapes(self) -> tuple[RegionShape, ...]:
        """Solids whose union draws the region (unbounded sides cut off).

        A region that ignores height (a planar task's) is drawn as its footprint: thin solids on
        the floor under the objects, whose horizontal extent matches ``contains``.
        """
        ...


def all_inside(
    region: Region,
    object_positions: np.ndarray,
    object_velocities: np.ndarray | None = None,
    object_quaternions: np.ndarray | None = None,
) -> np.ndarray:
    """True where every object of a state lies in ``region``.

    Args:
        region: the region.
        object_positions: shape (..., n_objects, 3), metres.
        object_velocities: shape (..., n_objects, 6), m/s and rad/s, or ``None``.
        object_quaternions: shape (..., n_objects, 4), ``(w, x, y, z)``, or ``None``; passed on to a
            region whose ``uses_orientation`` attribute is true (e.g. a contact test).

    Returns:
        Boolean array of shape (...).

    """
    if object_quaternions is not None and getattr(region, "uses_orientation", False):
        inside = region.contains(object_positions, object_velocities, quaternions=object_quaternions)  # type: ignore[call-arg]
    else:
        inside = region.contains(object_positions, object_velocities)
    return np.all(inside, axis=-1)
