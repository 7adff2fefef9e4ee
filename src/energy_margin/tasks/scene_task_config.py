"""Settings of a scene-file task: :class:`SceneTaskConfig`, and its variants with ``[design]`` parameters.

A scene file's ``[design]`` parameters become number fields of a configuration class of their own
(:func:`design_config_class`), so ``--set``, ``sweep --param`` and ``design`` treat them as they
treat a built-in task's settings.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from energy_margin.errors import constrained
from energy_margin.tasks.config import NUMBER, TaskConfig

__all__ = ["BASE_FIELDS", "SceneTaskConfig", "design_config_class", "design_overrides"]


@dataclass(frozen=True)
class SceneTaskConfig(TaskConfig):
    """Settings of a scene-file task (everything else comes from the file).

    Attributes:
        scene_file: path of the scene file (absolute once resolved).
        scene_sha256: SHA-256 of the scene file the data were made with ("" accepts any).
        model_sha256: SHA-256 of the compiled model the data were made with ("" accepts any).

    """

    scene_file: str = ""
    scene_sha256: str = ""
    model_sha256: str = ""


BASE_FIELDS = frozenset(field.name for field in dataclasses.fields(SceneTaskConfig))
_DESIGN_CONFIGS: dict[tuple[tuple[str, float], ...], type[SceneTaskConfig]] = {}


def design_config_class(values: Mapping[str, float]) -> type[SceneTaskConfig]:
    """:class:`SceneTaskConfig` with one number field per ``[design]`` parameter (defaults: ``values``).

    A configuration field per parameter lets ``--set``, ``sweep --param`` and ``design`` treat a
    scene file's design parameters as they treat a built-in task's settings.
    """
    if not values:
        return SceneTaskConfig
    key = tuple(values.items())
    if key not in _DESIGN_CONFIGS:
        fields = [(name, float, constrained(float(value), NUMBER)) for name, value in values.items()]
        _DESIGN_CONFIGS[key] = dataclasses.make_dataclass(
            "SceneDesignConfig", fields, bases=(SceneTaskConfig,), frozen=True
        )
    return _DESIGN_CONFIGS[key]


def design_overrides(config: SceneTaskConfig) -> dict[str, Any]:
    """The ``[design]`` values a configuration holds (its fields beyond :class:`SceneTaskConfig`'s)."""
    return {
        field.name: getattr(config, field.name) for field in dataclasses.fields(config) if field.name not in BASE_FIELDS
    }
