"""Task registry: ``register_task`` adds a task class, ``get_task`` builds one by name.

Installed packages add tasks through the entry-point group ``energy_margin.tasks``: each entry
point names a :class:`Task` subclass (``my_task = "my_package.tasks:MyTask"``), registered under
its ``name`` the first time the registry is read, so ``--task my_task`` works after
``pip install my-package``.
"""

from __future__ import annotations

import sys
from importlib.metadata import entry_points
from typing import Any

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks.base import (
    DesignAlias,
    DesignParameter,
    ReferenceLayout,
    Region,
    RobotState,
    Task,
    TaskConfig,
    Trajectory,
    WrenchLimits,
    all_inside,
    command_robot,
    with_contacts,
)
from energy_margin.tasks.protocols import DesignSpace, PhysicsReadout, ScriptedMotion, TaskRegions
from energy_margin.tasks.pushing import PushingConfig, PushingTask
from energy_margin.tasks.scene_task import SceneTask, SceneTaskConfig
from energy_margin.tasks.scooping import ScoopingConfig, ScoopingTask

_REGISTRY: dict[str, type[Task]] = {}
ENTRY_POINT_GROUP = "energy_margin.tasks"
#: Entry points that could not be loaded: name -> reason (shown when the task is asked for).
_BROKEN: dict[str, str] = {}
_plugins_loaded = False


def load_plugin_tasks() -> None:
    """Register the tasks of the ``energy_margin.tasks`` entry points (once per process)."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for point in entry_points(group=ENTRY_POINT_GROUP):
        try:
            task_class = point.load()
            if not (isinstance(task_class, type) and issubclass(task_class, Task)):
                raise TypeError(f"{point.value} is not a Task subclass")
            register_task(task_class)
        except Exception as error:
            reason = " ".join(f"{type(error).__name__}: {error}".split())
            _BROKEN[point.name] = reason
            print(
                f"energy-margin: warning: task entry point {point.name!r} ({point.value}) skipped: {reason}",
                file=sys.stderr,
            )


def register_task(task_class: type[Task]) -> type[Task]:
    """Register a :class:`Task` subclass under its ``name`` (usable as a class decorator)."""
    if not getattr(task_class, "name", ""):
        # A defect of the task class (its author's code), not of a user's input.
        raise InvalidParameterError("task_class", "needs a non-empty `name`")
    _REGISTRY[task_class.name] = task_class
    return task_class


def available_tasks() -> list[str]:
    """Names of the registered tasks (built-in and from entry points)."""
    load_plugin_tasks()
    return sorted(_REGISTRY)


def task_class(name: str) -> type[Task]:
    """The registered :class:`Task` subclass ``name`` (for its class-level hooks, without building it)."""
    load_plugin_tasks()
    if name in _BROKEN and name not in _REGISTRY:
        raise EnergyMarginError(f"task {name!r} comes from an entry point that cannot be loaded: {_BROKEN[name]}")
    if name not in _REGISTRY:
        raise EnergyMarginError(f"unknown task {name!r}; available: {', '.join(available_tasks())}")
    return _REGISTRY[name]


def get_task(name: str, config: dict[str, Any] | None = None) -> Task:
    """Build the registered task ``name`` with optional configuration overrides."""
    return task_class(name).build(config)


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


def resolve_task(task: str | Task, config: dict[str, Any] | None = None) -> Task:
    """The task an entry point works on, resolved once, with ``config`` applied.

    A registered task's name is built with ``config``; a task object gets ``config`` through
    :meth:`Task.configured`. Every stage after the entry point is given the object, never the name to look up again.
    """
    if isinstance(task, Task):
        return task.configured(config)
    return get_task(task, config)


register_task(PushingTask)
register_task(ScoopingTask)
register_task(SceneTask)

__all__ = [
    "DesignAlias",
    "DesignParameter",
    "DesignSpace",
    "PhysicsReadout",
    "PushingConfig",
    "PushingTask",
    "ReferenceLayout",
    "Region",
    "RobotState",
    "SceneTask",
    "SceneTaskConfig",
    "ScoopingConfig",
    "ScoopingTask",
    "ScriptedMotion",
    "Task",
    "TaskConfig",
    "TaskRegions",
    "Trajectory",
    "WrenchLimits",
    "all_inside",
    "available_tasks",
    "command_robot",
    "get_recorded_task",
    "get_task",
    "load_plugin_tasks",
    "register_task",
    "resolve_task",
    "task_class",
    "with_contacts",
]
