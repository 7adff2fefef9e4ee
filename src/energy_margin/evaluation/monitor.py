"""A failure alarm calibrated by split-conformal prediction on successful roll-outs only.

The monitor watches one per-frame score of a trajectory (the energy margin's ``success`` or
``capture`` score, their frame-wise minimum ``min``, or the same three from the ``distance``
baseline) from frame ``start_frame`` on, and raises an alarm at the ``persistence``-th monitored
frame whose score falls below a threshold (``persistence`` 1: the first such frame).

Calibration needs no failure. Each successful calibration roll-out i gives its nonconformity
``w_i``, its ``persistence``-th smallest score over its monitored frames (with persistence 1, its
worst score). With the n values sorted, ``w_(1) <= ... <= w_(n)``, the threshold is ``w_(j)`` with
``j = floor((n + 1) alpha)``. A roll-out raises the alarm exactly when at least ``persistence`` of
its monitored scores are below the threshold, that is when its own ``w`` is below it; so a new
successful roll-out exchangeable with the calibration ones alarms exactly when ``w`` ranks among the
j smallest of the n + 1 values, and ``P(alarm) <= j / (n + 1) <= alpha`` (ties only lower it). When
``(n + 1) alpha < 1`` no order statistic keeps that promise and the calibration is refused
(alpha = 0.05 needs 19 successes, alpha = 0.1 needs 9).

The margin's scores are probabilities that reach exactly 0 where no tree state lies in the region.
A calibration success that scores 0 at ``persistence`` monitored frames can make the threshold 0,
and no score is below 0: such an alarm cannot fire (:attr:`MonitorCalibration.can_fire`). A
persistence above the number of frames at which the calibration successes score 0 keeps the
threshold above 0 where failures stay at 0 for longer.

The margin's ``capture`` is the tree's own capture score (``tree_capture_score`` of
``scores.csv``), not the gated ``capture_score`` that ``evaluate`` ranks: gated, a successful
roll-out whose objects leave their region for a moment scores 0 there, and one such frame among the
calibration successes sets the threshold near 0. A file written before the tree's own score was
kept falls back on ``capture_score`` (:func:`tree_capture_known`).

:func:`calibrate_grid` is the calibration of a score grid; :func:`calibrate_monitor` that of an
analysed dataset directory. :func:`write_calibration` and :func:`load_calibration` keep one or
more calibrations in a small versioned JSON file that a live scorer can load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice, check_float, check_int
from energy_margin.evaluation.baselines import distance_scores
from energy_margin.evaluation.metrics import score_grid
from energy_margin.runs.files import read_json, write_json
from energy_margin.runs.results import TypedResult

__all__ = [
    "CALIBRATION_FORMAT",
    "CALIBRATION_VERSION",
    "SCORERS",
    "SCORES",
    "SCORE_FLOORS",
    "LiveAlarm",
    "MonitorCalibration",
    "alarm_frames",
    "alarm_measures",
    "calibrate_grid",
    "calibrate_monitor",
    "conformal_rank",
    "failure_frames",
    "load_calibration",
    "monitored_grid",
    "monitored_grids",
    "tree_capture_known",
    "watched_score",
    "worst_scores",
    "write_calibration",
]

#: What the monitor watches: the energy margin's scores or the distance baseline's.
SCORERS = ("margin", "distance")
#: Which per-frame score: success, capture, or the frame-wise minimum of the two.
SCORES = ("success", "capture", "min")
#: Each scorer's lowest score: no score is below it, so a threshold there never fires.
SCORE_FLOORS = {"margin": 0.0, "distance": -math.inf}
#: The ``format`` and ``version`` keys of a calibration file.
CALIBRATION_FORMAT = "energy-margin-monitor"
CALIBRATION_VERSION = 1


def conformal_rank(n: int, alpha: float) -> int:
    """The order statistic j = floor((n + 1) alpha) whose worst score is the threshold, 1 <= j <= n.

    Raises:
        InvalidParameterError: when ``alpha`` is outside (0, 1), or (n + 1) alpha < 1: too few
            successful roll-outs for that false-alarm rate.

    """
    check_float("alpha", alpha, minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True)
    # The small tolerance keeps (19 + 1) * 0.05 at 1 despite rounding.
    rank = min(n, math.floor((n + 1) * alpha + 1e-9))
    if rank < 1:
        needed = math.ceil(1.0 / alpha - 1.0 - 1e-9)
        raise InvalidParameterError(
            "alpha",
            f"{alpha:g} needs at least {needed} successful calibration roll-outs ((n + 1) alpha >= 1); "
            f"the calibration set has {n}",
        )
    return rank


def _check_window(grid: np.ndarray, start_frame: int, persistence: int) -> None:
    """``start_frame`` within the K frames of ``grid``; ``persistence`` at most the monitored frames."""
    check_int("start_frame", start_frame, minimum=0, maximum=grid.shape[1] - 1)
    check_int("persistence", persistence, minimum=1, maximum=grid.shape[1] - start_frame)


def worst_scores(grid: np.ndarray, *, start_frame: int = 0, persistence: int = 1) -> np.ndarray:
    """Each trajectory's ``persistence``-th smallest score over frames ``start_frame`` .. K - 1.

    Args:
        grid: scores, shape (T, K).
        start_frame: the first monitored frame.
        persistence: which order statistic, 1 (the smallest) .. K - ``start_frame``.

    Returns:
        Shape (T,), the scores' unit.

    """
    grid = np.asarray(grid, dtype=float)
    _check_window(grid, start_frame, persistence)
    return np.sort(grid[:, start_frame:], axis=1)[:, persistence - 1]


def alarm_frames(grid: np.ndarray, threshold: float, *, start_frame: int = 0, persistence: int = 1) -> np.ndarray:
    """The ``persistence``-th frame >= ``start_frame`` whose score is below ``threshold``; -1: none.

    Args:
        grid: scores, shape (T, K).
        threshold: the calibrated threshold, in the scores' unit.
        start_frame: the first monitored frame.
        persistence: how many monitored frames below the threshold raise the alarm, >= 1.

    Returns:
        Frame indices, shape (T,), int; -1 where the alarm never fires.

    """
    grid = np.asarray(grid, dtype=float)
    _check_window(grid, start_frame, persistence)
    counted = np.cumsum(grid[:, start_frame:] < threshold, axis=1) >= persistence
    return np.where(counted.any(axis=1), counted.argmax(axis=1) + start_frame, -1)


def failure_frames(captured: np.ndarray, success: np.ndarray) -> np.ndarray:
    """The frame at which failure becomes certain by the labels, per trajectory; -1 for a success.

    Args:
        captured: capture label of every frame (k-hat 0), shape (T, K), bool.
        success: success label of every trajectory, shape (T,), bool.

    Returns:
        Shape (T,), int: for a failed trajectory the first frame from which ``captured`` stays
        False to the end (K - 1 when its last frame is captured), -1 for a successful one.

    """
    captured = np.asarray(captured, dtype=bool)
    frames = captured.shape[1]
    # Frames captured at or after each frame, counted from the end.
    later = np.cumsum(captured[:, ::-1], axis=1)[:, ::-1]
    never_again = later == 0
    first = np.where(never_again.any(axis=1), never_again.argmax(axis=1), frames - 1)
    return np.where(np.asarray(success, dtype=bool), -1, first)


def alarm_measures(alarms: np.ndarray, failures: np.ndarray, times: np.ndarray) -> dict[str, float | None]:
    """The four measures of one set of trajectories (``None`` where undefined).

    Args:
        alarms: alarm frame per trajectory, shape (T,), -1 for none (``monitor.alarm_frames``).
        failures: failure frame per trajectory, shape (T,), -1 for a success (:func:`failure_frames`).
        times: time of every frame, shape (T, K), s.

    """
    failed = failures >= 0
    fired = alarms >= 0
    rows = np.arange(alarms.size)
    detected = failed & fired
    lead = times[rows, failures] - times[rows, alarms]
    return {
        "detection_rate": float(fired[failed].mean()) if failed.any() else None,
        "early_detection_rate": float((detected & (alarms <= failures))[failed].mean()) if failed.any() else None,
        "lead_time_s": float(lead[detected].mean()) if detected.any() else None,
        "false_alarm_rate": float(fired[~failed].mean()) if (~failed).any() else None,
    }


@dataclass(frozen=True, kw_only=True)
class MonitorCalibration(TypedResult):
    """A calibrated alarm: fire at the ``persistence``-th monitored frame whose score is below ``threshold``.

    Attributes:
        threshold: the nonconformity of rank ``rank`` among the calibration successes (each
            success's ``persistence``-th smallest monitored score; the score's unit: a probability
            for ``margin``, metres for ``distance``).
        alpha: the false-alarm rate guaranteed on successful roll-outs exchangeable with the
            calibration ones.
        rank: j = floor((n + 1) alpha), the order statistic taken.
        n_successes: n, the successful calibration roll-outs.
        n_trajectories: all roll-outs of the calibration set (its failures are not used).
        scorer: ``margin`` or ``distance``.
        score: ``success``, ``capture`` or ``min``.
        start_frame: the first monitored frame.
        persistence: how many monitored frames below the threshold raise the alarm (1: the first).
        dataset: the calibration dataset's directory; empty for a grid.
        dataset_seed: its generation seed; ``None`` for a grid or a set without one.
        task: its task; empty for a grid.

    """

    threshold: float
    alpha: float
    rank: int
    n_successes: int
    n_trajectories: int
    scorer: str
    score: str
    start_frame: int
    persistence: int = 1
    dataset: str = ""
    dataset_seed: int | None = None
    task: str = ""

    @property
    def can_fire(self) -> bool:
        """False for a margin threshold of 0 or less: no probability is below it, the alarm never fires."""
        return self.threshold > SCORE_FLOORS[self.scorer]

    def fires(self, value: float) -> bool:
        """Whether a monitored frame whose score is ``value`` counts toward the alarm (is below the threshold)."""
        return bool(value < self.threshold)

    def watched(self, capture: float, success: float) -> float:
        """The watched score of a frame whose capture and success scores are given."""
        return watched_score(self.score, capture, success)


def watched_score(score: str, capture: float, success: float) -> float:
    """The ``score`` (of :data:`SCORES`) of a frame whose capture and success scores are given."""
    return {"success": success, "capture": capture, "min": min(capture, success)}[score]


class LiveAlarm:
    """The alarm of a margin calibration over the scored calls of one live episode.

    Call k after :meth:`reset` (the reset's own call is 0) stands for frame k of the calibration's
    trajectories, so the calibration set's frames should be as far apart as the live calls (a set
    recorded from the same wrapper and cadence, ``energy-margin record``, or the live calls
    themselves: :func:`~energy_margin.evaluation.live_calibration.calibrate_episodes`). The alarm is raised at
    the ``persistence``-th monitored call below the threshold and stays raised until the next reset.

    Raises:
        InvalidParameterError: a ``distance`` calibration (live calls score margins only), or one
            that cannot fire (:attr:`MonitorCalibration.can_fire`).

    """

    def __init__(self, calibration: MonitorCalibration) -> None:
        if calibration.scorer != "margin":
            raise InvalidParameterError(
                "calibration", f"watches the {calibration.scorer} baseline; a live scorer needs a margin calibration"
            )
        if not calibration.can_fire:
            raise InvalidParameterError(
                "calibration",
                f"has threshold {calibration.threshold:g}, below which no margin falls: the alarm could never fire; "
                "calibrate again with a larger persistence or a later start frame",
            )
        self.calibration = calibration
        self.calls = 0
        self.below = 0
        self.fired_at: int | None = None

    def reset(self) -> None:
        """A new episode: no call yet, no alarm."""
        self.calls = 0
        self.below = 0
        self.fired_at = None

    def update(self, capture: float, success: float) -> bool:
        """Add the next call's scores; whether the alarm is raised (now or earlier in the episode)."""
        frame = self.calls
        self.calls += 1
        found = self.calibration
        if self.fired_at is None and frame >= found.start_frame and found.fires(found.watched(capture, success)):
            self.below += 1
            if self.below >= found.persistence:
                self.fired_at = frame
        return self.fired_at is not None


def calibrate_grid(
    grid: np.ndarray,
    success: np.ndarray,
    *,
    alpha: float,
    start_frame: int = 0,
    persistence: int = 1,
    scorer: str = "margin",
    score: str = "success",
) -> MonitorCalibration:
    """Calibrate on the successful rows of a score grid (the failed rows are ignored).

    Args:
        grid: per-frame scores, shape (T, K).
        success: success label of each trajectory, shape (T,), bool.
        alpha: the false-alarm rate to guarantee, in (0, 1).
        start_frame: the first monitored frame.
        persistence: how many monitored frames below the threshold raise the alarm, >= 1.
        scorer: recorded in the result (``margin`` or ``distance``).
        score: recorded in the result (``success``, ``capture`` or ``min``).

    """
    worst = worst_scores(grid, start_frame=start_frame, persistence=persistence)[np.asarray(success, dtype=bool)]
    rank = conformal_rank(worst.size, alpha)
    return MonitorCalibration(
        threshold=float(np.sort(worst)[rank - 1]),
        alpha=float(alpha),
        rank=rank,
        n_successes=int(worst.size),
        n_trajectories=int(np.asarray(grid).shape[0]),
        scorer=scorer,
        score=score,
        start_frame=start_frame,
        persistence=persistence,
    )


def monitored_grids(dataset: Dataset, path: Path | str, *, scorer: str = "margin") -> dict[str, np.ndarray]:
    """Every score the monitor can watch of an analysed dataset, each shape (T, K), by name.

    Keys are :data:`SCORES`: ``success``, ``capture`` and ``min`` (their frame-wise minimum). The
    grids are built once here, for callers that try several scores.

    Raises:
        EnergyMarginError: ``scorer="distance"`` on a task whose regions measure no distance.

    """
    check_choice("scorer", scorer, SCORERS)
    if scorer == "margin":
        scores = load_scores(path)
        column = "tree_capture_score" if tree_capture_known(scores) else "capture_score"
        capture = score_grid(dataset, scores, column)
        success = score_grid(dataset, scores, "success_score")
    else:
        distances = distance_scores(dataset)
        if distances is None:
            raise EnergyMarginError(f"the regions of task {dataset.metadata['task']} measure no distance")
        capture, success = distances
    return {"success": success, "capture": capture, "min": np.minimum(capture, success)}


def tree_capture_known(scores: dict[str, np.ndarray]) -> bool:
    """Whether scores columns hold every frame's tree capture score (``tree_capture_score``).

    ``scores``: columns as :func:`~energy_margin.data.scores_file.load_scores` reads them. Files
    written before the tree's own capture score was kept, and scores no tree grew, lack it.
    """
    return bool(np.all(np.isfinite(scores["tree_capture_score"])))


def monitored_grid(dataset: Dataset, path: Path | str, *, scorer: str = "margin", score: str = "success") -> np.ndarray:
    """The per-frame score the monitor watches, shape (T, K), of an analysed dataset.

    Raises:
        EnergyMarginError: ``scorer="distance"`` on a task whose regions measure no distance.

    """
    check_choice("score", score, SCORES)
    return monitored_grids(dataset, path, scorer=scorer)[score]


def calibrate_monitor(
    path: Path | str,
    *,
    alpha: float,
    scorer: str = "margin",
    score: str = "success",
    start_frame: int = 0,
    persistence: int = 1,
) -> MonitorCalibration:
    """Calibrate the alarm on the successful trajectories of an analysed dataset directory.

    Args:
        path: dataset directory; ``scorer="margin"`` needs its ``scores.csv``.
        alpha: the false-alarm rate to guarantee on successful roll-outs, in (0, 1).
        scorer: ``margin`` (the energy-margin scores) or ``distance`` (the distance baseline).
        score: ``success``, ``capture`` or ``min`` (their frame-wise minimum).
        start_frame: the first monitored frame.
        persistence: how many monitored frames below the threshold raise the alarm, >= 1.

    Raises:
        InvalidParameterError: too few successes for ``alpha``, or a bad option.

    """
    dataset = require_valid(path, overlaps=True, scores=True if scorer == "margin" else None)
    grid = monitored_grid(dataset, path, scorer=scorer, score=score)
    found = calibrate_grid(
        grid,
        dataset.success_labels(),
        alpha=alpha,
        start_frame=start_frame,
        persistence=persistence,
        scorer=scorer,
        score=score,
    )
    seed = dataset.metadata.get("seed")
    recorded = {"dataset": str(path), "dataset_seed": seed if isinstance(seed, int) else None}
    return MonitorCalibration.from_dict(found.to_dict() | recorded | {"task": dataset.metadata["task"]})


def write_calibration(path: Path | str, calibrations: list[MonitorCalibration]) -> None:
    """Write calibrations (one per alpha, say) as ``{"format", "version", "calibrations": [...]}``."""
    write_json(
        Path(path),
        {
            "format": CALIBRATION_FORMAT,
            "version": CALIBRATION_VERSION,
            "calibrations": [calibration.to_dict() for calibration in calibrations],
        },
    )


def load_calibration(path: Path | str, *, alpha: float | None = None) -> MonitorCalibration:
    """The calibration of ``alpha`` in a file of :func:`write_calibration` (``None``: its only one).

    Raises:
        EnergyMarginError: not a monitor calibration file, an unknown version, or no (single)
            calibration of that alpha.

    """
    data: Any = read_json(Path(path), what="monitor calibration")
    if not isinstance(data, dict) or data.get("format") != CALIBRATION_FORMAT:
        raise EnergyMarginError(f"{path} is not a monitor calibration file (format {CALIBRATION_FORMAT!r})")
    if data.get("version") != CALIBRATION_VERSION:
        raise EnergyMarginError(f"{path} has version {data.get('version')!r}; this release reads {CALIBRATION_VERSION}")
    found = [MonitorCalibration.from_dict(entry) for entry in data.get("calibrations", [])]
    chosen = found if alpha is None else [entry for entry in found if math.isclose(entry.alpha, alpha)]
    if len(chosen) != 1:
        alphas = ", ".join(f"{entry.alpha:g}" for entry in found) or "none"
        if alpha is None:
            raise EnergyMarginError(f"{path} holds {len(found)} calibrations (alphas: {alphas}); pick one by its alpha")
        raise InvalidParameterError("alpha", f"{alpha} picks no single calibration of {path} (alphas: {alphas})")
    return chosen[0]
