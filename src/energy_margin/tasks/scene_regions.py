"""A scene task's capture and success sets: built at a frame, at many frames, and at a tree's states.

:class:`SceneRegions` holds the region hooks of :class:`~energy_margin.tasks.scene_task.SceneTask`:
the file's region tables built with the poses of its bodies and sites at a frame
(:mod:`~energy_margin.tasks.scene_lookup`), and a region that follows the robot
(:mod:`~energy_margin.tasks.scene_follow`) built at every tree state's own robot configuration. The
regions of many frames are one region over stacked poses where every region type of the set allows
it (:attr:`~energy_margin.tasks.regions.RegionType.stacks`): the same tests, row by row, without a
region per frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from energy_margin.errors import InvalidParameterError
from energy_margin.sim.mujoco_index import ModelIndex
from energy_margin.tasks.base import Region, all_inside
from energy_margin.tasks.region_types import FrameRegions
from energy_margin.tasks.regions import AtLeast, build_region, builds_stacked
from energy_margin.tasks.scene_follow import node_frames
from energy_margin.tasks.scene_lookup import SceneFrameLookup, lookup_frame, lookup_frames
from energy_margin.tasks.scene_model import LoadedScene
from energy_margin.tasks.scene_sections import region_names
from energy_margin.world.state import FrameState

if TYPE_CHECKING:
    from energy_margin.tasks.base import Task

    _Base = Task
else:
    _Base = object

__all__ = ["SceneRegions"]


class SceneRegions(_Base):
    """The region hooks of a scene task (a mixin of :class:`~energy_margin.tasks.scene_task.SceneTask`).

    The task sets ``loaded``, ``_index`` (its :class:`ModelIndex`), ``_kinematics`` (an ``MjData`` of
    the model) and ``_success`` (``None`` until the success region at the start is built).
    """

    loaded: LoadedScene
    _index: ModelIndex
    _kinematics: mujoco.MjData
    _success: Region | None

    def frame_lookup(self, frame: FrameState | None, *, objects: bool = True) -> SceneFrameLookup:
        """Poses of bodies, sites and geoms at ``frame`` (the model's start configuration for ``None``).

        The lookup holds the scene's kinematics data, which the next call overwrites: regions copy
        what they keep when they are built. ``objects=False`` leaves the frame's objects out, for
        elements whose poses they do not move.
        """
        return lookup_frame(self.loaded, self._index, self._kinematics, frame, self.model_command, objects=objects)

    def _table(self, name: str) -> tuple[dict[str, Any], int | None]:
        spec = self.loaded.spec
        return (spec.capture, spec.capture_at_least) if name == "capture" else (spec.success, spec.success_at_least)

    def _set(self, name: str, frame: FrameState | None) -> Region:
        table, at_least = self._table(name)
        region = build_region(table, self.frame_lookup(frame, objects=self.loaded.follow[name].placed_by_objects))
        return _counted(at_least, region)

    def _sets(self, name: str, frames: Sequence[FrameState]) -> Region:
        """Set ``name`` at every one of ``frames``: row f of positions (F, n, 3) against frame f's."""
        table, at_least = self._table(name)
        if not builds_stacked(table):
            return FrameRegions([self._set(name, frame) for frame in frames])
        elements = [(kind, element) for kind, element, _ in region_names(table, f"{name}.region")]
        placed = self.loaded.follow[name].placed_by_objects
        lookup = lookup_frames(self.loaded, self._index, self._kinematics, frames, elements, objects=placed)
        return _counted(at_least, build_region(table, lookup))

    def capture_region(self, root: FrameState) -> Region:
        """The capture set with body and site frames taken at ``root``."""
        return self._set("capture", root)

    def capture_regions(self, roots: Sequence[FrameState]) -> Region:
        """The capture sets of many frames as one region over stacked positions (F, ..., 3).

        One region over stacked poses where every region type of the set stacks, else one region
        per frame (:class:`FrameRegions`); row f is measured against frame f's set either way, with
        the same arithmetic.
        """
        return self._sets("capture", roots)

    def capture_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        """Which reached states have every object captured; a region that follows, in each state's own.

        A region in the frame of a body the robot moves (a paddle's band) moves on with it in the
        tree's states, so an object that stays in the moving band would leave one frozen at the
        analysed frame: such a region follows unless the file says ``capture.follow = false``
        (:mod:`~energy_margin.tasks.scene_follow`), built at every state's own ``robot_q``.

        Raises:
            InvalidParameterError: a following region and no robot configuration per state.
        """
        if not self.loaded.spec.capture_follows:
            return super().capture_inside(root, object_pos, object_vel, object_quat)
        states = self._node_states("capture", root, object_pos, object_vel, object_quat, robot_q)
        return all_inside(self.capture_regions(states), object_pos, object_vel, object_quat)

    def success_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        """As :meth:`capture_inside`, for the success region and ``success.follow`` (a tray the robot carries)."""
        if not self.loaded.spec.success_follows:
            return super().success_inside(root, object_pos, object_vel, object_quat)
        states = self._node_states("success", root, object_pos, object_vel, object_quat, robot_q)
        return all_inside(self._sets("success", states), object_pos, object_vel, object_quat)

    def _node_states(
        self,
        name: str,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None,
        robot_q: np.ndarray | None,
    ) -> list[FrameState]:
        if robot_q is None:
            raise InvalidParameterError(
                "robot_q",
                f"is needed for {self.loaded.spec.path}: its {name} region follows the robot "
                f"({self.loaded.follow[name].describe()}), so every state's robot coordinates are needed; "
                f"pass them, or write {name}.follow = false in the scene file to freeze the region at the "
                "analysed frame",
            )
        return node_frames(root, object_pos, object_vel, object_quat, robot_q)

    def success_region(self) -> Region:
        """The success set with body and site frames at the model's start configuration."""
        if self._success is None:
            self._success = self._set("success", None)
        return self._success

    def success_region_at(self, root: FrameState) -> Region:
        """The success set with body and site frames taken at ``root``."""
        return self._set("success", root)


def _counted(at_least: int | None, region: Region) -> Region:
    """``region`` as a set: every object inside it, or at least ``at_least`` of them."""
    return AtLeast(at_least, region) if at_least is not None else region
