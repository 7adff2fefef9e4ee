"""User-facing errors and the validators of keyword arguments.

Every problem caused by the user's input (a missing dataset, a bad option, NaN in a frame) raises
:class:`EnergyMarginError`. The command line prints its message as one line and exits non-zero;
anything else is a defect in the package.

A bad keyword argument raises :class:`InvalidParameterError`, which is both an
:class:`EnergyMarginError` and a :class:`ValueError` and carries the argument's name in
``parameter``; its message starts with that name (``"seed must be a non-negative integer, got -1"``)
so the command line can say the flag instead (``"--seed must be ..."``). The ``check_*``
validators below are the one place such checks are written. A message that names another
keyword argument writes it in backticks, with a value where it needs one (```overwrite=True```,
```policy=learned```, ```out```), and never as a command-line flag: the command line writes the
flag of each (``--overwrite``, ``--policy learned``, ``--out``). Unusable content that is no
keyword argument (a file, a stored model) raises :class:`InvalidDataError`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any, TypeVar

__all__ = [
    "Constraint",
    "EnergyMarginError",
    "InvalidDataError",
    "InvalidParameterError",
    "check_choice",
    "check_fields",
    "check_float",
    "check_int",
    "check_positive_float",
    "check_positive_int",
    "check_seed",
    "constrained",
    "constrained_required",
    "field_constraint",
    "field_default",
]

_T = TypeVar("_T")


class EnergyMarginError(Exception):
    """A problem with the user's input, reported as one clear line."""


class InvalidParameterError(EnergyMarginError, ValueError):
    """A keyword argument with a bad value; ``parameter`` is its name, which starts the message."""

    def __init__(self, parameter: str, message: str) -> None:
        super().__init__(f"{parameter} {message}")
        self.parameter = parameter
        #: The message without the parameter's name ("must be >= 1, got 0").
        self.reason = message


class InvalidDataError(EnergyMarginError, ValueError):
    """Content that is not a keyword argument is unusable: a file, a stored model, an array of data.

    The message says what and where (``"scene file s.toml changed since these data were made"``);
    a bad keyword argument raises :class:`InvalidParameterError` instead.
    """


def _is_integer(value: object) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, int):
        return True
    import numpy as np

    return isinstance(value, np.integer)


def check_int(name: str, value: Any, *, minimum: int | None = None, maximum: int | None = None) -> int:
    """Return ``value`` as an ``int`` if it is an integer (not a bool) within the bounds.

    Args:
        name: the keyword argument's name, which starts the error message.
        value: the value given.
        minimum: smallest value allowed, inclusive; ``None`` for no bound.
        maximum: largest value allowed, inclusive; ``None`` for no bound.

    Raises:
        InvalidParameterError: ``value`` is not an integer or out of bounds.

    """
    if not _is_integer(value):
        raise InvalidParameterError(name, f"must be {_int_phrase(minimum, maximum)}, got {value!r}")
    number = int(value)
    if (minimum is not None and number < minimum) or (maximum is not None and number > maximum):
        raise InvalidParameterError(name, f"must be {_int_phrase(minimum, maximum)}, got {number}")
    return number


def _int_phrase(minimum: int | None, maximum: int | None) -> str:
    if minimum == 0 and maximum is None:
        return "a non-negative integer"
    if minimum == 1 and maximum is None:
        return "a positive integer"
    if minimum is not None and maximum is not None:
        return f"an integer in [{minimum}, {maximum}]"
    if minimum is not None:
        return f"an integer >= {minimum}"
    if maximum is not None:
        return f"an integer <= {maximum}"
    return "an integer"


def check_seed(value: Any, *, name: str = "seed") -> int:
    """Return a seed as an ``int``: a non-negative integer (``numpy.random.SeedSequence`` takes it)."""
    return check_int(name, value, minimum=0)


def check_float(
    name: str,
    value: Any,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: bool = False,
    exclusive_maximum: bool = False,
) -> float:
    """Return ``value`` as a finite ``float`` within the bounds.

    Args:
        name: the keyword argument's name, which starts the error message.
        value: the value given (a bool or a string is refused, even ``"1.5"``).
        minimum: lower bound; ``None`` for no bound.
        maximum: upper bound; ``None`` for no bound.
        exclusive_minimum: the lower bound itself is refused (``> minimum``).
        exclusive_maximum: the upper bound itself is refused (``< maximum``).

    Raises:
        InvalidParameterError: ``value`` is not a finite number or out of bounds.

    """
    wanted = "a finite number" + _bounds_phrase(minimum, maximum, exclusive_minimum, exclusive_maximum)
    if isinstance(value, bool | str | bytes):
        raise InvalidParameterError(name, f"must be {wanted}, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InvalidParameterError(name, f"must be {wanted}, got {value!r}") from None
    if not math.isfinite(number):
        raise InvalidParameterError(name, f"must be {wanted}, got {value!r}")
    too_low = minimum is not None and (number <= minimum if exclusive_minimum else number < minimum)
    too_high = maximum is not None and (number >= maximum if exclusive_maximum else number > maximum)
    if too_low or too_high:
        raise InvalidParameterError(name, f"must be {wanted}, got {value!r}")
    return number


def _bounds_phrase(
    minimum: float | None, maximum: float | None, exclusive_minimum: bool, exclusive_maximum: bool
) -> str:
    """The bounds in words after a noun: ``" > 0 and < 1"``, ``" >= 0"``; ``""`` for none."""
    lower = None if minimum is None else f"{'>' if exclusive_minimum else '>='} {minimum:g}"
    upper = None if maximum is None else f"{'<' if exclusive_maximum else '<='} {maximum:g}"
    phrase = " and ".join(part for part in (lower, upper) if part)
    return f" {phrase}" if phrase else ""


def check_positive_int(name: str, value: Any, *, minimum: int = 1) -> int:
    """Return ``value`` if it is an integer ``>= minimum`` (:func:`check_int` with a lower bound)."""
    return check_int(name, value, minimum=minimum)


def check_positive_float(name: str, value: Any, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float if it is finite and positive (or zero when allowed)."""
    return check_float(name, value, minimum=0.0, exclusive_minimum=not allow_zero)


def check_choice(name: str, value: Any, choices: Iterable[str]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise naming the choices."""
    options = list(choices)
    if not isinstance(value, str) or value not in options:
        raise InvalidParameterError(name, f"must be one of {', '.join(options)}, got {value!r}")
    return value


@dataclasses.dataclass(frozen=True)
class Constraint:
    """The values a keyword argument or configuration field takes, declared once beside its default.

    Attributes:
        kind: ``"int"`` (:func:`check_int`), ``"float"`` (:func:`check_float`), ``"choice"``
            (:func:`check_choice`), ``"floats"`` (a list or tuple of ``length`` numbers, each
            within the bounds: half extents, a gravity vector) or ``"range"`` (a ``(low, high)``
            pair of numbers within the bounds with ``low <= high``).
        minimum: lower bound of an ``int`` or ``float`` (of each number of ``floats`` and
            ``range``); ``None`` for none.
        maximum: upper bound; ``None`` for none.
        exclusive: a ``float``'s bounds themselves are refused (``> minimum``, ``< maximum``).
        exclusive_minimum: the lower bound itself is refused (``> minimum``) even without ``exclusive``.
        exclusive_maximum: the upper bound itself is refused (``< maximum``) even without ``exclusive``.
        choices: the values of a ``choice``.
        optional: ``None`` is allowed too.
        length: how many numbers a ``floats`` holds.
    """

    kind: str
    minimum: float | None = None
    maximum: float | None = None
    exclusive: bool = False
    exclusive_minimum: bool = False
    exclusive_maximum: bool = False
    choices: tuple[str, ...] = ()
    optional: bool = False
    length: int = 0

    def check(self, name: str, value: Any) -> Any:
        """Return ``value`` (as an ``int``, a ``float`` or a tuple of floats for those kinds) or raise naming ``name``.

        Raises:
            InvalidParameterError: ``value`` is outside the constraint.

        """
        if value is None and self.optional:
            return None
        if self.kind == "int":
            low = None if self.minimum is None else int(self.minimum)
            high = None if self.maximum is None else int(self.maximum)
            return check_int(name, value, minimum=low, maximum=high)
        if self.kind == "float":
            return self._number(name, value)
        if self.kind in ("floats", "range"):
            return self._numbers(name, value)
        return check_choice(name, value, self.choices)

    def _number(self, name: str, value: Any) -> float:
        return check_float(
            name,
            value,
            minimum=self.minimum,
            maximum=self.maximum,
            exclusive_minimum=self.exclusive or self.exclusive_minimum,
            exclusive_maximum=self.exclusive or self.exclusive_maximum,
        )

    def _numbers(self, name: str, value: Any) -> tuple[float, ...]:
        bounds = _bounds_phrase(
            self.minimum,
            self.maximum,
            self.exclusive or self.exclusive_minimum,
            self.exclusive or self.exclusive_maximum,
        )
        if self.kind == "range":
            count, wanted = 2, f"a (low, high) pair of finite numbers{bounds} with low <= high"
        else:
            count, wanted = self.length, f"{self.length} finite numbers{bounds}"
        if not isinstance(value, tuple | list) or len(value) != count:
            raise InvalidParameterError(name, f"must be {wanted}, got {value!r}")
        try:
            numbers = tuple(self._number(name, item) for item in value)
        except InvalidParameterError:
            raise InvalidParameterError(name, f"must be {wanted}, got {value!r}") from None
        if self.kind == "range" and numbers[0] > numbers[1]:
            raise InvalidParameterError(name, f"must be {wanted}, got {value!r}")
        return numbers


def constrained(default: _T, constraint: Constraint) -> _T:
    """A dataclass field with ``default`` whose values :func:`check_fields` checks against ``constraint``."""
    return dataclasses.field(default=default, metadata={"constraint": constraint})


def constrained_required(constraint: Constraint) -> Any:
    """A dataclass field without a default whose values :func:`check_fields` checks against ``constraint``."""
    return dataclasses.field(metadata={"constraint": constraint})


def field_constraint(cls: type, name: str) -> Constraint | None:
    """The :class:`Constraint` declared on field ``name`` of dataclass ``cls``; ``None`` if none."""
    field = {field.name: field for field in dataclasses.fields(cls)}[name]
    constraint = field.metadata.get("constraint")
    return constraint if isinstance(constraint, Constraint) else None


def field_default(cls: type, name: str) -> Any:
    """The default of field ``name`` of dataclass ``cls`` (what the command line takes as its own)."""
    field = {field.name: field for field in dataclasses.fields(cls)}[name]
    if field.default is dataclasses.MISSING:
        raise KeyError(f"field {name} of {cls.__name__} has no default")
    return field.default


def check_fields(instance: Any) -> None:
    """Check every field of the dataclass ``instance`` that declares a :class:`Constraint`, in order.

    Raises:
        InvalidParameterError: the first field whose value is outside its constraint.

    """
    for field in dataclasses.fields(instance):
        constraint = field.metadata.get("constraint")
        if isinstance(constraint, Constraint):
            constraint.check(field.name, getattr(instance, field.name))
