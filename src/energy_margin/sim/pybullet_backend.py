"""PyBullet backend (the authors' engine): the scene built with ``createMultiBody``, nodes as saved states.

Design (see docs/engines.md for the reasoning and the measured differences to MuJoCo):

* One ``DIRECT`` client per simulator; every call passes its ``physicsClientId``. Time step
  ``scene.timestep``, Bullet's default 50 solver iterations, gravity ``scene.gravity`` and
  ``deterministicOverlappingPairs = 1`` (with it, ``restoreState`` replays are bit-identical).
* Statics are fixed single-base bodies. Free objects are single-base bodies. An upright object is a
  fixed-base chain of four links (prismatic x, y, z then revolute z), the last one carrying the
  shape, mass and inertia, so its coordinates are exactly the MuJoCo joints ``x, y, z, yaw``. The
  robot is one fixed-base multibody: every :class:`~energy_margin.world.scene.Joint` becomes one link
  (massless helper links where a scene link has several joints; the last carries the geoms).
  Inertias are set to the scene's (uniform solid of the first geom) with ``localInertiaDiagonal``.
* Friction: Bullet multiplies the two bodies' coefficients, so every body gets ``sqrt(mu)``
  (lateral; spinning and rolling friction 0) and every contact has the scene's ``mu``. Linear and
  angular damping are 0; Bullet's default joint velocity motors are disabled.
* External forces are cleared by ``stepSimulation``: object wrenches, end-effector forces, servo
  torques and gravity compensation are re-applied before every step. Upright objects take their
  wrench as generalized joint forces (exact: the joint axes are the world axes); free objects via
  ``applyExternalForce`` at the centre of mass and ``applyExternalTorque``, world frame.
* Servos: a joint with a servo stiffness uses Bullet's implicit ``POSITION_CONTROL`` motor, whose
  gains are the scene's stiffness and damping scaled by the joint's effective mass (see
  :func:`_motor_gains`); a passive spring and joint damping of that joint are folded into it.
  Other joints get their generalized force plus passive spring and damping as ``TORQUE_CONTROL``
  (a generalized force on a servoed joint is not applied: Bullet drives a joint in one mode).
* States: :meth:`PybulletSimulator.get_state` calls ``saveState`` and returns
  ``[state id, time, servo targets, end-effector forces, object wrenches]`` (the parts MuJoCo's
  integration state also holds); :meth:`~PybulletSimulator.set_state` restores them. Saved states
  take 100-300 KB each inside Bullet: :meth:`~PybulletSimulator.release_states` removes every
  state saved since the last release (the EST calls it when a tree is done).
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import os
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidDataError
from energy_margin.world.scene import Geom, Joint, Link, Scene
from energy_margin.world.state import FrameState, yaw_from_quat


def _import_pybullet() -> Any:
    """Import pybullet with its build-time banner (printed by the C library) silenced."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = (os.dup(1), os.dup(2))
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        import pybullet

        ctypes.CDLL(None).fflush(None)
        return pybullet
    except ImportError:  # pragma: no cover - exercised only without the optional extra
        return None
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


_pb = _import_pybullet()

_IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)
_PLANAR = (
    ("slide", (1.0, 0.0, 0.0)),
    ("slide", (0.0, 1.0, 0.0)),
    ("slide", (0.0, 0.0, 1.0)),
    ("hinge", (0.0, 0.0, 1.0)),
)
_HIDDEN_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def _is_planar(joints: tuple[Joint, ...]) -> bool:
    """Whether a link moves as an upright planar body: slides x, y, z then a hinge about z."""
    return len(joints) == 4 and all(
        joint.kind == kind and tuple(float(a) for a in joint.axis) == axis
        for joint, (kind, axis) in zip(joints, _PLANAR, strict=True)
    )


def _require_pybullet() -> Any:
    if _pb is None:
        raise EnergyMarginError("the pybullet engine needs the optional extra: pip install 'energy-margin[pybullet]'")
    return _pb


def _xyzw(quat_wxyz: tuple[float, ...] | np.ndarray) -> list[float]:
    w, x, y, z = (float(v) for v in quat_wxyz)
    return [x, y, z, w]


@dataclass
class _LinkSpec:
    """One Bullet link of a multibody under construction."""

    parent: int  # Bullet parent index: 0 = base, i = link i - 1
    pos: tuple[float, float, float]
    joint_type: int
    axis: tuple[float, float, float]
    mass: float = 0.0
    shape: int = -1
    inertial_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertial_quat: list[float] = field(default_factory=lambda: list(_IDENTITY_XYZW))
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint: Joint | None = None
    link: Link | None = None


@dataclass
class _Servo:
    index: int  # position in the robot coordinates
    joint: int  # Bullet joint index
    stiffness: float
    damping: float
    spring: float
    force_limit: float
    position_gain: float
    velocity_gain: float


def _motor_gains(stiffness: float, damping: float, effective_mass: float, dt: float) -> tuple[float, float]:
    """Bullet motor gains of a servo ``f = kp (target - q) - kv qdot`` on a joint of inertia ``M``.

    Bullet's motor asks for the end-of-step velocity ``qdot + kpb (target - q) / dt - kvb qdot``;
    an implicit PD step on inertia ``M`` gives ``kpb = kp dt^2 / M`` and ``kvb = kv dt / M``
    (to first order), each capped at 1 (a dead-beat servo).
    """
    mass = max(effective_mass, 1e-12)
    return min(1.0, stiffness * dt * dt / mass), min(1.0, damping * dt / mass)


class PybulletSimulator:
    """A :class:`~energy_margin.sim.base.Simulator` on PyBullet (``DIRECT`` mode, one client each)."""

    def __init__(self, scene: Scene) -> None:
        pb = _require_pybullet()
        self._pb = pb
        self.scene = scene
        self._client = pb.connect(pb.DIRECT)
        if self._client < 0:
            raise EnergyMarginError("cannot start a PyBullet client")
        cid = self._client
        pb.resetSimulation(physicsClientId=cid)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=scene.timestep,
            numSolverIterations=50,
            numSubSteps=0,
            deterministicOverlappingPairs=1,
            physicsClientId=cid,
        )
        pb.setGravity(*scene.gravity, physicsClientId=cid)
        self._friction = math.sqrt(scene.friction)
        self._gravity = np.asarray(scene.gravity, dtype=float)
        self._upright = scene.object_motion == "upright"
        n = scene.n_objects
        self._masses = scene.object_masses
        self._inertias = scene.object_inertias
        self._statics = [self._static_body(geom) for geom in scene.statics]
        self._object_ids: list[int] = []
        for obj in scene.objects:
            if obj.geom.pos != (0.0, 0.0, 0.0) or obj.geom.quat != (1.0, 0.0, 0.0, 0.0):
                raise InvalidDataError(f"object {obj.name!r}: its geom must be centred at the body origin")
            shape = self._shape((obj.geom,))
            body = pb.createMultiBody(
                baseMass=obj.mass, baseCollisionShapeIndex=shape, basePosition=[0.0, 0.0, 0.0], physicsClientId=cid
            )
            pb.changeDynamics(body, -1, localInertiaDiagonal=list(obj.inertia), physicsClientId=cid)
            self._object_ids.append(body)
        # The end-effector.
        self._robot = -1
        self._robot_joints: list[int] = []
        self._specs: list[_LinkSpec] = []
        if scene.robot is not None:
            self._robot, self._specs = self._chain_body(scene.robot)
            self._robot_joints = [i for i, spec in enumerate(self._specs) if spec.joint is not None]
        self._n_robot = len(self._robot_joints)
        self._configure_robot()
        # Friction and damping of every body.
        for body in [*self._statics, *self._object_ids, *([self._robot] if self._robot >= 0 else [])]:
            for link in range(-1, pb.getNumJoints(body, physicsClientId=cid)):
                pb.changeDynamics(
                    body,
                    link,
                    lateralFriction=self._friction,
                    spinningFriction=0.0,
                    rollingFriction=0.0,
                    restitution=0.0,
                    linearDamping=0.0,
                    angularDamping=0.0,
                    jointDamping=0.0,
                    physicsClientId=cid,
                )
            joints = pb.getNumJoints(body, physicsClientId=cid)
            if joints:
                # Bullet motorizes every joint by default; a zero force disables those motors.
                pb.setJointMotorControlArray(
                    body, list(range(joints)), pb.VELOCITY_CONTROL, forces=[0.0] * joints, physicsClientId=cid
                )
        self._collision_filters()
        self._wrenches = np.zeros((n, 6))
        self._robot_force = np.zeros(self._n_robot)
        self._targets = np.zeros(self._n_robot)
        self._time = 0.0
        self._saved: list[int] = []
        self._clean = pb.saveState(physicsClientId=cid)
        self._state_size = 2 + 2 * self._n_robot + 6 * n

    # ------------------------------------------------------------------ construction

    def _shape(self, geoms: tuple[Geom, ...]) -> int:
        pb, cid = self._pb, self._client
        kinds, radii, halves, lengths, normals, positions, orientations = [], [], [], [], [], [], []
        for geom in geoms:
            kind, radius, half, length, normal = pb.GEOM_BOX, 0.5, [0.5, 0.5, 0.5], 1.0, [0.0, 0.0, 1.0]
            if geom.shape == "box":
                half = list(geom.size)
            elif geom.shape == "cylinder":
                kind, radius, length = pb.GEOM_CYLINDER, geom.size[0], 2.0 * geom.size[1]
            elif geom.shape == "sphere":
                kind, radius = pb.GEOM_SPHERE, geom.size[0]
            else:
                kind = pb.GEOM_PLANE
            kinds.append(kind)
            radii.append(radius)
            halves.append(half)
            lengths.append(length)
            normals.append(normal)
            positions.append(list(geom.pos))
            orientations.append(_xyzw(geom.quat))
        if len(geoms) == 1:
            if kinds[0] == pb.GEOM_PLANE:
                return int(
                    pb.createCollisionShape(
                        kinds[0],
                        planeNormal=normals[0],
                        collisionFramePosition=positions[0],
                        collisionFrameOrientation=orientations[0],
                        physicsClientId=cid,
                    )
                )
            return int(
                pb.createCollisionShape(
                    kinds[0],
                    radius=radii[0],
                    halfExtents=halves[0],
                    height=lengths[0],
                    collisionFramePosition=positions[0],
                    collisionFrameOrientation=orientations[0],
                    physicsClientId=cid,
                )
            )
        return int(
            pb.createCollisionShapeArray(
                shapeTypes=kinds,
                radii=radii,
                halfExtents=halves,
                lengths=lengths,
                planeNormals=normals,
                collisionFramePositions=positions,
                collisionFrameOrientations=orientations,
                physicsClientId=cid,
            )
        )

    def _static_body(self, geom: Geom) -> int:
        pb = self._pb
        shape = self._shape((Geom(geom.shape, geom.size),))
        return int(
            pb.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=shape,
                basePosition=list(geom.pos),
                baseOrientation=_xyzw(geom.quat),
                physicsClientId=self._client,
            )
        )

    def _link_specs(self, link: Link, parent: int, specs: list[_LinkSpec]) -> None:
        """Append the Bullet links of ``link`` and its children (depth first, like the scene)."""
        pb = self._pb
        joints: tuple[Joint | None, ...] = link.joints or (None,)
        if _is_planar(link.joints):
            # Roll and pitch stay free (hidden) so the body can rock on its contacts, see the module docstring.
            joints = (*link.joints[:3], None, None, link.joints[3])
        for number, joint in enumerate(joints):
            last = number == len(joints) - 1
            joint_type = pb.JOINT_FIXED
            axis = (0.0, 0.0, 1.0)
            if joint is not None:
                joint_type = pb.JOINT_PRISMATIC if joint.kind == "slide" else pb.JOINT_REVOLUTE
                axis = joint.axis
            elif len(joints) > 1:
                joint_type = pb.JOINT_REVOLUTE
                axis = _HIDDEN_AXES[number - 3]
            spec = _LinkSpec(
                parent=parent,
                pos=link.pos if number == 0 else (0.0, 0.0, 0.0),
                joint_type=joint_type,
                axis=axis,
                joint=joint,
            )
            if last:
                first = link.inertia_geom
                spec.mass = link.mass
                spec.shape = self._shape(link.geoms)
                spec.inertial_pos = first.pos
                spec.inertial_quat = _xyzw(first.quat)
                spec.inertia = first.principal_inertia(link.mass)
                spec.link = link
            specs.append(spec)
            parent = len(specs)  # this link, in Bullet's 1-based parent numbering
        for child in link.children:
            self._link_specs(child, parent, specs)

    def _chain_body(self, root: Link) -> tuple[int, list[_LinkSpec]]:
        pb, cid = self._pb, self._client
        specs: list[_LinkSpec] = []
        self._link_specs(root, 0, specs)
        body = pb.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=-1,
            basePosition=[0.0, 0.0, 0.0],
            linkMasses=[s.mass for s in specs],
            linkCollisionShapeIndices=[s.shape for s in specs],
            linkVisualShapeIndices=[-1] * len(specs),
            linkPositions=[list(s.pos) for s in specs],
            linkOrientations=[list(_IDENTITY_XYZW)] * len(specs),
            linkInertialFramePositions=[list(s.inertial_pos) for s in specs],
            linkInertialFrameOrientations=[s.inertial_quat for s in specs],
            linkParentIndices=[s.parent for s in specs],
            linkJointTypes=[s.joint_type for s in specs],
            linkJointAxis=[list(s.axis) for s in specs],
            physicsClientId=cid,
        )
        for index, spec in enumerate(specs):
            if spec.mass > 0:
                pb.changeDynamics(body, index, localInertiaDiagonal=list(spec.inertia), physicsClientId=cid)
            if spec.joint is not None and spec.joint.limits is not None:
                low, high = spec.joint.limits
                pb.changeDynamics(body, index, jointLowerLimit=low, jointUpperLimit=high, physicsClientId=cid)
        return int(body), specs

    def _subtree_mass(self, index: int) -> float:
        mass = self._specs[index].mass
        for child, spec in enumerate(self._specs):
            if spec.parent == index + 1:
                mass += self._subtree_mass(child)
        return mass

    def _effective_inertia(self, index: int) -> float:
        """Rough joint-space inertia of a robot joint: subtree mass (slide) or the carried link's inertia about it."""
        spec = self._specs[index]
        assert spec.joint is not None
        if spec.joint.kind == "slide":
            return self._subtree_mass(index)
        total = 0.0
        for other, candidate in enumerate(self._specs):
            if other == index or self._descends(other, index):
                offset = np.asarray(candidate.inertial_pos)
                total += float(max(candidate.inertia, default=0.0)) + candidate.mass * float(offset @ offset)
        return total

    def _descends(self, index: int, ancestor: int) -> bool:
        parent = self._specs[index].parent
        while parent > 0:
            if parent - 1 == ancestor:
                return True
            parent = self._specs[parent - 1].parent
        return False

    def _configure_robot(self) -> None:
        dt = self.scene.timestep
        self._servos: list[_Servo] = []
        self._free_joints: list[int] = []  # robot coordinates driven by generalized forces
        self._stiffness = np.zeros(self._n_robot)
        self._damping = np.zeros(self._n_robot)
        for coordinate, joint_index in enumerate(self._robot_joints):
            joint = self._specs[joint_index].joint
            assert joint is not None
            self._stiffness[coordinate] = joint.stiffness
            self._damping[coordinate] = joint.damping
            if joint.servo_stiffness is None:
                self._free_joints.append(coordinate)
                continue
            kp = joint.servo_stiffness + joint.stiffness
            kv = joint.servo_damping + joint.damping
            position_gain, velocity_gain = _motor_gains(kp, kv, self._effective_inertia(joint_index), dt)
            self._servos.append(
                _Servo(
                    coordinate,
                    joint_index,
                    joint.servo_stiffness,
                    kv,
                    joint.stiffness,
                    joint.force_limit if joint.force_limit is not None else 1e6,
                    position_gain,
                    velocity_gain,
                )
            )
        self._free_bullet = [self._robot_joints[c] for c in self._free_joints]
        self._compensated = [
            (index, spec.mass)
            for index, spec in enumerate(self._specs)
            if spec.link is not None and spec.link.gravity_compensation
        ]

    def _collision_filters(self) -> None:
        pb, cid = self._pb, self._client
        for index, spec in enumerate(self._specs):
            if spec.link is not None and not spec.link.collides_with_statics:
                for static in self._statics:
                    pb.setCollisionFilterPair(self._robot, static, index, -1, 0, physicsClientId=cid)

    # ------------------------------------------------------------------ protocol

    @property
    def timestep(self) -> float:
        """Physics time step, seconds."""
        return float(self.scene.timestep)

    @property
    def state_size(self) -> int:
        """Length of a state vector."""
        return self._state_size

    @property
    def saved_states(self) -> int:
        """Number of states saved by :meth:`get_state` and not yet released."""
        return len(self._saved)

    def close(self) -> None:
        """Disconnect the client (also done when the simulator is garbage collected)."""
        # __init__ may have failed before connecting (e.g. pybullet not installed): nothing to close.
        client, pb = getattr(self, "_client", -1), getattr(self, "_pb", None)
        if client >= 0 and pb is not None:
            with contextlib.suppress(Exception):
                pb.disconnect(physicsClientId=client)
            self._client = -1

    def __del__(self) -> None:
        self.close()

    def reset(self, frame: FrameState) -> None:
        """Set poses and velocities from ``frame``; clear wrenches, forces and contact caches."""
        frame.validate(n_objects=self.scene.n_objects, n_robot_dofs=self.scene.n_robot_dofs)
        pb, cid = self._pb, self._client
        pb.restoreState(self._clean, physicsClientId=cid)
        quat = np.asarray(frame.object_quat, dtype=float)
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        pos = np.asarray(frame.object_pos, dtype=float)
        vel = np.asarray(frame.object_vel, dtype=float)
        angular = vel[:, 3:].copy()
        if self._upright:
            # Upright objects start level, turned about z only.
            half_yaw = 0.5 * yaw_from_quat(quat)
            zeros = np.zeros_like(half_yaw)
            quat = np.column_stack([np.cos(half_yaw), zeros, zeros, np.sin(half_yaw)])
            angular[:, :2] = 0.0
        for i, body in enumerate(self._object_ids):
            pb.resetBasePositionAndOrientation(body, pos[i].tolist(), _xyzw(quat[i]), physicsClientId=cid)
            pb.resetBaseVelocity(body, vel[i, :3].tolist(), angular[i].tolist(), physicsClientId=cid)
        for coordinate, joint in enumerate(self._robot_joints):
            pb.resetJointState(
                self._robot,
                joint,
                float(frame.robot_q[coordinate]),
                float(frame.robot_v[coordinate]),
                physicsClientId=cid,
            )
        self._wrenches = np.zeros_like(self._wrenches)
        self._robot_force = np.zeros(self._n_robot)
        self._targets = np.asarray(frame.robot_q, dtype=float).copy()
        self._time = 0.0

    def get_state(self) -> np.ndarray:
        """Save the world (``saveState``) and return ``[id, time, targets, forces, wrenches]``."""
        state_id = self._pb.saveState(physicsClientId=self._client)
        self._saved.append(int(state_id))
        return np.concatenate([[float(state_id), self._time], self._targets, self._robot_force, self._wrenches.ravel()])

    def set_state(self, state: np.ndarray) -> None:
        """Restore a state from :meth:`get_state` (bit-identical replays)."""
        state = np.asarray(state, dtype=float)
        self._pb.restoreState(int(state[0]), physicsClientId=self._client)
        r = self._n_robot
        self._time = float(state[1])
        self._targets = state[2 : 2 + r].copy()
        self._robot_force = state[2 + r : 2 + 2 * r].copy()
        self._wrenches = state[2 + 2 * r :].reshape(self._wrenches.shape).copy()

    def release_states(self) -> None:
        """Remove every state saved by :meth:`get_state` since the last release (frees Bullet memory)."""
        for state_id in self._saved:
            self._pb.removeState(state_id, physicsClientId=self._client)
        self._saved.clear()

    def set_object_wrenches(self, wrenches: np.ndarray) -> None:
        """Hold world-frame wrenches (n_objects, 6) [N, N m] at the objects' centres of mass."""
        self._wrenches = np.array(wrenches, dtype=float).reshape(self._wrenches.shape)

    def set_robot_force(self, force: np.ndarray) -> None:
        """Hold generalized forces (n_robot_dofs,) on the end-effector joints."""
        self._robot_force = np.array(force, dtype=float).reshape(self._n_robot)

    def set_robot_targets(self, targets: np.ndarray) -> None:
        """Hold servo targets (n_robot_dofs,); entries of unservoed joints are ignored."""
        self._targets = np.array(targets, dtype=float).reshape(self._n_robot)

    def _apply_controls(self) -> None:
        pb, cid = self._pb, self._client
        wrenches = self._wrenches
        for i, body in enumerate(self._object_ids):
            if not wrenches[i].any():
                continue
            com = pb.getBasePositionAndOrientation(body, physicsClientId=cid)[0]
            pb.applyExternalForce(body, -1, wrenches[i, :3].tolist(), com, pb.WORLD_FRAME, physicsClientId=cid)
            torque = wrenches[i, 3:].copy()
            if self._upright:
                torque[:2] = 0.0  # an upright object turns about z only
            pb.applyExternalTorque(body, -1, torque.tolist(), pb.WORLD_FRAME, physicsClientId=cid)
        if self._robot < 0:
            return
        if self._free_joints or self._servos:
            states = pb.getJointStates(self._robot, self._robot_joints, physicsClientId=cid)
            q = np.array([s[0] for s in states])
            qd = np.array([s[1] for s in states])
        if self._free_joints:
            idx = self._free_joints
            torque = self._robot_force[idx] - self._stiffness[idx] * q[idx] - self._damping[idx] * qd[idx]
            pb.setJointMotorControlArray(
                self._robot, self._free_bullet, pb.TORQUE_CONTROL, forces=torque.tolist(), physicsClientId=cid
            )
        for servo in self._servos:
            kp, spring = servo.stiffness, servo.spring
            target = kp * self._targets[servo.index] / (kp + spring)
            pb.setJointMotorControl2(
                self._robot,
                servo.joint,
                pb.POSITION_CONTROL,
                targetPosition=float(target),
                targetVelocity=0.0,
                positionGain=servo.position_gain,
                velocityGain=servo.velocity_gain,
                force=servo.force_limit,
                physicsClientId=cid,
            )
        if self._compensated:
            links = [index for index, _ in self._compensated]
            states = pb.getLinkStates(self._robot, links, physicsClientId=cid)
            for (link, mass), link_state in zip(self._compensated, states, strict=True):
                pb.applyExternalForce(
                    self._robot,
                    link,
                    (-mass * self._gravity).tolist(),
                    link_state[0],
                    pb.WORLD_FRAME,
                    physicsClientId=cid,
                )

    def step(self, n_steps: int, *, track_friction_work: bool = False) -> float:
        """Advance ``n_steps`` steps; optionally return the friction work at object contacts (J)."""
        pb, cid = self._pb, self._client
        work = 0.0
        for _ in range(n_steps):
            before = self._body_velocities() if track_friction_work else None
            self._apply_controls()
            pb.stepSimulation(physicsClientId=cid)
            self._time += self.scene.timestep
            if before is not None:
                work += self._friction_power(before) * self.scene.timestep
        return work

    # ------------------------------------------------------------------ friction work

    def _body_velocities(self) -> dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(body, link) -> (centre of mass, linear velocity, angular velocity) of every moving part."""
        pb, cid = self._pb, self._client
        result: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        pos, vel = self.object_positions(), self.object_velocities()
        for i, body in enumerate(self._object_ids):
            result[(body, -1)] = (pos[i], vel[i, :3], vel[i, 3:])
        if self._robot >= 0 and self._specs:
            states = pb.getLinkStates(
                self._robot, list(range(len(self._specs))), computeLinkVelocity=1, physicsClientId=cid
            )
            for index, link_state in enumerate(states):
                result[(self._robot, index)] = (
                    np.asarray(link_state[0]),
                    np.asarray(link_state[6]),
                    np.asarray(link_state[7]),
                )
        return result

    def _friction_power(self, before: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]]) -> float:
        """Power of the last step's friction forces at contacts that involve an object, W (<= 0).

        Each contact reports the lateral friction on body B along two directions; its power is
        ``f . (v_B - v_A)`` at the contact point with the bodies' midpoint velocities of the step.
        """
        pb, cid = self._pb, self._client
        after = self._body_velocities()
        zero = np.zeros(3)
        power = 0.0
        objects = set(self._object_ids)
        for contact in pb.getContactPoints(physicsClientId=cid):
            body_a, body_b, link_a, link_b = contact[1], contact[2], contact[3], contact[4]
            if body_a not in objects and body_b not in objects:
                continue
            force = contact[10] * np.asarray(contact[11]) + contact[12] * np.asarray(contact[13])
            point_a, point_b = np.asarray(contact[5]), np.asarray(contact[6])
            velocities = []
            for body, link, point in ((body_a, link_a, point_a), (body_b, link_b, point_b)):
                key = (body, link)
                if key not in after:
                    velocities.append(zero)
                    continue
                com0, v0, w0 = before[key]
                com1, v1, w1 = after[key]
                velocities.append(0.5 * (v0 + v1) + np.cross(0.5 * (w0 + w1), point - 0.5 * (com0 + com1)))
            power += float(force @ (velocities[0] - velocities[1]))
        return power

    # ------------------------------------------------------------------ read-outs

    def object_penetrations(self) -> list[tuple[int, int, float]]:
        """Penetrating contacts that involve an object: ``(object, other or -1, depth in m)``.

        Uses ``getClosestPoints`` (no side effect on the contact caches).
        """
        pb, cid = self._pb, self._client
        others = [*self._statics, *([self._robot] if self._robot >= 0 else [])]
        result = []
        for i, body in enumerate(self._object_ids):
            candidates = [(j, other) for j, other in enumerate(self._object_ids) if j > i]
            candidates += [(-1, other) for other in others]
            for j, other in candidates:
                for point in pb.getClosestPoints(body, other, 0.0, physicsClientId=cid):
                    if point[8] < 0:
                        result.append((i, j, -float(point[8])))
        return result

    def _base_poses(self) -> tuple[np.ndarray, np.ndarray]:
        pb, cid = self._pb, self._client
        poses = [pb.getBasePositionAndOrientation(body, physicsClientId=cid) for body in self._object_ids]
        return np.array([pose[0] for pose in poses]), np.array([pose[1] for pose in poses])[:, [3, 0, 1, 2]]

    def object_positions(self) -> np.ndarray:
        """Centre-of-mass positions (n_objects, 3), metres."""
        return self._base_poses()[0]

    def object_quaternions(self) -> np.ndarray:
        """Orientations (n_objects, 4), (w, x, y, z); upright objects report their rotation about z only."""
        quat = self._base_poses()[1]
        if self._upright:
            half_yaw = 0.5 * yaw_from_quat(quat)
            zeros = np.zeros_like(half_yaw)
            return np.column_stack([np.cos(half_yaw), zeros, zeros, np.sin(half_yaw)])
        return quat

    def object_velocities(self) -> np.ndarray:
        """Linear and angular velocities in the world frame (n_objects, 6); upright: angular about z only."""
        pb, cid = self._pb, self._client
        velocities = np.array(
            [np.concatenate(pb.getBaseVelocity(body, physicsClientId=cid)) for body in self._object_ids]
        )
        if self._upright:
            velocities[:, 3:5] = 0.0
        return velocities

    def robot_positions(self) -> np.ndarray:
        """End-effector joint positions (n_robot_dofs,)."""
        if not self._robot_joints:
            return np.zeros(0)
        states = self._pb.getJointStates(self._robot, self._robot_joints, physicsClientId=self._client)
        return np.array([s[0] for s in states])

    def robot_velocities(self) -> np.ndarray:
        """End-effector joint velocities (n_robot_dofs,)."""
        if not self._robot_joints:
            return np.zeros(0)
        states = self._pb.getJointStates(self._robot, self._robot_joints, physicsClientId=self._client)
        return np.array([s[1] for s in states])

    def mechanical_energy(self) -> float:
        """Kinetic plus potential energy of the objects, joules."""
        pos, vel = self.object_positions(), self.object_velocities()
        kinetic = 0.5 * float(np.sum(self._masses * np.sum(vel[:, :3] ** 2, axis=1)))
        if self._upright:
            kinetic += 0.5 * float(np.sum(self._inertias[:, 2] * vel[:, 5] ** 2))
        else:
            quat = self.object_quaternions()
            for i in range(len(self._object_ids)):
                rotation = _matrix(quat[i])
                local = rotation.T @ vel[i, 3:]
                kinetic += 0.5 * float(np.sum(self._inertias[i] * local * local))
        potential = -float(np.sum(self._masses * (pos @ self._gravity)))
        return kinetic + potential

    def diverged(self) -> bool:
        """Whether the state holds a non-finite number."""
        return not bool(np.all(np.isfinite(self.get_state())))

    def frame_state(self) -> FrameState:
        """Current poses and velocities."""
        return FrameState(
            object_pos=self.object_positions(),
            object_quat=self.object_quaternions(),
            object_vel=self.object_velocities(),
            robot_q=self.robot_positions(),
            robot_v=self.robot_velocities(),
        )


def _matrix(quat: np.ndarray) -> np.ndarray:
    w, x, y, z = quat
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
