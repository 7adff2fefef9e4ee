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

import numpy as np

from energy_margin.tasks.base import MeasurableRegion, Region, Task
from energy_margin.world.state import FrameState

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
        if len(frames) == 0:
            raise ValueError("frames must hold at least one frame state")
        out = np.empty((len(frames), self.dimension))
        groups: dict[int, list[int]] = {}
        for index, frame in enumerate(frames):
            if np.shape(frame.robot_q) != (self.n_robot_dofs,) or np.shape(frame.robot_v) != (self.n_robot_dofs,):
                raise ValueError(
                    f"frames[{index}] has robot_q of shape {np.shape(frame.robot_q)}; "
                    f"{self.task.label} has {self.n_robot_dofs} end-effector coordinates"
                )
            groups.setdefault(frame.n_objects, []).append(index)
        for indices in groups.values():
            out[indices] = self._same_size([frames[i] for i in indices])
        return out

    def _same_size(self, frames: list[FrameState]) -> np.ndarray:
        """Features of frames that all hold the same number of objects, shape (F, D)."""
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
        for f, frame in enumerate(frames):
            capture = task.capture_region(frame)
            success = task.success_region_at(frame)
            regions[f, :, 0] = _signed_distance(capture, pos[f])
            regions[f, :, 1] = _signed_distance(success, pos[f])
            regions[f, :, 2] = capture.contains(pos[f], vel[f])
            regions[f, :, 3] = success.contains(pos[f], vel[f])
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
        return np.concatenate([statistics, set_features, robot_q, robot_v], axis=1)


#: Whether each region class measures distances (a protocol ``isinstance`` is slow per frame).
_MEASURABLE: dict[type, bool] = {}


def _signed_distance(region: Region, positions: np.ndarray) -> np.ndarray:
    """Signed distance (n,) of each object to ``region``, m; 0 where the region measures none."""
    kind = type(region)
    measurable = _MEASURABLE.get(kind)
    if measurable is None:
        measurable = _MEASURABLE[kind] = isinstance(region, MeasurableRegion)
    if measurable:
        return np.asarray(region.signed_distance(positions), dtype=float)  # type: ignore[attr-defined]
    return np.zeros(positions.shape[0])


def _end_effector_anchor(task: Task, n_robot_dofs: int) -> tuple[np.ndarray, np.ndarray]:
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
