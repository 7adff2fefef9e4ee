"""The physical state of one recorded frame and the end-effector state a scripted command sees, engine-free."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from energy_margin.errors import InvalidParameterError

__all__ = [
    "FrameState",
    "RobotState",
    "relative_rotation_vector",
    "yaw_from_quat",
]


@dataclass(frozen=True)
class FrameState:
    """Poses and velocities of the objects and the end-effector at one instant.

    Attributes:
        object_pos: centre-of-mass positions, shape (n_objects, 3), metres, world frame.
        object_quat: orientations, shape (n_objects, 4), ``(w, x, y, z)``.
        object_vel: linear then angular velocity, shape (n_objects, 6), m/s and rad/s, world frame.
        robot_q: end-effector joint positions, shape (n_robot_dofs,), metres or radians.
        robot_v: end-effector joint velocities, shape (n_robot_dofs,), m/s or rad/s.

    """

    object_pos: np.ndarray
    object_quat: np.ndarray
    object_vel: np.ndarray
    robot_q: np.ndarray
    robot_v: np.ndarray

    @property
    def n_objects(self) -> int:
        """Number of objects."""
        return int(self.object_pos.shape[0])

    def validate(self, *, n_objects: int, n_robot_dofs: int) -> None:
        """Raise ``ValueError`` naming the first array with a wrong shape or a non-finite value."""
        expected = {
            "object_pos": (n_objects, 3),
            "object_quat": (n_objects, 4),
            "object_vel": (n_objects, 6),
            "robot_q": (n_robot_dofs,),
            "robot_v": (n_robot_dofs,),
        }
        for name, shape in expected.items():
            value = np.asarray(getattr(self, name))
            if value.shape != shape:
                raise InvalidParameterError(name, f"must have shape {shape}, got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise InvalidParameterError(name, "contains NaN or infinite values")
        norms = np.linalg.norm(self.object_quat, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-3):
            raise InvalidParameterError("object_quat", "must hold unit quaternions")


def yaw_from_quat(quat: np.ndarray) -> np.ndarray:
    """Rotation about world z of quaternions ``(..., 4)`` ``(w, x, y, z)``, radians, shape ``(...)``."""
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


_NEXT = np.array([1, 2, 0])
_PREVIOUS = np.array([2, 0, 1])


def relative_rotation_vector(quat_from: np.ndarray, quat_to: np.ndarray) -> np.ndarray:
    """Rotation vector of ``R_to R_from^T`` (world frame), shape (..., 3), radians.

    Args:
        quat_from: start orientations, shape (..., 4), ``(w, x, y, z)``.
        quat_to: end orientations, the same shape.
    """
    # q_rel = q_to * conj(q_from), written out on columns (the tree costs its nodes in batches).
    w_from, v_from = quat_from[..., :1], quat_from[..., 1:]
    w_to, v_to = quat_to[..., :1], quat_to[..., 1:]
    w_rel = np.sum(quat_to * quat_from, axis=-1)
    cross = v_to[..., _NEXT] * v_from[..., _PREVIOUS] - v_to[..., _PREVIOUS] * v_from[..., _NEXT]
    v_rel = w_from * v_to - w_to * v_from - cross
    # The shortest rotation has w >= 0.
    sign = np.where(w_rel < 0.0, -1.0, 1.0)
    sin_half = np.sqrt(np.sum(v_rel * v_rel, axis=-1))
    angle = 2.0 * np.arctan2(sin_half, sign * w_rel)
    # angle / sin(angle / 2) -> 2 as the angle -> 0.
    scale = np.divide(angle, sin_half, out=np.full_like(angle, 2.0), where=sin_half > 1e-12) * sign
    return v_rel * scale[..., None]


@dataclass(frozen=True, slots=True)
class RobotState:
    """The end-effector at one instant of a roll-out, as a task's scripted command sees it.

    Passed to ``Task.robot_force(state, rng)`` and ``Task.robot_targets(state, rng)``.

    Attributes:
        drive: the trajectory's drive parameters (``Trajectory.drive``), shape (n_drive,), in the
            task's units.
        time: time since the start of the roll-out, s.
        q: end-effector generalized coordinates, shape (n_robot_dofs,), m or rad.
        v: end-effector generalized velocities, shape (n_robot_dofs,), m/s or rad/s.

    """

    drive: np.ndarray
    time: float
    q: np.ndarray
    v: np.ndarray
