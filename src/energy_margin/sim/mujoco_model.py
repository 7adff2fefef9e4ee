"""MuJoCo backend on a user's compiled model (a scene file's MJCF) instead of a generated one.

The model is simulated exactly as compiled. The objects are bodies with a free joint (or the
upright joints slide x, y, z and hinge z, in that order); every other joint is the robot's and
must be a hinge or a slide. The robot's coordinates ``robot_q`` are those joints' positions
followed by every mocap body's position (3) and quaternion (4); ``robot_v`` the joints'
velocities followed by zeros for the mocap coordinates (a mocap body has no velocity state). The
robot is driven by :class:`~energy_margin.sim.base.ModelCommand` (the model's actuator controls
and mocap poses) through ``set_model_command``; ``set_robot_force`` adds generalized forces on
the robot joints (its mocap entries are ignored).

A simulator built with ``still=True`` holds the robot where each reset puts it: its joint
velocities are set to zero and its joints get an armature of :data:`STILL_ARMATURE` (kg m^2 for
hinges, kg for slides), so that no actuator, gravity or contact force of a manipulation scene moves
it measurably during a propagation of a few tenths of a second (mocap bodies stay where the frame
puts them in any case). For recorded states whose commands are not known, and for live scoring
with ``hold="still"``.

A simulator built with ``coasting=True`` keeps the velocities each reset gives the robot's joints
and gives them an armature of :data:`COASTING_ARMATURE`: the robot goes on moving as each frame has
it moving (a joint turning at 0.5 rad/s at the frame turns on at 0.5 rad/s), a body too heavy for
the objects' contacts, gravity or its actuators to slow it much, as a robot following its own path
does; its joint limits still stop it. For recorded states whose commands are not known but whose
velocities are (``motion.robot = "coasting"``, the live wrappers' ``hold="coasting"``). Contacts
between the robot and the world are kept (the robot moves). A moving robot is a hundredth of a
held one's armature: a body of :data:`STILL_ARMATURE` moving into the objects throws them (the
contact solver's impulses against it), and on recorded demonstrations the lighter one ranks
future capture better (``benchmarks/coasting_armature.py``, docs/howto/scenes.md); a held robot
keeps the heavier one, which ranks it better there.
"""

from __future__ import annotations

import mujoco
import numpy as np

from energy_margin.errors import InvalidParameterError
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.sim.mujoco_index import ModelIndex
from energy_margin.world.scene import Scene

__all__ = [
    "COASTING_ARMATURE",
    "STILL_ARMATURE",
    "MujocoModelSimulator",
]

#: Armature of the robot's joints in a ``still=True`` simulator, kg m^2 or kg.
STILL_ARMATURE = 1e8
#: Armature of the robot's joints in a ``coasting=True`` simulator (a robot that moves), kg m^2 or kg.
COASTING_ARMATURE = 1e6


class MujocoModelSimulator(MujocoSimulator):
    """A :class:`~energy_margin.sim.base.Simulator` on a compiled user model."""

    def __init__(
        self,
        model: mujoco.MjModel,
        scene: Scene,
        *,
        object_joints: list[int],
        robot_joints: list[int],
        still: bool = False,
        coasting: bool = False,
        robot_armature: float | None = None,
    ) -> None:
        """Simulate ``model``.

        Args:
            model: the compiled model (not copied: one simulator per model).
            scene: the objects' description; ``scene.objects[i].name`` is object i's body.
            object_joints: joint id of each object's free joint (or first upright joint).
            robot_joints: ids of the robot's hinge and slide joints, in ``robot_q`` order (none
                is servoed: the model's own actuators drive the robot).
            still: hold the robot where each reset puts it (see the module docstring); the
                model's robot armature is changed.
            coasting: the robot keeps the velocities each reset gives it (see the module
                docstring); the model's robot armature is changed.
            robot_armature: the robot joints' armature when ``still`` or ``coasting``, kg m^2 or kg
                (``None``: :data:`STILL_ARMATURE` or :data:`COASTING_ARMATURE`).

        Raises:
            InvalidParameterError: both ``still`` and ``coasting``.

        """
        if still and coasting:
            raise InvalidParameterError("coasting", "cannot be combined with still: the robot is held still or coasts")
        index = ModelIndex.of(model, scene, object_joints=object_joints, robot_joints=robot_joints)
        super().__init__(scene, model=model, index=index)
        self._n_mocap = int(model.nmocap)
        self.still = still
        self.coasting = coasting
        if (still or coasting) and index.robot_qvel.size:
            if robot_armature is None:
                robot_armature = STILL_ARMATURE if still else COASTING_ARMATURE
            model.dof_armature[index.robot_qvel] = robot_armature

    @property
    def _robot_still(self) -> bool:
        """Whether the robot is held still during a propagation (``still=True``)."""
        return self.still

    @property
    def n_robot_dofs(self) -> int:
        """Robot joints plus seven coordinates per mocap body."""
        return int(self.index.robot_qpos.size) + 7 * self._n_mocap

    def _set_robot_state(self, robot_q: np.ndarray, robot_v: np.ndarray) -> None:
        joints = self.index.robot_qpos.size
        self.data.qpos[self.index.robot_qpos] = robot_q[:joints]
        self.data.qvel[self.index.robot_qvel] = 0.0 if self.still else robot_v[:joints]
        if self._n_mocap:
            mocap = np.asarray(robot_q[joints:], dtype=float)
            self.data.mocap_pos[:] = mocap[: 3 * self._n_mocap].reshape(-1, 3)
            quat = mocap[3 * self._n_mocap :].reshape(-1, 4)
            self.data.mocap_quat[:] = quat / np.linalg.norm(quat, axis=1, keepdims=True)

    def robot_positions(self) -> np.ndarray:
        """Robot joint positions, then mocap positions and quaternions, shape (n_robot_dofs,)."""
        return np.concatenate(
            [self.data.qpos[self.index.robot_qpos], self.data.mocap_pos.ravel(), self.data.mocap_quat.ravel()]
        )

    def robot_velocities(self) -> np.ndarray:
        """Robot joint velocities, then zeros for the mocap coordinates, shape (n_robot_dofs,)."""
        return np.concatenate([self.data.qvel[self.index.robot_qvel], np.zeros(7 * self._n_mocap)])

    def set_robot_force(self, force: np.ndarray) -> None:
        """Hold generalized forces on the robot joints (the first entries of ``force``)."""
        robot_qvel = self.index.robot_qvel
        self.data.qfrc_applied[robot_qvel] = np.asarray(force)[: robot_qvel.size]
