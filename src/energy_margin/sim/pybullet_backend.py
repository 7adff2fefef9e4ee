"""PyBullet backend (the authors' engine): the scene built with ``createMultiBody``, nodes as saved states.

Design (see docs/reference/engines.md for the reasoning and the measured differences to MuJoCo):

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
import math

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidDataError
from energy_margin.sim.pybullet_build import (
    _BulletBodies,
    _LinkSpec,
    _require_pybullet,
    _xyzw,
)
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState, yaw_from_quat

__all__ = ["PybulletSimulator"]


class PybulletSimulator(_BulletBodies):
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
