"""The types of a task's scripted motion: a roll-out's start and the end-effector state its hooks see.

:meth:`~energy_margin.tasks.base.Task.sample_trajectory` draws a :class:`Trajectory`; at every
step :func:`~energy_margin.tasks.command.command_robot` hands the task's ``robot_force`` and
``robot_targets`` hooks a :class:`RobotState`. Hooks still written with the old five arguments
are adapted here (:func:`adapt_legacy_robot_hooks`).
"""

from __future__ import annotations

import functools
import inspect
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.errors import InvalidDataError
from energy_margin.world.state import FrameState, RobotState

__all__ = [
    "ROBOT_HOOKS",
    "RobotState",
    "Trajectory",
    "adapt_legacy_robot_hooks",
    "sample_separated",
]


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


#: The hooks that take a :class:`RobotState`: ``hook(state, rng)``.
ROBOT_HOOKS = ("robot_force", "robot_targets")
#: Positional parameters of a hook of the old signature ``(drive, time, robot_q, robot_v, rng)``.
_LEGACY_ARGUMENTS = 5


def adapt_legacy_robot_hooks(cls: type) -> None:
    """Adapt the :data:`ROBOT_HOOKS` of ``cls`` still written ``(drive, time, robot_q, robot_v, rng)``.

    Such a hook (a task class of another package) is wrapped to take ``(state, rng)``, and one
    ``DeprecationWarning`` names the class and its hooks; the old signature is accepted for one release. A call
    with the old five arguments still reaches the wrapped hook unchanged.
    """
    legacy = [
        hook
        for hook in ROBOT_HOOKS
        if inspect.isfunction(cls.__dict__.get(hook)) and _takes_legacy_arguments(cls.__dict__[hook])
    ]
    if not legacy:
        return
    warnings.warn(
        f"task class {cls.__module__}.{cls.__qualname__}: {' and '.join(legacy)} "
        f"{'takes' if len(legacy) == 1 else 'take'} (drive, time, robot_q, "
        f"robot_v, rng); write them (state: RobotState, rng): the old signature is accepted for one release",
        DeprecationWarning,
        stacklevel=4,
    )
    for hook in legacy:
        setattr(cls, hook, _adapted(cls.__dict__[hook]))


def _takes_legacy_arguments(method: Callable[..., Any]) -> bool:
    try:
        parameters = list(inspect.signature(method).parameters.values())[1:]
    except (TypeError, ValueError):
        return False
    positional = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return sum(parameter.kind in positional for parameter in parameters) >= _LEGACY_ARGUMENTS


def _adapted(method: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(method)
    def hook(self: Any, state: Any, rng: Any = None, *legacy: Any) -> Any:
        if legacy or not isinstance(state, RobotState):
            return method(self, state, rng, *legacy)
        return method(self, state.drive, state.time, state.q, state.v, rng)

    return hook


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
