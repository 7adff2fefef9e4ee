"""What a rendered frame draws besides the scene: region solids (or grid cells) and the tree's reached states.

Markers are ``(type, size, pos, mat, rgba)`` tuples the renderer turns into MuJoCo geoms;
:func:`drawn_inside` tells which objects lie inside what is drawn of a region.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from energy_margin.report.render_view import (
    likelihood_scale,
    viridis,
)

if TYPE_CHECKING:
    from energy_margin.planning import CostField
    from energy_margin.tasks.base import Region, RegionShape

__all__ = ["drawn_inside", "region_shapes", "shape_markers", "tree_markers"]


# A region solid at most this high (half height, m) is a footprint, drawn as one translucent geom.
_FLAT_HALF_HEIGHT = 0.005
# Cells of the grid a region without shapes is drawn with, per side.
_GRID_CELLS = 48


def _rotation_z(yaw: float) -> np.ndarray:
    cos, sin = np.cos(yaw), np.sin(yaw)
    return np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])


def shape_markers(shape: RegionShape, rgba: tuple[float, float, float, float]) -> list[tuple[Any, ...]]:
    """Render markers (geom type, size, position, rotation, rgba) of a region solid.

    A flat solid (a footprint) is one translucent geom; a box with height gets a fainter fill and
    its edges as lines, so that what lies inside stays visible.
    """
    import mujoco

    kind = mujoco.mjtGeom.mjGEOM_BOX if shape.kind == "box" else mujoco.mjtGeom.mjGEOM_CYLINDER
    size = np.asarray(shape.half_size, dtype=float)
    centre = np.asarray(shape.centre, dtype=float)
    rotation = _rotation_z(shape.yaw)
    fill = np.asarray(rgba, dtype=np.float32)
    height = size[2] if shape.kind == "box" else size[1]
    if height <= _FLAT_HALF_HEIGHT:
        return [(int(kind), size, centre, rotation, fill)]
    faint = fill.copy()
    faint[3] *= 0.45
    markers: list[tuple[Any, ...]] = [(int(kind), size, centre, rotation, faint)]
    if shape.kind == "box":
        edges = np.array([*fill[:3], 0.9], dtype=np.float32)
        markers.append((int(mujoco.mjtGeom.mjGEOM_LINEBOX), size, centre, rotation, edges))
    return markers


def region_shapes(region: Region, extent: np.ndarray, *, height: float) -> tuple[RegionShape, ...]:
    """Solids that draw ``region``: its own shapes, or cells of a grid over ``extent`` where it holds.

    Args:
        region: the region.
        extent: (low, high) corners of the drawn box, shape (2, 3), m; a region without shapes is
            sampled on a grid in the plane ``z = height`` over it.
        height: z of that plane, m.

    """
    from energy_margin.tasks.base import DrawableRegion, RegionShape

    if isinstance(region, DrawableRegion):
        return tuple(region.shapes())
    low, high = np.asarray(extent, dtype=float)
    xs = np.linspace(low[0], high[0], _GRID_CELLS + 1)
    ys = np.linspace(low[1], high[1], _GRID_CELLS + 1)
    centres_x, centres_y = 0.5 * (xs[1:] + xs[:-1]), 0.5 * (ys[1:] + ys[:-1])
    grid_x, grid_y = np.meshgrid(centres_x, centres_y, indexing="ij")
    points = np.stack([grid_x, grid_y, np.full_like(grid_x, height)], axis=-1)
    inside = np.asarray(region.contains(points), dtype=bool)
    half = (0.5 * (xs[1] - xs[0]), 0.5 * (ys[1] - ys[0]), 0.002)
    return tuple(
        RegionShape("box", (float(grid_x[i, j]), float(grid_y[i, j]), height), half) for i, j in np.argwhere(inside)
    )


def drawn_inside(region: Region, positions: np.ndarray) -> np.ndarray | None:
    """Whether each position (n, 3), m, lies in the drawing of ``region`` (its shapes), or ``None`` without shapes.

    Flat solids (footprints of a region that ignores height) are tested in the plane.
    """
    from energy_margin.tasks.base import DrawableRegion

    if not isinstance(region, DrawableRegion):
        return None
    positions = np.asarray(positions, dtype=float).reshape(-1, 3)
    inside = np.zeros(len(positions), dtype=bool)
    for shape in region.shapes():
        height = shape.half_size[2] if shape.kind == "box" else shape.half_size[1]
        probe = positions.copy()
        if height <= _FLAT_HALF_HEIGHT:
            probe[:, 2] = shape.centre[2]
        inside |= shape.contains(probe)
    return inside


def tree_markers(field: CostField, likelihoods: np.ndarray, *, radius: float) -> list[tuple[Any, ...]]:
    """One sphere marker per object per node (the root's hide inside the objects), coloured by likelihood."""
    import mujoco

    colours = viridis(likelihood_scale(likelihoods))
    size = np.array([radius, radius, radius])
    identity = np.eye(3)
    sphere = int(mujoco.mjtGeom.mjGEOM_SPHERE)
    markers = []
    # Most likely first: a scene too small for every marker leaves out the least likely nodes.
    for node in np.argsort(-np.asarray(likelihoods), kind="stable"):
        rgba = np.append(colours[node], 1.0).astype(np.float32)
        for position in field.object_pos[node]:
            markers.append((sphere, size, np.asarray(position, dtype=float), identity, rgba))
    return markers
