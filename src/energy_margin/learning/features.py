"""Frame features of a learned margin: fixed-length statistics of any number of objects.

The feature set ``frame-statistics`` (version :data:`FEATURE_VERSION`) describes one frame state by
numbers that do not depend on the order of the objects and whose count does not depend on how many
there are:

* per object, 13 channels: the position relative to the end-effector anchor (x, y, z, m) and its
  horizontal distance (m); the linear velocity relative to the anchor's (x, y, z, m/s); the speed
  (m/s) and angular speed (rad/s); the signed distance to the capture region built from the frame
  and to the success region (m, > 0 inside; 0 for a region that measures no distance); whether the
  object lies in each region (0 or 1, velocities included where the region uses them);
* of each channel over the objects: the minimum, mean, maximum and standard deviation (52 numbers);
* of the set of object centres: the centroid relative to the anchor (3, m), the six entries of its
  covariance matrix (the shape of the set, m²; the moment form of the minimum-volume ellipsoid,
  computed in closed form for every frame at once), and the centroid's velocity relative to the
  anchor's (3, m/s);
* the number of objects, then the end-effector coordinates ``robot_q`` and velocities ``robot_v``
  as recorded (the task's units).

The end-effector anchor is the origin of the robot's root link moved along its slide joints (the
pusher's centre for ``pushing``, the base centre for ``scooping``); a task without a robot link
(a scene file) uses the world origin at rest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from energy_margin.errors import InvalidParameterError
from energy_margin.tasks.base import MeasurableRegion, Region, Task
from energy_margin.tasks.protocols import PhysicsReadout
from energy_margin.world.state import FrameState

__all__ = [
    "FEATURE_SET",
    "FEATURE_VERSION",
    "FrameFeatures",
    "ObjectSetFeatures",
    "SetInputs",
]

#: Name of the feature definition.
FEATURE_SET = "frame-statistics"
#: Version of the feature definition; a change of any channel bumps it.
FEATURE_VERSION = 1

_OBJECT_CHANNELS = (
    "dx",
    "dy",
    "dz",
    "horizontal_distance",
    "dvx",
    "dvy",
    "dvz",
    "speed",
    "angular_speed",
    "capture_distance",
    "success_distance",
    "in_capture",
    "in_success",
)
_STATISTICS = ("min", "mean", "max", "std")
_SET_CHANNELS = (
    "centroid_dx",
    "centroid_dy",
    "centroid_dz",
    "cov_xx",
    "cov_yy",
    "cov_zz",
    "cov_xy",
    "cov_xz",
    "cov_yz",
    "centroid_dvx",
    "centroid_dvy",
    "centroid_dvz",
    "n_objects",
)


class FrameFeatures:
    """The ``frame-statistics`` features of one task's frames.

    Args:
        task: the task whose regions and end-effector the features measure.
    """

    name = FEATURE_SET
    version = FEATURE_VERSION

    def __init__(self, task: Task) -> None:
        self.task = task
        self.n_robot_dofs = task.robot_dofs()
        self._anchor_origin, self._anchor_axes = _end_effector_anchor(task, self.n_robot_dofs)
        # A task that does not override success_region_at has one success region for every frame.
        self._success_moves = type(task).success_region_at is not Task.success_region_at

    @property
    def identifier(self) -> str:
        """``name/version``, e.g. ``"frame-statistics/1"``."""
        return f"{self.name}/{self.version}"

    @property
    def names(self) -> tuple[str, ...]:
        """Name of every feature column, in order."""
        per_object = tuple(f"{channel}_{statistic}" for channel in _OBJECT_CHANNELS for statistic in _STATISTICS)
        robot = tuple(f"robot_q{i}" for i in range(self.n_robot_dofs)) + tuple(
            f"robot_v{i}" for i in range(self.n_robot_dofs)
        )
        return per_object + _SET_CHANNELS + robot

    @property
    def dimension(self) -> int:
        """Number of features D."""
        return len(_OBJECT_CHANNELS) * len(_STATISTICS) + len(_SET_CHANNELS) + 2 * self.n_robot_dofs

    def __call__(self, frames: Sequence[FrameState]) -> np.ndarray:
        """Features of ``frames``, shape (F, D), in the units listed in the module docstring.

        Frames may hold different numbers of objects; each must have the task's end-effector size.

        Raises:
            ValueError: an empty ``frames``, or a frame whose ``robot_q`` or ``robot_v`` is not of
                the task's size.
        """
        groups = self._groups(frames)
        out = np.empty((len(frames), self.dimension))
        for indices in groups.values():
            out[indices] = self._same_size([frames[i] for i in indices])[1]
        return out

    def _groups(self, frames: Sequence[FrameState]) -> dict[int, list[int]]:
        """Indices of the frames by number of objects, after checking every frame's robot size."""
        if len(frames) == 0:
            raise InvalidParameterError("frames", "must hold at least one frame state")
        groups: dict[int, list[int]] = {}
        for index, frame in enumerate(frames):
            if np.shape(frame.robot_q) != (self.n_robot_dofs,) or np.shape(frame.robot_v) != (self.n_robot_dofs,):
                raise InvalidParameterError(
                    "frames",
                    f"must match the task: frames[{index}] has robot_q of shape {np.shape(frame.robot_q)}; "
                    f"{self.task.label} has {self.n_robot_dofs} end-effector coordinates",
                )
            groups.setdefault(frame.n_objects, []).append(index)
        return groups

    def _same_size(self, frames: list[FrameState]) -> tuple[np.ndarray, np.ndarray]:
        """Per-object channels (F, n, C) and features (F, D) of frames that all hold n objects."""
        pos = np.stack([np.asarray(frame.object_pos, dtype=float) for frame in frames])  # (F, n, 3)
        vel = np.stack([np.asarray(frame.object_vel, dtype=float) for frame in frames])  # (F, n, 6)
        robot_q = np.stack([np.asarray(frame.robot_q, dtype=float) for frame in frames])  # (F, r)
        robot_v = np.stack([np.asarray(frame.robot_v, dtype=float) for frame in frames])  # (F, r)
        anchor = self._anchor_origin + robot_q @ self._anchor_axes  # (F, 3)
        anchor_vel = robot_v @ self._anchor_axes  # (F, 3)
        relative = pos - anchor[:, None, :]
        relative_vel = vel[:, :, :3] - anchor_vel[:, None, :]
        regions = np.empty((len(frames), pos.shape[1], 4))
        task = self.task
        capture = task.capture_regions(frames)  # row f: the region built from frames[f]
        regions[:, :, 0] = _signed_distance(capture, pos)
        regions[:, :, 2] = capture.contains(pos, vel)
        if self._success_moves:
            for f, frame in enumerate(frames):
                success = task.success_region_at(frame)
                regions[f, :, 1] = _signed_distance(success, pos[f])
                regions[f, :, 3] = success.contains(pos[f], vel[f])
        else:
            # One region for every frame: measured on all of them at once (regions take (..., 3)).
            success = task.success_region()
            regions[:, :, 1] = _signed_distance(success, pos)
            regions[:, :, 3] = success.contains(pos, vel)
        channels = np.concatenate(
            [
                relative,
                np.linalg.norm(relative[:, :, :2], axis=2, keepdims=True),
                relative_vel,
                np.linalg.norm(vel[:, :, :3], axis=2, keepdims=True),
                np.linalg.norm(vel[:, :, 3:], axis=2, keepdims=True),
                regions,
            ],
            axis=2,
        )  # (F, n, C)
        statistics = np.stack(
            [channels.min(axis=1), channels.mean(axis=1), channels.max(axis=1), channels.std(axis=1)], axis=2
        ).reshape(len(frames), -1)  # (F, C * 4), channel-major
        centred = pos - pos.mean(axis=1, keepdims=True)
        covariance = np.einsum("fni,fnj->fij", centred, centred) / pos.shape[1]  # (F, 3, 3)
        rows, cols = (0, 1, 2, 0, 0, 1), (0, 1, 2, 1, 2, 2)
        set_features = np.concatenate(
            [
                relative.mean(axis=1),
                covariance[:, rows, cols],
                relative_vel.mean(axis=1),
                np.full((len(frames), 1), float(pos.shape[1])),
            ],
            axis=1,
        )
        return channels, np.concatenate([statistics, set_features, robot_q, robot_v], axis=1)


@dataclass(frozen=True)
class SetInputs:
    """Inputs of a set model: every object's channels, padded, beside the frame's features.

    Attributes:
        objects: per-object channels, shape (F, N, C), N the most objects of any frame; the rows
            past a frame's own objects are zeros.
        mask: which rows of ``objects`` are objects, shape (F, N), bool.
        frame: the ``frame-statistics`` features of each frame, shape (F, D).
    """

    objects: np.ndarray
    mask: np.ndarray
    frame: np.ndarray

    def __len__(self) -> int:
        return int(self.frame.shape[0])

    def take(self, rows: np.ndarray | slice) -> SetInputs:
        """The inputs of the frames ``rows`` (indices or a slice), padding trimmed to their most objects."""
        mask = self.mask[rows]
        width = max(1, int(mask.sum(axis=1).max())) if mask.shape[0] else 1
        return SetInputs(self.objects[rows][:, :width], mask[:, :width], self.frame[rows])

    @staticmethod
    def concatenate(parts: Sequence[SetInputs]) -> SetInputs:
        """The frames of ``parts`` in order, padded to the most objects of any of them."""
        if not parts:
            raise InvalidParameterError("parts", "must hold at least one SetInputs")
        width = max(part.objects.shape[1] for part in parts)
        channels = parts[0].objects.shape[2]
        total = sum(len(part) for part in parts)
        objects = np.zeros((total, width, channels))
        mask = np.zeros((total, width), dtype=bool)
        row = 0
        for part in parts:
            count, n = len(part), part.objects.shape[1]
            objects[row : row + count, :n] = part.objects
            mask[row : row + count, :n] = part.mask
            row += count
        return SetInputs(objects, mask, np.concatenate([part.frame for part in parts]))


class ObjectSetFeatures(FrameFeatures):
    """The ``object-sets`` inputs of a set model: each object's 13 channels and the frame's features.

    The per-object channels are those the ``frame-statistics`` summarise (module docstring), kept
    object by object so that a permutation-invariant network (:mod:`energy_margin.learning.set_network`)
    can weigh each object and its neighbours itself; the frame's ``frame-statistics`` features come
    beside them.
    """

    name = "object-sets"
    version = 1

    @property
    def object_channels(self) -> tuple[str, ...]:
        """Name of every per-object channel, in order."""
        return _OBJECT_CHANNELS

    @property
    def names(self) -> tuple[str, ...]:
        """``object.<channel>`` for every per-object channel, then the frame features' names."""
        return tuple(f"object.{channel}" for channel in _OBJECT_CHANNELS) + super().names

    @property
    def dimension(self) -> int:
        """Number of per-object channels plus frame features, C + D."""
        return len(_OBJECT_CHANNELS) + super().dimension

    def __call__(self, frames: Sequence[FrameState]) -> SetInputs:  # type: ignore[override]
        """The set inputs of ``frames`` (any numbers of objects), in the units of the module docstring.

        Raises:
            ValueError: as :meth:`FrameFeatures.__call__`.
        """
        groups = self._groups(frames)
        width = max(groups)
        objects = np.zeros((len(frames), width, len(_OBJECT_CHANNELS)))
        mask = np.zeros((len(frames), width), dtype=bool)
        frame = np.empty((len(frames), super().dimension))
        for n, indices in groups.items():
            channels, features = self._same_size([frames[i] for i in indices])
            objects[indices, :n] = channels
            mask[indices, :n] = True
            frame[indices] = features
        return SetInputs(objects, mask, frame)


#: Whether each region class measures distances (a protocol ``isinstance`` is slow per frame).
_MEASURABLE: dict[type, bool] = {}


def _signed_distance(region: Region, positions: np.ndarray) -> np.ndarray:
    """Signed distance (...) of each position (..., 3) to ``region``, m; 0 where the region measures none."""
    kind = type(region)
    measurable = _MEASURABLE.get(kind)
    if measurable is None:
        measurable = _MEASURABLE[kind] = isinstance(region, MeasurableRegion)
    if measurable:
        return np.asarray(region.signed_distance(positions), dtype=float)  # type: ignore[attr-defined]
    return np.zeros(positions.shape[:-1])


def _end_effector_anchor(task: PhysicsReadout, n_robot_dofs: int) -> tuple[np.ndarray, np.ndarray]:
    """The anchor ``origin + robot_q @ axes``: origin (3,) m and axes (r, 3) of the root link's slides."""
    axes = np.zeros((n_robot_dofs, 3))
    scene = task.build_scene(task.fixed_objects or 1, 0.5)
    if scene.robot is None:
        return np.zeros(3), axes
    # The root link's joints come first in robot_q (depth-first order of the links).
    for index, joint in enumerate(scene.robot.joints[:n_robot_dofs]):
        if joint.kind == "slide":
            axis = np.asarray(joint.axis, dtype=float)
            axes[index] = axis / np.linalg.norm(axis)
    return np.asarray(scene.robot.pos, dtype=float), axes
