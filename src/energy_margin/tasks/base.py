"""What a task is: its world, its scripted manipulation, and the meaning of capture and success.

A task never runs physics itself and never grows trees: the data generator drives a
:class:`~energy_margin.sim.base.Simulator` with the task's scripted forces, and the analyzer asks
the task which reached states are captured or successful. Tasks are registered by name in
:mod:`energy_margin.tasks` so a user can add one without editing the core.

:class:`Task` implements the protocols of :mod:`energy_margin.tasks.protocols`, one per concern;
the types it speaks in live beside it (:mod:`~energy_margin.tasks.config`,
:mod:`~energy_margin.tasks.design_params`, :mod:`~energy_margin.tasks.motion`,
:mod:`~energy_margin.tasks.region_types`) and are re-exported here.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice
from energy_margin.sim import make_simulator
from energy_margin.sim.base import ModelCommand, Simulator
from energy_margin.tasks.command import command_robot
from energy_margin.tasks.config import (
    CONTACT_MODELS,
    ReferenceLayout,
    TaskConfig,
    require_non_negative,
    require_positive,
    require_ranges,
)
from energy_margin.tasks.design_params import DesignAlias, DesignParameter
from energy_margin.tasks.motion import RobotState, Trajectory, adapt_legacy_robot_hooks, sample_separated
from energy_margin.tasks.region_types import (
    DrawableRegion,
    FrameRegions,
    MeasurableRegion,
    Region,
    RegionShape,
    all_inside,
)
from energy_margin.tasks.state_box import StateBox, WrenchLimits
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState

__all__ = [
    "CONTACT_MODELS",
    "DesignAlias",
    "DesignParameter",
    "DrawableRegion",
    "FrameRegions",
    "MeasurableRegion",
    "ReferenceLayout",
    "Region",
    "RegionShape",
    "RobotState",
    "Task",
    "TaskConfig",
    "Trajectory",
    "WrenchLimits",
    "all_inside",
    "command_robot",
    "require_non_negative",
    "require_positive",
    "require_ranges",
    "sample_separated",
    "with_contacts",
]


class Task(ABC):
    """Base class of a manipulation task: it implements every protocol of :mod:`energy_margin.tasks.protocols`.

    Its hooks by protocol:

    * ``PhysicsReadout``: :meth:`build_scene`, :meth:`make_simulator`, :meth:`model_sha256`,
      :meth:`wrench_limits`, :attr:`state_box` (from :meth:`_state_box`), :attr:`frame_box`,
      :meth:`within_bounds`, :attr:`planar`, :attr:`engines`, :attr:`fixed_objects`,
      :attr:`typical_objects`, :attr:`default_objects`.
    * ``ScriptedMotion``: :meth:`sample_trajectory`, :meth:`robot_force`, :meth:`robot_targets`,
      :meth:`model_command`, :meth:`drive_size`, :meth:`robot_dofs`, :attr:`n_steps`,
      :meth:`frame_steps`, :attr:`control_period`.
    * ``TaskRegions``: :meth:`capture_region`, :meth:`capture_regions`, :meth:`capture_inside`,
      :meth:`success_region`, :meth:`success_region_at`, :meth:`success_inside`, :meth:`is_captured`,
      :meth:`is_successful`, :meth:`capture_region_shape`, :attr:`region_caption`.
    * ``DesignSpace``: :attr:`config`, :meth:`design_aliases`, :meth:`design_fields`,
      :meth:`design_space`, :meth:`configured`.

    Besides them the task's identity: :attr:`name`, :attr:`label`, :attr:`config_class`,
    :meth:`from_dict`, :meth:`analysis_problem` and :attr:`reference_layout`.
    """

    name: ClassVar[str]
    config_class: ClassVar[type[TaskConfig]] = TaskConfig
    #: How the task's likelihood lambda was chosen: ``"set"`` (by the task), ``"default"`` or ``"derived"``.
    lambda_origin: str = "set"

    def __init__(self, config: TaskConfig | None = None) -> None:
        self.config = config if config is not None else self.config_class()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # A task class of another package may still write the robot hooks with five arguments.
        adapt_legacy_robot_hooks(cls)

    @classmethod
    def from_dict(cls, values: dict[str, Any] | None) -> Task:
        """Build the task from a configuration dictionary (unknown keys: InvalidParameterError)."""
        values = dict(values or {})
        fields = {f.name: f for f in dataclasses.fields(cls.config_class)}
        unknown = sorted(set(values) - set(fields))
        if unknown:
            raise InvalidParameterError("config", f"names unknown {cls.name} configuration keys: {', '.join(unknown)}")
        converted: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(cls.config_class(**converted))

    @property
    def label(self) -> str:
        """How messages name the task, e.g. ``task 'pushing'``."""
        return f"task {self.name!r}"

    @abstractmethod
    def build_scene(self, n_objects: int, friction: float, drive: np.ndarray | None = None) -> Scene:
        """The world with ``n_objects`` objects and contact friction ``friction``.

        Args:
            n_objects: number of objects.
            friction: Coulomb coefficient of every contact.
            drive: the trajectory's drive parameters, shape (n_drive,), for tasks whose model
                depends on them (e.g. a servo stiffness); ``None`` for the task's nominal drive.

        """

    @abstractmethod
    def sample_trajectory(self, rng: np.random.Generator, n_objects: int) -> Trajectory:
        """Randomised initial state, friction and drive parameters of one scripted roll-out."""

    @abstractmethod
    def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        """Generalized end-effector forces (n_robot_dofs,) at ``state``: N, or N m on a rotation.

        ``state`` holds the roll-out's ``drive``, the ``time`` (s) and the end-effector's ``q`` and ``v``.
        With ``rng`` the scripted roll-out's random variation is drawn; with ``None`` the nominal
        (expected) force is returned, which the analyzer applies while it perturbs the objects.
        """

    def robot_targets(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray | None:
        """Servo targets (n_robot_dofs,) at ``state``, or ``None`` for a task without servos.

        Called after :meth:`robot_force` with the same ``state`` (and the same ``rng``).
        """
        del state, rng
        return None

    def model_command(self, drive: np.ndarray, time: float) -> ModelCommand | None:
        """Actuator controls and mocap poses of a task built on a user's MuJoCo model at ``time`` (s).

        ``None`` (the default) for a task whose end-effector is driven by :meth:`robot_force` and
        :meth:`robot_targets` only. Evaluated after them by :func:`command_robot`.
        """
        del drive, time
        return None

    #: Engines that can simulate the task; ``None`` for every engine of :data:`energy_margin.sim.ENGINES`.
    engines: ClassVar[tuple[str, ...] | None] = None

    #: Objects of every scene of the task, when the task fixes them (a scene file does); ``None``
    #: lets ``generate --objects`` choose.
    fixed_objects: int | None = None

    #: Objects per scene of the task's usual dataset (a study's, a timing calibration's) when the
    #: task does not fix them.
    typical_objects: ClassVar[int] = 5

    #: What the report's pictures of the task draw as its regions (one paragraph; empty: nothing said).
    region_caption: ClassVar[str] = ""

    #: How the authors' published files of the task read (``import-reference``); ``None``: they published none.
    reference_layout: ClassVar[ReferenceLayout | None] = None

    @property
    def default_objects(self) -> int:
        """Objects per scene when a caller does not choose: :attr:`fixed_objects`, else :attr:`typical_objects`."""
        return self.fixed_objects or self.typical_objects

    @property
    def planar(self) -> bool:
        """Whether the objects stay upright on the floor (pictures draw the task from the top), from its scene."""
        return self.build_scene(self.fixed_objects or 1, 0.5).object_motion == "upright"

    @classmethod
    def design_aliases(cls) -> tuple[DesignAlias, ...]:
        """Friendly ``sweep --param`` names of the task besides its configuration fields (none by default)."""
        return ()

    def design_fields(self) -> tuple[str, ...]:
        """Configuration fields a design may set (``design --param``): every field by default."""
        return tuple(item.name for item in dataclasses.fields(self.config))

    def design_space(self) -> tuple[DesignParameter, ...]:
        """The task's tool family over its documented ranges: what ``design`` searches by default (none by default).

        An instance method: a scene file's family is its ``[design]`` table.
        """
        return ()

    def configured(self, overrides: dict[str, Any] | None) -> Task:
        """This task with ``overrides`` applied to its configuration (one design); itself if they change nothing.

        A design, a sweep's grid point or a verification episode is the resolved task with some
        settings changed: it is built from this object (:meth:`from_dict` of its settings and
        ``overrides``), not looked up by name again.

        Raises:
            EnergyMarginError: an unknown setting or an invalid configuration, naming the task.

        """
        overrides = dict(overrides or {})
        settings = self._settings()
        as_given = {key: tuple(value) if isinstance(value, list) else value for key, value in overrides.items()}
        if all(key in settings and settings[key] == value for key, value in as_given.items()):
            return self  # nothing changes: ``fixed`` applied again at each stage rebuilds nothing
        return type(self).build({**settings, **overrides})

    @classmethod
    def build(cls, values: dict[str, Any] | None) -> Task:
        """:meth:`from_dict`, its errors naming the task (a parameter's keeps its name)."""
        try:
            return cls.from_dict(values)
        except InvalidParameterError as error:
            raise InvalidParameterError(error.parameter, f"{error.reason} (task {cls.name!r})") from None
        except (TypeError, ValueError) as error:
            raise EnergyMarginError(f"bad configuration for task {cls.name!r}: {error}") from None

    def _settings(self) -> dict[str, Any]:
        """The settings :meth:`configured` builds a variant from: every configuration field."""
        return self.config.to_dict()

    def model_sha256(self, n_objects: int) -> str:
        """SHA-256 of the task's compiled MuJoCo model with ``n_objects`` objects (``dataset.json``).

        The model of :meth:`build_scene` at friction 0.5 and the nominal drive, in MuJoCo's binary
        format: the same design (configuration) gives the same hash, another tool another one.
        """
        from energy_margin.sim.mujoco_spec import build_model, model_hash

        return model_hash(build_model(self.build_scene(n_objects, 0.5)))

    def capture_region_shape(self, root: FrameState) -> str:
        """A word for the capture region built from ``root`` in captions: its drawn solids' kinds, else ``"region"``."""
        region = self.capture_region(root)
        if isinstance(region, DrawableRegion):
            kinds = sorted({shape.kind for shape in region.shapes()})
            if kinds:
                return " and ".join(kinds)
        return "region"

    def make_simulator(
        self,
        n_objects: int,
        friction: float,
        drive: np.ndarray | None = None,
        engine: str = "mujoco",
        *,
        device: str | None = None,
    ) -> Simulator:
        """A simulator of the task's world: :meth:`build_scene` on ``engine`` (on ``device``) by default.

        A task built on a compiled MuJoCo model overrides this to simulate that model itself.
        """
        return make_simulator(self.build_scene(n_objects, friction, drive), engine, device=device)

    def robot_dofs(self) -> int:
        """Length of the end-effector coordinates ``robot_q`` and ``robot_v`` of a frame."""
        return self.build_scene(self.fixed_objects or 1, 0.5).n_robot_dofs

    def drive_size(self) -> int:
        """Length of a trajectory's drive parameters."""
        trajectory = self.sample_trajectory(np.random.default_rng(0), self.fixed_objects or 1)
        return int(np.asarray(trajectory.drive).size)

    #: During analysis the scripted command is re-evaluated every this many seconds of a
    #: propagation; ``None`` evaluates it once at the start of each propagation.
    control_period: float | None = None

    @abstractmethod
    def capture_region(self, root: FrameState) -> Region:
        """The capture region R_cap(z_init) built from the frame being analysed."""

    def analysis_problem(self, *, batch: int) -> str | None:
        """Why this task cannot be analysed with these settings (one line), or ``None``.

        Args:
            batch: expansions per batched round (``AnalyzerConfig.batch``).
        """
        del batch
        return None

    def capture_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        """Which of M reached states of ``root``'s tree have every object captured.

        By default the capture region is the one of ``root`` (:meth:`capture_region`); a task
        whose region moves with the robot may build it at each state's own robot configuration.

        Args:
            root: the analysed frame.
            object_pos: object centres of the states, shape (M, n_objects, 3), m.
            object_vel: their velocities, shape (M, n_objects, 6), m/s and rad/s.
            object_quat: their orientations, shape (M, n_objects, 4), or ``None``.
            robot_q: the robot's coordinates at every state, shape (M, n_robot), or ``None``
                when the tree did not keep them.

        Returns:
            Shape (M,), bool.
        """
        del robot_q
        return all_inside(self.capture_region(root), object_pos, object_vel, object_quat)

    def capture_regions(self, roots: Sequence[FrameState]) -> Region:
        """The capture regions of many frames as one region over stacked positions.

        Row f of positions (F, ..., 3) (and velocities (F, ..., 6)) is measured against the region
        built from ``roots[f]``; a region that measures distances measures them the same way. By
        default one region per frame, measured frame by frame (:class:`FrameRegions`); a task whose
        region can be built for all frames at once overrides this (the learned margin's features
        measure thousands of frames per call).
        """
        return FrameRegions([self.capture_region(root) for root in roots])

    @abstractmethod
    def success_region(self) -> Region:
        """The task success region R_suc (at the task's start configuration)."""

    def success_region_at(self, root: FrameState) -> Region:
        """The success region for ``root`` (the analysed frame z_init, or the frame being labelled).

        A task whose success set moves with a body (a tray the robot carries) overrides this to
        take the body's pose in ``root``; by default the region does not depend on the frame.
        """
        del root
        return self.success_region()

    def success_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        """As :meth:`capture_inside`, for success: by default in the region of :meth:`success_region_at` ``root``."""
        del robot_q
        return all_inside(self.success_region_at(root), object_pos, object_vel, object_quat)

    @abstractmethod
    def wrench_limits(self, scene: Scene) -> WrenchLimits:
        """Perturbation ranges for ``scene`` (scaled by each object's mass and inertia)."""

    @abstractmethod
    def _state_box(self) -> StateBox:
        """The task's :class:`StateBox` (built once, by :attr:`state_box`)."""

    @property
    def state_box(self) -> StateBox:
        """Where the objects of a sane state lie and how fast they move at most.

        A tree rejects every reached state outside it, and no frame outside it becomes data.
        """
        box = self.__dict__.get("_state_box_cache")
        if box is None:
            box = self.__dict__["_state_box_cache"] = self._state_box()
        return box

    @property
    def frame_box(self) -> StateBox:
        """Where the objects of a recorded frame may physically be, and how fast they move at most.

        No frame outside it becomes data (data/physical.py). It is :attr:`state_box` unless the
        task's state box is a narrower workspace for its trees (the built-in tasks widen theirs).
        """
        return self.state_box

    def within_bounds(self, object_pos: np.ndarray, object_vel: np.ndarray) -> bool:
        """Whether a reached state lies in :attr:`state_box` (states outside are rejected).

        Args:
            object_pos: positions, shape (n_objects, 3), m.
            object_vel: velocities, shape (n_objects, 6), m/s and rad/s.
        """
        return self.state_box.contains(object_pos, object_vel)

    def is_captured(self, frame: FrameState) -> bool:
        """Whether every object of ``frame`` lies in the capture region built from ``frame``."""
        return bool(all_inside(self.capture_region(frame), frame.object_pos, frame.object_vel, frame.object_quat))

    def is_successful(self, frame: FrameState) -> bool:
        """Whether every object of ``frame`` lies in the success region."""
        return bool(all_inside(self.success_region_at(frame), frame.object_pos, frame.object_vel, frame.object_quat))

    @property
    def n_steps(self) -> int:
        """Physics steps of a scripted roll-out."""
        return round(self.config.duration / self.config.timestep)

    def frame_steps(self, n_frames: int) -> np.ndarray:
        """Steps at which frames are recorded: evenly spaced from the start to the end, shape (K,)."""
        if n_frames == 1:
            return np.array([self.n_steps])
        return np.round(np.linspace(0, self.n_steps, n_frames)).astype(int)


def with_contacts(task: Task, contacts: str) -> Task:
    """``task`` with the contact model ``contacts``.

    Args:
        task: a task, as recorded by its dataset.
        contacts: ``"recorded"`` (the task itself) or ``"fast"`` (its settings
            :attr:`TaskConfig.fast_contacts` applied).

    Raises:
        InvalidParameterError: ``contacts`` is unknown, or ``"fast"`` for a task without a fast model.

    """
    if check_choice("contacts", contacts, CONTACT_MODELS) == "recorded":
        return task
    fast = type(task.config).fast_contacts
    if not fast:
        raise InvalidParameterError(
            "contacts", f"must be 'recorded': task {task.name!r} has no fast contact model, got {contacts!r}"
        )
    current = task.config.to_dict()
    if all(current.get(key) == value for key, value in fast.items()):
        return task
    return type(task)(dataclasses.replace(task.config, **fast))
