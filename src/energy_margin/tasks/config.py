"""Settings of a task: :class:`TaskConfig`, the checks of its fields, its contact models and reference layout.

Every task's configuration is a frozen dataclass derived from :class:`TaskConfig`; its fields are
checked on construction (type and length of the default, then the ranges of :meth:`TaskConfig.check`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from energy_margin.errors import InvalidParameterError

__all__ = [
    "CONTACT_MODELS",
    "ReferenceLayout",
    "TaskConfig",
    "require_non_negative",
    "require_positive",
    "require_ranges",
]


@dataclass(frozen=True)
class TaskConfig:
    """Settings shared by every task.

    Attributes:
        duration: length of a scripted roll-out, seconds.
        timestep: physics time step, seconds.
        likelihood_lambda: softmax inverse temperature lambda of Algorithm 1, 1/J.
        max_duration: longest perturbation propagation of the analyzer, seconds.

    """

    #: Settings added after datasets were first written, with the value those datasets used:
    #: a recorded configuration without the key gets this value (see ``get_recorded_task``).
    recorded_defaults: ClassVar[dict[str, Any]] = {}
    #: Settings that select the task's fast contact model: the same contact geometry from cheaper
    #: pairs (``AnalyzerConfig(contacts="fast")``, ``analyze --contacts fast``); empty: none.
    fast_contacts: ClassVar[dict[str, Any]] = {}

    duration: float = 2.0
    timestep: float = 1.0 / 240.0
    likelihood_lambda: float = 5.0
    max_duration: float = 0.1

    def __post_init__(self) -> None:
        # Every setting must have the type and length of its default: a number stays a finite
        # number, a range stays a pair of finite numbers.
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            default = field.default
            if isinstance(default, tuple):
                if not isinstance(value, tuple | list) or len(value) != len(default):
                    raise InvalidParameterError(field.name, f"must be a list of {len(default)} numbers, got {value!r}")
                numbers = tuple(_finite(field.name, item) for item in value)
                object.__setattr__(self, field.name, numbers)
            elif field.type in ("int", int):
                number = _finite(field.name, value)
                if not number.is_integer():
                    raise InvalidParameterError(field.name, f"must be an integer, got {value!r}")
                object.__setattr__(self, field.name, int(number))
            elif isinstance(default, int | float) and not isinstance(default, bool):
                object.__setattr__(self, field.name, _finite(field.name, value))
        self.check()

    def check(self) -> None:
        """Raise ``ValueError`` naming the first setting outside its valid range."""
        require_positive(self, "duration", "timestep", "max_duration")
        require_non_negative(self, "likelihood_lambda")
        if self.timestep > self.duration:
            raise InvalidParameterError("timestep", f"({self.timestep}) must not exceed duration ({self.duration})")

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible dictionary of every field."""
        return dataclasses.asdict(self)


CONTACT_MODELS = ("recorded", "fast")


def _finite(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidParameterError(name, f"must be a number, got {value!r}")
    if not np.isfinite(value):
        raise InvalidParameterError(name, f"must be finite, got {value!r}")
    return float(value)


def require_positive(config: TaskConfig, *names: str) -> None:
    """Raise ``ValueError`` unless every named setting (or every entry of a tuple) is > 0."""
    for name in names:
        values = np.atleast_1d(getattr(config, name))
        if np.any(values <= 0):
            raise InvalidParameterError(name, f"must be > 0, got {getattr(config, name)!r}")


def require_non_negative(config: TaskConfig, *names: str) -> None:
    """Raise ``ValueError`` unless every named setting (or every entry of a tuple) is >= 0."""
    for name in names:
        values = np.atleast_1d(getattr(config, name))
        if np.any(values < 0):
            raise InvalidParameterError(name, f"must be >= 0, got {getattr(config, name)!r}")


def require_ranges(config: TaskConfig, *names: str) -> None:
    """Raise ``ValueError`` unless every named ``(low, high)`` setting has low <= high."""
    for name in names:
        low, high = getattr(config, name)
        if low > high:
            raise InvalidParameterError(name, f"must be (low, high) with low <= high, got {getattr(config, name)!r}")


@dataclass(frozen=True)
class ReferenceLayout:
    """How the authors' published CSV files of a task read (:mod:`energy_margin.data.reference`).

    Attributes:
        suffix: their task name, the suffix of their file names (e.g. ``"PlanePushMulti"``); it
            selects the mapping of their columns onto this project's frames.
        object_columns: frame-state columns per object.
        robot_columns: frame-state columns of the end-effector, after the objects'.
        drives: the ``import-reference --drive`` values the task accepts.
        replays_recorded: whether analysis of the imported frames replays the end-effector's
            recorded motion whatever the drive (recorded as ``imported_drive = "recorded"``).

    """

    suffix: str
    object_columns: int
    robot_columns: int
    drives: tuple[str, ...] = ("nominal",)
    replays_recorded: bool = False
