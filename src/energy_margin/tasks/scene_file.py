"""The scene file (TOML, ``schema_version = 1``): parsing and validation with line-exact errors.

A scene file names a user's MuJoCo model and declares what energy-margin needs beside it: the
manipulated objects, the robot's motion, the randomisation of ``generate``, the perturbation
ranges and the capture and success sets (``docs/scenes.md`` lists every key, unit and default).
This module checks the file's own structure, types and ranges; the names it uses (bodies,
actuators, sites) are checked against the compiled model by :mod:`energy_margin.tasks.scene_model`.
Every problem raises :class:`~energy_margin.errors.EnergyMarginError` as one line
``FILE:LINE: KEY: message``.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from energy_margin.errors import EnergyMarginError, InvalidDataError, InvalidParameterError
from energy_margin.tasks.regions import REGION_TYPES

SCHEMA_VERSION = 1
#: Most copies of a template body (``objects.count``).
MAX_COPIES = 1000
#: Deepest nesting of arrays and tables in a scene file (regions nest through ``of`` and ``region``).
MAX_DEPTH = 64
#: ``bounds.max_speed`` when the file leaves it out, m/s: nothing on a table moves this fast (a
#: fall of 2 m ends at 6.3 m/s), and every blown-up simulation does.
DEFAULT_MAX_SPEED = 10.0
#: Without ``bounds.low`` or ``bounds.high``, the box reaches this far past the model's extent on
#: every side, m (around the bounding box of every geom at the initial state,
#: :func:`energy_margin.tasks.state_box.box_around_model`).
BOUNDS_MARGIN = 1.0

Interpolation = Literal["linear", "hold"]
ObjectJoints = Literal["free", "upright"]
RobotDuringAnalysis = Literal["declared", "still"]

_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"'. ]+?)\s*=")


class Locator:
    """Line numbers of the keys of a TOML text (1-based), by dotted path with array indices."""

    def __init__(self, text: str) -> None:
        """Index ``text``."""
        self.lines: dict[str, int] = {}
        table = ""
        counts: dict[str, int] = {}
        for number, line in enumerate(text.splitlines(), start=1):
            header = _HEADER.match(line)
            if header:
                name = _dotted(header.group(2))
                if header.group(1) == "[[":
                    index = counts.get(name, 0)
                    counts[name] = index + 1
                    table = f"{name}[{index}]"
                else:
                    table = name
                self.lines.setdefault(table, number)
                continue
            key = _KEY.match(line)
            if key:
                path = f"{table}.{_dotted(key.group(1))}" if table else _dotted(key.group(1))
                self.lines.setdefault(path, number)

    def line(self, path: str) -> int | None:
        """The line of ``path`` or of its nearest enclosing key that is written in the file."""
        candidate = path
        while candidate:
            if candidate in self.lines:
                return self.lines[candidate]
            stripped = re.sub(r"(\[\d+\]|\.[^.\[]+)$", "", candidate)
            if stripped == candidate:
                break
            candidate = stripped
        return None


def _dotted(text: str) -> str:
    return ".".join(part.strip().strip("\"'") for part in text.split("."))


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
            robot is held where each analysed frame has it (for recorded states whose commands
            are not known; see :class:`~energy_margin.sim.mujoco_model.MujocoModelSimulator`).

    """

    keyframes: tuple[Keyframe, ...]
    ctrl_file: Path | None
    interpolation: Interpolation
    duration: float
    initial_keyframe: str | None
    control_period: float
    actuators: tuple[str, ...] | None = None
    robot: RobotDuringAnalysis = "declared"


@dataclass(frozen=True)
class StartSpec:
    """Object start poses of ``generate``.

    Attributes:
        mode: ``"ranges"`` (per-axis ranges and yaw) or ``"pile"`` (uniform in a box, any orientation).
        ranges: for ``"ranges"``: ``x``, ``y``, ``z`` (m) and ``yaw`` (rad) -> (low, high); a
            missing axis keeps the body's model position (yaw: 0).
        low: for ``"pile"``: lower corner (3,), m.
        high: for ``"pile"``: upper corner (3,), m.
        min_separation: smallest distance between object origins, m; ``None``: twice the largest
            bounding radius of an object.

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
    """A validated scene file (see ``docs/scenes.md``).

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
            own robot configuration (``capture.follow = true``), not frozen at the analysed frame.
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
    capture_follows: bool = False
    derive_perturbation: bool = False
    design: tuple[DesignEntry, ...] = ()
    defaulted: frozenset[str] = frozenset()

    def error(self, key: str, message: str) -> EnergyMarginError:
        """An error naming this file, the line of ``key`` and ``key``."""
        return _error(self.path, self.locator, key, message)


def _error(path: Path, locator: Locator, key: str, message: str) -> EnergyMarginError:
    line = locator.line(key) if key else None
    where = f"{path}:{line}" if line is not None else str(path)
    return EnergyMarginError(" ".join(f"{where}: {key + ': ' if key else ''}{message}".split()))


class _Reader:
    """Typed access to the parsed TOML with errors that name the file, line and key."""

    def __init__(self, path: Path, locator: Locator) -> None:
        self.path = path
        self.locator = locator

    def fail(self, key: str, message: str) -> EnergyMarginError:
        return _error(self.path, self.locator, key, message)

    def table(self, parent: Mapping[str, Any], name: str, prefix: str, allowed: set[str]) -> dict[str, Any]:
        key = f"{prefix}{name}"
        value = parent.get(name, {})
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table, got {_kind(value)}")
        self.only(value, key, allowed)
        return value

    def only(self, table: Mapping[str, Any], key: str, allowed: set[str]) -> None:
        for name in table:
            if name not in allowed:
                listed = ", ".join(sorted(allowed))
                raise self.fail(f"{key}.{name}" if key else name, f"unknown key (accepted: {listed})")

    def number(self, value: Any, key: str, *, minimum: float | None = None, positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self.fail(key, f"must be a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.fail(key, f"must be > 0, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.fail(key, f"must be >= {minimum}, got {value!r}")
        return float(value)

    def integer(self, value: Any, key: str, *, minimum: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise self.fail(key, f"must be an integer >= {minimum}, got {value!r}")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"must be a non-empty string, got {value!r}")
        return value

    def file(self, value: Any, key: str, directory: Path) -> Path:
        """The absolute path of a file named by ``value``, relative to ``directory``."""
        name = self.string(value, key)
        if "\0" in name:
            raise self.fail(key, f"must be a file name without NUL characters, got {name!r}")
        try:
            return (directory / name).resolve()
        except (OSError, RuntimeError) as error:
            raise self.fail(key, f"{name!r} is not a usable file name ({error})") from None

    def vector(
        self, value: Any, key: str, length: int | None = 3, *, minimum: float | None = None
    ) -> tuple[float, ...]:
        if not isinstance(value, list) or (length is not None and len(value) != length):
            size = f"{length} numbers" if length is not None else "numbers"
            raise self.fail(key, f"must be a list of {size}, got {value!r}")
        return tuple(self.number(item, key, minimum=minimum) for item in value)

    def range(self, value: Any, key: str, *, minimum: float | None = None) -> tuple[float, float]:
        low, high = self.vector(value, key, 2, minimum=minimum)
        if low > high:
            raise self.fail(key, f"must be [low, high] with low <= high, got {value!r}")
        return low, high

    def choice(self, value: Any, key: str, choices: tuple[str, ...]) -> str:
        if value not in choices:
            raise self.fail(key, f"must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
        return str(value)


def _depth(document: Any) -> int:
    """How deep arrays and tables nest in ``document`` (a scalar is 0), without recursion."""
    deepest = 0
    pending = [(document, 0)]
    while pending:
        value, depth = pending.pop()
        children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else None
        if children is None:
            continue
        deepest = max(deepest, depth + 1)
        if deepest > MAX_DEPTH:
            break
        pending.extend((child, depth + 1) for child in children)
    return deepest


def _kind(value: Any) -> str:
    return {dict: "a table", list: "a list", str: "a string", bool: "a boolean"}.get(type(value), repr(value))


_TOP_KEYS = {
    "schema_version",
    "mjcf",
    "name",
    "objects",
    "motion",
    "randomize",
    "perturbation",
    "capture",
    "success",
    "bounds",
    "design",
}


#: Keys a scene file may leave out, whose value then comes from a default (docs/scenes.md "Every key");
#: besides these, an axis of ``randomize.start`` in mode ``"ranges"`` and a design parameter's ``default``.
DEFAULTED_KEYS = (
    "objects.joints",
    "motion.duration",
    "motion.interpolation",
    "motion.actuators",
    "motion.initial_keyframe",
    "motion.control_period",
    "motion.robot",
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
    "bounds.low",
    "bounds.high",
    "bounds.max_speed",
)


def _left_out(document: Mapping[str, Any], start: StartSpec, design: tuple[DesignEntry, ...]) -> frozenset[str]:
    """The keys with a default that the validated ``document`` leaves out (``SceneSpec.defaulted``)."""
    keys = list(DEFAULTED_KEYS)
    if start.mode == "ranges":
        keys.extend(f"randomize.start.{axis}" for axis in ("x", "y", "z", "yaw"))
    keys.extend(f"{entry.key}.default" for entry in design)
    left_out = set()
    for key in keys:
        table: Any = document
        for part in key.split("."):
            if not isinstance(table, Mapping) or part not in table:
                left_out.add(key)
                break
            table = table[part]
    return frozenset(left_out)


def read_scene_file(path: Path | str) -> SceneSpec:
    """Parse and validate the scene file at ``path`` (its model is not loaded here)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise EnergyMarginError(f"{path}: scene file does not exist") from None
    except OSError as error:
        raise EnergyMarginError(f"{path}: cannot read the scene file ({error.strerror})") from None
    try:
        text = raw.decode("utf-8")
        document = tomllib.loads(text)
    except UnicodeDecodeError:
        raise EnergyMarginError(f"{path}: the scene file is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as error:
        raise EnergyMarginError(f"{path}: not valid TOML ({error})") from None
    except RecursionError:
        raise EnergyMarginError(f"{path}: not valid TOML (arrays or tables nested too deeply)") from None
    if _depth(document) > MAX_DEPTH:
        raise EnergyMarginError(f"{path}: arrays or tables are nested more than {MAX_DEPTH} levels deep")
    return _read_document(document, path, Locator(text), hashlib.sha256(raw).hexdigest())


def scene_spec_from_tables(document: Mapping[str, Any], *, origin: str) -> SceneSpec:
    """Validate a scene file's tables given in memory (e.g. by a Gymnasium wrapper), without a file.

    Args:
        document: the tables a scene file holds (``schema_version`` and ``mjcf`` may be left out:
            the model is given beside it, and ``mjcf``, ``origin`` by default, only names it in
            messages).
        origin: what errors name instead of a file, e.g. ``"MarginWrapper(Pusher-v5)"``.

    Raises:
        EnergyMarginError: the first problem, as one line ``ORIGIN: KEY: message``.
    """
    document = {"schema_version": SCHEMA_VERSION, "mjcf": origin, **dict(document)}
    if _depth(document) > MAX_DEPTH:
        raise EnergyMarginError(f"{origin}: arrays or tables are nested more than {MAX_DEPTH} levels deep")
    digest = hashlib.sha256(json.dumps(document, sort_keys=True, default=str).encode("utf-8")).hexdigest()
    return _read_document(document, Path(origin), Locator(""), digest)


def set_table(name: str, value: Any) -> dict[str, Any]:
    """A ``[capture]`` or ``[success]`` table from the region table itself or the whole set table.

    ``{"type": ..., ...}`` is a region (a ``not`` region holds a ``region`` key too);
    ``{"region": {...}, "at_least": n}`` without a ``type`` is the set's table.

    Raises:
        InvalidParameterError: ``value`` is not a mapping (named by ``name``).
    """
    if not isinstance(value, Mapping):
        raise InvalidParameterError(name, f"must be a region table (a mapping with a type), got {value!r}")
    table = dict(value)
    if "region" in table and "type" not in table:
        return table
    return {"region": table}


def _read_document(document: Mapping[str, Any], path: Path, locator: Locator, digest: str) -> SceneSpec:
    """Validate a parsed scene document; ``path`` and ``locator`` name its keys in errors."""
    read = _Reader(path, locator)
    read.only(document, "", _TOP_KEYS)
    version = document.get("schema_version")
    if version is None:
        raise read.fail("schema_version", f"is missing (this version reads schema_version = {SCHEMA_VERSION})")
    if isinstance(version, bool) or not isinstance(version, int) or version != SCHEMA_VERSION:
        raise read.fail("schema_version", f"{version!r} is not supported (this version reads {SCHEMA_VERSION})")
    if "mjcf" not in document:
        raise read.fail("mjcf", "is missing: the path of the MuJoCo model, relative to the scene file")
    mjcf = read.file(document["mjcf"], "mjcf", path.parent)

    objects = read.table(document, "objects", "", {"bodies", "template", "count", "joints"})
    bodies: tuple[str, ...] | None = None
    template: str | None = None
    count: int | None = None
    if "template" in objects:
        if "bodies" in objects:
            raise read.fail("objects.bodies", "give either bodies or template and count, not both")
        template = read.string(objects["template"], "objects.template")
        if "count" not in objects:
            raise read.fail("objects.template", "needs objects.count, the number of copies")
        count = read.integer(objects["count"], "objects.count", minimum=1)
        if count > MAX_COPIES:
            raise read.fail("objects.count", f"must be at most {MAX_COPIES}, got {count}")
    elif "bodies" in objects:
        value = objects["bodies"]
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not value:
            raise read.fail("objects.bodies", f"must be a non-empty list of body names or patterns, got {value!r}")
        bodies = tuple(read.string(item, "objects.bodies") for item in value)
        if "count" in objects:
            raise read.fail("objects.count", "applies to objects.template only")
    else:
        raise read.fail("objects", "is missing: give objects.bodies (names or patterns) or objects.template and count")
    # Left out, the kind of the objects' joints is read from the compiled model.
    joints = read.choice(objects["joints"], "objects.joints", ("free", "upright")) if "joints" in objects else None

    motion = _read_motion(read, document, path)
    randomize = read.table(document, "randomize", "", {"friction", "mass_scale", "time_scale", "start"})
    friction = read.range(randomize["friction"], "randomize.friction", minimum=0.0) if "friction" in randomize else None
    mass_scale = _scale(read, randomize, "mass_scale")
    time_scale = _scale(read, randomize, "time_scale")
    start = _read_start(read, randomize)

    perturbation = read.table(
        document,
        "perturbation",
        "",
        {"linear_acceleration", "angular_acceleration", "max_duration", "lambda", "derive"},
    )
    derive = perturbation.get("derive", False)
    if not isinstance(derive, bool):
        raise read.fail("perturbation.derive", f"must be true or false, got {derive!r}")
    # A key left out takes its default, or with derive = true is derived from the scene once its
    # model is compiled (tasks/scene_defaults.py).
    linear = (
        read.vector(perturbation["linear_acceleration"], "perturbation.linear_acceleration", minimum=0.0)
        if "linear_acceleration" in perturbation
        else None
    )
    angular = (
        read.vector(perturbation["angular_acceleration"], "perturbation.angular_acceleration", minimum=0.0)
        if "angular_acceleration" in perturbation
        else None
    )
    max_duration = (
        read.number(perturbation["max_duration"], "perturbation.max_duration", positive=True)
        if "max_duration" in perturbation
        else None
    )
    lam = read.number(perturbation["lambda"], "perturbation.lambda", minimum=0.0) if "lambda" in perturbation else None

    sets = {}
    follows = False
    for name in ("capture", "success"):
        table = read.table(
            document, name, "", {"region", "at_least", "follow"} if name == "capture" else {"region", "at_least"}
        )
        if "follow" in table:
            if not isinstance(table["follow"], bool):
                raise read.fail(f"{name}.follow", f"must be true or false, got {table['follow']!r}")
            follows = table["follow"]
        if "region" not in table:
            raise read.fail(name, f"is missing {name}.region, the region table of the {name} set")
        region = _check_region(read, table["region"], f"{name}.region")
        at_least = read.integer(table["at_least"], f"{name}.at_least", minimum=1) if "at_least" in table else None
        sets[name] = (region, at_least)

    bounds = read.table(document, "bounds", "", {"low", "high", "max_speed"})
    low = read.vector(bounds["low"], "bounds.low") if "low" in bounds else None
    high = read.vector(bounds["high"], "bounds.high") if "high" in bounds else None
    if low is not None and high is not None and any(a >= b for a, b in zip(low, high, strict=True)):
        raise read.fail("bounds.high", f"must exceed bounds.low on every axis, got {list(low)} and {list(high)}")
    max_speed = read.number(bounds.get("max_speed", DEFAULT_MAX_SPEED), "bounds.max_speed", positive=True)
    design = _read_design(read, document)

    return SceneSpec(
        path=path,
        text_sha256=digest,
        mjcf=mjcf,
        bodies=bodies,
        template=template,
        count=count,
        object_joints=joints,  # type: ignore[arg-type]
        motion=motion,
        friction_range=friction,
        mass_scale=mass_scale,
        time_scale=time_scale,
        start=start,
        linear_acceleration=linear,
        angular_acceleration=angular,
        max_duration=max_duration,
        likelihood_lambda=lam,
        capture=sets["capture"][0],
        capture_at_least=sets["capture"][1],
        success=sets["success"][0],
        success_at_least=sets["success"][1],
        bounds_low=low,
        bounds_high=high,
        max_speed=max_speed,
        locator=locator,
        capture_follows=follows,
        derive_perturbation=derive,
        design=design,
        defaulted=_left_out(document, start, design),
    )


def _read_design(read: _Reader, document: Mapping[str, Any]) -> tuple[DesignEntry, ...]:
    """The ``[design]`` table: ``NAME = { geom = "...", attribute = "size", index = 0, low = .., high = .. }``."""
    table = document.get("design", {})
    if not isinstance(table, dict):
        raise read.fail("design", f"must be a table of design parameters, got {_kind(table)}")
    entries: list[DesignEntry] = []
    targets: dict[tuple[str, str, str, int | None], str] = {}
    allowed = {*DESIGN_ELEMENTS, "attribute", "index", "low", "high", "default", "doc"}
    for name, value in table.items():
        key = f"design.{name}"
        if not _DESIGN_NAME.fullmatch(name):
            raise read.fail(key, "a design parameter's name must be a letter or _ then letters, digits or _")
        if name in RESERVED_DESIGN_NAMES:
            raise read.fail(key, f"{name!r} is a setting of the scene task; choose another name")
        if not isinstance(value, dict):
            raise read.fail(
                key, f"must be a table {{ geom = NAME, attribute = ..., low = .., high = .. }}, got {_kind(value)}"
            )
        read.only(value, key, allowed)
        kinds = [kind for kind in DESIGN_ELEMENTS if kind in value]
        if len(kinds) != 1:
            what = "give only one of" if kinds else "needs one of"
            raise read.fail(key, f"{what} {', '.join(DESIGN_ELEMENTS)}: the element whose attribute it sets")
        kind = kinds[0]
        element = read.string(value[kind], f"{key}.{kind}")
        if "attribute" not in value:
            raise read.fail(key, "needs an attribute (a numeric attribute of the element, e.g. size, pos, mass)")
        attribute = read.string(value["attribute"], f"{key}.attribute")
        if not _DESIGN_NAME.fullmatch(attribute) or attribute.startswith("_"):
            raise read.fail(f"{key}.attribute", f"{attribute!r} is not an attribute name")
        index = read.integer(value["index"], f"{key}.index", minimum=0) if "index" in value else None
        for bound in ("low", "high"):
            if bound not in value:
                raise read.fail(key, f"needs low and high, the range of the parameter (no {bound})")
        low = read.number(value["low"], f"{key}.low")
        high = read.number(value["high"], f"{key}.high")
        if low == high:
            raise read.fail(f"{key}.high", f"the range [{low:g}, {high:g}] is empty: high must exceed low")
        if low > high:
            raise read.fail(f"{key}.high", f"the range [{low:g}, {high:g}] is inverted: high must exceed low")
        default = read.number(value["default"], f"{key}.default") if "default" in value else None
        if default is not None and not low <= default <= high:
            raise read.fail(f"{key}.default", f"{default:g} lies outside the range [{low:g}, {high:g}]")
        doc = read.string(value["doc"], f"{key}.doc") if "doc" in value else ""
        target = (kind, element, attribute, index)
        if target in targets:
            raise read.fail(key, f"sets what design.{targets[target]} sets")
        targets[target] = name
        entries.append(DesignEntry(name, kind, element, attribute, index, low, high, default, doc))
    return tuple(entries)


def _scale(read: _Reader, randomize: Mapping[str, Any], name: str) -> tuple[float, float] | None:
    if name not in randomize:
        return None
    low, high = read.range(randomize[name], f"randomize.{name}")
    if low <= 0:
        raise read.fail(f"randomize.{name}", f"must be > 0, got {randomize[name]!r}")
    return low, high


def _read_start(read: _Reader, randomize: Mapping[str, Any]) -> StartSpec:
    start = read.table(
        randomize, "start", "randomize.", {"mode", "x", "y", "z", "yaw", "low", "high", "min_separation"}
    )
    mode = read.choice(start.get("mode", "ranges"), "randomize.start.mode", ("ranges", "pile"))
    separation = (
        read.number(start["min_separation"], "randomize.start.min_separation", minimum=0.0)
        if "min_separation" in start
        else None
    )
    if mode == "pile":
        for axis in ("x", "y", "z", "yaw"):
            if axis in start:
                raise read.fail(f"randomize.start.{axis}", "applies to mode 'ranges'; a pile uses low and high")
        if "low" not in start or "high" not in start:
            raise read.fail("randomize.start.mode", "a pile needs randomize.start.low and randomize.start.high")
        low = read.vector(start["low"], "randomize.start.low")
        high = read.vector(start["high"], "randomize.start.high")
        if any(a > b for a, b in zip(low, high, strict=True)):
            raise read.fail("randomize.start.high", "must not be below randomize.start.low on any axis")
        return StartSpec("pile", {}, low, high, separation)
    for corner in ("low", "high"):
        if corner in start:
            raise read.fail(f"randomize.start.{corner}", "applies to mode 'pile'")
    ranges: dict[str, tuple[float, float]] = {
        axis: read.range(start[axis], f"randomize.start.{axis}") for axis in ("x", "y", "z", "yaw") if axis in start
    }
    return StartSpec("ranges", ranges, None, None, separation)


_MOTION_KEYS = {
    "keyframes",
    "ctrl_file",
    "interpolation",
    "duration",
    "initial_keyframe",
    "control_period",
    "actuators",
    "robot",
}


def _read_motion(read: _Reader, document: Mapping[str, Any], path: Path) -> MotionSpec:
    motion = read.table(document, "motion", "", _MOTION_KEYS)
    interpolation = read.choice(motion.get("interpolation", "linear"), "motion.interpolation", ("linear", "hold"))
    ctrl_file = read.file(motion["ctrl_file"], "motion.ctrl_file", path.parent) if "ctrl_file" in motion else None
    raw_keyframes = motion.get("keyframes", [])
    if not isinstance(raw_keyframes, list) or not all(isinstance(k, dict) for k in raw_keyframes):
        raise read.fail("motion.keyframes", "must be a list of tables ([[motion.keyframes]])")
    keyframes = []
    previous = -math.inf
    for index, raw in enumerate(raw_keyframes):
        key = f"motion.keyframes[{index}]"
        read.only(raw, key, {"time", "ctrl", "mocap"})
        if "time" not in raw:
            raise read.fail(key, "needs a time (s)")
        time = read.number(raw["time"], f"{key}.time", minimum=0.0)
        if time <= previous:
            raise read.fail(f"{key}.time", f"must increase from one keyframe to the next ({time} after {previous})")
        previous = time
        ctrl = read.vector(raw["ctrl"], f"{key}.ctrl", None) if "ctrl" in raw else None
        if ctrl is not None and ctrl_file is not None:
            raise read.fail(f"{key}.ctrl", "give controls in keyframes or in motion.ctrl_file, not both")
        mocap_table = raw.get("mocap", {})
        if not isinstance(mocap_table, dict):
            raise read.fail(f"{key}.mocap", "must be a table of mocap body name -> {pos, quat}")
        mocap: dict[str, tuple[tuple[float, ...], tuple[float, ...] | None]] = {}
        for body, pose in mocap_table.items():
            pose_key = f"{key}.mocap.{body}"
            if not isinstance(pose, dict) or "pos" not in pose:
                raise read.fail(pose_key, "must be a table with pos (3 numbers, m) and optionally quat (w, x, y, z)")
            read.only(pose, pose_key, {"pos", "quat"})
            quat = read.vector(pose["quat"], f"{pose_key}.quat", 4) if "quat" in pose else None
            if quat is not None and math.fsum(q * q for q in quat) < 1e-12:
                raise read.fail(f"{pose_key}.quat", "must not be zero")
            mocap[body] = (read.vector(pose["pos"], f"{pose_key}.pos"), quat)
        keyframes.append(Keyframe(time, ctrl, mocap, key))
    if keyframes:
        widths = {len(k.ctrl) for k in keyframes if k.ctrl is not None}
        with_ctrl = [k for k in keyframes if k.ctrl is not None]
        if with_ctrl and len(with_ctrl) != len(keyframes):
            missing = next(k for k in keyframes if k.ctrl is None)
            raise read.fail(missing.key, "has no ctrl while other keyframes have one")
        if len(widths) > 1:
            first = len(keyframes[0].ctrl or ())
            odd = next(k for k in keyframes if len(k.ctrl or ()) != first)
            raise read.fail(f"{odd.key}.ctrl", f"has {len(odd.ctrl or ())} values, the first keyframe {first}")
        names = set(keyframes[0].mocap)
        for keyframe in keyframes[1:]:
            if set(keyframe.mocap) != names:
                raise read.fail(
                    f"{keyframe.key}.mocap", f"must give the same mocap bodies as the first keyframe ({sorted(names)})"
                )
    last = keyframes[-1].time if keyframes else 0.0
    if "duration" in motion:
        duration = read.number(motion["duration"], "motion.duration", positive=True)
    elif last > 0:
        duration = last
    else:
        raise read.fail("motion.duration", "is missing (and no keyframe after t = 0 gives it)")
    initial = (
        read.string(motion["initial_keyframe"], "motion.initial_keyframe") if "initial_keyframe" in motion else None
    )
    period = read.number(motion.get("control_period", 0.01), "motion.control_period", positive=True)
    actuators = None
    if "actuators" in motion:
        value = motion["actuators"]
        if not isinstance(value, list) or not value:
            raise read.fail("motion.actuators", f"must be a non-empty list of actuator names, got {value!r}")
        actuators = tuple(read.string(item, "motion.actuators") for item in value)
    robot = read.choice(motion.get("robot", "declared"), "motion.robot", ("declared", "still"))
    return MotionSpec(
        tuple(keyframes),
        ctrl_file,
        interpolation,  # type: ignore[arg-type]
        duration,
        initial,
        period,
        actuators,
        robot,  # type: ignore[arg-type]
    )


def _check_region(read: _Reader, table: Any, key: str) -> dict[str, Any]:
    """Validate a region table recursively; returns it with numbers as floats."""
    if not isinstance(table, dict):
        raise read.fail(key, f"must be a region table with a type, got {_kind(table)}")
    if "type" not in table:
        raise read.fail(key, f"needs a type ({', '.join(sorted(REGION_TYPES))})")
    kind = table["type"]
    if not isinstance(kind, str) or kind not in REGION_TYPES:
        raise read.fail(f"{key}.type", f"unknown region type {kind!r} (known: {', '.join(sorted(REGION_TYPES))})")
    region_type = REGION_TYPES[kind]
    read.only(table, key, {"type", *region_type.keys})
    for name in region_type.required:
        if name not in table:
            raise read.fail(key, f"a {kind} region needs {name}")
    for group in region_type.one_of:
        given = [name for name in group if name in table]
        if len(given) > 1:
            raise read.fail(f"{key}.{given[1]}", f"give only one of {', '.join(group)}")
    if region_type.require_one_of and not any(name in table for name in region_type.require_one_of):
        raise read.fail(key, f"a {kind} region needs one of {', '.join(region_type.require_one_of)}")
    checked: dict[str, Any] = {"type": kind}
    for name, value in table.items():
        if name == "type":
            continue
        what = region_type.keys[name]
        sub = f"{key}.{name}"
        if what == "vector3":
            checked[name] = read.vector(value, sub)
        elif what == "number":
            checked[name] = read.number(
                value, sub, minimum=0.0 if name in ("radius", "half_height", "margin") else None
            )
        elif what in ("body", "site", "geom"):
            checked[name] = read.string(value, sub)
        elif what == "regions":
            if not isinstance(value, list) or not value:
                raise read.fail(sub, "must be a non-empty list of region tables")
            checked[name] = [_check_region(read, part, f"{sub}[{i}]") for i, part in enumerate(value)]
        elif what == "region":
            checked[name] = _check_region(read, value, sub)
    for name in ("half_size",):
        if name in checked and min(checked[name]) <= 0:
            raise read.fail(f"{key}.{name}", f"must be > 0 on every axis, got {list(checked[name])}")
    for name in ("radius", "half_height"):
        if name in checked and checked[name] <= 0:
            raise read.fail(f"{key}.{name}", f"must be > 0, got {checked[name]}")
    if "min" in checked and "max" in checked and checked["min"] > checked["max"]:
        raise read.fail(f"{key}.min", f"must not exceed max ({checked['min']} > {checked['max']})")
    return checked


def region_names(table: Mapping[str, Any], key: str) -> list[tuple[str, str, str]]:
    """Every ``(kind, name, key)`` of a body or site named in a validated region table."""
    found = []
    for name, value in table.items():
        if name in ("body", "site", "geom"):
            found.append((name, value, f"{key}.{name}"))
        elif name == "of":
            for index, part in enumerate(value):
                found.extend(region_names(part, f"{key}.of[{index}]"))
        elif name == "region":
            found.extend(region_names(value, f"{key}.region"))
    return found


# -- writing scene files -------------------------------------------------------------------


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def toml_key(key: str) -> str:
    """``key`` as a TOML key (quoted unless it is bare)."""
    return key if _BARE_KEY.fullmatch(key) else _toml_string(key)


def _toml_string(text: str) -> str:
    """``text`` as a TOML basic string (quotes, backslashes and control characters escaped)."""
    escaped = []
    for char in text:
        if char in ('"', "\\"):
            escaped.append("\\" + char)
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            escaped.append(f"\\u{ord(char):04X}")
        else:
            escaped.append(char)
    return '"' + "".join(escaped) + '"'


def toml_value(value: Any) -> str:
    """``value`` (string, number, list or table) as an inline TOML value (for writing scene files)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InvalidDataError(f"a scene file holds finite numbers, got {value}")
        return repr(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(item) for item in value) + "]"
    if isinstance(value, Mapping):
        items = ", ".join(f"{toml_key(str(key))} = {toml_value(item)}" for key, item in value.items())
        return "{ " + items + " }" if items else "{}"
    raise TypeError(f"no TOML value for {type(value).__name__}")
