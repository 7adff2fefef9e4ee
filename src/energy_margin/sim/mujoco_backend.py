"""MuJoCo backend: a scene's model built with ``mujoco.MjSpec``, states as ``mjSTATE_INTEGRATION`` vectors.

The model is :func:`~energy_margin.sim.mujoco_spec.build_model`'s (its contact settings, servos
and contact helpers are described there); batched roll-outs go through
:class:`~energy_margin.sim.mujoco_rollout.RolloutPropagator`. Besides the
:class:`~energy_margin.sim.base.Simulator` protocol the simulator provides the optional
capabilities :class:`~energy_margin.sim.base.BatchedRollout`,
:class:`~energy_margin.sim.base.ModelCommands`, :class:`~energy_margin.sim.base.CompiledModel` and
:class:`~energy_margin.sim.base.ReleasableStates`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from energy_margin.compat import contact_depths
from energy_margin.errors import InvalidParameterError
from energy_margin.sim.analysis_model import PrunedContacts, keep_object_contacts
from energy_margin.sim.base import ModelCommand
from energy_margin.sim.mujoco_index import (
    ModelIndex,
    apply_model_command,
    object_inertials,
    object_owners,
    rotate,
    rotate_inverse,
)
from energy_margin.sim.mujoco_rollout import RolloutPropagator
from energy_margin.sim.mujoco_spec import build_model, scene_index
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState, yaw_from_quat

__all__ = [
    "MujocoSimulator",
]

_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


class MujocoSimulator:
    """A :class:`~energy_margin.sim.base.Simulator` on MuJoCo.

    Args:
        scene: the world description.
        model: a compiled model of ``scene`` to simulate instead of building one (not copied: one
            simulator per model); given together with ``index``.
        index: the objects' and the robot's addresses in ``model``.

    Attributes:
        scene: the world description.
        model: the compiled model.
        data: the simulation state.
        index: the objects' and the robot's addresses in ``model``.

    """

    def __init__(self, scene: Scene, *, model: mujoco.MjModel | None = None, index: ModelIndex | None = None) -> None:
        if (model is None) != (index is None):
            raise InvalidParameterError("index", "must be given together with model (both or neither)")
        if model is None or index is None:
            model = build_model(scene)
            index = scene_index(model, scene)
        self.scene = scene
        self.model = model
        self.data = mujoco.MjData(model)
        self.index = index
        self._propagators: dict[int, RolloutPropagator] = {}
        bodies = index.object_bodies
        # An object is its body's rigid subtree: geoms and mass on welded child bodies count.
        self._masses, self._inertias = object_inertials(model, bodies)
        self._gravity = np.asarray(model.opt.gravity, dtype=float).copy()
        self._geom_object = object_owners(model, bodies)[model.geom_bodyid]
        self._geom_is_object = self._geom_object >= 0
        self._state_buffer = np.empty(mujoco.mj_stateSize(model, _STATE_SPEC))
        self._spin_dof = np.zeros(model.nv, dtype=bool)
        if index.upright:
            spinning = model.dof_frictionloss[index.yaw_rate_index] > 0
            if index.axis_mask is not None:
                spinning &= index.axis_mask[:, 3]
            self._spin_dof[index.yaw_rate_index] = spinning
        self._has_spin_friction = bool(self._spin_dof.any())
        self._pyramid = np.arange(4)
        self.pruned_contacts: PrunedContacts | None = None

    def keep_object_contacts(self) -> PrunedContacts:
        """Simulate the analysis model from now on (:mod:`energy_margin.sim.analysis_model`).

        The model's contact masks are rewritten once; later calls return the first result.
        """
        if self.pruned_contacts is None:
            self.pruned_contacts = keep_object_contacts(self.model, self._geom_is_object, robot_still=self._robot_still)
        return self.pruned_contacts

    @property
    def _robot_still(self) -> bool:
        """Whether the robot is held still during a propagation (not for generated scenes)."""
        return False

    @property
    def n_robot_dofs(self) -> int:
        """Length of the end-effector coordinate vectors (``robot_q`` and ``robot_v``)."""
        return int(self.index.robot_qpos.size)

    def _set_robot_state(self, robot_q: np.ndarray, robot_v: np.ndarray) -> None:
        """Write the end-effector coordinates of a frame into ``data`` (before ``mj_forward``)."""
        self.data.qpos[self.index.robot_qpos] = robot_q
        self.data.qvel[self.index.robot_qvel] = robot_v

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
        model, data, index = self.model, self.data, self.index
        mujoco.mj_resetData(model, data)
        quat = np.asarray(frame.object_quat, dtype=float)
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        if index.upright:
            # Upright objects keep only the rotation about z and the z angular velocity.
            index.write_objects(
                data.qpos,
                data.qvel,
                frame.object_pos,
                frame.object_vel[:, :3],
                yaw_from_quat(quat),
                frame.object_vel[:, 5],
            )
        else:
            data.qpos[index.pos_index] = frame.object_pos
            data.qvel[index.linvel_index] = frame.object_vel[:, :3]
            data.qpos[index.quat_index] = quat
            # Free-joint angular velocity is expressed in the body frame.
            data.qvel[index.angvel_index] = rotate_inverse(quat, np.asarray(frame.object_vel[:, 3:], float))
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
        self.data.xfrc_applied[self.index.object_bodies] = wrenches

    def set_robot_force(self, force: np.ndarray) -> None:
        """Hold generalized forces (n_robot_dofs,) on the end-effector joints."""
        self.data.qfrc_applied[self.index.robot_qvel] = force

    def set_model_command(self, command: ModelCommand) -> None:
        """Hold a model command: the model's actuator controls and mocap body poses."""
        apply_model_command(self.data, command)

    def set_robot_targets(self, targets: np.ndarray) -> None:
        """Hold servo targets (n_robot_dofs,) [m or rad]; entries of unservoed joints are ignored."""
        index = self.index
        if index.servo_actuators.size:
            self.data.ctrl[index.servo_actuators] = np.asarray(targets, dtype=float)[index.servoed]

    def diverged(self) -> bool:
        """Whether MuJoCo found a non-finite acceleration (and restarted the simulation) since the last reset."""
        return bool(self.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0)

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
        depths = contact_depths(self.model, data)
        penetrating = (depths > 0) & ((first >= 0) | (second >= 0))
        result = []
        for a, b, depth in zip(first[penetrating], second[penetrating], depths[penetrating], strict=True):
            obj, other = (int(a), int(b)) if a >= 0 else (int(b), int(a))
            result.append((obj, other, float(depth)))
        return result

    def object_positions(self) -> np.ndarray:
        """Centre-of-mass positions (n_objects, 3), metres."""
        return self.index.object_positions(self.data.qpos)

    def object_quaternions(self) -> np.ndarray:
        """Orientations (n_objects, 4), (w, x, y, z)."""
        return self.index.object_quaternions(self.data.qpos)

    def object_velocities(self) -> np.ndarray:
        """Linear and angular velocities in the world frame (n_objects, 6)."""
        qvel, index = self.data.qvel, self.index
        if index.upright:
            velocity = np.zeros((index.linvel_index.shape[0], 6))
            velocity[:, :3] = index.linear_velocities(qvel)
            velocity[:, 5] = index.yaw_rates(qvel)
            return velocity
        angular = rotate(self.object_quaternions(), qvel[index.angvel_index])
        return np.concatenate([qvel[index.linvel_index], angular], axis=1)

    def robot_positions(self) -> np.ndarray:
        """End-effector joint positions (n_robot_dofs,)."""
        return self.data.qpos[self.index.robot_qpos].copy()

    def robot_velocities(self) -> np.ndarray:
        """End-effector joint velocities (n_robot_dofs,)."""
        return self.data.qvel[self.index.robot_qvel].copy()

    def mechanical_energy(self) -> float:
        """Kinetic plus potential energy of the objects, joules."""
        data, index = self.data, self.index
        linear = index.linear_velocities(data.qvel)
        kinetic = 0.5 * float(np.sum(self._masses * np.sum(linear * linear, axis=1)))
        if index.upright:
            yaw_rate = index.yaw_rates(data.qvel)
            kinetic += 0.5 * float(np.sum(self._inertias[:, 2] * yaw_rate * yaw_rate))
        else:
            angular_local = data.qvel[index.angvel_index]
            kinetic += 0.5 * float(np.sum(self._inertias * angular_local * angular_local))
        potential = -float(np.sum(self._masses * (index.object_positions(data.qpos) @ self._gravity)))
        return kinetic + potential

    def objects_of(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Object positions (k, n, 3), quaternions (k, n, 4), velocities (k, n, 6) of qpos (k, nq), qvel (k, nv)."""
        return self.index.objects_of(qpos, qvel)

    def rollout_propagator(self, threads: int = 1) -> RolloutPropagator:
        """A batched propagator on ``threads`` threads, cached per thread count."""
        if threads not in self._propagators:
            self._propagators[threads] = RolloutPropagator(self.model, self.data, self.index, threads)
        return self._propagators[threads]

    def frame_state(self) -> FrameState:
        """Current poses and velocities."""
        return FrameState(
            object_pos=self.object_positions().copy(),
            object_quat=self.object_quaternions().copy(),
            object_vel=self.object_velocities(),
            robot_q=self.robot_positions(),
            robot_v=self.robot_velocities(),
        )
