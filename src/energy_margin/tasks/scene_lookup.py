"""Poses of a scene's named bodies, sites and geoms in one frame's kinematics, or in many frames' stacked.

:class:`SceneFrameLookup` is the ``FrameLookup`` a scene's regions are built with
(:func:`~energy_margin.tasks.regions.build_region`); :class:`StackedFrameLookup` holds the poses of
many frames, row by row, for the region types that measure each row against its own pose
(:attr:`~energy_margin.tasks.regions.RegionType.stacks`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import ClassVar

import mujoco
import numpy as np

from energy_margin.errors import EnergyMarginError
from energy_margin.sim.base import ModelCommand
from energy_margin.sim.mujoco_index import ModelIndex
from energy_margin.tasks.scene_model import LoadedScene
from energy_margin.world.state import FrameState, yaw_from_quat

__all__ = ["SceneFrameLookup", "StackedFrameLookup", "lookup_frame", "lookup_frames"]


class SceneFrameLookup:
    """Poses of named bodies, sites and geoms in one frame's kinematics (a ``FrameLookup``)."""

    _KINDS: ClassVar[dict[str, mujoco.mjtObj]] = {
        "body": mujoco.mjtObj.mjOBJ_BODY,
        "site": mujoco.mjtObj.mjOBJ_SITE,
        "geom": mujoco.mjtObj.mjOBJ_GEOM,
    }

    def __init__(self, loaded: LoadedScene, data: mujoco.MjData, object_geoms: list[np.ndarray]) -> None:
        self.loaded = loaded
        self.model = loaded.model
        self.data = data
        self.object_geoms = object_geoms
        self._poses: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, kind: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Origin (3,) m and rotation matrix (3, 3) of body, site or geom ``name``."""
        if (kind, name) not in self._poses:
            index = _element(self.loaded, kind, name)
            positions, matrices = _poses(self.data, kind)
            self._poses[(kind, name)] = (positions[index].copy(), matrices[index].reshape(3, 3).copy())
        return self._poses[(kind, name)]


class StackedFrameLookup:
    """Poses of named elements at M frames, stacked: row m is frame m's (a ``FrameLookup`` of stacked poses).

    ``lookup(kind, name)`` returns origins (M, 1, 3), m, and rotations (M, 1, 3, 3): a region built
    from them broadcasts over the objects of positions (M, n, 3) and measures row m against frame m's
    pose, as :class:`~energy_margin.tasks.region_types.FrameRegions` measures row m against a region
    built at frame m alone (for the region types whose ``stacks`` is true). ``data`` holds the last
    frame's kinematics only.
    """

    def __init__(
        self, loaded: LoadedScene, data: mujoco.MjData, poses: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
    ) -> None:
        self.loaded = loaded
        self.model = loaded.model
        self.data = data
        self.object_geoms = loaded.object_geoms
        self._poses = poses

    def __call__(self, kind: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Origins (M, 1, 3) m and rotations (M, 1, 3, 3) of body, site or geom ``name``."""
        return self._poses[(kind, name)]


def _element(loaded: LoadedScene, kind: str, name: str) -> int:
    """The id of body, site or geom ``name``; one line naming the file where the model has none."""
    index = int(mujoco.mj_name2id(loaded.model, SceneFrameLookup._KINDS[kind], name))
    if index < 0:
        spec = loaded.spec
        raise EnergyMarginError(f"{spec.path}: no {kind} {name!r} in {spec.mjcf.name}")
    return index


def _poses(data: mujoco.MjData, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions (k, 3) and rotation matrices (k, 9) of every body, site or geom in ``data``."""
    return {
        "body": (data.xpos, data.xmat),
        "site": (data.site_xpos, data.site_xmat),
        "geom": (data.geom_xpos, data.geom_xmat),
    }[kind]


def lookup_frames(
    loaded: LoadedScene,
    model_index: ModelIndex,
    data: mujoco.MjData,
    frames: Sequence[FrameState],
    elements: Sequence[tuple[str, str]],
    *,
    objects: bool = True,
) -> StackedFrameLookup:
    """The poses of ``elements`` (``(kind, name)`` pairs) at every one of ``frames``, stacked.

    Each frame's kinematics is :func:`lookup_frame`'s, computed in ``data`` (overwritten), so row m
    holds the very numbers a lookup at frame m alone gives.
    """
    count = len(frames)
    poses = {key: (np.empty((count, 1, 3)), np.empty((count, 1, 3, 3))) for key in dict.fromkeys(elements)}
    # Each element's row in data's pose arrays (views, which kinematics fills in place), and its stacks.
    sources = [(*_poses(data, kind), _element(loaded, kind, name), *poses[(kind, name)]) for kind, name in poses]
    for row, frame in enumerate(frames):
        _place(loaded, model_index, data, frame, objects=objects)
        for positions, matrices, index, origins, rotations in sources:
            origins[row, 0] = positions[index]
            rotations[row, 0] = matrices[index].reshape(3, 3)
    return StackedFrameLookup(loaded, data, poses)


def lookup_frame(
    loaded: LoadedScene,
    model_index: ModelIndex,
    data: mujoco.MjData,
    frame: FrameState | None,
    command_at: Callable[[np.ndarray, float], ModelCommand | None],
    *,
    objects: bool = True,
) -> SceneFrameLookup:
    """Poses of bodies, sites and geoms at ``frame``, computed in ``data`` (overwritten).

    Args:
        loaded: the scene.
        model_index: the scene's :class:`~energy_margin.sim.mujoco_index.ModelIndex`.
        data: kinematics data of the scene's model, overwritten here.
        frame: the frame; ``None`` for the model's start configuration.
        command_at: the task's model command at a drive and a time (s): without a frame, it
            places the mocap bodies where it puts them at time 0.
        objects: write the frame's objects; ``False`` leaves them at the model's start, for
            elements whose poses no object's coordinates move (:attr:`RegionFollow.placed_by_objects`).

    """
    model = loaded.model
    if frame is not None:
        _place(loaded, model_index, data, frame, objects=objects)
    else:
        mujoco.mj_resetData(model, data)
        data.qpos[:] = loaded.initial_qpos
        command = command_at(np.ones(2), 0.0)
        if command is not None and command.mocap_pos is not None:
            data.mocap_pos[:] = command.mocap_pos
            data.mocap_quat[:] = command.mocap_quat
        mujoco.mj_kinematics(model, data)
    return SceneFrameLookup(loaded, data, loaded.object_geoms)


def _place(loaded: LoadedScene, index: ModelIndex, data: mujoco.MjData, frame: FrameState, *, objects: bool) -> None:
    """The kinematics of ``frame`` in ``data`` (its objects too with ``objects``).

    Kinematics reads the joint positions and the mocap poses only, and this writes them all.
    """
    model = loaded.model
    data.qpos[:] = loaded.initial_qpos
    if objects:
        _write_objects(loaded, index, data, frame)
    joints = len(loaded.robot_joints)
    data.qpos[index.robot_qpos] = frame.robot_q[:joints]
    nmocap = int(model.nmocap)
    if nmocap:
        data.mocap_pos[:] = frame.robot_q[joints : joints + 3 * nmocap].reshape(-1, 3)
        data.mocap_quat[:] = frame.robot_q[joints + 3 * nmocap :].reshape(-1, 4)
    mujoco.mj_kinematics(model, data)


def _write_objects(loaded: LoadedScene, index: ModelIndex, data: mujoco.MjData, frame: FrameState) -> None:
    """The frame's object positions and orientations into ``data.qpos``."""
    if index.upright:
        zeros = np.zeros((loaded.n_objects, 3))
        yaw = yaw_from_quat(np.asarray(frame.object_quat, dtype=float))
        index.write_objects(data.qpos, data.qvel, frame.object_pos, zeros, yaw, zeros[:, 0])
    else:
        data.qpos[index.pos_index] = frame.object_pos
        data.qpos[index.quat_index] = frame.object_quat
