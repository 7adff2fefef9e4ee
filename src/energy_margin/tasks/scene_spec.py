"""The validated scene file as data: :class:`SceneSpec` and its parts, with the file's limits and defaults.

The parts are the motion and its keyframes, the start poses and the design parameters.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from energy_margin.errors import EnergyMarginError
from energy_margin.tasks.scene_toml import (
    Locator,
    _error,
)

__all__ = [
    "BOUNDS_MARGIN",
    "DEFAULTED_KEYS",
    "DEFAULT_MAX_SPEED",
    "DESIGN_ELEMENTS",
    "MAX_COPIES",
    "RESERVED_DESIGN_NAMES",
    "DesignEntry",
    "Interpolation",
    "Keyframe",
    "MotionSpec",
    "ObjectJoints",
    "RobotDuringAnalysis",
    "SceneSpec",
    "StartSpec",
]


#: Most copies of a template body (``objects.count``).
MAX_COPIES = 1000


#: ``bounds.max_speed`` when the file leaves it out, m/s: nothing on a table moves this fast (a
#: fall of 2 m ends at 6.3 m/s), and every blown-up simulation does.
DEFAULT_MAX_SPEED = 10.0
#: Without ``bounds.low`` or ``bounds.high``, the box reaches this far past the model's extent on
#: every side, m (around the bounding box of every geom at the initial state,
#: :func:`energy_margin.tasks.state_box.box_around_model`).
BOUNDS_MARGIN = 1.0


Interpolation = Literal["linear", "hold"]
ObjectJoints = Literal["free", "upright"]
RobotDuringAnalysis = Literal["declared", "still", "coasting", "recorded"]


@dataclass(frozen=True)
class Keyframe:
    """One keyframe of the robot's motion.

    Attributes:
        time: s from the start of the roll-out.
        ctrl: the model's actuator controls (nu,), or ``None`` when the motion has no controls.
        mocap: mocap body name -> (position (3,) m, quaternion (4,) ``(w, x, y, z)`` or ``None``).
        key: the keyframe's key in the file, e.g. ``"motion.keyframes[2]"``.

    """

    time: float
    ctrl: tuple[float, ...] | None
    mocap: dict[str, tuple[tuple[float, ...], tuple[float, ...] | None]]
    key: str


@dataclass(frozen=True)
class MotionSpec:
    """The robot's declared motion (identical in generation and analysis).

    Attributes:
        keyframes: keyframes in increasing time.
        ctrl_file: ``.npz`` with ``time`` (n,) s and ``ctrl`` (n, nu), instead of keyframe controls.
        interpolation: ``"linear"`` or ``"hold"`` (zero-order hold) between keyframes.
        duration: length of a roll-out, s.
        initial_keyframe: a ``<key>`` of the model that gives the robot's start, or ``None`` for
            the model's reference configuration.
        control_period: during analysis the command is re-evaluated every this many seconds, s.
        actuators: the actuators the control columns drive, in order (others get 0), or ``None``
            for every actuator of the model in its order.
        robot: ``"declared"``: during analysis the robot follows this motion; ``"still"``: the
            robot is held where each analysed frame has it; ``"coasting"``: the robot keeps each
            analysed frame's joint velocities (both for recorded states whose commands are not
            known; see :class:`~energy_margin.sim.mujoco_model.MujocoModelSimulator`);
            ``"recorded"``: the robot follows the path each roll-out was recorded on, carried in
            its drive parameters (:mod:`~energy_margin.tasks.recorded_path`).
        path_points: knots of a recorded path (``robot = "recorded"``).

    """

    keyframes: tuple[Keyframe, ...]
    ctrl_file: Path | None
    interpolation: Interpolation
    duration: float
    initial_keyframe: str | None
    control_period: float
    actuators: tuple[str, ...] | None = None
    robot: RobotDuringAnalysis = "declared"
    path_points: int = 64


@dataclass(frozen=True)
class StartSpec:
    """Object start poses of ``generate``.

    Attributes:
        mode: ``"ranges"`` (per-axis ranges and yaw) or ``"pile"`` (uniform in a box, any orientation).
        ranges: for ``"ranges"``: ``x``, ``y``, ``z`` (m) and ``yaw`` (rad) -> (low, high); a
            missing axis keeps the object's position in the start configuration: the
            ``motion.initial_keyframe``'s when the file names one, else the model's (yaw: 0).
        low: for ``"pile"``: lower corner (3,), m.
        high: for ``"pile"``: upper corner (3,), m.
        min_separation: smallest distance between object origins, m; ``None``: chosen from the
            objects' shapes (:func:`energy_margin.tasks.scene_layout.start_separation`).

    """

    mode: Literal["ranges", "pile"] = "ranges"
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    low: tuple[float, ...] | None = None
    high: tuple[float, ...] | None = None
    min_separation: float | None = None


#: Kinds of model element a ``[design]`` parameter may name (the key that names the element).
DESIGN_ELEMENTS = ("body", "geom", "site", "joint", "actuator")
#: Settings of the scene task that a design parameter must not be named as.
RESERVED_DESIGN_NAMES = frozenset(
    {"scene_file", "scene_sha256", "model_sha256", "duration", "timestep", "likelihood_lambda", "max_duration"}
)
_DESIGN_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@dataclass(frozen=True)
class DesignEntry:
    """One parameter of the ``[design]`` table: a numeric attribute of a named model element.

    Attributes:
        name: the parameter's name (``--set NAME=V``, ``design --param NAME=...``).
        kind: the element's kind, one of :data:`DESIGN_ELEMENTS`.
        element: the element's name in the model.
        attribute: the ``mujoco.MjSpec`` attribute, e.g. ``"size"``, ``"pos"``, ``"mass"``, ``"gear"``.
        index: the entry of an attribute that holds several numbers, or ``None`` for a single number.
        low: smallest value of the parameter, in the attribute's unit.
        high: largest value (above ``low``).
        default: the value without an override, or ``None`` for the model's own.
        doc: what the parameter is (empty: described by its element and attribute).

    """

    name: str
    kind: str
    element: str
    attribute: str
    index: int | None
    low: float
    high: float
    default: float | None = None
    doc: str = ""

    @property
    def key(self) -> str:
        """The parameter's key in the scene file, ``design.NAME``."""
        return f"design.{self.name}"

    def describe(self) -> str:
        """``size[0] of geom 'paddle'``."""
        where = f"[{self.index}]" if self.index is not None else ""
        return f"{self.attribute}{where} of {self.kind} {self.element!r}"


@dataclass(frozen=True)
class SceneSpec:
    """A validated scene file (see ``docs/howto/scenes.md``).

    Attributes:
        path: the scene file.
        text_sha256: SHA-256 of its text.
        mjcf: the model file.
        bodies: object body names or glob patterns (``None`` with a template).
        template: a body copied ``count`` times, or ``None``.
        count: copies of ``template``.
        object_joints: ``"free"`` (a free joint) or ``"upright"`` (slide x, y, z and hinge z);
            ``None`` (the key left out): read from the compiled model when the scene is resolved.
        motion: the robot's motion.
        friction_range: per-trajectory sliding friction of every geom, or ``None`` for the model's.
        mass_scale: per-trajectory object mass (and inertia) scale range, or ``None``.
        time_scale: per-trajectory speed-up of the motion, or ``None``.
        start: object start poses.
        linear_acceleration: perturbation force bound per world axis divided by mass, (3,), m/s^2
            (``None``: not in the file, derived from the scene by
            :func:`~energy_margin.tasks.scene_defaults.resolve_perturbation` gives its default or,
            with ``derive_perturbation``, derives it from the scene; as for the next three).
        angular_acceleration: perturbation torque bound per axis divided by inertia, (3,), rad/s^2.
        max_duration: longest perturbation propagation, s.
        likelihood_lambda: softmax inverse temperature lambda, 1/J.
        capture: the capture region table (built at the analysed frame).
        capture_at_least: capture needs at least this many objects inside, or ``None`` for every object.
        capture_follows: the capture region's body and site frames are taken at every tree node's
            own robot configuration (``capture.follow = true``), not frozen at the analysed frame;
            ``None`` where the file leaves it out, until the scene is resolved against its model:
            then true where the region is attached to a body the robot moves
            (:func:`~energy_margin.tasks.scene_follow.region_follow`).
        success_follows: the same for the success region (``success.follow``).
        derive_perturbation: ``[perturbation] derive = true``: keys left out are derived from the
            scene (tasks/scene_defaults.py) instead of taking the fixed defaults.
        success: the success region table.
        success_at_least: success needs at least this many objects inside, or ``None`` for every object.
        bounds_low: reached states with an object below this corner are rejected, and frames too,
            (3,), m; ``None`` when the file leaves it out (a box around the model, :data:`BOUNDS_MARGIN`).
        bounds_high: and above this one, (3,), m, or ``None``.
        max_speed: reached states and frames with a faster object (m/s) are rejected (default
            :data:`DEFAULT_MAX_SPEED`).
        locator: line numbers of the file's keys.
        design: the ``[design]`` parameters, in the file's order (applied to the model with
            ``MjSpec`` before it is compiled, :func:`~energy_margin.tasks.scene_model.compile_spec`).
        defaulted: the keys of :data:`DEFAULTED_KEYS` (and ``randomize.start.x`` ... ``yaw`` in
            mode ``"ranges"``, ``design.NAME.default``) that the file leaves out, so that their
            values come from a default, the model or, with ``derive_perturbation``, the scene
            (``energy-margin scene`` marks them); dotted, e.g. ``"perturbation.lambda"``.

    """

    path: Path
    text_sha256: str
    mjcf: Path
    bodies: tuple[str, ...] | None
    template: str | None
    count: int | None
    object_joints: ObjectJoints | None
    motion: MotionSpec
    friction_range: tuple[float, float] | None
    mass_scale: tuple[float, float] | None
    time_scale: tuple[float, float] | None
    start: StartSpec
    linear_acceleration: tuple[float, ...] | None
    angular_acceleration: tuple[float, ...] | None
    max_duration: float | None
    likelihood_lambda: float | None
    capture: dict[str, Any]
    capture_at_least: int | None
    success: dict[str, Any]
    success_at_least: int | None
    bounds_low: tuple[float, ...] | None
    bounds_high: tuple[float, ...] | None
    max_speed: float
    locator: Locator = field(repr=False, compare=False)
    capture_follows: bool | None = None
    success_follows: bool | None = None
    derive_perturbation: bool = False
    design: tuple[DesignEntry, ...] = ()
    defaulted: frozenset[str] = frozenset()

    def error(self, key: str, message: str) -> EnergyMarginError:
        """An error naming this file, the line of ``key`` and ``key``."""
        return _error(self.path, self.locator, key, message)


#: Keys a scene file may leave out, whose value then comes from a default (docs/howto/scenes.md "Every key");
#: besides these, an axis of ``randomize.start`` in mode ``"ranges"`` and a design parameter's ``default``.
DEFAULTED_KEYS = (
    "objects.joints",
    "motion.duration",
    "motion.interpolation",
    "motion.actuators",
    "motion.initial_keyframe",
    "motion.control_period",
    "motion.robot",
    "motion.path_points",
    "randomize.friction",
    "randomize.mass_scale",
    "randomize.time_scale",
    "randomize.start.mode",
    "randomize.start.min_separation",
    "perturbation.linear_acceleration",
    "perturbation.angular_acceleration",
    "perturbation.max_duration",
    "perturbation.lambda",
    "perturbation.derive",
    "capture.at_least",
    "capture.follow",
    "success.at_least",
    "success.follow",
    "bounds.low",
    "bounds.high",
    "bounds.max_speed",
)
