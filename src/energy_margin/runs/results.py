"""Typed results: what a command-level function returns, read by attribute and written as JSON.

A result is a frozen dataclass deriving from :class:`TypedResult`. Its fields are the keys of the
JSON the command writes, in that order; :meth:`TypedResult.to_dict` gives that JSON-compatible
dictionary (leaving out the fields a result says are absent, :meth:`TypedResult.absent`).

Releases before 0.2 returned the dictionary itself. For one release a result still reads as one
(``result["capture_ap"]``), with a :class:`DeprecationWarning` naming the attribute to use.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterator, Mapping
from typing import Any

__all__ = ["TypedResult", "plain_result"]


class TypedResult(Mapping[str, Any]):
    """Base of a result dataclass: :meth:`to_dict` for JSON, and the read-only mapping of earlier releases."""

    def absent(self) -> set[str]:
        """Names of the fields this result does not have (left out of :meth:`to_dict`); none by default."""
        return set()

    def to_dict(self) -> dict[str, Any]:
        """The result as the JSON-compatible dictionary the command writes, its fields in order."""
        left_out = self.absent()
        return {
            field.name: getattr(self, field.name)
            for field in dataclasses.fields(self)  # type: ignore[arg-type]
            if field.name not in left_out
        }

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> Any:
        """The result of a dictionary written by :meth:`to_dict` (absent fields take their defaults)."""
        names = {field.name for field in dataclasses.fields(cls)}  # type: ignore[arg-type]
        return cls(**{key: value for key, value in values.items() if key in names})

    def __getitem__(self, key: str) -> Any:
        warnings.warn(
            f"{type(self).__name__}[{key!r}] reads the result as a dictionary, which goes in 0.3; "
            f"use .{key} (or .to_dict())",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.to_dict()[key]

    def __contains__(self, key: object) -> bool:
        return key in self.to_dict()

    def __iter__(self) -> Iterator[str]:
        return iter(self.to_dict())

    def __len__(self) -> int:
        return len(self.to_dict())


def plain_result(result: TypedResult | dict[str, Any]) -> dict[str, Any]:
    """A result as the dictionary its command writes: ``to_dict()`` of a :class:`TypedResult`, else itself."""
    return result.to_dict() if isinstance(result, TypedResult) else result
