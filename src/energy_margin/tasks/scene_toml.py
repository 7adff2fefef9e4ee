"""TOML for scene files: line numbers of keys, typed reading with line-exact errors, and inline values for writing.

:class:`Locator` finds the line of a dotted key in a TOML text; :class:`_Reader` reads typed values
from parsed tables and raises :class:`~energy_margin.errors.EnergyMarginError` as one line
``FILE:LINE: KEY: message``; :func:`toml_value` and :func:`toml_key` write inline TOML.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from energy_margin.errors import EnergyMarginError, InvalidDataError

__all__ = ["MAX_DEPTH", "Locator", "toml_key", "toml_value"]


#: Deepest nesting of arrays and tables in a scene file (regions nest through ``of`` and ``region``).
MAX_DEPTH = 64


_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"'. ]+?)\s*=")


class Locator:
    """Line numbers of the keys of a TOML text (1-based), by dotted path with array indices."""

    def __init__(self, text: str) -> None:
        """Index ``text``."""
        self.lines: dict[str, int] = {}
        table = ""
        counts: dict[str, int] = {}
        for number, line in enumerate(text.splitlines(), start=1):
            header = _HEADER.match(line)
            if header:
                name = _dotted(header.group(2))
                if header.group(1) == "[[":
                    index = counts.get(name, 0)
                    counts[name] = index + 1
                    table = f"{name}[{index}]"
                else:
                    table = name
                self.lines.setdefault(table, number)
                continue
            key = _KEY.match(line)
            if key:
                path = f"{table}.{_dotted(key.group(1))}" if table else _dotted(key.group(1))
                self.lines.setdefault(path, number)

    def line(self, path: str) -> int | None:
        """The line of ``path`` or of its nearest enclosing key that is written in the file."""
        candidate = path
        while candidate:
            if candidate in self.lines:
                return self.lines[candidate]
            stripped = re.sub(r"(\[\d+\]|\.[^.\[]+)$", "", candidate)
            if stripped == candidate:
                break
            candidate = stripped
        return None


def _dotted(text: str) -> str:
    return ".".join(part.strip().strip("\"'") for part in text.split("."))


def _error(path: Path, locator: Locator, key: str, message: str) -> EnergyMarginError:
    line = locator.line(key) if key else None
    where = f"{path}:{line}" if line is not None else str(path)
    return EnergyMarginError(" ".join(f"{where}: {key + ': ' if key else ''}{message}".split()))


class _Reader:
    """Typed access to the parsed TOML with errors that name the file, line and key."""

    def __init__(self, path: Path, locator: Locator) -> None:
        self.path = path
        self.locator = locator

    def fail(self, key: str, message: str) -> EnergyMarginError:
        return _error(self.path, self.locator, key, message)

    def table(self, parent: Mapping[str, Any], name: str, prefix: str, allowed: set[str]) -> dict[str, Any]:
        key = f"{prefix}{name}"
        value = parent.get(name, {})
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table, got {_kind(value)}")
        self.only(value, key, allowed)
        return value

    def only(self, table: Mapping[str, Any], key: str, allowed: set[str]) -> None:
        for name in table:
            if name not in allowed:
                listed = ", ".join(sorted(allowed))
                raise self.fail(f"{key}.{name}" if key else name, f"unknown key (accepted: {listed})")

    def number(self, value: Any, key: str, *, minimum: float | None = None, positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self.fail(key, f"must be a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.fail(key, f"must be > 0, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.fail(key, f"must be >= {minimum}, got {value!r}")
        return float(value)

    def integer(self, value: Any, key: str, *, minimum: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise self.fail(key, f"must be an integer >= {minimum}, got {value!r}")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"must be a non-empty string, got {value!r}")
        return value

    def file(self, value: Any, key: str, directory: Path) -> Path:
        """The absolute path of a file named by ``value``, relative to ``directory``."""
        name = self.string(value, key)
        if "\0" in name:
            raise self.fail(key, f"must be a file name without NUL characters, got {name!r}")
        try:
            return (directory / name).resolve()
        except (OSError, RuntimeError) as error:
            raise self.fail(key, f"{name!r} is not a usable file name ({error})") from None

    def vector(
        self, value: Any, key: str, length: int | None = 3, *, minimum: float | None = None
    ) -> tuple[float, ...]:
        if not isinstance(value, list) or (length is not None and len(value) != length):
            size = f"{length} numbers" if length is not None else "numbers"
            raise self.fail(key, f"must be a list of {size}, got {value!r}")
        return tuple(self.number(item, key, minimum=minimum) for item in value)

    def range(self, value: Any, key: str, *, minimum: float | None = None) -> tuple[float, float]:
        low, high = self.vector(value, key, 2, minimum=minimum)
        if low > high:
            raise self.fail(key, f"must be [low, high] with low <= high, got {value!r}")
        return low, high

    def choice(self, value: Any, key: str, choices: tuple[str, ...]) -> str:
        if value not in choices:
            raise self.fail(key, f"must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
        return str(value)


def _depth(document: Any) -> int:
    """How deep arrays and tables nest in ``document`` (a scalar is 0), without recursion."""
    deepest = 0
    pending = [(document, 0)]
    while pending:
        value, depth = pending.pop()
        children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else None
        if children is None:
            continue
        deepest = max(deepest, depth + 1)
        if deepest > MAX_DEPTH:
            break
        pending.extend((child, depth + 1) for child in children)
    return deepest


def _kind(value: Any) -> str:
    return {dict: "a table", list: "a list", str: "a string", bool: "a boolean"}.get(type(value), repr(value))


# -- writing scene files -------------------------------------------------------------------

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def toml_key(key: str) -> str:
    """``key`` as a TOML key (quoted unless it is bare)."""
    return key if _BARE_KEY.fullmatch(key) else _toml_string(key)


def _toml_string(text: str) -> str:
    """``text`` as a TOML basic string (quotes, backslashes and control characters escaped)."""
    escaped = []
    for char in text:
        if char in ('"', "\\"):
            escaped.append("\\" + char)
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            escaped.append(f"\\u{ord(char):04X}")
        else:
            escaped.append(char)
    return '"' + "".join(escaped) + '"'


def toml_value(value: Any) -> str:
    """``value`` (string, number, list or table) as an inline TOML value (for writing scene files)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InvalidDataError(f"a scene file holds finite numbers, got {value}")
        return repr(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(item) for item in value) + "]"
    if isinstance(value, Mapping):
        items = ", ".join(f"{toml_key(str(key))} = {toml_value(item)}" for key, item in value.items())
        return "{ " + items + " }" if items else "{}"
    raise TypeError(f"no TOML value for {type(value).__name__}")
