"""Start layouts of a scene's objects: origins drawn apart by the separation, orientations drawn after each.

:meth:`~energy_margin.tasks.scene_task.SceneTask.sample_trajectory` draws layouts here until one
places no object into the robot or an obstacle. The separation is ``randomize.start.min_separation``
(between origins, in 3-D) when the file gives it; else :func:`start_separation` chooses it from the
objects' shapes: for ``ranges`` starts under gravity along world z, twice the largest footprint
radius in the x-y plane, measured in that plane; otherwise (a pile, or gravity with an x or y
component or none) twice the largest bounding radius, in 3-D.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from energy_margin.errors import InvalidDataError
from energy_margin.sim.mujoco_index import ModelIndex
from energy_margin.tasks.scene_model import LoadedScene

__all__ = ["Separation", "draw_layout", "start_separation"]

#: Draws of one object's origin before the layout starts again (the objects before took its room).
_DRAWS_PER_OBJECT = 2_000
#: Fresh layouts before the separation is declared impossible in the start ranges.
_LAYOUT_RESTARTS = 50


@dataclass(frozen=True)
class Separation:
    """How far apart the start layout keeps object origins.

    Attributes:
        distance: the smallest distance between two origins, m.
        planar: whether it is measured in the world x-y plane (else in 3-D).
        source: where it comes from, for messages (e.g. ``twice the largest footprint radius in x-y``).
    """

    distance: float
    planar: bool
    source: str

    def apart(self, placed: np.ndarray, candidate: np.ndarray) -> bool:
        """Whether ``candidate`` (3,) lies farther than :attr:`distance` from every origin of ``placed`` (k, 3)."""
        if placed.shape[0] == 0:
            return True
        offsets = placed - candidate
        if self.planar:
            offsets = offsets[:, :2]
        return bool(np.min(np.linalg.norm(offsets, axis=1)) > self.distance)


def start_separation(loaded: LoadedScene) -> Separation:
    """The separation of ``loaded``'s start layouts: the file's ``min_separation``, else from the objects' shapes.

    Objects drawn by ``ranges`` turn only about world z; under gravity along z they stand on what
    holds them, so two of them cannot overlap when their origins lie farther apart in x-y than twice
    the largest footprint radius (:attr:`LoadedScene.object_footprint`). A pile turns objects
    every way, and other gravity leaves no plane they rest in: twice the largest bounding radius, in 3-D.
    """
    start = loaded.spec.start
    if start.min_separation is not None:
        return Separation(float(start.min_separation), planar=False, source="randomize.start.min_separation")
    gravity = np.asarray(loaded.model.opt.gravity, dtype=float)
    if start.mode != "pile" and gravity[2] != 0.0 and not np.any(gravity[:2]):
        footprint = 2.0 * float(np.max(loaded.object_footprint))
        return Separation(footprint, planar=True, source="twice the largest footprint radius, in the x-y plane")
    radius = 2.0 * float(np.max(loaded.object_radius))
    return Separation(radius, planar=False, source="twice the largest bounding radius")


def draw_layout(
    loaded: LoadedScene, model_index: ModelIndex, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Object origins (n, 3) and quaternions (n, 4), origins pairwise apart by the separation.

    Objects are placed one at a time, each drawn until it lies the separation away from those
    already placed; an object that finds no room in :data:`_DRAWS_PER_OBJECT` draws (the ones
    before took it) starts the layout again, up to :data:`_LAYOUT_RESTARTS` times.

    Raises:
        InvalidDataError: no layout fits, naming the object that found no room, the start ranges,
            the separation and how many origins a grid of that spacing fits in the ranges.
    """
    n = loaded.n_objects
    separation = start_separation(loaded)
    most_placed = 0
    for _restart in range(_LAYOUT_RESTARTS):
        pos = np.empty((n, 3))
        quat = np.empty((n, 4))
        placed = 0
        for index in range(n):
            for _attempt in range(_DRAWS_PER_OBJECT):
                candidate = _draw_origin(loaded, model_index, rng, index)
                if separation.apart(pos[:index], candidate):
                    pos[index] = candidate
                    # Drawn right after its origin: the order of draws of every layout that fits.
                    quat[index] = _draw_orientation(loaded, rng, index)
                    placed += 1
                    break
            else:
                break
        most_placed = max(most_placed, placed)
        if placed == n:
            return pos, quat
    raise InvalidDataError(_placement_failure(loaded, most_placed, separation))


def _draw_origin(loaded: LoadedScene, model_index: ModelIndex, rng: np.random.Generator, index: int) -> np.ndarray:
    start = loaded.spec.start
    if start.low is not None and start.high is not None:
        return np.asarray(rng.uniform(start.low, start.high), dtype=float)
    candidate = model_index.object_positions(loaded.initial_qpos)[index].copy()
    for axis, column in (("x", 0), ("y", 1), ("z", 2)):
        if axis in start.ranges:
            candidate[column] = rng.uniform(*start.ranges[axis])
    return np.asarray(candidate, dtype=float)


def _draw_orientation(loaded: LoadedScene, rng: np.random.Generator, index: int) -> np.ndarray:
    start = loaded.spec.start
    if start.mode == "pile":
        axis_angle = rng.normal(size=4)
        return np.asarray(axis_angle / np.linalg.norm(axis_angle), dtype=float)
    yaw = float(rng.uniform(*start.ranges["yaw"])) if "yaw" in start.ranges else 0.0
    return _quat_multiply(_quat_yaw(yaw), _base_quat(loaded, index))


def _placement_failure(loaded: LoadedScene, most_placed: int, rule: Separation) -> str:
    """Why no layout fits: the object that found no room, the ranges and a grid's capacity."""
    start = loaded.spec.start
    n = loaded.n_objects
    if start.low is not None and start.high is not None:
        spans = {axis: (float(lo), float(hi)) for axis, lo, hi in zip("xyz", start.low, start.high, strict=True)}
    else:
        spans = {axis: start.ranges[axis] for axis in "xyz" if axis in start.ranges}
    described = ", ".join(f"{axis} in [{lo:.3g}, {hi:.3g}] m" for axis, (lo, hi) in spans.items())
    stuck = loaded.object_names[min(most_placed, n - 1)]
    separation = rule.distance
    grid = ""
    if separation > 0.0:
        capacity = 1
        for axis, (lo, hi) in spans.items():
            if rule.planar and axis == "z":
                continue
            capacity *= int(np.floor((hi - lo) / separation + 1e-9)) + 1
        # An upper bound: objects drawn one at a time jam well before a grid is full.
        grid = f"; a grid of {separation:.3g} m spacing holds at most {capacity} origins there"
    return (
        f"{loaded.spec.path}: randomize.start: cannot place {n} objects {separation:.3g} m apart"
        f"{' in x-y' if rule.planar else ''} "
        f"({described or 'at their model positions'}): at most {most_placed} fit in {_LAYOUT_RESTARTS} layouts, "
        f"then {stuck} found no room in {_DRAWS_PER_OBJECT} draws{grid}; widen the start ranges or lower "
        "min_separation"
    )


def _qpos_address(loaded: LoadedScene, index: int) -> int:
    return int(loaded.model.jnt_qposadr[loaded.object_joints[index]])


def _base_quat(loaded: LoadedScene, index: int) -> np.ndarray:
    if loaded.spec.object_joints == "upright":
        return np.array([1.0, 0.0, 0.0, 0.0])
    address = _qpos_address(loaded, index)
    quat = loaded.initial_qpos[address + 3 : address + 7]
    return quat / np.linalg.norm(quat)


def _quat_yaw(yaw: float) -> np.ndarray:
    return np.array([np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)])


def _quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    result = np.empty(4)
    mujoco.mju_mulQuat(result, a, b)
    return result
