"""MuJoCo backend: the scene as MJCF generated in code, states as ``mjSTATE_INTEGRATION`` vectors.

Contacts use MuJoCo's defaults (Newton solver, pyramidal friction cone, Euler integrator) with
``condim = 3`` (sliding friction only) and every geom's sliding friction set to the scene's
coefficient, so the contact coefficient (MuJoCo takes the larger of the two geoms') equals it.
A scene may choose the ``implicitfast`` integrator and the contact time constant. Servoed joints
get one ``<general>`` position actuator each (force ``kp (target - q) - kv qdot``, clamped to the
joint's force limit), in the order of the end-effector joints; links with gravity compensation get
``gravcomp="1"``, and links that do not collide with the statics get an ``<exclude>`` against the
world body.
"""

from __future__ import annotations

from typing import Any
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np

from energy_margin.sim.base import ModelCommand
from energy_margin.world.scene import Geom, Link, RigidObject, Scene
from energy_margin.world.state import FrameState, yaw_from_quat

_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


# Joints of an upright object, in qpos order: position x, y, z then yaw.
_UPRIGHT_JOINTS = (
    ("_x", "slide", "1 0 0"),
    ("_y", "slide", "0 1 0"),
    ("_z", "slide", "0 0 1"),
    ("_yaw", "hinge", "0 0 1"),
)


def _fmt(values: tuple[float, ...] | list[float] | np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)


# Collision bits: ordinary geoms have contype = conaffinity = _BODIES. With footprints or sphere
# stand-ins a floor plane only emits _FLOOR, which footprints, robot links and objects without a
# footprint accept; a cylinder's sphere emits _BODIES and accepts only _BODIES, never _FLOOR, and
# the cylinder itself then keeps only the floor.
_BODIES = 1
_FLOOR = 2


def _geom_xml(geom: Geom, name: str, extra: str = "") -> str:
    size = list(geom.size)
    if geom.shape == "plane":
        size = [*size, 0.1]
    return (
        f"<geom name={quoteattr(name)} type={quoteattr(geom.shape)} size={quoteattr(_fmt(size))} "
        f'pos="{_fmt(geom.pos)}" quat="{_fmt(geom.quat)}" rgba="{_fmt(geom.rgba)}"{extra}/>'
    )


def _is_floor(geom: Geom) -> bool:
    """A plane whose normal is the world +z axis."""
    if geom.shape != "plane":
        return False
    _, x, y, _ = geom.quat
    # The plane's normal is its local z axis rotated by the quaternion.
    normal_z = 1.0 - 2.0 * (x * x + y * y)
    return normal_z > 1.0 - 1e-9


def _base_radius(geom: Geom) -> float | None:
    """Distance from the centre of an upright shape's flat base to its rim contacts, m."""
    if geom.shape == "cylinder":
        return float(geom.size[0])
    if geom.shape == "box":
        return float(np.hypot(geom.size[0], geom.size[1]))
    return None


def _spin_friction(scene: Scene, obj: RigidObject) -> str:
    """Dry friction of an upright object's yaw joint: the spin resistance of its rim contacts.

    Rim contacts carrying the weight m g at the base radius r resist spinning with a torque up to
    mu m g r; the footprint's single point cannot, so the yaw joint gets it as ``frictionloss``,
    independent of the sliding friction (as the rim's is, to first order).
    """
    rim = _base_radius(obj.geom)
    if rim is None:
        return ""
    weight = obj.mass * float(np.linalg.norm(scene.gravity))
    return f' frictionloss="{scene.friction * weight * rim!r}"'


def _footprint_xml(scene: Scene, name: str, geom: Geom) -> str:
    """The base-centre contact of an upright object with the floor (see ``Scene.ground_contact``)."""
    rim = _base_radius(geom)
    if rim is None:
        return ""
    half_height = float(geom.size[-1])
    # A small sphere touching the base's centre: one contact point at the same height as the base.
    radius = min(0.25 * rim, half_height)
    return (
        f'<geom name={quoteattr(name + "_footprint")} type="sphere" size="{radius!r}" '
        f'pos="0 0 {-half_height + radius!r}" contype="0" conaffinity="{_FLOOR}" '
        f'group="3" rgba="0 0 0 0"/>'
    )


def _object_geoms_xml(scene: Scene, obj: RigidObject, *, split_floor: bool) -> str:
    """An object's own geom, its footprint and its sphere stand-in (see ``Scene``)."""
    footprint = scene.ground_contact == "footprint" and _base_radius(obj.geom) is not None
    base = _footprint_xml(scene, obj.name, obj.geom) if footprint else ""
    floor = 0 if footprint or not split_floor else _FLOOR
    if not (scene.lateral_contact == "sphere" and obj.geom.shape == "cylinder"):
        extra = f' conaffinity="{_BODIES | floor}"' if floor else ""
        return _geom_xml(obj.geom, obj.name, extra) + base
    # In the plane of the centres the sphere is the cylinder's circle: every contact of that plane
    # (another upright cylinder, a vertical face of the robot or a wall) has the cylinder's
    # point, normal and depth. (Against a face the engine reports the cylinder's line contact as
    # two identical rows; the sphere gives one.)
    stand_in = (
        f'<geom name={quoteattr(obj.name + "_sphere")} type="sphere" size="{float(obj.geom.size[0])!r}" '
        f'contype="{_BODIES}" conaffinity="{_BODIES}" group="3" rgba="0 0 0 0"/>'
    )
    own = f' contype="0" conaffinity="{floor}"'
    return _geom_xml(obj.geom, obj.name, own) + stand_in + base


def _link_xml(link: Link, geom_extra: str = "") -> str:
    gravcomp = ' gravcomp="1"' if link.gravity_compensation else ""
    parts = [f'<body name={quoteattr(link.name)} pos="{_fmt(link.pos)}"{gravcomp}>']
    for joint in link.joints:
        attrs = [
            f"name={quoteattr(joint.name)}",
            f'type="{joint.kind}"',
            f'axis="{_fmt(joint.axis)}"',
            f'damping="{joint.damping!r}"',
            f'stiffness="{joint.stiffness!r}"',
        ]
        if joint.limits is not None:
            attrs.append(f'range="{_fmt(joint.limits)}" limited="true"')
        parts.append(f"<joint {' '.join(attrs)}/>")
    first = link.geoms[0]
    inertia = first.principal_inertia(link.mass)
    parts.append(
        f'<inertial pos="{_fmt(first.pos)}" quat="{_fmt(first.quat)}" mass="{link.mass!r}" '
        f'diaginertia="{_fmt(inertia)}"/>'
    )
    for index, geom in enumerate(link.geoms):
        parts.append(_geom_xml(geom, geom.name or f"{link.name}_geom{index}", geom_extra))
    parts.extend(_link_xml(child, geom_extra) for child in link.children)
    parts.append("</body>")
    return "".join(parts)


def _actuators_xml(scene: Scene) -> str:
    """One position servo per servoed end-effector joint (``<general>``, affine bias)."""
    parts = []
    for joint in scene.robot_joints:
        if joint.servo_stiffness is None:
            continue
        kp, kv = joint.servo_stiffness, joint.servo_damping
        attrs = [
            f"name={quoteattr(joint.name + '_servo')}",
            f"joint={quoteattr(joint.name)}",
            'gaintype="fixed"',
            'biastype="affine"',
            f'gainprm="{kp!r}"',
            f'biasprm="0 {-kp!r} {-kv!r}"',
        ]
        if joint.force_limit is not None:
            attrs.append(f'forcelimited="true" forcerange="{-joint.force_limit!r} {joint.force_limit!r}"')
        parts.append(f"<general {' '.join(attrs)}/>")
    return f"<actuator>{''.join(parts)}</actuator>" if parts else ""


def _excludes_xml(scene: Scene) -> str:
    """Contact exclusions between the world (statics) and links that glide along them."""
    parts = [
        f'<exclude body1="world" body2={quoteattr(link.name)}/>'
        for link in scene.robot_links
        if not link.collides_with_statics
    ]
    return f"<contact>{''.join(parts)}</contact>" if parts else ""


def build_mjcf(scene: Scene) -> str:
    """MJCF text of ``scene`` (objects are free bodies named after :attr:`RigidObject.name`)."""
    worldbody = []
    footprint = scene.ground_contact == "footprint"
    # Footprints and lateral stand-ins need the floor on its own collision bit.
    split_floor = footprint or scene.lateral_contact == "sphere"
    for index, geom in enumerate(scene.statics):
        floor = f' contype="{_FLOOR}" conaffinity="0"' if split_floor and _is_floor(geom) else ""
        worldbody.append(_geom_xml(geom, geom.name or f"static{index}", floor))
    if scene.robot is not None:
        # Robot links keep touching the floor through their own shapes.
        worldbody.append(_link_xml(scene.robot, f' conaffinity="{_BODIES | _FLOOR}"' if split_floor else ""))
    for obj in scene.objects:
        if obj.geom.pos != (0.0, 0.0, 0.0) or obj.geom.quat != (1.0, 0.0, 0.0, 0.0):
            raise ValueError(f"object {obj.name!r}: its geom must be centred at the body origin")
        if scene.object_motion == "free":
            joints = f"<freejoint name={quoteattr(obj.name)}/>"
        else:
            joints = "".join(
                f'<joint name={quoteattr(obj.name + suffix)} type="{kind}" axis="{axis}"'
                f"{_spin_friction(scene, obj) if suffix == '_yaw' and footprint else ''}/>"
                for suffix, kind, axis in _UPRIGHT_JOINTS
            )
        worldbody.append(
            f"<body name={quoteattr(obj.name)}>{joints}"
            f'<inertial pos="0 0 0" mass="{obj.mass!r}" diaginertia="{_fmt(obj.inertia)}"/>'
            f"{_object_geoms_xml(scene, obj, split_floor=split_floor)}</body>"
        )
    integrator = f' integrator="{scene.integrator}"' if scene.integrator != "Euler" else ""
    solref = f' solref="{scene.contact_time_constant!r} 1"' if scene.contact_time_constant is not None else ""
    return (
        '<mujoco model="energy_margin"><compiler angle="radian"/>'
        f'<option timestep="{scene.timestep!r}" gravity="{_fmt(scene.gravity)}"{integrator}/>'
        f'<default><geom condim="3" friction="{scene.friction!r} 0 0"{solref}/></default>'
        f"<worldbody>{''.join(worldbody)}</worldbody>{_excludes_xml(scene)}{_actuators_xml(scene)}</mujoco>"
    )


def apply_model_command(data: mujoco.MjData, command: ModelCommand) -> None:
    """Write a model command's actuator controls and mocap poses into ``data``."""
    if command.ctrl is not None:
        data.ctrl[:] = command.ctrl
    if command.mocap_pos is not None:
        data.mocap_pos[:] = command.mocap_pos
    if command.mocap_quat is not None:
        data.mocap_quat[:] = command.mocap_quat


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    return int(mujoco.mj_name2id(model, kind, name))


def _rotate(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """Rotate vectors (n, 3) by quaternions (n, 4) (w, x, y, z)."""
    w = quat[:, :1]
    u = quat[:, 1:]
    t = 2.0 * np.cross(u, vec)
    return vec + w * t + np.cross(u, t)


def _rotate_inverse(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    conj = quat * np.array([1.0, -1.0, -1.0, -1.0])
    return _rotate(conj, vec)


class MujocoSimulator:
    """A :class:`~energy_margin.sim.base.Simulator` on MuJoCo."""

    def __init__(self, scene: Scene) -> None:
        model = mujoco.MjModel.from_xml_string(build_mjcf(scene))
        first_joint = "_x" if scene.object_motion == "upright" else ""
        self._bind(
            scene,
            model,
            object_joints=[_id(model, mujoco.mjtObj.mjOBJ_JOINT, obj.name + first_joint) for obj in scene.objects],
            robot_joints=[_id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in scene.robot_joint_names],
            servoed=[joint.servoed for joint in scene.robot_joints],
            servo_actuators=[
                _id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, joint.name + "_servo")
                for joint in scene.robot_joints
                if joint.servoed
            ],
        )

    def _bind(
        self,
        scene: Scene,
        model: mujoco.MjModel,
        *,
        object_joints: list[int],
        robot_joints: list[int],
        servoed: list[bool],
        servo_actuators: list[int],
    ) -> None:
        """Index the model: the objects' first joints, the robot's joints and servo actuators (ids)."""
        self.scene = scene
        self.model = model
        self.data = mujoco.MjData(self.model)
        self._object_bodies = np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, obj.name) for obj in scene.objects]
        )
        self._upright = scene.object_motion == "upright"
        qpos_adr = model.jnt_qposadr[object_joints]
        qvel_adr = model.jnt_dofadr[object_joints]
        # Index arrays gather every object's coordinates in one fancy-indexing operation.
        self._pos_index = qpos_adr[:, None] + np.arange(3)
        self._linvel_index = qvel_adr[:, None] + np.arange(3)
        if self._upright:
            self._yaw_index = qpos_adr + 3
            self._yaw_rate_index = qvel_adr + 3
        else:
            self._quat_index = qpos_adr[:, None] + 3 + np.arange(4)
            self._angvel_index = qvel_adr[:, None] + 3 + np.arange(3)
        self._robot_qpos = np.array(model.jnt_qposadr[robot_joints], dtype=int)
        self._robot_qvel = np.array(model.jnt_dofadr[robot_joints], dtype=int)
        # Robot coordinates driven by a servo, and the actuator of each (same order).
        self._servoed = np.array(servoed, dtype=bool)
        self._servo_actuators = np.array(servo_actuators, dtype=int)
        self._masses = model.body_mass[self._object_bodies].copy()
        self._inertias = model.body_inertia[self._object_bodies].copy()
        self._gravity = np.asarray(model.opt.gravity, dtype=float).copy()
        self._geom_is_object = np.isin(model.geom_bodyid, self._object_bodies)
        body_object = np.full(model.nbody, -1)
        body_object[self._object_bodies] = np.arange(len(self._object_bodies))
        self._geom_object = body_object[model.geom_bodyid]
        self._state_buffer = np.empty(mujoco.mj_stateSize(model, _STATE_SPEC))
        self._spin_dof = np.zeros(model.nv, dtype=bool)
        if self._upright:
            self._spin_dof[self._yaw_rate_index] = model.dof_frictionloss[self._yaw_rate_index] > 0
        self._has_spin_friction = bool(self._spin_dof.any())
        self._pyramid = np.arange(4)

    @property
    def n_robot_dofs(self) -> int:
        """Length of the end-effector coordinate vectors (``robot_q`` and ``robot_v``)."""
        return int(self._robot_qpos.size)

    def _set_robot_state(self, robot_q: np.ndarray, robot_v: np.ndarray) -> None:
        """Write the end-effector coordinates of a frame into ``data`` (before ``mj_forward``)."""
        self.data.qpos[self._robot_qpos] = robot_q
        self.data.qvel[self._robot_qvel] = robot_v

    @property
    def timestep(self) -> float:
        """Physics time step, seconds."""
        return float(self.model.opt.timestep)

    @property
    def state_size(self) -> int:
        """Length of a state vector."""
        return int(self._state_buffer.shape[0])

    def reset(self, frame: FrameState) -> None:
        """Set poses and velocities from ``frame``; clear wrenches, forces and warm starts.

        Servo targets are set to the frame's joint positions (the servos hold the pose).
        """
        frame.validate(n_objects=self.scene.n_objects, n_robot_dofs=self.n_robot_dofs)
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        quat = np.asarray(frame.object_quat, dtype=float)
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        data.qpos[self._pos_index] = frame.object_pos
        data.qvel[self._linvel_index] = frame.object_vel[:, :3]
        if self._upright:
            # Upright objects keep only the rotation about z and the z angular velocity.
            data.qpos[self._yaw_index] = yaw_from_quat(quat)
            data.qvel[self._yaw_rate_index] = frame.object_vel[:, 5]
        else:
            data.qpos[self._quat_index] = quat
            # Free-joint angular velocity is expressed in the body frame.
            data.qvel[self._angvel_index] = _rotate_inverse(quat, np.asarray(frame.object_vel[:, 3:], float))
        self._set_robot_state(frame.robot_q, frame.robot_v)
        # Servos hold the frame's joint positions until new targets are set.
        self.set_robot_targets(frame.robot_q)
        mujoco.mj_forward(model, data)

    def get_state(self) -> np.ndarray:
        """The ``mjSTATE_INTEGRATION`` vector (time, qpos, qvel, act, warm start, applied forces)."""
        mujoco.mj_getState(self.model, self.data, self._state_buffer, _STATE_SPEC)
        return self._state_buffer.copy()

    def set_state(self, state: np.ndarray) -> None:
        """Restore a vector from :meth:`get_state` (bit-identical replays)."""
        mujoco.mj_setState(self.model, self.data, state, _STATE_SPEC)

    def release_states(self) -> None:
        """Nothing to free: a MuJoCo state is a self-contained vector."""

    def set_object_wrenches(self, wrenches: np.ndarray) -> None:
        """Hold world-frame wrenches (n_objects, 6) [N, N m] at the objects' centres of mass."""
        self.data.xfrc_applied[self._object_bodies] = wrenches

    def set_robot_force(self, force: np.ndarray) -> None:
        """Hold generalized forces (n_robot_dofs,) on the end-effector joints."""
        self.data.qfrc_applied[self._robot_qvel] = force

    def set_model_command(self, command: ModelCommand) -> None:
        """Hold a model command: the model's actuator controls and mocap body poses."""
        apply_model_command(self.data, command)

    def set_robot_targets(self, targets: np.ndarray) -> None:
        """Hold servo targets (n_robot_dofs,) [m or rad]; entries of unservoed joints are ignored."""
        if self._servo_actuators.size:
            self.data.ctrl[self._servo_actuators] = np.asarray(targets, dtype=float)[self._servoed]

    def step(self, n_steps: int, *, track_friction_work: bool = False) -> float:
        """Advance ``n_steps`` steps; optionally return the friction work at object contacts (J)."""
        model, data = self.model, self.data
        if not track_friction_work:
            mujoco.mj_step(model, data, n_steps)
            return 0.0
        work = 0.0
        for _ in range(n_steps):
            qvel_before = data.qvel.copy()
            mujoco.mj_step(model, data)
            work += self._friction_power(0.5 * (qvel_before + data.qvel)) * model.opt.timestep
        return work

    def _friction_power(self, qvel: np.ndarray) -> float:
        """Power of the friction forces of the last step at object contacts, W (<= 0).

        After ``mj_step`` the contacts, constraint Jacobian and forces describe the start of the
        step. A pyramidal condim-3 contact has four rows with directions ``n + s mu_j t_j``; with row
        forces ``f`` and row velocities ``u = J qvel`` the tangential power is
        ``((f0 - f1)(u0 - u1) + (f2 - f3)(u2 - u3)) / 2``, which drops the normal component. With
        footprints (``Scene.ground_contact``) the objects' yaw-joint dry friction is added.
        """
        data = self.data
        power = self._joint_friction_power(qvel) if self._has_spin_friction else 0.0
        if data.ncon == 0:
            return power
        contacts = data.contact
        involved = self._geom_is_object[contacts.geom1] | self._geom_is_object[contacts.geom2]
        selected = involved & (contacts.efc_address >= 0) & (contacts.dim == 3)
        if not np.any(selected):
            return power
        row_velocity = np.empty(data.nefc)
        mujoco.mj_mulJacVec(self.model, data, row_velocity, qvel)
        rows = contacts.efc_address[selected][:, None] + self._pyramid
        force = data.efc_force[rows]
        velocity = row_velocity[rows]
        contact_power = (force[:, 0] - force[:, 1]) * (velocity[:, 0] - velocity[:, 1]) + (
            force[:, 2] - force[:, 3]
        ) * (velocity[:, 2] - velocity[:, 3])
        return power + 0.5 * float(contact_power.sum())

    def _joint_friction_power(self, qvel: np.ndarray) -> float:
        """Power of the dry friction of the objects' yaw joints (``Scene.ground_contact`` footprint), W."""
        data = self.data
        rows = np.flatnonzero(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)
        if rows.size == 0:
            return 0.0
        dofs = data.efc_id[rows]
        own = self._spin_dof[dofs]
        if not np.any(own):
            return 0.0
        # A dof-friction row's Jacobian is the unit vector of its dof: its velocity is qvel[dof].
        return float(np.dot(data.efc_force[rows[own]], qvel[dofs[own]]))

    def object_penetrations(self) -> list[tuple[int, int, float]]:
        """Penetrating contacts that involve an object: ``(object, other or -1, depth in m)``."""
        data = self.data
        if data.ncon == 0:
            return []
        contacts = data.contact
        first = self._geom_object[contacts.geom1]
        second = self._geom_object[contacts.geom2]
        penetrating = (contacts.dist < 0) & ((first >= 0) | (second >= 0))
        result = []
        for a, b, distance in zip(first[penetrating], second[penetrating], contacts.dist[penetrating], strict=True):
            obj, other = (int(a), int(b)) if a >= 0 else (int(b), int(a))
            result.append((obj, other, -float(distance)))
        return result

    def object_positions(self) -> np.ndarray:
        """Centre-of-mass positions (n_objects, 3), metres."""
        return self.data.qpos[self._pos_index]

    def object_quaternions(self) -> np.ndarray:
        """Orientations (n_objects, 4), (w, x, y, z)."""
        if self._upright:
            half_yaw = 0.5 * self.data.qpos[self._yaw_index]
            quat = np.zeros((half_yaw.shape[0], 4))
            quat[:, 0] = np.cos(half_yaw)
            quat[:, 3] = np.sin(half_yaw)
            return quat
        return self.data.qpos[self._quat_index]

    def object_velocities(self) -> np.ndarray:
        """Linear and angular velocities in the world frame (n_objects, 6)."""
        qvel = self.data.qvel
        if self._upright:
            velocity = np.zeros((self._linvel_index.shape[0], 6))
            velocity[:, :3] = qvel[self._linvel_index]
            velocity[:, 5] = qvel[self._yaw_rate_index]
            return velocity
        angular = _rotate(self.object_quaternions(), qvel[self._angvel_index])
        return np.concatenate([qvel[self._linvel_index], angular], axis=1)

    def robot_positions(self) -> np.ndarray:
        """End-effector joint positions (n_robot_dofs,)."""
        return self.data.qpos[self._robot_qpos].copy()

    def robot_velocities(self) -> np.ndarray:
        """End-effector joint velocities (n_robot_dofs,)."""
        return self.data.qvel[self._robot_qvel].copy()

    def mechanical_energy(self) -> float:
        """Kinetic plus potential energy of the objects, joules."""
        data = self.data
        linear = data.qvel[self._linvel_index]
        kinetic = 0.5 * float(np.sum(self._masses * np.sum(linear * linear, axis=1)))
        if self._upright:
            yaw_rate = data.qvel[self._yaw_rate_index]
            kinetic += 0.5 * float(np.sum(self._inertias[:, 2] * yaw_rate * yaw_rate))
        else:
            angular_local = data.qvel[self._angvel_index]
            kinetic += 0.5 * float(np.sum(self._inertias * angular_local * angular_local))
        potential = -float(np.sum(self._masses * (data.qpos[self._pos_index] @ self._gravity)))
        return kinetic + potential

    def objects_of(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Object positions (k, n, 3), quaternions (k, n, 4), velocities (k, n, 6) of qpos (k, nq), qvel (k, nv)."""
        pos = qpos[:, self._pos_index]
        linear = qvel[:, self._linvel_index]
        if self._upright:
            half_yaw = 0.5 * qpos[:, self._yaw_index]
            zeros = np.zeros_like(half_yaw)
            quat = np.stack([np.cos(half_yaw), zeros, zeros, np.sin(half_yaw)], axis=-1)
            angular = np.zeros_like(linear)
            angular[..., 2] = qvel[:, self._yaw_rate_index]
        else:
            quat = qpos[:, self._quat_index]
            local = qvel[:, self._angvel_index]
            angular = _rotate(quat.reshape(-1, 4), local.reshape(-1, 3)).reshape(local.shape)
        return pos, quat, np.concatenate([linear, angular], axis=-1)

    def rollout_propagator(self, threads: int = 1) -> RolloutPropagator:
        """A batched propagator on ``threads`` threads, cached per thread count."""
        cache: dict[int, RolloutPropagator] = self.__dict__.setdefault("_propagators", {})
        if threads not in cache:
            cache[threads] = RolloutPropagator(self, threads)
        return cache[threads]

    def frame_state(self) -> FrameState:
        """Current poses and velocities."""
        return FrameState(
            object_pos=self.object_positions().copy(),
            object_quat=self.object_quaternions().copy(),
            object_vel=self.object_velocities(),
            robot_q=self.robot_positions(),
            robot_v=self.robot_velocities(),
        )


_FULL_PHYSICS = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CONTROL_SPEC = (
    mujoco.mjtState.mjSTATE_CTRL
    | mujoco.mjtState.mjSTATE_QFRC_APPLIED
    | mujoco.mjtState.mjSTATE_XFRC_APPLIED
    | mujoco.mjtState.mjSTATE_MOCAP_POS
    | mujoco.mjtState.mjSTATE_MOCAP_QUAT
)


class RolloutPropagator:
    """Batched propagations of one :class:`MujocoSimulator` through ``mujoco.rollout``.

    States are ``mjSTATE_FULLPHYSICS`` vectors (time, qpos, qvel, act, ...): ``mujoco.rollout``
    starts from and returns these. Every propagation starts with a zero warm start of the
    constraint solver (``mjSTATE_INTEGRATION`` states of the one-at-a-time path carry the previous
    step's), so its result depends on nothing but its own inputs: the same on 1 or 2 threads and
    in any batch. The object wrenches, the end-effector's generalized forces and servo targets go
    in as per-step controls (``mjSTATE_XFRC_APPLIED | QFRC_APPLIED | CTRL``); the scripted command
    is evaluated from the propagation's start state (robot joint positions and velocities) at the
    times the one-at-a-time path evaluates it.

    Args:
        simulator: the simulator whose model is rolled out.
        threads: worker threads (1 runs on the calling thread).

    """

    def __init__(self, simulator: MujocoSimulator, threads: int) -> None:
        from mujoco import rollout

        if threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self.simulator = simulator
        self.threads = threads
        model = simulator.model
        self._rollout = rollout.Rollout(nthread=threads if threads > 1 else 0)
        self._datas = [mujoco.MjData(model) for _ in range(threads)]
        self._scratch = mujoco.MjData(model)
        self.state_size = int(mujoco.mj_stateSize(model, _FULL_PHYSICS))
        self.control_size = int(mujoco.mj_stateSize(model, _CONTROL_SPEC))
        self._nq, self._nv = int(model.nq), int(model.nv)
        self._warmstart = np.zeros((0, self._nv))

    def close(self) -> None:
        """Stop the thread pool."""
        self._rollout.close()

    def current_state(self) -> np.ndarray:
        """The simulator's current state as a ``mjSTATE_FULLPHYSICS`` vector."""
        state = np.empty(self.state_size)
        mujoco.mj_getState(self.simulator.model, self.simulator.data, state, _FULL_PHYSICS)
        return state

    def qpos_qvel(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and velocities of states (..., state_size)."""
        nq, nv = self._nq, self._nv
        return states[..., 1 : 1 + nq], states[..., 1 + nq : 1 + nq + nv]

    def _control(
        self, wrenches: np.ndarray, force: np.ndarray, targets: np.ndarray | None, command: ModelCommand | None
    ) -> np.ndarray:
        sim, scratch = self.simulator, self._scratch
        scratch.xfrc_applied[sim._object_bodies] = wrenches
        scratch.qfrc_applied[sim._robot_qvel] = np.asarray(force)[: sim._robot_qvel.size]
        if targets is not None and sim._servo_actuators.size:
            scratch.ctrl[sim._servo_actuators] = np.asarray(targets, dtype=float)[sim._servoed]
        if command is not None:
            apply_model_command(scratch, command)
        row = np.empty(self.control_size)
        mujoco.mj_getState(sim.model, scratch, row, _CONTROL_SPEC)
        return row

    def roll_commands(
        self,
        state: np.ndarray,
        forces: np.ndarray,
        targets: np.ndarray | None = None,
        ctrl: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Roll ``k`` end-effector command sequences out from one state, without object wrenches.

        Args:
            state: start state, a ``mjSTATE_FULLPHYSICS`` vector (:meth:`current_state`).
            forces: end-effector generalized forces of every step, shape (k, steps, n_robot_dofs),
                N or N m.
            targets: servo targets of every step, shape (k, steps, n_robot_dofs), m or rad;
                ``None`` keeps the targets held in ``state``'s model (none for a task without servos).
            ctrl: every actuator's control of every step, shape (k, steps, nu) (a user's model);
                ``None`` leaves the controls to ``targets``.

        Returns:
            The states after every step, shape (k, steps, state_size), and the end states
            (k, state_size).

        """
        sim = self.simulator
        forces = np.asarray(forces, dtype=float)
        k, steps = forces.shape[:2]
        base = self._control(np.zeros((sim.scene.n_objects, 6)), np.zeros(sim._robot_qvel.size), None, None)
        if targets is None and sim._servo_actuators.size:
            base[: sim.model.nu] = sim.data.ctrl
        controls = np.broadcast_to(base, (k, steps, self.control_size)).copy()
        # mjSTATE_CTRL comes first in the control vector, then mjSTATE_QFRC_APPLIED (nu + nv).
        controls[..., sim.model.nu + sim._robot_qvel] = forces
        if targets is not None and sim._servo_actuators.size:
            controls[..., sim._servo_actuators] = np.asarray(targets, dtype=float)[..., sim._servoed]
        if ctrl is not None:
            controls[..., : sim.model.nu] = ctrl
        initial = np.broadcast_to(state, (k, self.state_size)).copy()
        warmstart = np.zeros((k, self._nv))
        out, _ = self._rollout.rollout(
            sim.model,
            self._datas,
            initial,
            controls,
            control_spec=int(_CONTROL_SPEC),
            nstep=steps,
            initial_warmstart=warmstart,
        )
        return out, out[:, -1]

    def object_states(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Object positions, quaternions, velocities and robot coordinates of states (k, state_size).

        Returns:
            Positions (k, n_objects, 3), quaternions (k, n_objects, 4), velocities (k, n_objects, 6),
            robot joint positions (k, n_robot_dofs) and velocities (k, n_robot_dofs).

        """
        sim = self.simulator
        qpos, qvel = self.qpos_qvel(states)
        pos, quat, vel = sim.objects_of(qpos, qvel)
        return pos, quat, vel, qpos[:, sim._robot_qpos], qvel[:, sim._robot_qvel]

    def propagate(
        self,
        task: Any,
        drive: np.ndarray,
        states: np.ndarray,
        start_times: np.ndarray,
        wrenches: np.ndarray,
        n_steps: np.ndarray,
        control_steps: int | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Propagate every state with its wrenches for its number of steps.

        Args:
            task: the task (its scripted ``robot_force`` and ``robot_targets``, without variation).
            drive: the trajectory's drive parameters.
            states: start states, shape (k, state_size).
            start_times: script time at each start, shape (k,), s.
            wrenches: object wrenches, shape (k, n_objects, 6).
            n_steps: steps of each propagation, shape (k,), >= 1; shorter ones are padded to the
                longest and read at their own last step.
            control_steps: the command is re-evaluated every this many steps (``None``: once).

        Returns:
            Object positions (k, n_objects, 3), velocities (k, n_objects, 6), quaternions
            (k, n_objects, 4) and end states (k, state_size).

        """
        sim = self.simulator
        k = states.shape[0]
        longest = int(n_steps.max())
        dt = sim.timestep
        qpos, qvel = self.qpos_qvel(states)
        controls = np.empty((k, longest, self.control_size))
        for j in range(k):
            robot_q, robot_v = qpos[j, sim._robot_qpos], qvel[j, sim._robot_qvel]
            done, steps = 0, int(n_steps[j])
            row = controls[j, 0]
            while done < steps:
                chunk = steps - done if control_steps is None else min(control_steps, steps - done)
                time = float(start_times[j]) + done * dt
                force = task.robot_force(drive, time, robot_q, robot_v, None)
                targets = task.robot_targets(drive, time, robot_q, robot_v, None)
                row = self._control(wrenches[j], force, targets, task.model_command(drive, time))
                controls[j, done : done + chunk] = row
                done += chunk
            controls[j, steps:] = row
        if self._warmstart.shape[0] != k:
            self._warmstart = np.zeros((k, self._nv))
        out, _ = self._rollout.rollout(
            sim.model,
            self._datas,
            states,
            controls,
            control_spec=int(_CONTROL_SPEC),
            nstep=longest,
            initial_warmstart=self._warmstart,
        )
        final = out[np.arange(k), n_steps - 1]
        pos, quat, vel = sim.objects_of(*self.qpos_qvel(final))
        return pos, vel, quat, final
