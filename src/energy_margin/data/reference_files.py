"""Reading the authors' CSV files: the typed rows of a file, the frame grid, where their scores are.

Every problem raises :class:`~energy_margin.errors.EnergyMarginError` naming the file (and the line
and column where one is at fault). The files are described in :mod:`energy_margin.data.reference`.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from energy_margin.errors import EnergyMarginError

__all__ = ["AO_EST_COLUMNS", "DEFAULT_SCORES", "SCORES_NAME", "ReferenceSet"]


#: Sub-folders holding the true-state scores, in order of preference.
DEFAULT_SCORES = ("original", "original-data", ".")
SCORES_NAME = "ao_est.csv"


AO_EST_COLUMNS = (
    "data_id",
    "trial",
    "plan_iters",
    "plan_time",
    "best_cost",
    "capture_exists_score",
    "capture_score",
    "success_exists_score",
    "success_score",
    "runtime",
)


@dataclass(frozen=True)
class ReferenceSet:
    """Parsed reference files of one task folder."""

    task: str
    suffix: str
    states: np.ndarray  # (T, K, columns) frame state columns after num_traj, data_id
    capture_label: np.ndarray  # (T, K) bool
    friction_per_body: np.ndarray  # (T,)
    success_label: np.ndarray  # (T,) bool
    scores: np.ndarray | None  # (T * K, 10) ao_est rows in data_id order, or None


def _fail(path: Path, message: str) -> EnergyMarginError:
    return EnergyMarginError(f"{path}: {message}")


def _read_csv(path: Path, expected_header: tuple[str, ...] | None = None) -> tuple[list[str], np.ndarray]:
    """Header and float rows of a CSV file; every problem raises :class:`EnergyMarginError`."""
    if not path.is_file():
        raise _fail(path, "does not exist")
    try:
        with path.open(encoding="utf-8", newline="") as stream:
            rows = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise _fail(path, f"cannot be read as CSV ({error})") from None
    rows = [row for row in rows if row]
    if len(rows) < 2:
        raise _fail(path, "has no data rows")
    header = [name.strip() for name in rows[0]]
    if expected_header is not None and tuple(header) != expected_header:
        raise _fail(path, f"unexpected header (expected {','.join(expected_header)})")
    values = np.empty((len(rows) - 1, len(header)))
    for number, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise _fail(path, f"line {number} has {len(row)} fields, expected {len(header)}")
        for column, text in enumerate(row):
            try:
                value = float(text)
            except ValueError:
                raise _fail(path, f"line {number}, column {header[column]}: {text[:40]!r} is not a number") from None
            if not math.isfinite(value) and header[column] != "best_cost":
                raise _fail(path, f"line {number}, column {header[column]}: NaN or infinite value")
            values[number - 2, column] = value
    return header, values


def _scores_path(folder: Path, scores: str | None) -> Path | None:
    if scores is not None:
        path = folder / scores / SCORES_NAME if scores != "." else folder / SCORES_NAME
        if not path.is_file():
            raise EnergyMarginError(f"{folder}: no {SCORES_NAME} in {scores!r}")
        return path
    for name in DEFAULT_SCORES:
        path = folder / name / SCORES_NAME if name != "." else folder / SCORES_NAME
        if path.is_file():
            return path
    return None


def _grid(path: Path, values: np.ndarray, trajectories: np.ndarray, frames: np.ndarray) -> tuple[int, int]:
    """Check that rows are trajectory-major with equal frame counts; return (T, K)."""
    if np.any(trajectories != np.round(trajectories)) or np.any(frames != np.round(frames)):
        raise _fail(path, "num_traj and data_id must be integers")
    n_traj = int(trajectories.max()) + 1
    if values.shape[0] % n_traj:
        raise _fail(path, f"{values.shape[0]} rows do not split into {n_traj} trajectories of equal length")
    n_frames = values.shape[0] // n_traj
    expected_traj = np.repeat(np.arange(n_traj), n_frames)
    if not np.array_equal(trajectories, expected_traj):
        raise _fail(path, "rows must be ordered by num_traj with the same number of frames each")
    local = frames - frames.reshape(n_traj, n_frames)[:, :1].repeat(n_frames, axis=1).ravel()
    if not np.array_equal(local, np.tile(np.arange(n_frames), n_traj)):
        raise _fail(path, "data_id must count the frames of each trajectory in order")
    return n_traj, n_frames
