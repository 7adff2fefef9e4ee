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

__all__ = [
    "ModelIndex",
    "apply_model_command",
    "name_id",
    "object_geoms",
    "object_inertials",
    "object_owners",
    "rotate",
    "rotate_inverse",
    "upright_axes",
    "world_aligned",
    "zero_joint_position",
]


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
        axis_mask: for upright objects with only some of the four joints (e.g. a puck on slide x
            and slide y, as in Gymnasium's Pusher), which of x, y, z, yaw each object has, shape
            (n_objects, 4); ``None`` when every object has all four (or is free). The addresses
            of a missing axis point at coordinate 0 and are masked out.
        pos_offset: world position of each partially jointed object's body at zero joint
            positions, shape (n_objects, 3), m; ``None`` with ``axis_mask``.

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
    axis_mask: np.ndarray | None = None
    pos_offset: np.ndarray | None = None

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
        robot = {
            "robot_qpos": np.array(model.jnt_qposadr[list(robot_joints)], dtype=int),
            "robot_qvel": np.array(model.jnt_dofadr[list(robot_joints)], dtype=int),
            "servoed": np.array([False] * len(robot_joints) if servoed is None else servoed, dtype=bool),
            "servo_actuators": np.array(servo_actuators, dtype=int),
        }
        if upright:
            axes = [_upright_axes(model, int(body)) for body in bodies]
            if not all(np.all(mask) and np.all(offset == 0) for _, _, mask, offset in axes):
                return cls(
                    object_bodies=bodies,
                    upright=True,
                    pos_index=np.array([qpos[:3] for qpos, _, _, _ in axes], dtype=int).reshape(-1, 3),
                    linvel_index=np.array([qvel[:3] for _, qvel, _, _ in axes], dtype=int).reshape(-1, 3),
                    yaw_index=np.array([qpos[3] for qpos, _, _, _ in axes], dtype=int),
                    yaw_rate_index=np.array([qvel[3] for _, qvel, _, _ in axes], dtype=int),
                    quat_index=none.reshape(0, 4),
                    angvel_index=none.reshape(0, 3),
                    axis_mask=np.array([mask for _, _, mask, _ in axes], dtype=bool).reshape(-1, 4),
                    pos_offset=np.array([offset for _, _, _, offset in axes], dtype=float).reshape(-1, 3),
                    **robot,
                )
        return cls(
            object_bodies=bodies,
            upright=upright,
            pos_index=qpos_adr[:, None] + np.arange(3),
            linvel_index=qvel_adr[:, None] + np.arange(3),
            yaw_index=qpos_adr + 3 if upright else none,
            yaw_rate_index=qvel_adr + 3 if upright else none,
            quat_index=none.reshape(0, 4) if upright else qpos_adr[:, None] + 3 + np.arange(4),
            angvel_index=none.reshape(0, 3) if upright else qvel_adr[:, None] + 3 + np.arange(3),
            **robot,
        )

    def object_positions(self, qpos: np.ndarray) -> np.ndarray:
        """World positions (..., n_objects, 3), m, of joint positions (..., nq)."""
        if self.axis_mask is None or self.pos_offset is None:
            return qpos[..., self.pos_index]
        return np.where(self.axis_mask[:, :3], qpos[..., self.pos_index], 0.0) + self.pos_offset

    def linear_velocities(self, qvel: np.ndarray) -> np.ndarray:
        """World linear velocities (..., n_objects, 3), m/s, of joint velocities (..., nv)."""
        if self.axis_mask is None:
            return qvel[..., self.linvel_index]
        return np.where(self.axis_mask[:, :3], qvel[..., self.linvel_index], 0.0)

    def yaw_rates(self, qvel: np.ndarray) -> np.ndarray:
        """Upright objects' yaw rates (..., n_objects), rad/s, of joint velocities (..., nv)."""
        if self.axis_mask is None:
            return qvel[..., self.yaw_rate_index]
        return np.where(self.axis_mask[:, 3], qvel[..., self.yaw_rate_index], 0.0)

    def write_objects(
        self,
        qpos: np.ndarray,
        qvel: np.ndarray,
        pos: np.ndarray,
        linear: np.ndarray,
        yaw: np.ndarray,
        yaw_rate: np.ndarray,
    ) -> None:
        """Write upright objects' positions (n, 3), linear velocities (n, 3), yaws and yaw rates (n,).

        A partially jointed object keeps only the coordinates it has (its others are fixed).
        """
        if self.axis_mask is None or self.pos_offset is None:
            qpos[self.pos_index] = pos
            qvel[self.linvel_index] = linear
            qpos[self.yaw_index] = yaw
            qvel[self.yaw_rate_index] = yaw_rate
            return
        mask = self.axis_mask
        qpos[self.pos_index[mask[:, :3]]] = (np.asarray(pos) - self.pos_offset)[mask[:, :3]]
        qvel[self.linvel_index[mask[:, :3]]] = np.asarray(linear)[mask[:, :3]]
        qpos[self.yaw_index[mask[:, 3]]] = np.asarray(yaw)[mask[:, 3]]
        qvel[self.yaw_rate_index[mask[:, 3]]] = np.asarray(yaw_rate)[mask[:, 3]]

    def object_quaternions(self, qpos: np.ndarray) -> np.ndarray:
        """Orientations (..., n_objects, 4), (w, x, y, z), of joint positions (..., nq)."""
        if self.upright:
            yaw = qpos[..., self.yaw_index]
            if self.axis_mask is not None:
                yaw = np.where(self.axis_mask[:, 3], yaw, 0.0)
            half_yaw = 0.5 * yaw
            quat = np.zeros((*half_yaw.shape, 4))
            quat[..., 0] = np.cos(half_yaw)
            quat[..., 3] = np.sin(half_yaw)
            return quat
        return qpos[..., self.quat_index]

    def objects_of(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Object positions (k, n, 3), quaternions (k, n, 4), velocities (k, n, 6) of qpos (k, nq), qvel (k, nv)."""
        pos = self.object_positions(qpos)
        linear = self.linear_velocities(qvel)
        quat = self.object_quaternions(qpos)
        if self.upright:
            angular = np.zeros_like(linear)
            angular[..., 2] = self.yaw_rates(qvel)
        else:
            local = qvel[:, self.angvel_index]
            angular = rotate(quat.reshape(-1, 4), local.reshape(-1, 3)).reshape(local.shape)
        return pos, quat, np.concatenate([linear, angular], axis=-1)


def object_owners(model: mujoco.MjModel, bodies: Sequence[int] | np.ndarray) -> np.ndarray:
    """The object each body moves with as one rigid piece, shape (nbody,) (-1: none).

    An object is the subtree of its body (the one carrying its joint): the body itself and every
    descendant welded to it (reached without crossing a joint), as robosuite's and Meta-World's
    objects hold their geoms on child bodies. MuJoCo numbers a parent before its children.
    """
    owner = np.full(int(model.nbody), -1, dtype=int)
    owner[np.asarray(bodies, dtype=int)] = np.arange(len(bodies))
    parents, joints = model.body_parentid, model.body_jntnum
    for body in range(1, int(model.nbody)):
        if owner[body] < 0 and int(joints[body]) == 0 and owner[int(parents[body])] >= 0:
            owner[body] = owner[int(parents[body])]
    return owner


def object_geoms(model: mujoco.MjModel, bodies: Sequence[int] | np.ndarray) -> list[np.ndarray]:
    """The geom ids of each object's rigid subtree (:func:`object_owners`), one array per object."""
    owner = object_owners(model, bodies)[model.geom_bodyid]
    return [np.flatnonzero(owner == index) for index in range(len(bodies))]


def object_inertials(model: mujoco.MjModel, bodies: Sequence[int] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mass (n,), kg, and diagonal inertia (n, 3), kg m^2, of each object's rigid subtree.

    An object of one body keeps that body's ``body_mass`` and ``body_inertia`` (principal
    moments). An object whose welded descendants carry mass gets their sum and the composite
    inertia about the subtree's centre of mass, expressed in the object body's frame (its
    diagonal: the energy uses the body-frame angular velocity).
    """
    bodies = np.asarray(bodies, dtype=int)
    owner = object_owners(model, bodies)
    mass = np.array(model.body_mass[bodies], dtype=float)
    inertia = np.array(model.body_inertia[bodies], dtype=float)
    composite = [index for index in range(bodies.size) if np.count_nonzero(owner == index) > 1]
    if not composite:
        return mass, inertia
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    for index in composite:
        members = np.flatnonzero(owner == index)
        masses = model.body_mass[members]
        total = float(np.sum(masses))
        if total <= 0.0:
            continue
        centre = masses @ data.xipos[members] / total
        world = np.zeros((3, 3))
        for member, member_mass in zip(members, masses, strict=True):
            rotation = data.ximat[member].reshape(3, 3)
            offset = data.xipos[member] - centre
            world += rotation @ np.diag(model.body_inertia[member]) @ rotation.T
            world += member_mass * (float(offset @ offset) * np.eye(3) - np.outer(offset, offset))
        frame = data.xmat[bodies[index]].reshape(3, 3)
        mass[index] = total
        inertia[index] = np.diag(frame.T @ world @ frame)
    return mass, inertia


#: The joints of an upright object in qpos order: slide x, slide y, slide z, hinge z.
_UPRIGHT_AXES = (
    (mujoco.mjtJoint.mjJNT_SLIDE, (1.0, 0.0, 0.0)),
    (mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 1.0, 0.0)),
    (mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 0.0, 1.0)),
    (mujoco.mjtJoint.mjJNT_HINGE, (0.0, 0.0, 1.0)),
)


def upright_axes(model: mujoco.MjModel, body: int) -> list[int] | None:
    """Which of slide x, slide y, slide z, hinge z (0..3) each of ``body``'s joints is, or ``None``.

    ``None`` when a joint is of another kind or axis, or two joints move along the same axis. The
    joints may come in any order (Gymnasium's Pusher declares slide y before slide x).
    """
    first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
    axes: list[int] = []
    for joint in range(first, first + count):
        kind, axis = int(model.jnt_type[joint]), model.jnt_axis[joint]
        matches = [
            position
            for position, (expected_kind, expected_axis) in enumerate(_UPRIGHT_AXES)
            if kind == int(expected_kind) and np.allclose(axis, expected_axis)
        ]
        if not matches or matches[0] in axes:
            return None
        axes.append(matches[0])
    return axes


def _upright_axes(model: mujoco.MjModel, body: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Qpos and qvel addresses (4,), axis mask (4,) and zero-joint world position (3,) of an upright body."""
    axes = upright_axes(model, body) or []
    qpos = np.zeros(4, dtype=int)
    qvel = np.zeros(4, dtype=int)
    mask = np.zeros(4, dtype=bool)
    first = int(model.body_jntadr[body])
    for offset, axis in enumerate(axes):
        qpos[axis] = model.jnt_qposadr[first + offset]
        qvel[axis] = model.jnt_dofadr[first + offset]
        mask[axis] = True
    return qpos, qvel, mask, zero_joint_position(model, body)


def zero_joint_position(model: mujoco.MjModel, body: int) -> np.ndarray:
    """World position (3,), m, of ``body`` at zero joint positions, its ancestors welded to the world.

    A child of the world is at its ``body_pos``; a body under jointless holders is placed by them.
    """
    parent = int(model.body_parentid[body])
    if parent == 0:
        return np.array(model.body_pos[body], dtype=float)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    result: np.ndarray = data.xpos[parent] + data.xmat[parent].reshape(3, 3) @ model.body_pos[body]
    return result


def world_aligned(model: mujoco.MjModel, body: int) -> bool:
    """Whether ``body``'s frame is parallel to the world's (its own and its ancestors' quaternions 1 0 0 0)."""
    while body:
        if np.any(model.body_quat[body] != [1, 0, 0, 0]):
            return False
        body = int(model.body_parentid[body])
    return True
