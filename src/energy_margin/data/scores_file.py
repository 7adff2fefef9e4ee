"""The scores file: ``scores.csv``, its append-only journal and the analysis record beside it.

``scores.csv`` has one row per frame, sorted by trajectory and frame, with the columns
:data:`COLUMNS`; floats are written by ``repr`` so a read gives back the exact values.
``rejected`` and ``diverged`` count the states each frame's tree rejected for leaving the task's
state box and for a non-finite number; -1 where unknown (a file written before they were counted,
read with :data:`EARLIER_COLUMNS`, or scores that no tree produced). ``tree_capture_score`` is
the tree's own capture score before the capture gate (``capture_score`` is gated); NaN where
unknown (a file written before it was kept, read with :data:`UNGATED_COLUMNS`, or scores that no
tree produced). While an
analysis runs, rows are appended to ``scores.journal.csv`` (same columns) as frames finish;
``analysis.json`` records the resolved configuration that produced them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._renamed import RENAMED_KEYS
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.journal import Journal

__all__ = [
    "COLUMNS",
    "CONFIG_FILE",
    "DIVERGED_SHARE",
    "EARLIER_COLUMNS",
    "INTEGER_COLUMNS",
    "JOURNAL_FILE",
    "REJECTED_SHARE",
    "RENAMED_COLUMNS",
    "SCORES_FILE",
    "UNGATED_COLUMNS",
    "UNKNOWN_COUNT",
    "UNREACHED_SHARE",
    "current_names",
    "file_columns",
    "format_row",
    "header",
    "load_scores",
    "parse_row",
    "read_journal",
    "rejection_note",
    "scores_journal",
    "tree_rejections",
    "unreached_success_share",
]

SCORES_FILE = "scores.csv"
JOURNAL_FILE = "scores.journal.csv"
CONFIG_FILE = "analysis.json"
#: Columns of scores.csv written as integers.
INTEGER_COLUMNS = ("trajectory", "frame", "nodes", "expansions", "seed", "rejected", "diverged")
#: The columns of scores files (the expansions of a frame's tree are ``expansions``).
COLUMNS = (
    "trajectory",
    "frame",
    "capture_score",
    "success_score",
    "nodes",
    "expansions",
    "runtime_s",
    "physics_s",
    "seed",
    "rejected",
    "diverged",
    "tree_capture_score",
)
#: The columns of scores files written before the tree's own capture score was kept (still read).
UNGATED_COLUMNS = COLUMNS[:-1]
#: The columns of scores files of release 0.2, whose expansions column was ``iterations`` (still read).
RENAMED_COLUMNS = tuple("iterations" if name == "expansions" else name for name in UNGATED_COLUMNS)
#: The columns of scores files written before the trees' rejections were counted (still read).
EARLIER_COLUMNS = RENAMED_COLUMNS[:9]
#: ``rejected`` and ``diverged`` where unknown.
UNKNOWN_COUNT = -1
#: What a row lacking a column holds: the counts unknown, the tree's own capture score unknown.
_UNKNOWN = {"rejected": UNKNOWN_COUNT, "diverged": UNKNOWN_COUNT, "tree_capture_score": math.nan}


def format_row(row: dict[str, Any]) -> str:
    """One scores row as a CSV line without its newline (floats by ``repr``: exact round trip).

    A row without ``rejected`` or ``diverged`` (scores no tree of this package grew) gets
    :data:`UNKNOWN_COUNT`, without ``tree_capture_score`` NaN.
    """
    values = {**_UNKNOWN, **row}
    return ",".join(repr(float(values[c])) if isinstance(values[c], float) else str(values[c]) for c in COLUMNS)


def parse_row(line: str, columns: tuple[str, ...] = COLUMNS) -> dict[str, Any] | None:
    """A journal line as a row, or ``None`` for a torn or foreign line.

    ``columns`` are the file's (:data:`COLUMNS` or an earlier layout, :func:`file_columns`); an
    earlier file's ``iterations`` is the row's ``expansions``, the counts it lacks are
    :data:`UNKNOWN_COUNT` and its lacking tree capture score NaN.
    """
    fields = line.rstrip("\n").split(",")
    if len(fields) != len(columns) or not line.endswith("\n"):
        return None
    try:
        row: dict[str, Any] = dict(_UNKNOWN)
        for key, text in zip(current_names(columns), fields, strict=True):
            row[key] = int(text) if key in INTEGER_COLUMNS else float(text)
    except ValueError:
        return None
    return row


def current_names(columns: tuple[str, ...]) -> tuple[str, ...]:
    """A file's columns under today's names (release 0.2's ``iterations`` is ``expansions``)."""
    return tuple(RENAMED_KEYS.get(name, name) for name in columns)


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


def file_columns(first_line: str) -> tuple[str, ...] | None:
    """The columns a scores file's header line declares (current or earlier), or ``None``."""
    for columns in (COLUMNS, UNGATED_COLUMNS, RENAMED_COLUMNS, EARLIER_COLUMNS):
        if first_line.rstrip("\n") == ",".join(columns):
            return columns
    return None


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
    columns = file_columns(lines[0] if lines else "")
    if columns is None:
        raise EnergyMarginError(f"{scores_path}: unexpected header (expected {','.join(COLUMNS)})")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        row = parse_row(line if line.endswith("\n") else line + "\n", columns)
        if row is None:
            raise EnergyMarginError(f"{scores_path}: line {number} is malformed")
        rows.append(row)
    dtypes = {name: np.int64 for name in INTEGER_COLUMNS} | {"seed": np.uint64}
    try:
        return {name: np.array([row[name] for row in rows], dtype=dtypes.get(name, np.float64)) for name in COLUMNS}
    except OverflowError:
        raise EnergyMarginError(f"{scores_path}: a count or seed is out of range") from None


#: ``analyze`` says so when more than this share of a dataset's expansions diverged.
DIVERGED_SHARE = 0.01
#: ``analyze`` says so when more than this share of a dataset's expansions left the state box.
REJECTED_SHARE = 0.25


def tree_rejections(scores: dict[str, np.ndarray]) -> dict[str, float] | None:
    """The states the trees rejected: per frame on average, and as shares of the expansions.

    Returns:
        ``rejected_per_frame``, ``diverged_per_frame``, ``rejected_share``, ``diverged_share``;
        ``None`` when the counts are unknown (:data:`UNKNOWN_COUNT`) or nothing was expanded.
    """
    rejected, diverged = scores["rejected"], scores["diverged"]
    known = (rejected >= 0) & (diverged >= 0)
    expansions = float(scores["expansions"][known].sum())
    if not known.any() or expansions <= 0:
        return None
    return {
        "rejected_per_frame": float(rejected[known].mean()),
        "diverged_per_frame": float(diverged[known].mean()),
        "rejected_share": float(rejected[known].sum()) / expansions,
        "diverged_share": float(diverged[known].sum()) / expansions,
    }


def rejection_note(scores: dict[str, np.ndarray]) -> str | None:
    """One line when the trees diverged or left the state box often, with the likely cause; else ``None``."""
    summary = tree_rejections(scores)
    if summary is None:
        return None
    if summary["diverged_share"] > DIVERGED_SHARE:
        return (
            f"note: {100 * summary['diverged_share']:.1f}% of the trees' expansions diverged "
            f"({summary['diverged_per_frame']:.1f} per frame): the perturbation wrenches may be too large for light "
            "objects, or the time step too long for them (lower [perturbation], or a smaller time step)"
        )
    if summary["rejected_share"] > REJECTED_SHARE:
        return (
            f"note: {100 * summary['rejected_share']:.1f}% of the trees' expansions left the state box "
            f"({summary['rejected_per_frame']:.1f} per frame): objects reach the task's bounds or speed bound "
            "often (widen [bounds] if they belong there, or lower [perturbation])"
        )
    return None


#: ``analyze`` says so when at least this share of the first-half frames scores success exactly 0.
UNREACHED_SHARE = 0.9


def unreached_success_share(scores: dict[str, np.ndarray]) -> float | None:
    """Share of the first-half frames (index < ceil(K / 2)) whose success score is exactly 0.

    A success score is exactly 0 when no state of the frame's tree lies in the success region: the
    trees end before the motion reaches it, and the score cannot rank those frames' futures (a
    success continuation can: :mod:`energy_margin.analysis.continuation`). ``None`` without frames.
    """
    frames = scores["frame"]
    if frames.size == 0:
        return None
    first_half = frames < -(-(int(frames.max()) + 1) // 2)
    return float(np.mean(scores["success_score"][first_half] == 0.0))
