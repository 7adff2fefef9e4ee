"""The Simulator protocol and the optional capabilities an engine may add to it.

:class:`Simulator` is everything the analyzer and the data generator need from an engine. Some
callers need more, which only some engines provide; each such capability is a small
runtime-checkable protocol here, and :func:`require` checks one once and returns the simulator
typed as it (or says clearly which capability is missing):

* :class:`BatchedRollout`: many propagations at once (``mujoco.rollout``), for the EST's batched
  expansion and the MPPI controller;
* :class:`ModelCommands`: the actuator controls and mocap poses of a MuJoCo model
  (:class:`ModelCommand`);
* :class:`CompiledModel`: the compiled ``mujoco.MjModel`` and its ``mujoco.MjData``;
* :class:`ReleasableStates`: engine memory behind saved states, freed by :func:`release_states`;
* :class:`ObjectContacts`: the analysis model, whose contacts are only those that can move an
  object (:mod:`energy_margin.sim.analysis_model`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, cast, runtime_checkable

import numpy as np

from energy_margin.errors import EnergyMarginError
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState

if TYPE_CHECKING:
    import mujoco

__all__ = [
    "BatchedRollout",
    "C",
    "CompiledModel",
    "IncompatibleModelsError",
    "MissingCapabilityError",
    "ModelCommand",
    "ModelCommands",
    "ObjectContacts",
    "Propagator",
    "ReleasableStates",
    "Simulator",
    "release_states",
    "require",
]


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

    def apply_to(self, simulator: object, *, purpose: str = "a model command") -> None:
        """Hold this command on ``simulator``, which must provide :class:`ModelCommands`.

        Args:
            simulator: the simulator.
            purpose: what sends the command, which starts the error message.

        Raises:
            MissingCapabilityError: the simulator takes no model commands.

        """
        require(simulator, ModelCommands, purpose=purpose).set_model_command(self)


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

    def diverged(self) -> bool:
        """Whether the integration blew up since the simulator was built or last reset.

        MuJoCo restarts a blown-up simulation from the model's reference state by itself (warning
        ``mjWARN_BADQACC``), so a roll-out that diverged can look like a quiet one.
        """
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


class Propagator(Protocol):
    """Batched propagations of one simulator's model (see :class:`BatchedRollout`).

    States are the propagator's own vectors (``state_size`` long), not :meth:`Simulator.get_state`'s.
    """

    state_size: int

    def current_state(self, data: Any = None) -> np.ndarray:
        """The simulator's current state, shape (state_size,), or that of ``data``.

        ``data``: another simulator's live data, of a model like this one (another roll-out's).
        """
        ...

    def propagate(
        self,
        task: Any,
        drive: np.ndarray,
        states: np.ndarray,
        start_times: np.ndarray,
        wrenches: np.ndarray,
        n_steps: np.ndarray,
        control_steps: int | None,
        models: list[Any] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Propagate states (k, state_size) with object wrenches (k, n_objects, 6) and the task's script.

        ``drive`` is one roll-out's (n_drive,) or each propagation's (k, n_drive); ``models``, when
        given, each propagation's model (the models of other roll-outs of the same scene).

        Returns:
            Object positions (k, n_objects, 3), velocities (k, n_objects, 6), quaternions
            (k, n_objects, 4) and end states (k, state_size).

        """
        ...

    def roll_commands(
        self,
        state: np.ndarray,
        forces: np.ndarray,
        targets: np.ndarray | None = None,
        ctrl: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Roll ``k`` end-effector command sequences (k, steps, ...) out from one state.

        Returns:
            The states after every step (k, steps, state_size) and the end states (k, state_size).

        """
        ...

    def object_states(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Object positions, quaternions, velocities, robot positions and velocities of states (k, state_size)."""
        ...

    def end_robot_positions(self, states: np.ndarray) -> np.ndarray:
        """The robot's coordinates (as :meth:`Simulator.robot_positions`) at the end states of the last propagate."""
        ...


@runtime_checkable
class BatchedRollout(Protocol):
    """Capability: batched propagations of the simulator's model on worker threads."""

    def rollout_propagator(self, threads: int = 1) -> Propagator:
        """A propagator on ``threads`` threads (the same object for the same count)."""
        ...


@runtime_checkable
class ModelCommands(Protocol):
    """Capability: a MuJoCo model's actuator controls and mocap poses (:class:`ModelCommand`)."""

    def set_model_command(self, command: ModelCommand) -> None:
        """Hold a model command until changed."""
        ...


@runtime_checkable
class CompiledModel(Protocol):
    """Capability: the compiled MuJoCo model and its live data (read them; step through the simulator)."""

    model: mujoco.MjModel
    data: mujoco.MjData


@runtime_checkable
class ReleasableStates(Protocol):
    """Capability: :meth:`Simulator.get_state` vectors refer to engine-side snapshots to free."""

    def release_states(self) -> None:
        """Free them; the states returned before are invalid afterwards."""
        ...


@runtime_checkable
class ObjectContacts(Protocol):
    """Capability: simulate the analysis model, whose contacts are only those that can move an object."""

    def keep_object_contacts(self) -> Any:
        """Drop the other contact pairs from the simulator's model, once.

        Robot self-collision, and robot-world pairs when the robot is held still; later calls
        return the first result (a :class:`~energy_margin.sim.analysis_model.PrunedContacts`).
        """
        ...


_MUJOCO = ": use the 'mujoco' engine"
#: What each capability gives, its members and a hint, for :func:`require`'s message.
_CAPABILITIES: dict[type, tuple[str, tuple[str, ...], str]] = {
    BatchedRollout: ("batched roll-outs", ("rollout_propagator",), _MUJOCO),
    ModelCommands: ("MuJoCo model commands", ("set_model_command",), _MUJOCO),
    CompiledModel: ("a compiled MuJoCo model", ("model", "data"), _MUJOCO),
    ReleasableStates: ("releasable states", ("release_states",), ""),
    ObjectContacts: ("the analysis model", ("keep_object_contacts",), _MUJOCO),
}

C = TypeVar("C")

#: (simulator class, capability) pairs whose class members provide the capability (see :func:`require`).
_PROVIDED_BY_CLASS: set[tuple[type, type]] = set()


class MissingCapabilityError(EnergyMarginError, ValueError):
    """A simulator lacks an optional capability a caller needs (see :func:`require`).

    Attributes:
        capability: the capability protocol.
        missing: the names of its members the simulator lacks.

    """

    def __init__(self, message: str, capability: type, missing: tuple[str, ...]) -> None:
        super().__init__(message)
        self.capability = capability
        self.missing = missing


class IncompatibleModelsError(EnergyMarginError, ValueError):
    """Models a batched propagator cannot run in one call (they differ in more than it batches per world)."""


def require(simulator: object, capability: Callable[..., C], *, purpose: str) -> C:
    """Return ``simulator`` typed as ``capability`` after checking that it provides it.

    Args:
        simulator: the simulator.
        capability: one of this module's capability protocols (:class:`BatchedRollout`,
            :class:`ModelCommands`, :class:`CompiledModel`, :class:`ReleasableStates`).
        purpose: what needs it, which starts the error message ("batched expansion").

    Raises:
        MissingCapabilityError: the simulator does not provide ``capability`` (an
            :class:`~energy_margin.errors.EnergyMarginError` naming the missing members).

    """
    protocol = cast(type, capability)
    if protocol not in _CAPABILITIES:
        raise TypeError(f"{protocol!r} is not a simulator capability")
    if (type(simulator), protocol) in _PROVIDED_BY_CLASS:
        return cast(C, simulator)
    what, members, hint = _CAPABILITIES[protocol]
    if isinstance(simulator, protocol):
        # A class whose own members satisfy the protocol satisfies it for every instance: checked
        # once (a protocol check costs about 10 us, and a propagation asks for each command it holds).
        if all(hasattr(type(simulator), name) for name in members):
            _PROVIDED_BY_CLASS.add((type(simulator), protocol))
        return cast(C, simulator)
    missing = tuple(name for name in members if not hasattr(simulator, name))
    raise MissingCapabilityError(
        f"{purpose} needs a simulator with {what} ({protocol.__name__}); {type(simulator).__name__} has no "
        f"{', '.join(missing)}{hint}",
        protocol,
        missing,
    )


def release_states(simulator: object) -> None:
    """Free the engine memory behind the states a simulator has returned, when it keeps any.

    A backend whose :meth:`Simulator.get_state` vectors refer to engine-side snapshots (PyBullet's
    ``saveState``) provides :class:`ReleasableStates`; the states it returned before are invalid
    afterwards. The EST calls this when a tree is done. Backends whose states are self-contained
    vectors (MuJoCo) need not provide it; for them this does nothing.
    """
    if isinstance(simulator, ReleasableStates):
        simulator.release_states()
