"""Settings of a task: :class:`TaskConfig`, the checks of its fields, its contact models and reference layout.

Every task's configuration is a frozen dataclass derived from :class:`TaskConfig`; its fields are
checked on construction: the type and length of the default, then each field's own
:class:`~energy_margin.errors.Constraint`, declared beside its default with
:func:`~energy_margin.errors.constrained` (a subclass that changes a default declares the
constraint again; one that does not keeps :class:`TaskConfig`'s), then the checks between fields
of :meth:`TaskConfig.check`. The shorthands :data:`POSITIVE`, :data:`NON_NEGATIVE`,
:data:`NUMBER`, :data:`RANGE` (and its variants) and :data:`EXTENTS` are the constraints most
settings take.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from energy_margin.errors import Constraint, InvalidParameterError, check_fields, constrained, field_constraint

__all__ = [
    "CONTACT_MODELS",
    "EXTENTS",
    "NON_NEGATIVE",
    "NON_NEGATIVE_RANGE",
    "NUMBER",
    "POSITIVE",
    "POSITIVE_RANGE",
    "RANGE",
    "ReferenceLayout",
    "TaskConfig",
    "require_non_negative",
    "require_positive",
    "require_ranges",
]


#: A finite number > 0.
POSITIVE = Constraint("float", minimum=0.0, exclusive_minimum=True)
#: A finite number >= 0.
NON_NEGATIVE = Constraint("float", minimum=0.0)
#: Any finite number (a position, or a setting only checked against another in ``check``).
NUMBER = Constraint("float")
#: A ``(low, high)`` pair of finite numbers with low <= high.
RANGE = Constraint("range")
#: A ``(low, high)`` pair of finite numbers >= 0 with low <= high (friction coefficients).
NON_NEGATIVE_RANGE = Constraint("range", minimum=0.0)
#: A ``(low, high)`` pair of finite numbers > 0 with low <= high (a log-uniform range).
POSITIVE_RANGE = Constraint("range", minimum=0.0, exclusive_minimum=True)
#: Three finite numbers > 0 (a box's half extents).
EXTENTS = Constraint("floats", length=3, minimum=0.0, exclusive_minimum=True)


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

    duration: float = constrained(2.0, POSITIVE)
    timestep: float = constrained(1.0 / 240.0, POSITIVE)
    likelihood_lambda: float = constrained(5.0, NON_NEGATIVE)
    max_duration: float = constrained(0.1, POSITIVE)

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
        check_fields(self)
        # A subclass that changes a default here without declaring the constraint again keeps this one.
        for field in dataclasses.fields(TaskConfig):
            if field_constraint(type(self), field.name) is None:
                field.metadata["constraint"].check(field.name, getattr(self, field.name))
        self.check()

    def check(self) -> None:
        """Raise ``InvalidParameterError`` naming the first setting that contradicts another.

        Each setting's own range is its declared constraint, checked before this.
        """
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


def _deprecated(helper: str, constraint: str) -> None:
    warnings.warn(
        f"{helper} is deprecated: declare the setting as constrained(default, {constraint}) "
        "(energy_margin.tasks.config); the helper goes in 0.3",
        DeprecationWarning,
        stacklevel=3,
    )


def require_positive(config: TaskConfig, *names: str) -> None:
    """Deprecated (goes in 0.3): declare the settings with :data:`POSITIVE` or :data:`EXTENTS`.

    Raises ``InvalidParameterError`` unless every named setting (or every entry of a tuple) is > 0.
    """
    _deprecated("require_positive", "POSITIVE")
    for name in names:
        values = np.atleast_1d(getattr(config, name))
        if np.any(values <= 0):
            raise InvalidParameterError(name, f"must be > 0, got {getattr(config, name)!r}")


def require_non_negative(config: TaskConfig, *names: str) -> None:
    """Deprecated (goes in 0.3): declare the settings with :data:`NON_NEGATIVE`.

    Raises ``InvalidParameterError`` unless every named setting (or every entry of a tuple) is >= 0.
    """
    _deprecated("require_non_negative", "NON_NEGATIVE")
    for name in names:
        values = np.atleast_1d(getattr(config, name))
        if np.any(values < 0):
            raise InvalidParameterError(name, f"must be >= 0, got {getattr(config, name)!r}")


def require_ranges(config: TaskConfig, *names: str) -> None:
    """Deprecated (goes in 0.3): declare the settings with :data:`RANGE`.

    Raises ``InvalidParameterError`` unless every named ``(low, high)`` setting has low <= high.
    """
    _deprecated("require_ranges", "RANGE")
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
