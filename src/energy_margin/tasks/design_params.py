"""The design parameters of a task's tool family: :class:`DesignParameter` axes and :class:`DesignAlias` names.

``design`` searches a task's :meth:`~energy_margin.tasks.base.Task.design_space`; ``sweep --param``
also accepts the names of its :meth:`~energy_margin.tasks.base.Task.design_aliases`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from energy_margin.errors import InvalidDataError

__all__ = ["DesignAlias", "DesignParameter"]


@dataclass(frozen=True)
class DesignAlias:
    """A design parameter that is not a configuration field itself but sets one (``sweep --param``).

    Attributes:
        name: the parameter's name on the command line.
        field: the configuration field it sets.
        doc: what the parameter is, with its unit.
        to_field: the field's value for a parameter value, given the field's current value.

    """

    name: str
    field: str
    doc: str
    to_field: Callable[[Any, Any], Any]


@dataclass(frozen=True)
class DesignParameter:
    """One axis of a task's tool family: what ``design`` searches when no ``--param`` is given.

    Exactly one of ``(low, high)`` or ``choices`` is set.

    Attributes:
        name: a ``sweep``/``design --param`` name (a configuration field or a :class:`DesignAlias`).
        doc: what the parameter is, with its unit.
        low: smallest value of a numeric range, in the parameter's unit (``None`` for a categorical one).
        high: largest value of a numeric range (``None`` for a categorical one).
        choices: the values of a categorical parameter (``None`` for a numeric one).
        integer: whether a numeric parameter takes whole values only (e.g. a number of tines).

    """

    name: str
    doc: str
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] | None = None
    integer: bool = False

    def __post_init__(self) -> None:
        if (self.choices is None) == (self.low is None or self.high is None):
            raise InvalidDataError(f"design parameter {self.name!r}: give either low and high or choices")
        if self.choices is None and not (self.low is not None and self.high is not None and self.low < self.high):
            raise InvalidDataError(f"design parameter {self.name!r}: low ({self.low}) must be below high ({self.high})")
        if self.choices is not None and len(self.choices) < 2:
            raise InvalidDataError(f"design parameter {self.name!r}: choices need at least two values")
