"""The scene file (TOML, ``schema_version = 1``): parsing and validation with line-exact errors.

A scene file names a user's MuJoCo model and declares what energy-margin needs beside it: the
manipulated objects, the robot's motion, the randomisation of ``generate``, the perturbation
ranges and the capture and success sets (``docs/howto/scenes.md`` lists every key, unit and default).
This module checks the file's own structure, types and ranges; the names it uses (bodies,
actuators, sites) are checked against the compiled model by :mod:`energy_margin.tasks.scene_model`.
Every problem raises :class:`~energy_margin.errors.EnergyMarginError` as one line
``FILE:LINE: KEY: message``.

This module reads the file and its top-level keys; :mod:`~energy_margin.tasks.scene_toml` holds the
TOML reading and writing with line-exact errors, :mod:`~energy_margin.tasks.scene_sections` the
readers of each section and :mod:`~energy_margin.tasks.scene_spec` the validated data and defaults
(all importable from here as before).
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks.scene_sections import (
    _read_bounds,
    _read_design,
    _read_motion,
    _read_objects,
    _read_perturbation,
    _read_randomize,
    _read_sets,
    region_names,
)
from energy_margin.tasks.scene_spec import (
    BOUNDS_MARGIN,
    DEFAULT_MAX_SPEED,
    DEFAULTED_KEYS,
    DESIGN_ELEMENTS,
    MAX_COPIES,
    RESERVED_DESIGN_NAMES,
    DesignEntry,
    Interpolation,
    Keyframe,
    MotionSpec,
    ObjectJoints,
    RobotDuringAnalysis,
    SceneSpec,
    StartSpec,
)
from energy_margin.tasks.scene_toml import (
    MAX_DEPTH,
    Locator,
    _depth,
    _Reader,
    toml_key,
    toml_value,
)

__all__ = [
    "BOUNDS_MARGIN",
    "DEFAULTED_KEYS",
    "DEFAULT_MAX_SPEED",
    "DESIGN_ELEMENTS",
    "MAX_COPIES",
    "MAX_DEPTH",
    "RESERVED_DESIGN_NAMES",
    "SCHEMA_VERSION",
    "DesignEntry",
    "Interpolation",
    "Keyframe",
    "Locator",
    "MotionSpec",
    "ObjectJoints",
    "RobotDuringAnalysis",
    "SceneSpec",
    "StartSpec",
    "read_scene_file",
    "region_names",
    "scene_spec_from_tables",
    "set_table",
    "toml_key",
    "toml_value",
]

SCHEMA_VERSION = 1


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
    mjcf = _read_header(read, document, path)
    bodies, template, count, joints = _read_objects(read, document)
    motion = _read_motion(read, document, path)
    friction, mass_scale, time_scale, start = _read_randomize(read, document)
    derive, linear, angular, max_duration, lam = _read_perturbation(read, document)
    sets, follows = _read_sets(read, document)
    low, high, max_speed = _read_bounds(read, document)
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
        capture_follows=follows["capture"],
        success_follows=follows["success"],
        derive_perturbation=derive,
        design=design,
        defaulted=_left_out(document, start, design),
    )


def _read_header(read: _Reader, document: Mapping[str, Any], path: Path) -> Path:
    """The top-level keys, ``schema_version`` and the model file ``mjcf``."""
    read.only(document, "", _TOP_KEYS)
    version = document.get("schema_version")
    if version is None:
        raise read.fail("schema_version", f"is missing (this version reads schema_version = {SCHEMA_VERSION})")
    if isinstance(version, bool) or not isinstance(version, int) or version != SCHEMA_VERSION:
        raise read.fail("schema_version", f"{version!r} is not supported (this version reads {SCHEMA_VERSION})")
    if "mjcf" not in document:
        raise read.fail("mjcf", "is missing: the path of the MuJoCo model, relative to the scene file")
    return read.file(document["mjcf"], "mjcf", path.parent)
