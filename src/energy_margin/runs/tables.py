"""Result tables: one CSV writer, one JSON writer and one text formatter for every command.

A result is a list of rows (dicts). :func:`write_csv` writes the chosen fields of each row (an
absent value or ``None`` as an empty cell, a list or dict as JSON, a float by ``repr`` so a read
gives back the exact value); :func:`write_json` writes any result object; :func:`format_table`
lays rows out as the fixed-width text tables the commands print, from :class:`Column`
descriptions. Every file is written atomically.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.runs.files import atomic_write_text
from energy_margin.runs.files import write_json as _write_json

__all__ = [
    "Column",
    "csv_text",
    "field",
    "fmt",
    "format_table",
    "write_csv",
    "write_json",
]


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, list | tuple | dict):
        return json.dumps(value)
    return value


def csv_text(rows: Sequence[dict[str, Any]], fields: Sequence[str]) -> str:
    """The CSV text of ``rows``: a header of ``fields``, then one line per row (other keys ignored)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(fields), lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({key: _cell(row.get(key)) for key in fields})
    return buffer.getvalue()


def write_csv(path: Path | str, rows: Sequence[dict[str, Any]], fields: Sequence[str]) -> Path:
    """Write ``rows`` as CSV with the columns ``fields``, atomically; the path."""
    path = Path(path)
    atomic_write_text(path, csv_text(rows, fields))
    return path


def write_json(path: Path | str, value: Any) -> Path:
    """Write ``value`` as indented JSON with sorted keys, atomically; the path."""
    path = Path(path)
    _write_json(path, value)
    return path


def fmt(value: float | None, digits: int = 3) -> str:
    """A number with ``digits`` decimals, ``"n/a"`` for ``None``."""
    return "n/a" if value is None else f"{value:.{digits}f}"


@dataclass(frozen=True)
class Column:
    """One column of a text table.

    Attributes:
        header: the column's title.
        cell: the row's cell as text.
        width: the least width in characters (wider titles or cells widen it).
        align: ``">"`` (right, for numbers) or ``"<"`` (left).

    """

    header: str
    cell: Callable[[dict[str, Any]], str]
    width: int = 0
    align: str = ">"


def field(key: str, header: str | None = None, *, digits: int | None = None, width: int = 0) -> Column:
    """A column showing ``row[key]`` (a number with ``digits`` decimals when given)."""

    def cell(row: dict[str, Any]) -> str:
        value = row.get(key)
        if digits is not None and (value is None or isinstance(value, int | float)):
            return fmt(value, digits)
        return "" if value is None else str(value)

    return Column(header if header is not None else key, cell, width)


def format_table(rows: Sequence[dict[str, Any]], columns: Sequence[Column]) -> str:
    """``rows`` as a fixed-width text table: titles, a rule, one line per row."""
    cells = [[column.cell(row) for column in columns] for row in rows]
    widths = [
        max([column.width, len(column.header), *(len(line[i]) for line in cells)]) for i, column in enumerate(columns)
    ]
    header = " ".join(f"{c.header:{c.align}{w}s}" for c, w in zip(columns, widths, strict=True))
    lines = [header, "-" * len(header)]
    lines += [
        " ".join(f"{text:{c.align}{w}s}" for text, c, w in zip(line, columns, widths, strict=True)).rstrip()
        for line in cells
    ]
    return "\n".join(lines)
