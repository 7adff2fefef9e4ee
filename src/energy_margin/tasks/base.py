"""What a task is: its world, its scripted manipulation, and the meaning of capture and success.

A task never runs physics itself and never grows trees: the data generator drives a
:class:`~energy_margin.sim.base.Simulator` with the task's scripted forces, and the analyzer asks
the task which reached states are captured or successful. Tasks are registered by name in
:mod:`energy_margin.tasks` so a user can add one without editing the core.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidDataError, InvalidParameterError, check_choice
from energy_margin.sim import make_simulator
from energy_margin.sim.base import ModelCommand, Simulator
from energy_margin.tasks.state_box import StateBox
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


class Region(Protocol):
    """A region of object states: centre-of-mass positions and, where it matters, velocities."""

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each object state lies inside.

        Args:
            positions: shape (..., 3), metres, world frame.
            velocities: linear then angular velocities, shape (..., 6), m/s and rad/s, world
                frame; ``None`` when unknown (a region that needs them then treats the objects
                as at rest).

        Returns:
            Boolean array of shape (...).

        """
        ...


@runtime_checkable
class MeasurableRegion(Region, Protocol):
    """A region that also tells how far object positions are from its boundary."""

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of each position (..., 3) to the boundary: > 0 inside, < 0 outside, 0 on it."""
        ...


class FrameRegions:
    """One region per frame, measured row by row: the default of :meth:`Task.capture_regions`.

    Args:
        regions: the region of each of F frames.
    """

    def __init__(self, regions: Sequence[Region]) -> None:
        self.regions = list(regions)
        # all_inside passes orientations on when some frame's region tests them (a contact test).
        self.uses_orientation = any(getattr(region, "uses_orientation", False) for region in self.regions)

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Whether row f of positions (F, ..., 3) lies in frame f's region; shape (F, ...).

        ``quaternions`` (F, ..., 4) go to the regions that test orientations.
        """
        rows = []
        for f, region in enumerate(self.regions):
            velocity = None if velocities is None else velocities[f]
            if quaternions is not None and getattr(region, "uses_orientation", False):
                rows.append(region.contains(positions[f], velocity, quaternions=quaternions[f]))  # type: ignore[call-arg]
            else:
                rows.append(region.contains(positions[f], velocity))
        return np.stack(rows)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of row f of positions (F, ..., 3) to frame f's region; 0 where it measures none."""
        return np.stack(
            [
                np.asarray(region.signed_distance(positions[f]), dtype=float)
                if isinstance(region, MeasurableRegion)
                else np.zeros(np.shape(positions[f])[:-1])
                for f, region in enumerate(self.regions)
            ]
        )


@dataclass(frozen=True)
class RegionShape:
    """One solid of a region's drawing (pictures only: :meth:`Region.contains` decides membership).

    Attributes:
        kind: ``"box"`` or ``"cylinder"`` (axis along world z).
        centre: centre of the solid, shape (3,), m, world frame.
        half_size: box half extents (x, y, z) before the yaw, or cylinder (radius, half height, 0), m.
        yaw: rotation about world z, rad.

    """

    kind: str
    centre: tuple[float, float, float]
    half_size: tuple[float, float, float]
    yaw: float = 0.0

    def __post_init__(self) -> None:
        check_choice("kind", self.kind, ("box", "cylinder"))

    def contains(self, positions: np.ndarray) -> np.ndarray:
        """Whether each position (..., 3), m, lies in the solid; shape (...)."""
        relative = np.asarray(positions, dtype=float) - np.asarray(self.centre)
        cos, sin = np.cos(self.yaw), np.sin(self.yaw)
        local_x = cos * relative[..., 0] + sin * relative[..., 1]
        local_y = -sin * relative[..., 0] + cos * relative[..., 1]
        within_z = np.abs(relative[..., 2]) <= self.half_size[2 if self.kind == "box" else 1]
        if self.kind == "cylinder":
            return (np.hypot(local_x, local_y) <= self.half_size[0]) & within_z
        return (np.abs(local_x) <= self.half_size[0]) & (np.abs(local_y) <= self.half_size[1]) & within_z


@runtime_checkable
class DrawableRegion(Region, Protocol):
    """A region that can be drawn as a union of solids (renders, interactive views)."""

    def shapes(self) -> tuple[RegionShape, ...]:
        """Solids whose union draws the region (unbounded sides cut off).

        A region that ignores height (a planar task's) is drawn as its footprint: thin solids on
        the floor under the objects, whose horizontal extent matches ``contains``.
        """
        ...


def all_inside(
    region: Region,
    object_positions: np.ndarray,
    object_velocities: np.ndarray | None = None,
    object_quaternions: np.ndarray | None = None,
) -> np.ndarray:
    """True where every object of a state lies in ``region``.

    Args:
        region: the region.
        object_positions: shape (..., n_objects, 3), metres.
        object_velocities: shape (..., n_objects, 6), m/s and rad/s, or ``None``.
        object_quaternions: shape (..., n_objects, 4), ``(w, x, y, z)``, or ``None``; passed on to a
            region whose ``uses_orientation`` attribute is true (e.g. a contact test).

    Returns:
        Boolean array of shape (...).

    """
    if object_quaternions is not None and getattr(region, "uses_orientation", False):
        inside = region.contains(object_positions, object_velocities, quaternions=object_quaternions)  # type: ignore[call-arg]
    else:
        inside = region.contains(object_positions, object_velocities)
    return np.all(inside, axis=-1)


@dataclass(frozen=True)
class Trajectory:
    """The randomised start of one scripted roll-out.

    Attributes:
        initial: the initial frame state.
        friction: Coulomb coefficient of every contact in this trajectory.
        drive: task-defined parameters of the scripted end-effector motion, shape (n_drive,).

    """

    initial: FrameState
    friction: float
    drive: np.ndarray


@dataclass(frozen=True)
class WrenchLimits:
    """Uniform perturbation ranges of one analysis.

    Attributes:
        max_wrench: per-object bound on |force| (N) and |torque| (N m) per world axis, shape
            (n_objects, 6); a zero entry is never perturbed.
        max_duration: longest propagation, seconds.

    """

    max_wrench: np.ndarray
    max_duration: float

    @property
    def control_dimension(self) -> int:
        """Number of perturbed wrench components (sets the duration bias)."""
        return int(np.count_nonzero(self.max_wrench))


@dataclass(frozen=True)
class TaskConfig:
    """Settings shared by every task.

    Attributes:
        duration: length of a scripted roll-out, seconds.
        timestep: physics time step, seconds.
        likelihood_lambda: softmax inverse temperature lambda of Algorithm 1, 1/J.
        max_duration: longest perturbation propagation of the analyzer, seconds.

    """

    #: Settings added after datasets were first written, with the value those datasets used:
    #: a recorded configuration without the key gets this value (see ``get_recorded_task``).
    recorded_defaults: ClassVar[dict[str, Any]] = {}
    #: Settings that select the task's fast contact model: the same contact geometry from cheaper
    #: pairs (``AnalyzerConfig(contacts="fast")``, ``analyze --contacts fast``); empty: none.
    fast_contacts: ClassVar[dict[str, Any]] = {}

    duration: float = 2.0
    timestep: float = 1.0 / 240.0
    likelihood_lambda: float = 5.0
    max_duration: float = 0.1

    def __post_init__(self) -> None:
        # Every setting must have the type and length of its default: a number stays a finite
        # number, a range stays a pair of finite numbers.
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            default = field.default
            if isinstance(default, tuple):
                if not isinstance(value, tuple | list) or len(value) != len(default):
                    raise InvalidParameterError(field.name, f"must be a list of {len(default)} numbers, got {value!r}")
                numbers = tuple(_finite(field.name, item) for item in value)
                object.__setattr__(self, field.name, numbers)
            elif field.type in ("int", int):
                number = _finite(field.name, value)
                if not number.is_integer():
                    raise InvalidParameterError(field.name, f"must be an integer, got {value!r}")
                object.__setattr__(self, field.name, int(number))
            elif isinstance(default, int | float) and not isinstance(default, bool):
                object.__setattr__(self, field.name, _finite(field.name, value))
        self.check()

    def check(self) -> None:
        """Raise ``ValueError`` naming the first setting outside its valid range."""
        require_positive(self, "duration", "timestep", "max_duration")
        require_non_negative(self, "likelihood_lambda")
        if self.timestep > self.duration:
            raise InvalidParameterError("timestep", f"({self.timestep}) must not exceed duration ({self.duration})")

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible dictionary of every field."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class DesignAlias:
    """A design parameter that is not a configuration field itself but sets one (``sweep --param``).

    Attributes:
        name: the parameter's name on the command line.
        field: the configuration field it sets.
        doc: what the parameter is, with its unit.
        to_field: the field's value for a parameter value, given the field's current value.

    """

    name: str
    field: str
    doc: str
    to_field: Callable[[Any, Any], Any]


@dataclass(frozen=True)
class DesignParameter:
    """One axis of a task's tool family: what ``design`` searches when no ``--param`` is given.

    Exactly one of ``(low, high)`` or ``choices`` is set.

    Attributes:
        name: a ``sweep``/``design --param`` name (a configuration field or a :class:`DesignAlias`).
        doc: what the parameter is, with its unit.
        low: smallest value of a numeric range, in the parameter's unit (``None`` for a categorical one).
        high: largest value of a numeric range (``None`` for a categorical one).
        choices: the values of a categorical parameter (``None`` for a numeric one).
        integer: whether a numeric parameter takes whole values only (e.g. a number of tines).

    """

    name: str
    doc: str
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] | None = None
    integer: bool = False

    def __post_init__(self) -> None:
        if (self.choices is None) == (self.low is None or self.high is None):
            raise InvalidDataError(f"design parameter {self.name!r}: give either low and high or choices")
        if self.choices is None and not (self.low is not None and self.high is not None and self.low < self.high):
            raise InvalidDataError(f"design parameter {self.name!r}: low ({self.low}) must be below high ({self.high})")
        if self.choices is not None and len(self.choices) < 2:
            raise InvalidDataError(f"design parameter {self.name!r}: choices need at least two values")


@dataclass(frozen=True)
class ReferenceLayout:
    """How the authors' published CSV files of a task read (:mod:`energy_margin.data.reference`).

    Attributes:
        suffix: their task name, the suffix of their file names (e.g. ``"PlanePushMulti"``); it
            selects the mapping of their columns onto this project's frames.
        object_columns: frame-state columns per object.
        robot_columns: frame-state columns of the end-effector, after the objects'.
        drives: the ``import-reference --drive`` values the task accepts.
        replays_recorded: whether analysis of the imported frames replays the end-effector's
            recorded motion whatever the drive (recorded as ``imported_drive = "recorded"``).

    """

    suffix: str
    object_columns: int
    robot_columns: int
    drives: tuple[str, ...] = ("nominal",)
    replays_recorded: bool = False


CONTACT_MODELS = ("recorded", "fast")


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


def _finite(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidParameterError(name, f"must be a number, got {value!r}")
    if not np.isfinite(value):
        raise InvalidParameterError(name, f"must be finite, got {value!r}")
    return float(value)


def require_positive(config: TaskConfig, *names: str) -> None:
    """Raise ``ValueError`` unless every named setting (or every entry of a tuple) is > 0."""
    for name in names:
        values = np.atleast_1d(getattr(config, name))
        if np.any(values <= 0):
            raise InvalidParameterError(name, f"must be > 0, got {getattr(config, name)!r}")


def require_non_negative(config: TaskConfig, *names: str) -> None:
    """Raise ``ValueError`` unless every named setting (or every entry of a tuple) is >= 0."""
    for name in names:
        values = np.atleast_1d(getattr(config, name))
        if np.any(values < 0):
            raise InvalidParameterError(name, f"must be >= 0, got {getattr(config, name)!r}")


def require_ranges(config: TaskConfig, *names: str) -> None:
    """Raise ``ValueError`` unless every named ``(low, high)`` setting has low <= high."""
    for name in names:
        low, high = getattr(config, name)
        if low > high:
            raise InvalidParameterError(name, f"must be (low, high) with low <= high, got {getattr(config, name)!r}")


class Task(ABC):
    """Base class of a manipulation task."""

    name: ClassVar[str]
    config_class: ClassVar[type[TaskConfig]] = TaskConfig

    def __init__(self, config: TaskConfig | None = None) -> None:
        self.config = config if config is not None else self.config_class()

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
    def robot_force(
        self,
        drive: np.ndarray,
        time: float,
        robot_q: np.ndarray,
        robot_v: np.ndarray,
        rng: np.random.Generator | None,
    ) -> np.ndarray:
        """Generalized end-effector forces at ``time`` (s) of a roll-out with parameters ``drive``.

        With ``rng`` the scripted roll-out's random variation is drawn; with ``None`` the nominal
        (expected) force is returned, which the analyzer applies while it perturbs the objects.
        """

    def robot_targets(
        self,
        drive: np.ndarray,
        time: float,
        robot_q: np.ndarray,
        robot_v: np.ndarray,
        rng: np.random.Generator | None,
    ) -> np.ndarray | None:
        """Servo targets (n_robot_dofs,) at ``time`` (s), or ``None`` for a task without servos.

        Called after :meth:`robot_force` with the same arguments (and the same ``rng``).
        """
        del drive, time, robot_q, robot_v, rng
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
        """This task with ``overrides`` applied to its configuration (one design of it); itself without any.

        A design, a sweep's grid point or a verification episode is the resolved task with some
        settings changed: it is built from this object (:meth:`from_dict` of its settings and
        ``overrides``), not looked up by name again.

        Raises:
            EnergyMarginError: an unknown setting or an invalid configuration, naming the task.

        """
        if not overrides:
            return self
        try:
            return type(self).from_dict({**self._settings(), **overrides})
        except InvalidParameterError as error:
            raise InvalidParameterError(error.parameter, f"{error.reason} (task {self.name!r})") from None
        except (TypeError, ValueError) as error:
            raise EnergyMarginError(f"bad configuration for task {self.name!r}: {error}") from None

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
        self, n_objects: int, friction: float, drive: np.ndarray | None = None, engine: str = "mujoco"
    ) -> Simulator:
        """A simulator of the task's world: :meth:`build_scene` on ``engine`` by default.

        A task built on a compiled MuJoCo model overrides this to simulate that model itself.
        """
        return make_simulator(self.build_scene(n_objects, friction, drive), engine)

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


def command_robot(
    task: Task, simulator: Simulator, drive: np.ndarray, time: float, rng: np.random.Generator | None
) -> None:
    """Hold the task's scripted command at ``time`` (s) on the simulator's end-effector.

    Sets the generalized forces of :meth:`Task.robot_force`, then, for a task with servos, the
    targets of :meth:`Task.robot_targets`; both see the current joint positions and velocities.
    A task on a user's model then sets its :meth:`Task.model_command`.
    Used identically by the data generator (every step, with ``rng``) and the analyzer (with
    ``None``).
    """
    robot_q, robot_v = simulator.robot_positions(), simulator.robot_velocities()
    simulator.set_robot_force(task.robot_force(drive, time, robot_q, robot_v, rng))
    targets = task.robot_targets(drive, time, robot_q, robot_v, rng)
    if targets is not None:
        simulator.set_robot_targets(targets)
    command = task.model_command(drive, time)
    if command is not None:
        command.apply_to(simulator, purpose=f"task {task.name!r}")


def sample_separated(
    rng: np.random.Generator, count: int, low: np.ndarray, high: np.ndarray, separation: float
) -> np.ndarray:
    """``count`` points uniform in the box [low, high] with pairwise distance > ``separation``.

    Rejection sampling, one candidate (``rng.uniform(low, high)``) at a time.

    Args:
        rng: random generator.
        count: number of points.
        low: lower corner, shape (d,).
        high: upper corner, shape (d,).
        separation: smallest distance between two points (same unit as the box).

    Returns:
        Points, shape (count, d).

    Raises:
        InvalidDataError: when 100 000 candidates do not suffice.

    """
    points = np.empty((count, len(low)))
    placed = 0
    attempts = 0
    while placed < count:
        attempts += 1
        if attempts > 100_000:
            raise InvalidDataError(f"cannot place {count} objects {separation} m apart in the spawn area")
        candidate = rng.uniform(low, high)
        if placed == 0 or np.min(np.linalg.norm(points[:placed] - candidate, axis=1)) > separation:
            points[placed] = candidate
            placed += 1
    return points
