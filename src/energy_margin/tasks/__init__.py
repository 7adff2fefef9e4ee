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


def get_recorded_task(name: str, config: dict[str, Any] | None) -> Task:
    """The task a dataset recorded (its ``task_config``), as the release that wrote it meant it.

    A setting added after a dataset was written is absent from its record; it takes the value
    that release used (:attr:`TaskConfig.recorded_defaults`), not today's default, so an old
    dataset is analysed with the physics it was generated with.
    """
    recorded = dict(config or {})
    task_class = _REGISTRY.get(name)
    if task_class is not None:
        for key, value in task_class.config_class.recorded_defaults.items():
            recorded.setdefault(key, value)
    return get_task(name, recorded)


register_task(PushingTask)
register_task(ScoopingTask)

__all__ = [
    "PushingConfig",
    "PushingTask",
    "Region",
    "ScoopingConfig",
    "ScoopingTask",
    "Task",
    "TaskConfig",
    "Trajectory",
    "WrenchLimits",
    "all_inside",
    "available_tasks",
    "command_robot",
    "get_recorded_task",
    "get_task",
    "register_task",
]
