"""The readers of a scene file's sections, one per table.

Objects, motion and its keyframes, randomisation and start poses, perturbation, the capture and
success regions, bounds and design parameters.

Each reader takes the parsed document and a :class:`~energy_margin.tasks.scene_toml._Reader`, checks
its section's structure, types and ranges and returns the validated values.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, get_args

from energy_margin.tasks.regions import REGION_TYPES
from energy_margin.tasks.scene_spec import (
    _DESIGN_NAME,
    DEFAULT_MAX_SPEED,
    DESIGN_ELEMENTS,
    MAX_COPIES,
    RESERVED_DESIGN_NAMES,
    DesignEntry,
    Keyframe,
    MotionSpec,
    RobotDuringAnalysis,
    StartSpec,
)
from energy_margin.tasks.scene_toml import (
    _kind,
    _Reader,
)

__all__ = ["region_names"]


def _read_objects(
    read: _Reader, document: Mapping[str, Any]
) -> tuple[tuple[str, ...] | None, str | None, int | None, str | None]:
    """The ``[objects]`` table: ``(bodies, template, count, joints)``."""
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
    return bodies, template, count, joints


def _read_randomize(
    read: _Reader, document: Mapping[str, Any]
) -> tuple[tuple[float, float] | None, tuple[float, float] | None, tuple[float, float] | None, StartSpec]:
    """The ``[randomize]`` table: ``(friction, mass_scale, time_scale, start)``."""
    randomize = read.table(document, "randomize", "", {"friction", "mass_scale", "time_scale", "start"})
    friction = read.range(randomize["friction"], "randomize.friction", minimum=0.0) if "friction" in randomize else None
    mass_scale = _scale(read, randomize, "mass_scale")
    time_scale = _scale(read, randomize, "time_scale")
    start = _read_start(read, randomize)
    return friction, mass_scale, time_scale, start


def _read_perturbation(
    read: _Reader, document: Mapping[str, Any]
) -> tuple[bool, tuple[float, ...] | None, tuple[float, ...] | None, float | None, float | None]:
    """The ``[perturbation]`` table: ``(derive, linear, angular, max_duration, lambda)``."""
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
    return derive, linear, angular, max_duration, lam


def _read_sets(
    read: _Reader, document: Mapping[str, Any]
) -> tuple[dict[str, tuple[dict[str, Any], int | None]], dict[str, bool | None]]:
    """The ``[capture]`` and ``[success]`` tables: name -> (region, at_least), and each ``follow``.

    A ``follow`` the file leaves out is ``None``: it is resolved against the model (a region on a
    body the robot moves follows it, :mod:`~energy_margin.tasks.scene_follow`).
    """
    sets = {}
    follows: dict[str, bool | None] = {}
    for name in ("capture", "success"):
        table = read.table(document, name, "", {"region", "at_least", "follow"})
        follows[name] = None
        if "follow" in table:
            if not isinstance(table["follow"], bool):
                raise read.fail(f"{name}.follow", f"must be true or false, got {table['follow']!r}")
            follows[name] = table["follow"]
        if "region" not in table:
            raise read.fail(name, f"is missing {name}.region, the region table of the {name} set")
        region = _check_region(read, table["region"], f"{name}.region")
        at_least = read.integer(table["at_least"], f"{name}.at_least", minimum=1) if "at_least" in table else None
        sets[name] = (region, at_least)
    return sets, follows


def _read_bounds(
    read: _Reader, document: Mapping[str, Any]
) -> tuple[tuple[float, ...] | None, tuple[float, ...] | None, float]:
    """The ``[bounds]`` table: ``(low, high, max_speed)``."""
    bounds = read.table(document, "bounds", "", {"low", "high", "max_speed"})
    low = read.vector(bounds["low"], "bounds.low") if "low" in bounds else None
    high = read.vector(bounds["high"], "bounds.high") if "high" in bounds else None
    if low is not None and high is not None and any(a >= b for a, b in zip(low, high, strict=True)):
        raise read.fail("bounds.high", f"must exceed bounds.low on every axis, got {list(low)} and {list(high)}")
    max_speed = read.number(bounds.get("max_speed", DEFAULT_MAX_SPEED), "bounds.max_speed", positive=True)
    return low, high, max_speed


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
    "path_points",
}


def _read_keyframes(read: _Reader, motion: Mapping[str, Any], ctrl_file: Path | None) -> list[Keyframe]:
    """``[[motion.keyframes]]``, each checked on its own, in increasing time."""
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
    return keyframes


def _check_keyframes(read: _Reader, keyframes: list[Keyframe]) -> None:
    """The keyframes agree with each other: every one or none has ctrl, of one width, and the same mocap bodies."""
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


def _read_motion(read: _Reader, document: Mapping[str, Any], path: Path) -> MotionSpec:
    motion = read.table(document, "motion", "", _MOTION_KEYS)
    interpolation = read.choice(motion.get("interpolation", "linear"), "motion.interpolation", ("linear", "hold"))
    ctrl_file = read.file(motion["ctrl_file"], "motion.ctrl_file", path.parent) if "ctrl_file" in motion else None
    keyframes = _read_keyframes(read, motion, ctrl_file)
    _check_keyframes(read, keyframes)
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
    robot = read.choice(motion.get("robot", "declared"), "motion.robot", get_args(RobotDuringAnalysis))
    points = read.integer(motion.get("path_points", 64), "motion.path_points", minimum=2)
    if "path_points" in motion and robot != "recorded":
        raise read.fail("motion.path_points", f'applies to robot = "recorded" only (robot is {robot!r})')
    return MotionSpec(
        tuple(keyframes),
        ctrl_file,
        interpolation,  # type: ignore[arg-type]
        duration,
        initial,
        period,
        actuators,
        robot,  # type: ignore[arg-type]
        points,
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
