"""The Simulator protocol: everything the analyzer and the data generator need from an engine."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState


@dataclass(frozen=True)
class ModelCommand:
    """Inputs of a user's MuJoCo model at one instant (see :class:`~energy_margin.sim.mujoco_model`).

    Attributes:
        ctrl: the model's actuator controls, shape (nu,), in each actuator's own unit; ``None``
            leaves them unchanged.
        mocap_pos: positions of the mocap bodies, shape (nmocap, 3), metres; ``None`` leaves them.
        mocap_quat: orientations of the mocap bodies, shape (nmocap, 4), ``(w, x, y, z)``; ``None``
            leaves them.

    """

    ctrl: np.ndarray | None = None
    mocap_pos: np.ndarray | None = None
    mocap_quat: np.ndarray | None = None


@runtime_checkable
class Simulator(Protocol):
    """A physics engine instance built from a :class:`~energy_margin.world.scene.Scene`.

    The scene (model) is immutable; the simulator holds the changing state. ``get_state`` returns an
    opaque float64 vector that ``set_state`` restores exactly: replaying the same wrenches from a
    restored state gives bit-identical results.
    """

    scene: Scene

    @property
    def timestep(self) -> float:
        """Physics time step, seconds."""
        ...

    @property
    def state_size(self) -> int:
        """Length of the vector returned by :meth:`get_state`."""
        ...

    def reset(self, frame: FrameState) -> None:
        """Set object and end-effector poses and velocities; clear wrenches and forces.

        Servo targets are set to the frame's joint positions (the servos hold the pose).
        """
        ...

    def get_state(self) -> np.ndarray:
        """The full integration state, shape (state_size,), float64."""
        ...

    def set_state(self, state: np.ndarray) -> None:
        """Restore a state returned by :meth:`get_state`."""
        ...

    def set_object_wrenches(self, wrenches: np.ndarray) -> None:
        """Hold wrenches on the objects until changed.

        Args:
            wrenches: shape (n_objects, 6): force (N) then torque (N m), world frame, applied at each
                object's centre of mass.

        """
        ...

    def set_robot_force(self, force: np.ndarray) -> None:
        """Hold generalized forces on the end-effector joints, shape (n_robot_dofs,), N or N m."""
        ...

    def set_robot_targets(self, targets: np.ndarray) -> None:
        """Hold position-servo targets, shape (n_robot_dofs,), m or rad.

        Entries of joints without a servo (:attr:`~energy_margin.world.scene.Joint.servo_stiffness` is
        ``None``) are ignored. Targets are part of the state saved by :meth:`get_state`.
        """
        ...

    def step(self, n_steps: int, *, track_friction_work: bool = False) -> float:
        """Advance ``n_steps`` time steps.

        Returns:
            The work done by friction at contacts that involve an object over these steps, joules
            (<= 0: friction dissipates), or 0.0 when ``track_friction_work`` is false.

        """
        ...

    def object_positions(self) -> np.ndarray:
        """Centre-of-mass positions, shape (n_objects, 3), metres."""
        ...

    def object_quaternions(self) -> np.ndarray:
        """Orientations, shape (n_objects, 4), (w, x, y, z)."""
        ...

    def object_velocities(self) -> np.ndarray:
        """Linear (m/s) then angular (rad/s) velocities, world frame, shape (n_objects, 6)."""
        ...

    def robot_positions(self) -> np.ndarray:
        """End-effector joint positions, shape (n_robot_dofs,)."""
        ...

    def robot_velocities(self) -> np.ndarray:
        """End-effector joint velocities, shape (n_robot_dofs,)."""
        ...

    def object_penetrations(self) -> list[tuple[int, int, float]]:
        """Interpenetrations of the objects in the current state.

        Returns:
            ``(object, other, depth)`` per penetrating contact: ``other`` is another object's index,
            or -1 for the end-effector or a static obstacle; ``depth`` > 0 in metres.
        """
        ...

    def mechanical_energy(self) -> float:
        """Kinetic plus gravitational potential energy of the objects, joules (potential zero at z=0)."""
        ...

    def frame_state(self) -> FrameState:
        """The current poses and velocities as a :class:`FrameState`."""
        ...


def release_states(simulator: object) -> None:
    """Free the engine memory behind the states a simulator has returned, when it keeps any.

    An optional hook of the protocol: a backend whose :meth:`Simulator.get_state` vectors refer to
    engine-side snapshots (PyBullet's ``saveState``) defines ``release_states()``; the states it
    returned before are invalid afterwards. The EST calls this when a tree is done. Backends whose
    states are self-contained vectors (MuJoCo) need not define it.
    """
    release = getattr(simulator, "release_states", None)
    if callable(release):
        release()
