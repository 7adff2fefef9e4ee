"""The scores file: ``scores.csv``, its append-only journal and the analysis record beside it.

``scores.csv`` has one row per frame, sorted by trajectory and frame, with the columns
:data:`COLUMNS`; floats are written by ``repr`` so a read gives back the exact values. While an
analysis runs, rows are appended to ``scores.journal.csv`` (same columns) as frames finish;
``analysis.json`` records the resolved configuration that produced them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError
from energy_margin.runs.journal import Journal

SCORES_FILE = "scores.csv"
JOURNAL_FILE = "scores.journal.csv"
CONFIG_FILE = "analysis.json"
#: Columns of scores.csv written as integers.
INTEGER_COLUMNS = ("trajectory", "frame", "nodes", "iterations", "seed")
COLUMNS = (
    "trajectory",
    "frame",
    "capture_score",
    "success_score",
    "nodes",
    "iterations",
    "runtime_s",
    "physics_s",
    "seed",
)


def format_row(row: dict[str, Any]) -> str:
    """One scores row as a CSV line without its newline (floats by ``repr``: exact round trip)."""
    return ",".join(repr(float(row[c])) if isinstance(row[c], float) else str(row[c]) for c in COLUMNS)


def parse_row(line: str) -> dict[str, Any] | None:
    """A journal line as a row, or ``None`` for a torn or foreign line."""
    fields = line.rstrip("\n").split(",")
    if len(fields) != len(COLUMNS) or not line.endswith("\n"):
        return None
    try:
        row: dict[str, Any] = {}
        for name, text in zip(COLUMNS, fields, strict=True):
            row[name] = int(text) if name in INTEGER_COLUMNS else float(text)
    except ValueError:
        return None
    return row


def scores_journal(directory: Path, *, path: Path | None = None) -> Journal[tuple[int, int]]:
    """The journal of scores rows in ``directory`` (or at ``path``), keyed by (trajectory, frame)."""
    return Journal(
        Path(path) if path is not None else Path(directory) / JOURNAL_FILE,
        header=header(),
        format_row=format_row,
        parse_row=parse_row,
        key=lambda row: (row["trajectory"], row["frame"]),
    )


def read_journal(path: Path) -> dict[tuple[int, int], dict[str, Any]]:
    """Completed rows of a journal, keyed by (trajectory, frame); torn or duplicate lines are dropped."""
    return scores_journal(Path(path).parent, path=path).read()


def header() -> str:
    """The header line of ``scores.csv`` and of the journal, with its newline."""
    return ",".join(COLUMNS) + "\n"


def load_scores(path: Path | str) -> dict[str, np.ndarray]:
    """Read ``scores.csv`` of a dataset directory into columns; raise :class:`EnergyMarginError`."""
    directory = Path(path)
    scores_path = directory / SCORES_FILE
    if not scores_path.is_file():
        hint = (
            " (an analysis was interrupted: run analyze again to resume)" if (directory / JOURNAL_FILE).exists() else ""
        )
        raise EnergyMarginError(f"{directory} has no {SCORES_FILE}; run `energy-margin analyze` first{hint}")
    lines = scores_path.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True)
    if not lines or lines[0] != header():
        raise EnergyMarginError(f"{scores_path}: unexpected header (expected {','.join(COLUMNS)})")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        row = parse_row(line if line.endswith("\n") else line + "\n")
        if row is None:
            raise EnergyMarginError(f"{scores_path}: line {number} is malformed")
        rows.append(row)
    dtypes = {"seed": np.uint64, "trajectory": np.int64, "frame": np.int64, "nodes": np.int64, "iterations": np.int64}
    try:
        return {name: np.array([row[name] for row in rows], dtype=dtypes.get(name, np.float64)) for name in COLUMNS}
    except OverflowError:
        raise EnergyMarginError(f"{scores_path}: a count or seed is out of range") from None
