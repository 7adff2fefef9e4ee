"""Task registry: ``register_task`` adds a task class, ``get_task`` builds one by name."""

from __future__ import annotations

from typing import Any

from energy_margin.errors import EnergyMarginError
from energy_margin.tasks.base import (
    Region,
    Task,
    TaskConfig,
    Trajectory,
    WrenchLimits,
    all_inside,
    command_robot,
)
from energy_margin.tasks.pushing import PushingConfig, PushingTask
from energy_margin.tasks.scene_task import SceneTask, SceneTaskConfig
from energy_margin.tasks.scooping import ScoopingConfig, ScoopingTask

_REGISTRY: dict[str, type[Task]] = {}


def register_task(task_class: type[Task]) -> type[Task]:
    """Register a :class:`Task` subclass under its ``name`` (usable as a class decorator)."""
    if not getattr(task_class, "name", ""):
        raise ValueError("a task class needs a non-empty `name`")
    _REGISTRY[task_class.name] = task_class
    return task_class


def available_tasks() -> list[str]:
    """Names of the registered tasks."""
    return sorted(_REGISTRY)


def get_task(name: str, config: dict[str, Any] | None = None) -> Task:
    """Build the registered task ``name`` with optional configuration overrides."""
    if name not in _REGISTRY:
        raise EnergyMarginError(f"unknown task {name!r}; available: {', '.join(available_tasks())}")
    try:
        return _REGISTRY[name].from_dict(config)
    except (TypeError, ValueError) as error:
        raise EnergyMarginError(f"bad configuration for task {name!r}: {error}") from None


register_task(PushingTask)
register_task(ScoopingTask)
register_task(SceneTask)

__all__ = [
    "PushingConfig",
    "PushingTask",
    "Region",
    "SceneTask",
    "SceneTaskConfig",
    "ScoopingConfig",
    "ScoopingTask",
    "Task",
    "TaskConfig",
    "Trajectory",
    "WrenchLimits",
    "all_inside",
    "available_tasks",
    "command_robot",
    "get_task",
    "register_task",
]
