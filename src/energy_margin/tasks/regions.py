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
``contact``
    the object's geoms, at its position and orientation, within ``margin`` (m, default 0.001) of
    the geom ``geom`` or of any geom of ``body`` (MuJoCo's ``mj_geomDistance``, the other body
    taken at the analysed frame). Needs orientations: ``uses_orientation`` is true.
``all``, ``any``
    every / at least one of the regions in ``of``.
``not``
    the complement of ``region``.

Sets quantify over objects: :class:`AtLeast` holds for every object of a state when at least k
objects of that state are inside its region, so ``all_inside`` of the tasks then means "at least
k objects" (the paper's sets are "every object": the region itself).

The combinations and :class:`AtLeast` are in :mod:`~energy_margin.tasks.region_sets`, the
``contact`` region and :class:`FrameLookup` in :mod:`~energy_margin.tasks.region_contact`; this
module re-exports them beside the geometric primitives and the registry.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.errors import InvalidParameterError, check_positive_float
from energy_margin.tasks.region_contact import ContactRegion, FrameLookup
from energy_margin.tasks.region_sets import AllOf, AnyOf, AtLeast, NotIn

__all__ = [
    "REGION_TYPES",
    "AllOf",
    "AnyOf",
    "AtLeast",
    "BoxRegion",
    "ContactRegion",
    "CylinderRegion",
    "FrameLookup",
    "IntervalRegion",
    "NotIn",
    "RegionType",
    "SpeedRegion",
    "build_region",
    "builds_stacked",
    "distance_region",
    "height_region",
    "register_region_type",
]


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
            raise InvalidParameterError("half_size", f"must be > 0, got {half_size!r}")
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
        check_positive_float("radius", radius)
        check_positive_float("half_height", half_height)
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
            raise InvalidParameterError("min", f"must not exceed max, got {low!r} and {high!r}")
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


def height_region(reference: float | np.ndarray, low: float, high: float) -> IntervalRegion:
    """Height z - ``reference`` between ``low`` and ``high``, m.

    ``reference`` is a number, or an array broadcast against the heights (one per row of stacked poses).
    """
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
            raise InvalidParameterError(
                "max_linear", f"and max_angular must be >= 0, got {max_linear!r} and {max_angular!r}"
            )
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
        stacks: built from a lookup of stacked poses (origins (M, 1, 3), rotations (M, 1, 3, 3)),
            the region measures row m of positions (M, n, 3) against pose m with the very
            arithmetic of a region built from pose m alone (so M states' regions are one region).

    """

    name: str
    keys: Mapping[str, str]
    required: tuple[str, ...]
    build: Callable[[Mapping[str, Any], FrameLookup, Callable[[Mapping[str, Any]], Any]], Any]
    one_of: tuple[tuple[str, ...], ...] = ()
    require_one_of: tuple[str, ...] = ()
    stacks: bool = False


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
    # A body's height: a number, or one per row of stacked poses (M, 1).
    reference = lookup("body", table["body"])[0][..., 2] if "body" in table else float(table.get("plane", 0.0))
    return height_region(reference, table.get("min", 0.0), table.get("max", np.inf))


def _build_distance(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    kind = "site" if "site" in table else "body"
    return distance_region(lookup(kind, table[kind])[0], table.get("min", 0.0), table["max"])


def _build_speed(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    del lookup
    return SpeedRegion(table["max"], table.get("angular_max", np.inf))


def _build_contact(table: Mapping[str, Any], lookup: FrameLookup, _: Callable[[Mapping[str, Any]], Any]) -> Any:
    model = lookup.model
    if "geom" in table:
        lookup("geom", table["geom"])  # raises for an unknown geom
        targets = np.array([_geom_id(model, table["geom"])])
    else:
        lookup("body", table["body"])
        targets = np.flatnonzero(model.geom_bodyid == _body_id(model, table["body"]))
    return ContactRegion(lookup, targets, table.get("margin", 0.001))


def _geom_id(model: Any, name: str) -> int:
    import mujoco

    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name))


def _body_id(model: Any, name: str) -> int:
    import mujoco

    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))


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
        stacks=True,
    ),
    RegionType(
        "distance",
        {"max": "number", "min": "number", **_FRAME_KEYS},
        ("max",),
        _build_distance,
        (("body", "site"),),
        ("body", "site"),
        stacks=True,
    ),
    RegionType("speed", {"max": "number", "angular_max": "number"}, ("max",), _build_speed, stacks=True),
    RegionType(
        "contact",
        {"geom": "geom", "body": "body", "margin": "number"},
        (),
        _build_contact,
        (("geom", "body"),),
        ("geom", "body"),
    ),
    RegionType("all", {"of": "regions"}, ("of",), _build_all, stacks=True),
    RegionType("any", {"of": "regions"}, ("of",), _build_any, stacks=True),
    RegionType("not", {"region": "region"}, ("region",), _build_not, stacks=True),
):
    register_region_type(_type)


def build_region(table: Mapping[str, Any], lookup: FrameLookup) -> Any:
    """The region of a validated region table, with body and site frames from ``lookup``."""
    region_type = REGION_TYPES[table["type"]]
    return region_type.build(table, lookup, lambda part: build_region(part, lookup))


def builds_stacked(table: Mapping[str, Any]) -> bool:
    """Whether the region of a validated table, and every region in it, stacks (:attr:`RegionType.stacks`)."""
    region_type = REGION_TYPES[table["type"]]
    parts = [part for key, kind in region_type.keys.items() if kind == "regions" for part in table.get(key, ())]
    parts += [table[key] for key, kind in region_type.keys.items() if kind == "region" and key in table]
    return region_type.stacks and all(builds_stacked(part) for part in parts)
