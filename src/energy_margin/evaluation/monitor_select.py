"""Choosing what an alarm watches on a selection set the calibration and test sets never see.

The watched score (``success``, ``capture`` or ``min``), the first monitored frame and the
persistence decide whether an alarm is useful: on pushing every success score is near 0 in the
first frames, and a calibration success that scores 0 at one frame makes a persistence-1 margin
threshold 0. :func:`select_alarm` tries every score, first frames 0 .. K / 2 and persistence
1 .. ``max_persistence`` on a third, *selection* set: each candidate is calibrated on the set's own
successes (split-conformal at ``alpha``) and kept by how many of the set's failed trajectories it
detects at or before their failure frame (ties: the longer mean lead time, then the earlier first
frame, then the smaller persistence, then the order of
:data:`~energy_margin.evaluation.monitor.SCORES`). Choosing on the calibration set itself would
spend its guarantee; on a separate set it is kept. :func:`select_alarms` chooses at several
alphas, the set loaded and its grids built once.

A candidate must also leave room above the score's floor. A success whose nonconformity is at the
floor (a margin of 0 at ``persistence`` monitored frames) would be a false alarm at any threshold
that can fire, and once j = floor((n + 1) alpha) of the calibration successes are there the
threshold is the floor and the alarm cannot fire. The share of such successes differs from set to
set, so a candidate is eligible only while the selection set's count of them is below half of
that, ``(n + 1) alpha / 2``: one at the edge on the selection set (a single floor success where j
is 2) ended at threshold 0 on a calibration set almost twice as large (35 successes against 19).
When no candidate is eligible the best of all is taken (``AlarmChoice.eligible`` is then False).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.validation import require_valid
from energy_margin.errors import check_choice, check_int
from energy_margin.evaluation.monitor import (
    SCORE_FLOORS,
    SCORERS,
    SCORES,
    alarm_frames,
    alarm_measures,
    calibrate_grid,
    conformal_rank,
    failure_frames,
    monitored_grids,
    worst_scores,
)
from energy_margin.runs.results import TypedResult

__all__ = ["AlarmChoice", "select_alarm", "select_alarms"]


@dataclass(frozen=True, kw_only=True)
class AlarmChoice(TypedResult):
    """What an alarm watches, chosen on a selection set.

    Attributes:
        scorer: ``margin`` or ``distance``.
        alpha: the false-alarm rate the candidates were calibrated at.
        score: the chosen watched score.
        start_frame: the chosen first monitored frame.
        persistence: the chosen number of monitored frames below the threshold that raise the alarm.
        early_detection_rate: the chosen alarm's share of the selection set's failures detected at
            or before their failure frame (``None``: the set has no failure).
        lead_time_s: its mean lead time on them, s (``None``: no detection).
        eligible: whether it left room above the score's floor (module docstring); False only
            when no candidate did.
        selection_dataset: the selection set's directory.
        selection_seed: its generation seed (``None``: not recorded).
        candidates: every candidate tried: score, start frame, persistence, early detection rate,
            lead time, the successes at the score's floor and whether it is eligible (candidates
            the set has too few successes for are left out).

    """

    scorer: str
    alpha: float
    score: str
    start_frame: int
    persistence: int
    early_detection_rate: float | None
    lead_time_s: float | None
    eligible: bool
    selection_dataset: str
    selection_seed: int | None
    candidates: list[dict[str, Any]]


def select_alarm(path: Path | str, *, alpha: float, scorer: str = "margin", max_persistence: int = 3) -> AlarmChoice:
    """Choose the watched score, first frame and persistence of an alarm on the selection set ``path``.

    Args:
        path: an analysed dataset directory (``scores.csv`` needed for ``scorer="margin"``) used for
            nothing else: neither the calibration nor the test set.
        alpha: the false-alarm rate to calibrate every candidate at, in (0, 1).
        scorer: ``margin`` or ``distance``.
        max_persistence: the largest persistence tried, >= 1.

    Raises:
        InvalidParameterError: ``alpha`` needs more successes than the selection set has, or a bad option.

    """
    return select_alarms(path, alphas=(alpha,), scorer=scorer, max_persistence=max_persistence)[0]


def select_alarms(
    path: Path | str, *, alphas: tuple[float, ...], scorer: str = "margin", max_persistence: int = 3
) -> list[AlarmChoice]:
    """:func:`select_alarm` at each of ``alphas``, the selection set loaded and its grids built once.

    Returns:
        One :class:`AlarmChoice` per alpha, in the order of ``alphas``.

    Raises:
        InvalidParameterError: an alpha needs more successes than the selection set has (checked
            for every alpha before any work), or a bad option.

    """
    check_choice("scorer", scorer, SCORERS)
    check_int("max_persistence", max_persistence, minimum=1)
    dataset = require_valid(path, overlaps=True, scores=True if scorer == "margin" else None)
    success = dataset.success_labels()
    for alpha in alphas:
        conformal_rank(int(success.sum()), alpha)  # too few successes for alpha: one line, before any work
    failures = failure_frames(dataset.arrays["captured"], success)
    times = np.asarray(dataset.arrays["frame_time"], dtype=float)
    grids = monitored_grids(dataset, path, scorer=scorer)
    seed = dataset.metadata.get("seed")
    choices: list[AlarmChoice] = []
    for alpha in alphas:
        candidates = _candidates(
            grids, success, failures, times, alpha=alpha, max_persistence=max_persistence, floor=SCORE_FLOORS[scorer]
        )
        best = max(
            [row for row in candidates if row["eligible"]] or candidates,
            key=lambda row: (
                row["early_detection_rate"] or 0.0,
                row["lead_time_s"] or 0.0,
                -row["start_frame"],
                -row["persistence"],
            ),
        )
        choices.append(
            AlarmChoice(
                scorer=scorer,
                alpha=float(alpha),
                score=best["score"],
                start_frame=best["start_frame"],
                persistence=best["persistence"],
                early_detection_rate=best["early_detection_rate"],
                lead_time_s=best["lead_time_s"],
                eligible=best["eligible"],
                selection_dataset=str(path),
                selection_seed=seed if isinstance(seed, int) else None,
                candidates=candidates,
            )
        )
    return choices


def _candidates(
    grids: dict[str, np.ndarray],
    success: np.ndarray,
    failures: np.ndarray,
    times: np.ndarray,
    *,
    alpha: float,
    max_persistence: int,
    floor: float,
) -> list[dict[str, Any]]:
    """Every score, first frame 0 .. K / 2 and persistence, calibrated at ``alpha`` and measured, in order.

    ``floor`` is the scorer's lowest score: a candidate is eligible while fewer than
    ``(n + 1) alpha / 2`` of the n successes have their nonconformity there.
    """
    room = (int(success.sum()) + 1) * alpha / 2
    candidates: list[dict[str, Any]] = []
    for score in SCORES:
        grid = grids[score]
        frames = grid.shape[1]
        for start in range(frames // 2 + 1):
            for persistence in range(1, min(max_persistence, frames - start) + 1):
                found = calibrate_grid(grid, success, alpha=alpha, start_frame=start, persistence=persistence)
                alarms = alarm_frames(grid, found.threshold, start_frame=start, persistence=persistence)
                measured = alarm_measures(alarms, failures, times)
                at_floor = int(np.sum(worst_scores(grid[success], start_frame=start, persistence=persistence) <= floor))
                candidates.append(
                    {
                        "score": score,
                        "start_frame": start,
                        "persistence": persistence,
                        "early_detection_rate": measured["early_detection_rate"],
                        "lead_time_s": measured["lead_time_s"],
                        "floor_successes": at_floor,
                        "eligible": at_floor < room,
                    }
                )
    return candidates
