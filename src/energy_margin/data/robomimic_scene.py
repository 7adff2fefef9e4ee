"""The scene of a robomimic dataset: where its objects and sets come from, and the scene file it gets.

The objects and the capture and success sets come from a scene file's tables or from body patterns
and region tables given directly; the dataset directory gets ``source/scene.toml`` whose motion
declares what the robot does during analysis (``motion.robot``: :data:`ROBOT_DURING_ANALYSIS` by default).
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks.scene_file import SCHEMA_VERSION, scene_spec_from_tables, set_table
from energy_margin.tasks.scene_model import LoadedScene
from energy_margin.tasks.scene_spec import SceneSpec
from energy_margin.tasks.scene_toml import toml_key, toml_value

__all__ = ["MODEL_FILE", "ROBOT_CHOICES", "ROBOT_DURING_ANALYSIS", "SCENE_FILE", "SOURCE_FOLDER"]


#: The folder of the dataset directory that holds its own scene file and model.
SOURCE_FOLDER = "source"
#: The scene file written into :data:`SOURCE_FOLDER`.
SCENE_FILE = "scene.toml"
#: The model written into :data:`SOURCE_FOLDER`.
MODEL_FILE = "model.xml"
#: A demonstration's states carry no actuator commands (robomimic's actions are a controller's
#: inputs), but they carry the robot's whole joint path: by default the robot follows it during
#: analysis (``motion.robot``; docs/howto/integrations.md says what was measured).
ROBOT_DURING_ANALYSIS = "recorded"
#: What the robot may do during analysis of demonstrations (``motion.robot``).
ROBOT_CHOICES = ("recorded", "coasting", "still")


#: The scene-file tables a robomimic recording takes from a scene file.
_SCENE_TABLES = ("schema_version", "objects", "perturbation", "bounds", "capture", "success")


@dataclass(frozen=True)
class _Tables:
    """Where the objects and sets come from: a scene file's document, or the tables given."""

    document: dict[str, Any]
    from_scene: bool


def _set_tables(
    scene_file: Path | str | None,
    objects: str | Sequence[str] | None,
    capture: Mapping[str, Any] | str | None,
    success: Mapping[str, Any] | str | None,
) -> _Tables:
    """The scene tables of the objects and sets, from ``scene_file`` or from the other three."""
    if scene_file is not None:
        for name, value in (("objects", objects), ("capture", capture), ("success", success)):
            if value is not None:
                raise InvalidParameterError(name, "cannot be combined with a scene file, which gives it")
        return _Tables(_scene_document(Path(scene_file)), from_scene=True)
    for name, value in (("objects", objects), ("capture", capture), ("success", success)):
        if value is None:
            raise InvalidParameterError(
                name, "is needed without a scene file: give a scene file, or the objects, capture and success sets"
            )
    assert objects is not None and capture is not None and success is not None
    patterns = [part.strip() for part in objects.split(",")] if isinstance(objects, str) else list(objects)
    if not patterns or any(not isinstance(p, str) or not p.strip() for p in patterns):
        raise InvalidParameterError("objects", f"must be body names or patterns separated by commas, got {objects!r}")
    document = {
        "objects": {"bodies": [p.strip() for p in patterns]},
        "capture": _set_table("capture", capture),
        "success": _set_table("success", success),
    }
    return _Tables(document, from_scene=False)


def _set_table(name: str, value: Mapping[str, Any] | str) -> dict[str, Any]:
    """A set's table ``{"region": ..., "at_least": ...}`` from a region table or the set's table (JSON or mapping)."""
    if isinstance(value, str):
        try:
            value = json.loads(value)
        except (ValueError, RecursionError) as error:
            raise InvalidParameterError(name, f"is not valid JSON ({error})") from None
    return set_table(name, value)


def _scene_document(path: Path) -> dict[str, Any]:
    """The tables of the scene file at ``path`` that apply to a recording (see :data:`_SCENE_TABLES`)."""
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise EnergyMarginError(f"{path}: scene file does not exist") from None
    except OSError as error:
        raise EnergyMarginError(f"{path}: cannot read the scene file ({error.strerror})") from None
    except UnicodeDecodeError:
        raise EnergyMarginError(f"{path}: the scene file is not UTF-8 text") from None
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise EnergyMarginError(f"{path}: not valid TOML ({error})") from None
    except RecursionError:
        raise EnergyMarginError(f"{path}: not valid TOML (arrays or tables nested too deeply)") from None
    objects = document.get("objects")
    if isinstance(objects, dict) and "template" in objects:
        raise EnergyMarginError(
            f"{path}: objects.template: a recorded model is used as it is: name its object bodies in objects.bodies"
        )
    return {key: document[key] for key in _SCENE_TABLES if key in document}


def _scene_spec(
    tables: _Tables, scene_file: Path | str | None, path: Path, duration: float, robot: str = ROBOT_DURING_ANALYSIS
) -> SceneSpec:
    """The validated scene of the recording (its ``mjcf`` names the HDF5 file in messages)."""
    document = dict(tables.document)
    document["mjcf"] = str(path.resolve())
    document["motion"] = {"duration": duration, "robot": robot}
    origin = str(scene_file) if scene_file is not None else "record options"
    return scene_spec_from_tables(document, origin=origin)


def _scene_text(spec: SceneSpec, loaded: LoadedScene, duration: float) -> str:
    """The scene file of the dataset's ``source`` folder (TOML)."""
    document: dict[str, Any] = {
        "objects": {"bodies": list(loaded.object_names), "joints": loaded.spec.object_joints},
        "motion": {"duration": duration, "robot": spec.motion.robot},
        "perturbation": {
            "linear_acceleration": list(loaded.perturbation.linear_acceleration),
            "angular_acceleration": list(loaded.perturbation.angular_acceleration),
            "max_duration": loaded.perturbation.max_duration,
            "lambda": loaded.perturbation.likelihood_lambda,
        },
        "bounds": {
            **({"low": list(spec.bounds_low)} if spec.bounds_low is not None else {}),
            **({"high": list(spec.bounds_high)} if spec.bounds_high is not None else {}),
            "max_speed": spec.max_speed,
        },
        "capture": _with_at_least(spec.capture, spec.capture_at_least),
        "success": _with_at_least(spec.success, spec.success_at_least),
    }
    lines = [
        "# The scene of demonstrations recorded with energy-margin record --format robomimic.",
        f"schema_version = {SCHEMA_VERSION}",
        f"mjcf = {toml_value(MODEL_FILE)}",
    ]
    for table, values in document.items():
        lines.extend(["", f"[{table}]"])
        lines.extend(f"{toml_key(key)} = {toml_value(value)}" for key, value in values.items())
    return "\n".join(lines) + "\n"


def _with_at_least(region: dict[str, Any], at_least: int | None) -> dict[str, Any]:
    return {"region": region} if at_least is None else {"region": region, "at_least": at_least}
