"""Region primitives that scene files compose into capture and success sets, and their registry.

A region tests object states: ``contains(positions (..., n, 3), velocities (..., n, 6) | None)``
returns a boolean per object, shape (..., n), and ``signed_distance(positions)`` how far inside
each position is (m, > 0 inside, < 0 outside, 0 on the boundary), so the distance baseline works
on every composed set. Velocities of ``None`` mean the objects are at rest.

Primitives (the ``type`` of a region table; keys in :data:`REGION_TYPES`):

``box``
    ``center`` (3,) m, ``half_size`` (3,) m, in the world frame or in the frame of ``body`` /
    ``site`` taken at the analysed frame.
``cylinder``
    ``center`` (3,) m, ``radius`` m, ``half_height`` m, axis along the frame's z.
``height``
    the height above the plane z = ``plane`` (m, default 0) or above the origin of ``body``,
    between ``min`` (default 0) and ``max`` (default unbounded), m.
``distance``
    the distance to the origin of ``site`` or ``body``, between ``min`` (default 0) and ``max``, m.
``speed``
    linear speed below ``max`` m/s (and angular speed below ``angular_max`` rad/s, default
    unbounded). At rest (no velocities) an object is inside; its signed distance is +inf.
``all``, ``any``
    every / at least one of the regions in ``of``.
``not``
    the complement of ``region``.

Sets quantify over objects: :class:`AtLeast` holds for every object of a state when at least k
objects of that state are inside its region, so ``all_inside`` of the tasks then means "at least
k objects" (the paper's sets are "every object": the region itself).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np


class FrameLookup(Protocol):
    """The pose of a named body or site at the frame a region is built from."""

    def __call__(self, kind: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Origin (3,) m and rotation matrix (3, 3) (columns: the frame's axes in world coordinates)."""
        ...


_IDENTITY = np.eye(3)


def _to_local(positions: np.ndarray, origin: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """World positions (..., 3) in a frame given by origin (3,) and rotation (3, 3)."""
    return (np.asarray(positions, dtype=float) - origin) @ rotation


class BoxRegion:
    """An oriented box: centre and half sizes in a frame (world or a body's at the analysed frame)."""

    def __init__(
        self,
        center: np.ndarray,
        half_size: np.ndarray,
        *,
        origin: np.ndarray | None = None,
        rotation: np.ndarray | None = None,
    ) -> None:
        """Build the box.

        Args:
            center: centre in the frame, shape (3,), m.
            half_size: half extents along the frame's axes, shape (3,), m, > 0.
            origin: the frame's origin in the world, shape (3,), m (world frame when ``None``).
            rotation: the frame's rotation matrix, shape (3, 3).

        """
        self.center = np.asarray(center, dtype=float)
        self.half_size = np.asarray(half_size, dtype=float)
        if np.any(self.half_size <= 0):
            raise ValueError(f"half_size must be > 0, got {half_size!r}")
        self.origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
        self.rotation = _IDENTITY if rotation is None else np.asarray(rotation, dtype=float)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) to the box's faces, shape (...): > 0 inside (to the nearest face)."""
        local = _to_local(positions, self.origin, self.rotation) - self.center
        outside = np.abs(local) - self.half_size
        inside_depth = -np.max(outside, axis=-1)
        beyond = np.linalg.norm(np.maximum(outside, 0.0), axis=-1)
        return np.where(inside_depth >= 0, inside_depth, -beyond)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each position (..., 3) is inside or on the box, shape (...)."""
        del velocities
        local = _to_local(positions, self.origin, self.rotation) - self.center
        return np.all(np.abs(local) <= self.half_size, axis=-1)


class CylinderRegion:
    """A solid cylinder with its axis along the frame's z."""

    def __init__(
        self,
        center: np.ndarray,
        radius: float,
        half_height: float,
        *,
        origin: np.ndarray | None = None,
        rotation: np.ndarray | None = None,
    ) -> None:
        """Build the cylinder: centre (3,) m in the frame, radius m, half height m."""
        if radius <= 0 or half_height <= 0:
            raise ValueError(f"radius and half_height must be > 0, got {radius!r} and {half_height!r}")
        self.center = np.asarray(center, dtype=float)
        self.radius = float(radius)
        self.half_height = float(half_height)
        self.origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
        self.rotation = _IDENTITY if rotation is None else np.asarray(rotation, dtype=float)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) to the cylinder's surface, shape (...)."""
        local = _to_local(positions, self.origin, self.rotation) - self.center
        radial = np.linalg.norm(local[..., :2], axis=-1) - self.radius
        axial = np.abs(local[..., 2]) - self.half_height
        inside_depth = -np.maximum(radial, axial)
        beyond = np.hypot(np.maximum(radial, 0.0), np.maximum(axial, 0.0))
        return np.where(inside_depth >= 0, inside_depth, -beyond)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each position (..., 3) is inside or on the cylinder, shape (...)."""
        del velocities
        local = _to_local(positions, self.origin, self.rotation) - self.center
        radial = np.linalg.norm(local[..., :2], axis=-1)
        return (radial <= self.radius) & (np.abs(local[..., 2]) <= self.half_height)


class IntervalRegion:
    """A scalar of each position (a height or a distance) between ``low`` and ``high``."""

    def __init__(self, measure: Callable[[np.ndarray], np.ndarray], low: float, high: float) -> None:
        """Build it: ``measure`` maps positions (..., 3) to values (...) in metres."""
        if not low <= high:
            raise ValueError(f"min must not exceed max, got {low!r} and {high!r}")
        self.measure = measure
        self.low = float(low)
        self.high = float(high)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Distance (m) of the measured value to the nearer bound, > 0 inside, shape (...)."""
        value = self.measure(np.asarray(positions, dtype=float))
        return np.minimum(value - self.low, self.high - value)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether the measured value of each position (..., 3) is in [low, high], shape (...)."""
        del velocities
        value = self.measure(np.asarray(positions, dtype=float))
        return (value >= self.low) & (value <= self.high)


def height_region(reference: float, low: float, high: float) -> IntervalRegion:
    """Height z - ``reference`` (m) between ``low`` and ``high``."""
    return IntervalRegion(lambda positions: positions[..., 2] - reference, low, high)


def distance_region(point: np.ndarray, low: float, high: float) -> IntervalRegion:
    """Distance (m) to ``point`` (3,) between ``low`` and ``high``."""
    point = np.asarray(point, dtype=float)
    return IntervalRegion(lambda positions: np.linalg.norm(positions - point, axis=-1), low, high)


class SpeedRegion:
    """Linear speed at most ``max_linear`` (m/s) and angular speed at most ``max_angular`` (rad/s)."""

    def __init__(self, max_linear: float, max_angular: float = np.inf) -> None:
        """Build it (bounds >= 0)."""
        if max_linear < 0 or max_angular < 0:
            raise ValueError(f"speed bounds must be >= 0, got {max_linear!r} and {max_angular!r}")
        self.max_linear = float(max_linear)
        self.max_angular = float(max_angular)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """+inf for every position (..., 3): positions alone are at rest, always inside."""
        return np.full(np.asarray(positions).shape[:-1], np.inf)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each object's speeds are within the bounds (at rest when ``velocities`` is None)."""
        shape = np.asarray(positions).shape[:-1]
        if velocities is None:
            return np.ones(shape, dtype=bool)
        velocities = np.asarray(velocities, dtype=float)
        linear = np.linalg.norm(velocities[..., :3], axis=-1)
        angular = np.linalg.norm(velocities[..., 3:], axis=-1)
        return (linear <= self.max_linear) & (angular <= self.max_angular)


class AllOf:
    """Inside every one of ``parts``."""

    def __init__(self, parts: list[Any]) -> None:
        """Build it from at least one region."""
        if not parts:
            raise ValueError("needs at least one region")
        self.parts = parts

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The smallest of the parts' signed distances (m), shape (...)."""
        return np.min([part.signed_distance(positions) for part in self.parts], axis=0)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Inside every part, shape (...)."""
        return np.all([part.contains(positions, velocities) for part in self.parts], axis=0)


class AnyOf(AllOf):
    """Inside at least one of ``parts``."""

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The largest of the parts' signed distances (m), shape (...)."""
        return np.max([part.signed_distance(positions) for part in self.parts], axis=0)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Inside some part, shape (...)."""
        return np.any([part.contains(positions, velocities) for part in self.parts], axis=0)


class NotIn:
    """Outside ``region``."""

    def __init__(self, region: Any) -> None:
        """Build the complement of ``region``."""
        self.region = region

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The region's signed distance, negated (m), shape (...)."""
        return -self.region.signed_distance(positions)

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Outside the region, shape (...)."""
        return ~self.region.contains(positions, velocities)


class AtLeast:
    """At least ``count`` objects of a state inside ``region``: the same answer for each object.

    ``contains`` returns, for every object of a state (last axis), whether ``count`` or more of
    that state's objects are inside, so "every object in this region" (``all_inside``) reads
    "at least ``count`` objects in ``region``".
    """

    def __init__(self, count: int, region: Any) -> None:
        """Build it (``count`` >= 1)."""
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ValueError(f"at_least must be an integer >= 1, got {count!r}")
        self.count = count
        self.region = region

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """The ``count``-th largest object distance of each state, for each object (m), shape (..., n)."""
        distances = self.region.signed_distance(positions)
        n = distances.shape[-1]
        if self.count > n:
            return np.full_like(distances, -np.inf)
        kth = -np.sort(-distances, axis=-1)[..., self.count - 1]
        return np.broadcast_to(kth[..., None], distances.shape).copy()

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether at least ``count`` objects of each state are inside, for each object, shape (..., n)."""
        inside = self.region.contains(positions, velocities)
        enough = np.sum(inside, axis=-1) >= self.count
        return np.broadcast_to(enough[..., None], inside.shape).copy()


@dataclass(frozen=True)
class RegionType:
    """A region primitive of scene files.

    Attributes:
        name: the ``type`` value.
        keys: every accepted key (besides ``type``) and the kind of its value: ``"vector3"``,
            ``"number"``, ``"name"``, ``"regions"`` (a list of region tables) or ``"region"``.
        required: keys that must be given.
        build: makes the region from the validated table and a lookup of body and site frames.
        one_of: groups of keys of which at most one may be given.
        require_one_of: keys of which exactly one must be given (empty: no such rule).

    """

    name: str
    keys: Mapping[str, str]
    required: tuple[str, ...]
    build: Callable[[Mapping[str, Any], FrameLookup, Callable[[Mapping[str, Any]], Any]], Any]
    one_of: tuple[tuple[str, ...], ...] = ()
    require_one_of: tuple[str, ...] = ()


def _frame(table: Mapping[str, Any], lookup: FrameLookup) -> dict[str, np.ndarray]:
    for kind in ("body", "site"):
        if kind in table:
            origin, rotation = lookup(kind, table[kind])
            return {"origin": origin, "rotation": rotation}
    return {}


def _build_box(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    return BoxRegion(table["center"], table["half_size"], **_frame(table, lookup))


def _build_cylinder(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    return CylinderRegion(table["center"], table["radius"], table["half_height"], **_frame(table, lookup))


def _build_height(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    reference = float(lookup("body", table["body"])[0][2]) if "body" in table else float(table.get("plane", 0.0))
    return height_region(reference, table.get("min", 0.0), table.get("max", np.inf))


def _build_distance(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    kind = "site" if "site" in table else "body"
    return distance_region(lookup(kind, table[kind])[0], table.get("min", 0.0), table["max"])


def _build_speed(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    del lookup
    return SpeedRegion(table["max"], table.get("angular_max", np.inf))


def _build_all(table: Mapping[str, Any], lookup: FrameLookup, build: Callable[[Mapping[str, Any]], Any]) -> Any:
    del lookup
    return AllOf([build(part) for part in table["of"]])


def _build_any(table: Mapping[str, Any], lookup: FrameLookup, build: Callable[[Mapping[str, Any]], Any]) -> Any:
    del lookup
    return AnyOf([build(part) for part in table["of"]])


def _build_not(table: Mapping[str, Any], lookup: FrameLookup, build: Callable[[Mapping[str, Any]], Any]) -> Any:
    del lookup
    return NotIn(build(table["region"]))


#: Region primitives by ``type``; add one with :func:`register_region_type`.
REGION_TYPES: dict[str, RegionType] = {}


def register_region_type(region_type: RegionType) -> RegionType:
    """Make a region primitive available to scene files under ``region_type.name``."""
    REGION_TYPES[region_type.name] = region_type
    return region_type


_FRAME_KEYS = {"body": "body", "site": "site"}
for _type in (
    RegionType(
        "box",
        {"center": "vector3", "half_size": "vector3", **_FRAME_KEYS},
        ("center", "half_size"),
        _build_box,
        (("body", "site"),),
    ),
    RegionType(
        "cylinder",
        {"center": "vector3", "radius": "number", "half_height": "number", **_FRAME_KEYS},
        ("center", "radius", "half_height"),
        _build_cylinder,
        (("body", "site"),),
    ),
    RegionType(
        "height",
        {"plane": "number", "body": "body", "min": "number", "max": "number"},
        (),
        _build_height,
        (("plane", "body"),),
    ),
    RegionType(
        "distance",
        {"max": "number", "min": "number", **_FRAME_KEYS},
        ("max",),
        _build_distance,
        (("body", "site"),),
        ("body", "site"),
    ),
    RegionType("speed", {"max": "number", "angular_max": "number"}, ("max",), _build_speed),
    RegionType("all", {"of": "regions"}, ("of",), _build_all),
    RegionType("any", {"of": "regions"}, ("of",), _build_any),
    RegionType("not", {"region": "region"}, ("region",), _build_not),
):
    register_region_type(_type)


def build_region(table: Mapping[str, Any], lookup: FrameLookup) -> Any:
    """The region of a validated region table, with body and site frames from ``lookup``."""
    region_type = REGION_TYPES[table["type"]]
    return region_type.build(table, lookup, lambda part: build_region(part, lookup))
