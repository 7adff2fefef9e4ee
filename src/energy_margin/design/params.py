"""The one grammar of a design parameter: ``NAME=LOW:HIGH`` (a range) or ``NAME=A,B,C`` (values).

``sweep`` runs the grid of listed values (:mod:`~energy_margin.design.grid`); ``design`` searches
ranges and sets of values (:mod:`~energy_margin.design.space`). Both read their parameters here,
so a parameter written for one reads the same in the other.
"""

from __future__ import annotations

import json
import math
from typing import Any

from energy_margin.errors import InvalidParameterError

__all__ = ["DesignParam", "is_range", "parse_param"]

#: A parsed design parameter: its name and either a range ``(low, high)`` or a list of values.
DesignParam = tuple[str, "tuple[float, float] | list[Any]"]


def is_range(spec: tuple[float, float] | list[Any]) -> bool:
    """Whether a parsed parameter's ``spec`` is a range ``(low, high)`` rather than a list of values."""
    return isinstance(spec, tuple)


def parse_param(text: str) -> tuple[str, tuple[float, float] | list[Any]]:
    """``NAME=LOW:HIGH`` as ``(name, (low, high))``; ``NAME=A,B,C`` as ``(name, [A, B, C])``.

    Each listed value is JSON: a number, a string in double quotes or a list. A range's bounds are
    finite numbers, ``LOW < HIGH``. One listed value is read; whether one is enough is the
    caller's to say (a sweep takes it, a search needs two).

    Raises:
        InvalidParameterError: (``params``) no ``=``, an empty name, bounds that are not finite
            numbers, an empty or inverted range, values that are not comma-separated JSON, no values
            or a value listed twice.

    """
    name, sep, body = text.partition("=")
    name = name.strip()
    if not sep or not name:
        raise InvalidParameterError("params", f"expects NAME=LOW:HIGH or NAME=A,B,C, got {text!r}")
    if not body.strip():
        raise InvalidParameterError("params", f"{name}: no values given")
    if ":" in body and not body.lstrip().startswith(("[", "{", '"')):
        low_text, _, high_text = body.partition(":")
        try:
            low, high = float(low_text), float(high_text)
        except ValueError:
            raise InvalidParameterError("params", f"{name}: {body!r} is not a range LOW:HIGH of two numbers") from None
        if not (math.isfinite(low) and math.isfinite(high)):
            raise InvalidParameterError("params", f"{name}: the range {body!r} must have finite bounds")
        if low == high:
            raise InvalidParameterError(
                "params", f"{name}: the range {low:g}:{high:g} is empty (LOW must be below HIGH)"
            )
        if low > high:
            raise InvalidParameterError(
                "params", f"{name}: the range {low:g}:{high:g} is inverted (LOW must be below HIGH)"
            )
        return name, (low, high)
    try:
        values = json.loads(f"[{body}]")
    except json.JSONDecodeError:
        raise InvalidParameterError(
            "params",
            f"{name}: {body!r} is neither a range LOW:HIGH nor comma-separated values A,B,C "
            "(numbers, strings in double quotes or JSON lists)",
        ) from None
    for index, value in enumerate(values):
        if value in values[:index]:
            raise InvalidParameterError("params", f"{name}: value {json.dumps(value)} is listed twice")
    return name, values
