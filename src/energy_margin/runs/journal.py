"""The append-only journal of a run: one line per finished item, durable as soon as it is written.

A journal is a text file with a header line and one line per finished item. Lines are appended,
flushed and synced as items finish, so a run killed at any moment leaves every finished item on
disk but the one being written, whose torn line is dropped on reading (as is a line that does not
parse, or a second line for the same key: the first one stays). On resume the journal is
rewritten without those lines (atomically) before appending again.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Hashable, Iterable
from pathlib import Path
from typing import Any, Generic, TextIO, TypeVar, cast

from energy_margin.runs.files import atomic_write_text

__all__ = [
    "Journal",
    "Key",
    "append_line",
]

Key = TypeVar("Key", bound=Hashable)


class Journal(Generic[Key]):
    """An append-only journal of rows.

    Args:
        path: the journal file.
        header: its first line, with the newline.
        format_row: a row as one line, without the newline.
        parse_row: a line (with its newline) as a row, ``None`` for a torn or foreign line.
        key: the key of a row (a row per key).

    """

    def __init__(
        self,
        path: Path | str,
        *,
        header: str,
        format_row: Callable[[dict[str, Any]], str],
        parse_row: Callable[[str], dict[str, Any] | None],
        key: Callable[[dict[str, Any]], Key],
    ) -> None:
        self.path = Path(path)
        self.header = header
        self.format_row = format_row
        self.parse_row = parse_row
        self.key = key
        self._stream: TextIO | None = None

    def read(self) -> dict[Key, dict[str, Any]]:
        """The finished rows by key (an absent journal has none)."""
        rows: dict[Key, dict[str, Any]] = {}
        if not self.path.is_file():
            return rows
        with self.path.open(encoding="utf-8", errors="replace") as stream:
            for line in stream:
                row = self.parse_row(line)
                if row is not None:
                    rows.setdefault(self.key(row), row)
        return rows

    def rewrite(self, rows: dict[Key, dict[str, Any]], *, order: Iterable[Key] | None = None) -> None:
        """Replace the journal atomically by ``rows`` (in ``order``, sorted keys by default)."""
        # Keys are hashable; the default order needs them comparable too (tuples of ints, say).
        keys = list(order) if order is not None else sorted(cast("list[Any]", list(rows)))
        atomic_write_text(self.path, self.header + "".join(self.format_row(rows[k]) + "\n" for k in keys))

    def append(self, row: dict[str, Any]) -> None:
        """Append one row and make it durable (flushed and synced); opens the journal on first use."""
        if self._stream is None:
            self._stream = self.path.open("a", encoding="utf-8")
        append_line(self._stream, self.format_row(row))

    def close(self) -> None:
        """Close the journal's stream (idempotent)."""
        if self._stream is not None:
            self._stream.close()
            self._stream = None

    def __enter__(self) -> Journal[Key]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def append_line(stream: TextIO, line: str) -> None:
    """Append ``line`` and its newline to an open stream and make it durable (flushed and synced)."""
    stream.write(line + "\n")
    stream.flush()
    os.fsync(stream.fileno())
