"""Hand-made ``scores.csv`` files for the evaluation tests (a module of its own, importable by name)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from energy_margin.data.scores_file import COLUMNS, SCORES_FILE


def write_scores(
    directory: Path,
    capture: np.ndarray,
    success: np.ndarray,
    *,
    runtime: float = 0.5,
    tree_capture: np.ndarray | None = None,
    columns: tuple[str, ...] = COLUMNS,
) -> None:
    """Write ``scores.csv`` of grids ``capture`` and ``success`` (each (T, K)), 30 expansions a frame.

    ``tree_capture``: the tree's own capture scores (``capture`` when ``None``); ``columns``: the
    file's layout (:data:`~energy_margin.data.scores_file.UNGATED_COLUMNS` leaves them out).
    """
    tree = capture if tree_capture is None else tree_capture
    lines = [",".join(columns)]
    for t in range(capture.shape[0]):
        for k in range(capture.shape[1]):
            row = f"{t},{k},{float(capture[t, k])!r},{float(success[t, k])!r},31,30,{runtime!r},0.25,{t * 10 + k},0,0"
            lines.append(row if len(columns) == 11 else f"{row},{float(tree[t, k])!r}")
    (directory / SCORES_FILE).write_text("\n".join(lines) + "\n")
