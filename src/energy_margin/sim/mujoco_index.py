"""Where a scene's objects and end-effector live in a compiled MuJoCo model.

A :class:`ModelIndex` holds the addresses the simulator and the roll-out propagator share: the
objects' bodies and coordinates, the robot's coordinates and its servo actuators. Index arrays
gather every object's coordinates in one fancy-indexing operation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from energy_margin.sim.base import ModelCommand
from energy_margin.world.scene import Scene


def rotate(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """Rotate vectors (n, 3) by quaternions (n, 4) (w, x, y, z)."""
    w = quat[:, :1]
    u = quat[:, 1:]
    t = 2.0 * np.cross(u, vec)
    return vec + w * t + np.cross(u, t)


def rotate_inverse(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """Rotate vectors (n, 3) by the inverses of quaternions (n, 4) (w, x, y, z)."""
    conj = quat * np.array([1.0, -1.0, -1.0, -1.0])
    return rotate(conj, vec)


def apply_model_command(data: mujoco.MjData, command: ModelCommand) -> None:
    """Write a model command's actuator controls and mocap poses into ``data``."""
    if command.ctrl is not None:
        data.ctrl[:] = command.ctrl
    if command.mocap_pos is not None:
        data.mocap_pos[:] = command.mocap_pos
    if command.mocap_quat is not None:
        data.mocap_quat[:] = command.mocap_quat


def name_id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    """The id of the element ``name`` of type ``kind`` in ``model`` (-1 when there is none)."""
    return int(mujoco.mj_name2id(model, kind, name))


@dataclass(frozen=True)
class ModelIndex:
    """Addresses of a scene's objects and robot in a compiled model.

    Attributes:
        object_bodies: body id of each object, shape (n_objects,).
        upright: whether the objects have the upright joints (x, y, z slides, then a z hinge)
            instead of a free joint.
        pos_index: qpos addresses of each object's position, shape (n_objects, 3).
        linvel_index: qvel addresses of each object's linear velocity, shape (n_objects, 3).
        yaw_index: qpos address of each upright object's yaw, shape (n_objects,) (empty when free).
        yaw_rate_index: qvel address of each upright object's yaw rate (empty when free).
        quat_index: qpos addresses of each free object's quaternion, shape (n_objects, 4) (empty
            when upright).
        angvel_index: qvel addresses of each free object's body-frame angular velocity, shape
            (n_objects, 3) (empty when upright).
        robot_qpos: qpos address of each robot joint, in ``robot_q`` order.
        robot_qvel: qvel address of each robot joint, in ``robot_v`` order.
        servoed: which robot coordinates a servo drives, shape (n_robot_joints,).
        servo_actuators: the actuator of each servoed coordinate, in the same order.

    """

    object_bodies: np.ndarray
    upright: bool
    pos_index: np.ndarray
    linvel_index: np.ndarray
    yaw_index: np.ndarray
    yaw_rate_index: np.ndarray
    quat_index: np.ndarray
    angvel_index: np.ndarray
    robot_qpos: np.ndarray
    robot_qvel: np.ndarray
    servoed: np.ndarray
    servo_actuators: np.ndarray

    @classmethod
    def of(
        cls,
        model: mujoco.MjModel,
        scene: Scene,
        *,
        object_joints: Sequence[int],
        robot_joints: Sequence[int],
        servoed: Sequence[bool] | None = None,
        servo_actuators: Sequence[int] = (),
    ) -> ModelIndex:
        """Index ``model`` from joint and actuator ids.

        Args:
            model: the compiled model.
            scene: its objects' description; ``scene.objects[i].name`` is object i's body.
            object_joints: id of each object's free joint (or first upright joint).
            robot_joints: ids of the robot's hinge and slide joints, in ``robot_q`` order.
            servoed: which of ``robot_joints`` a servo drives; ``None``: none.
            servo_actuators: the actuator id of each servoed joint, in order.

        """
        bodies = np.array([name_id(model, mujoco.mjtObj.mjOBJ_BODY, obj.name) for obj in scene.objects], dtype=int)
        qpos_adr = np.asarray(model.jnt_qposadr[list(object_joints)], dtype=int)
        qvel_adr = np.asarray(model.jnt_dofadr[list(object_joints)], dtype=int)
        upright = scene.object_motion == "upright"
        none = np.zeros(0, dtype=int)
        return cls(
            object_bodies=bodies,
            upright=upright,
            pos_index=qpos_adr[:, None] + np.arange(3),
            linvel_index=qvel_adr[:, None] + np.arange(3),
            yaw_index=qpos_adr + 3 if upright else none,
            yaw_rate_index=qvel_adr + 3 if upright else none,
            quat_index=none.reshape(0, 4) if upright else qpos_adr[:, None] + 3 + np.arange(4),
            angvel_index=none.reshape(0, 3) if upright else qvel_adr[:, None] + 3 + np.arange(3),
            robot_qpos=np.array(model.jnt_qposadr[list(robot_joints)], dtype=int),
            robot_qvel=np.array(model.jnt_dofadr[list(robot_joints)], dtype=int),
            servoed=np.array([False] * len(robot_joints) if servoed is None else servoed, dtype=bool),
            servo_actuators=np.array(servo_actuators, dtype=int),
        )

    def object_quaternions(self, qpos: np.ndarray) -> np.ndarray:
        """Orientations (..., n_objects, 4), (w, x, y, z), of joint positions (..., nq)."""
        if self.upright:
            half_yaw = 0.5 * qpos[..., self.yaw_index]
            zeros = np.zeros_like(half_yaw)
            return np.stack([np.cos(half_yaw), zeros, zeros, np.sin(half_yaw)], axis=-1)
        return qpos[..., self.quat_index]

    def objects_of(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Object positions (k, n, 3), quaternions (k, n, 4), velocities (k, n, 6) of qpos (k, nq), qvel (k, nv)."""
        pos = qpos[:, self.pos_index]
        linear = qvel[:, self.linvel_index]
        quat = self.object_quaternions(qpos)
        if self.upright:
            angular = np.zeros_like(linear)
            angular[..., 2] = qvel[:, self.yaw_rate_index]
        else:
            local = qvel[:, self.angvel_index]
            angular = rotate(quat.reshape(-1, 4), local.reshape(-1, 3)).reshape(local.shape)
        return pos, quat, np.concatenate([linear, angular], axis=-1)
