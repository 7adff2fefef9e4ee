"""Figures quoted in the Markdown pages, inserted from the results files that hold them.

A quoted figure is written between two markers that name its source::

    <!-- fig docs/figures/pushing_10.json#/evaluate/capture_ap_window2 :.3f -->0.895<!-- /fig -->

* the path is relative to the repository root;
* after ``#``: a JSON pointer (``/key/0/key``; ``~1`` stands for ``/`` in a key, ``~0`` for ``~``),
  for a CSV file ``COLUMN=VALUE,.../COLUMN`` (the one row whose cells match, then its column),
  for any other file ``L5`` (line 5, stripped);
* after `` :`` an optional Python format spec (``.3f``, ``.2f``, ``,.0f``); without it the value as
  written in the file. ``neg`` before the spec (``:neg.3f``) quotes the value negated: a change the
  file holds as negative, written as a loss; ``ms`` or ``us`` (``:us.1f``) quotes seconds in
  milliseconds or microseconds.

A table of a results file is a block generated from a template: its lines without a ``{cell}``
(the header and the separator) as they are, then its row line once per record of the file::

    <!-- table docs/figures/budget_pushing.csv where method=est
    | method | budget | capture AP |
    |---|---:|---:|
    | {method} | {budget:.0f|–} | {capture_ap:.3f} [{capture_ap_low:.3f}, {capture_ap_high:.3f}] |
    -->

    | method | budget | capture AP |
    |---|---:|---:|
    | est | 10 | 1.000 [1.000, 1.000] |

    <!-- /table -->

* the records: a CSV file's rows, or the list a JSON file holds at ``#/pointer``; ``where
  COLUMN=VALUE,...`` keeps the matching ones (a VALUE is a file-name pattern: ``*`` stands for
  any text, ``?`` for one character, a space included: ``comparison=*lambda*``);
* ``{column:spec}`` formats a cell as a figure marker does; ``{column:spec|X}`` writes ``X``
  when the cell is empty or zero (``–`` for a baseline's budget).

``python tools/figures.py`` lists every quoted figure that disagrees with its file, or whose file
or key is missing (exit status 1); ``--write`` rewrites each quoted figure from its file.
``tests/test_figures.py`` runs the check.
"""

from __future__ import annotations

import argparse
import csv
import fnmatch
import json
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: The pages whose markers are checked and refreshed.
PAGES = ("README.md", "docs/**/*.md", "examples/**/*.md")
MARKER = re.compile(r"<!-- fig (?P<path>[^#\s]+)#(?P<key>.*?)(?: :(?P<spec>[^\s>]*))? -->(?P<value>[^<]*)<!-- /fig -->")
TABLE = re.compile(
    r"<!-- table (?P<path>[^#\s]+)(?:#(?P<key>\S*))?(?: where (?P<where>\S+))?\n(?P<template>.*?)\n-->\n"
    r"(?P<rows>.*?)<!-- /table -->",
    re.S,
)
CELL = re.compile(r"\{(?P<column>[^{}:|]+)(?::(?P<spec>[^{}|]*))?(?:\|(?P<blank>[^{}]*))?\}")


class FigureError(Exception):
    """A marker whose file or key is missing, or whose value cannot be formatted."""


@dataclass(frozen=True)
class Quote:
    """One quoted figure: where it is, what it says, and what its file says."""

    page: Path
    line: int
    source: str
    quoted: str
    expected: str | None
    error: str | None

    def __str__(self) -> str:
        where = f"{self.page.relative_to(ROOT) if self.page.is_relative_to(ROOT) else self.page}:{self.line}"
        if self.error:
            return f"{where}: {self.source}: {self.error}"
        if self.source.startswith("table "):
            quoted, expected = self.quoted.splitlines(), (self.expected or "").splitlines()
            line = next((n for n, (q, e) in enumerate(zip(quoted, expected, strict=False)) if q != e), None)
            if line is None:
                return f"{where}: {self.source}: {len(quoted)} lines, the file gives {len(expected)}"
            found, given = quoted[line], expected[line]
            return f"{where}: {self.source}: line {line + 1} of the table is {found!r}, the file gives {given!r}"
        return f"{where}: {self.source}: quoted {self.quoted!r}, the file says {self.expected!r}"


def _json_value(document: Any, pointer: str) -> Any:
    if pointer in ("", "/"):
        return document
    if not pointer.startswith("/"):
        raise FigureError(f"a JSON pointer starts with '/', got {pointer!r}")
    value = document
    for part in pointer[1:].split("/"):
        key = part.replace("~1", "/").replace("~0", "~")
        if isinstance(value, list):
            if not key.isdigit() or int(key) >= len(value):
                raise FigureError(f"no item {key!r}")
            value = value[int(key)]
        elif isinstance(value, dict):
            if key not in value:
                raise FigureError(f"no key {key!r}")
            value = value[key]
        else:
            raise FigureError(f"{key!r} under a value that is neither an object nor a list")
    return value


def _csv_value(text: str, key: str) -> str:
    selector, _, column = key.rpartition("/")
    wanted = dict(pair.split("=", 1) for pair in selector.split(",") if pair)
    rows = [row for row in csv.DictReader(text.splitlines()) if all(row.get(k) == v for k, v in wanted.items())]
    if len(rows) != 1:
        raise FigureError(f"{len(rows)} rows match {selector!r}, not one")
    if column not in rows[0]:
        raise FigureError(f"no column {column!r}")
    return rows[0][column]


def lookup(path: str, key: str, root: Path = ROOT) -> Any:
    """The value a marker names: ``key`` in the results file ``path``."""
    file = root / path
    if not file.is_file():
        raise FigureError("no such file")
    text = file.read_text(encoding="utf-8")
    if file.suffix == ".json":
        return _json_value(json.loads(text), key)
    if file.suffix == ".csv":
        return _csv_value(text, key)
    match = re.fullmatch(r"L(\d+)", key)
    lines = text.splitlines()
    if not match or not 1 <= int(match.group(1)) <= len(lines):
        raise FigureError(f"no line {key!r} (the file has {len(lines)})")
    return lines[int(match.group(1)) - 1].strip()


#: Prefixes of a format spec that scale a number before it is formatted: a change the file holds as
#: negative written as a loss (``neg``), seconds written in milliseconds or microseconds.
SCALES = {"neg": -1.0, "ms": 1e3, "us": 1e6}


def render(value: Any, spec: str | None) -> str:
    """A value as quoted: formatted by ``spec`` (numbers from CSV and text files too), scaled first by a prefix."""
    prefix = next((name for name in SCALES if spec is not None and spec.startswith(name)), None)
    if spec is not None and prefix is not None:
        spec = spec[len(prefix) :]
    if not spec and prefix is None:
        return str(value)
    if isinstance(value, str) or prefix is not None:
        try:
            value = float(value)
        except (TypeError, ValueError) as error:
            raise FigureError(f"{value!r} is not a number for format {spec!r}") from error
    if prefix is not None:
        value = SCALES[prefix] * value
    try:
        return format(value, spec)
    except (TypeError, ValueError) as error:
        raise FigureError(f"cannot format {value!r} with {spec!r}") from error


def records(path: str, key: str | None, where: str | None, root: Path = ROOT) -> list[dict[str, Any]]:
    """The records a table block lists: a CSV file's rows or a JSON list, those matching ``where``."""
    file = root / path
    if not file.is_file():
        raise FigureError("no such file")
    text = file.read_text(encoding="utf-8")
    if file.suffix == ".csv":
        found: Any = list(csv.DictReader(text.splitlines()))
    elif file.suffix == ".json":
        found = _json_value(json.loads(text), key or "")
    else:
        raise FigureError("a table lists the records of a CSV or JSON file")
    if not isinstance(found, list) or not all(isinstance(row, dict) for row in found):
        raise FigureError(f"{key or 'the file'} is not a list of records")
    wanted = dict(pair.split("=", 1) for pair in where.split(",")) if where else {}
    return [row for row in found if all(fnmatch.fnmatchcase(str(row.get(k)), v) for k, v in wanted.items())]


def table_rows(template: str, rows: list[dict[str, Any]]) -> str:
    """The template's lines without cells as they are, then each line with cells once per record."""

    def line(row: dict[str, Any], text: str) -> str:
        def cell(match: re.Match[str]) -> str:
            column = match.group("column")
            if column not in row:
                raise FigureError(f"no column {column!r}")
            value, blank = row[column], match.group("blank")
            if blank is not None and (value in ("", None) or _is_zero(value)):
                return blank
            return render(value, match.group("spec")) if value not in ("", None) else ""

        return CELL.sub(cell, text)

    fixed = [text for text in template.splitlines() if not CELL.search(text)]
    varying = [text for text in template.splitlines() if CELL.search(text)]
    body = "".join(text + "\n" for text in fixed) + "".join(line(row, text) + "\n" for row in rows for text in varying)
    # Blank lines around the rows: Markdown reads each comment as a block of its own, the rows as a table.
    return "\n" + body + "\n"


def _is_zero(value: Any) -> bool:
    try:
        return float(value) == 0.0
    except (TypeError, ValueError):
        return False


def _table(match: re.Match[str], root: Path) -> str:
    """A table block's rows as its file gives them."""
    found = records(match.group("path"), match.group("key"), match.group("where"), root)
    return table_rows(match.group("template"), found)


def quotes(page: Path, root: Path = ROOT) -> Iterator[Quote]:
    """Every quoted figure of a page, with the value its file gives (or why there is none)."""
    text = page.read_text(encoding="utf-8")
    for match in MARKER.finditer(text):
        source = f"{match.group('path')}#{match.group('key')}"
        line = text.count("\n", 0, match.start()) + 1
        try:
            expected: str | None = render(lookup(match.group("path"), match.group("key"), root), match.group("spec"))
            error = None
        except FigureError as problem:
            expected, error = None, str(problem)
        yield Quote(page, line, source, match.group("value"), expected, error)
    for match in TABLE.finditer(text):
        source = f"table {match.group('path')}"
        line = text.count("\n", 0, match.start()) + 1
        try:
            expected = _table(match, root)
            error = None
        except FigureError as problem:
            expected, error = None, str(problem)
        yield Quote(page, line, source, match.group("rows"), expected, error)


def pages(root: Path = ROOT) -> list[Path]:
    """The Markdown pages that may quote figures."""
    found: set[Path] = set()
    for pattern in PAGES:
        found.update(root.glob(pattern))
    return sorted(path for path in found if ".venv" not in path.parts)


def problems(root: Path = ROOT) -> list[Quote]:
    """Every quoted figure that disagrees with its file or names a missing file or key."""
    found = [quote for page in pages(root) for quote in quotes(page, root)]
    return [quote for quote in found if quote.error or quote.quoted != quote.expected]


def write(page: Path, root: Path = ROOT) -> int:
    """Rewrite a page's quoted figures from their files; the number changed."""
    text = page.read_text(encoding="utf-8")
    changed = 0

    def refresh(match: re.Match[str]) -> str:
        nonlocal changed
        value = render(lookup(match.group("path"), match.group("key"), root), match.group("spec"))
        if value == match.group("value"):
            return match.group(0)
        changed += 1
        spec = f" :{match.group('spec')}" if match.group("spec") else ""
        return f"<!-- fig {match.group('path')}#{match.group('key')}{spec} -->{value}<!-- /fig -->"

    def refresh_table(match: re.Match[str]) -> str:
        nonlocal changed
        rows = _table(match, root)
        if rows == match.group("rows"):
            return match.group(0)
        changed += 1
        return match.group(0)[: match.start("rows") - match.start()] + rows + "<!-- /table -->"

    new = TABLE.sub(refresh_table, MARKER.sub(refresh, text))
    if changed:
        page.write_text(new, encoding="utf-8")
    return changed


def main(argv: list[str] | None = None) -> int:
    """Check the quoted figures, or rewrite them with ``--write``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite every quoted figure from its file")
    args = parser.parse_args(argv)
    if args.write:
        try:
            total = sum(write(page) for page in pages())
        except FigureError as error:
            print(f"figures: {error}", file=sys.stderr)
            return 1
        print(f"figures: {total} quoted figure(s) rewritten")
    found = problems()
    for quote in found:
        print(quote, file=sys.stderr)
    count = sum(1 for page in pages() for _ in quotes(page))
    print(f"figures: {count} quoted figure(s), {len(found)} disagree(s) with their file(s)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
