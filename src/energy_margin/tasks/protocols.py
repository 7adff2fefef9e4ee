"""What a task offers, one protocol per concern: its physics, its scripted motion, its regions, its design space.

:class:`~energy_margin.tasks.base.Task` implements all four; a function that needs one concern
only takes that protocol, so it can be handed any object that implements it (a test's fake, a
wrapper). Every protocol is ``runtime_checkable``: ``isinstance(task, TaskRegions)`` tells
whether an object has the members (not their signatures).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from energy_margin.sim.base import ModelCommand, Simulator
    from energy_margin.tasks.config import TaskConfig
    from energy_margin.tasks.design_params import DesignAlias, DesignParameter
    from energy_margin.tasks.motion import Trajectory
    from energy_margin.tasks.region_types import Region
    from energy_margin.tasks.state_box import StateBox, WrenchLimits
    from energy_margin.world.scene import Scene
    from energy_margin.world.state import FrameState, RobotState

__all__ = ["DesignSpace", "PhysicsReadout", "ScriptedMotion", "TaskRegions"]


@runtime_checkable
class PhysicsReadout(Protocol):
    """The task's world: its scene and simulator, its perturbation ranges, and its sane states."""

    @property
    def engines(self) -> tuple[str, ...] | None:
        """Engines that can simulate the task; ``None`` for every engine."""
        ...

    @property
    def fixed_objects(self) -> int | None:
        """Objects of every scene of the task when it fixes them, else ``None``."""
        ...

    @property
    def typical_objects(self) -> int:
        """Objects per scene of the task's usual dataset when it does not fix them."""
        ...

    @property
    def default_objects(self) -> int:
        """Objects per scene when a caller does not choose."""
        ...

    @property
    def planar(self) -> bool:
        """Whether the objects stay upright on the floor."""
        ...

    @property
    def state_box(self) -> StateBox:
        """Where the objects of a sane state lie and how fast they move at most."""
        ...

    @property
    def frame_box(self) -> StateBox:
        """Where the objects of a recorded frame may physically be."""
        ...

    def build_scene(self, n_objects: int, friction: float, drive: np.ndarray | None = None) -> Scene:
        """The world with ``n_objects`` objects and contact friction ``friction``."""
        ...

    def make_simulator(
        self,
        n_objects: int,
        friction: float,
        drive: np.ndarray | None = None,
        engine: str = "mujoco",
        *,
        device: str | None = None,
    ) -> Simulator:
        """A simulator of the task's world on ``engine`` (on ``device`` for an engine with devices)."""
        ...

    def model_sha256(self, n_objects: int) -> str:
        """SHA-256 of the task's compiled MuJoCo model with ``n_objects`` objects."""
        ...

    def wrench_limits(self, scene: Scene) -> WrenchLimits:
        """Perturbation ranges for ``scene``."""
        ...

    def within_bounds(self, object_pos: np.ndarray, object_vel: np.ndarray) -> bool:
        """Whether a reached state, positions (n_objects, 3) m and velocities (n_objects, 6), lies in the state box."""
        ...


@runtime_checkable
class ScriptedMotion(Protocol):
    """The task's scripted manipulation: a roll-out's start and the end-effector's command over time."""

    @property
    def label(self) -> str:
        """How messages name the task, e.g. ``task 'pushing'``."""
        ...

    @property
    def control_period(self) -> float | None:
        """Seconds between re-evaluations of the command during analysis; ``None``: once per propagation."""
        ...

    @property
    def n_steps(self) -> int:
        """Physics steps of a scripted roll-out."""
        ...

    def sample_trajectory(self, rng: np.random.Generator, n_objects: int) -> Trajectory:
        """Randomised initial state, friction and drive parameters of one scripted roll-out."""
        ...

    def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        """Generalized end-effector forces (n_robot_dofs,) at ``state``."""
        ...

    def robot_targets(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray | None:
        """Servo targets (n_robot_dofs,) at ``state``, or ``None`` without servos."""
        ...

    def model_command(self, drive: np.ndarray, time: float) -> ModelCommand | None:
        """Actuator controls and mocap poses at ``time`` (s), or ``None``."""
        ...

    def robot_dofs(self) -> int:
        """Length of the end-effector coordinates of a frame."""
        ...

    def drive_size(self) -> int:
        """Length of a trajectory's drive parameters."""
        ...

    def frame_steps(self, n_frames: int) -> np.ndarray:
        """Steps at which frames are recorded, shape (n_frames,)."""
        ...


@runtime_checkable
class TaskRegions(Protocol):
    """The meaning of capture and success: the regions of object states and the tests built on them."""

    @property
    def region_caption(self) -> str:
        """What pictures of the task draw as its regions (one paragraph; empty: nothing said)."""
        ...

    def capture_region(self, root: FrameState) -> Region:
        """The capture region built from the analysed frame ``root``."""
        ...

    def capture_regions(self, roots: Sequence[FrameState]) -> Region:
        """The capture regions of many frames as one region over stacked positions (F, ..., 3)."""
        ...

    def capture_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        """Which of M reached states of ``root``'s tree have every object captured, shape (M,)."""
        ...

    def success_region(self) -> Region:
        """The success region at the task's start configuration."""
        ...

    def success_region_at(self, root: FrameState) -> Region:
        """The success region for the frame ``root``."""
        ...

    def success_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        """Which of M reached states of ``root``'s tree have every object successful, shape (M,)."""
        ...

    def is_captured(self, frame: FrameState) -> bool:
        """Whether every object of ``frame`` lies in the capture region built from ``frame``."""
        ...

    def is_successful(self, frame: FrameState) -> bool:
        """Whether every object of ``frame`` lies in the success region."""
        ...

    def capture_region_shape(self, root: FrameState) -> str:
        """A word for the capture region built from ``root`` in captions."""
        ...


@runtime_checkable
class DesignSpace(Protocol):
    """The task's settings and its tool family: what ``sweep`` and ``design`` may change."""

    @property
    def config(self) -> TaskConfig:
        """The task's configuration."""
        ...

    def design_aliases(self) -> tuple[DesignAlias, ...]:
        """Friendly ``sweep --param`` names besides the configuration fields."""
        ...

    def design_fields(self) -> tuple[str, ...]:
        """Configuration fields a design may set."""
        ...

    def design_space(self) -> tuple[DesignParameter, ...]:
        """The task's tool family over its documented ranges."""
        ...

    def configured(self, overrides: dict[str, Any] | None) -> DesignSpace:
        """This task with ``overrides`` applied to its configuration."""
        ...
