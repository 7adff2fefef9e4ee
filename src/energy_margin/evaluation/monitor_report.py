"""How a calibrated alarm does on a test set: detection, lead time and the realised false-alarm rate.

On a failed test trajectory, failure becomes certain by the labels at its *failure frame*: the first
frame from which the capture label (``captured``, k-hat 0) stays negative to the last frame; when
the last frame is still captured (the trajectory fails only the success region), the last frame.
A successful trajectory has none.

* **detection rate**: share of failed trajectories on which the alarm fires at some monitored frame;
* **early detection rate**: share on which it fires at or before the failure frame;
* **lead time**: on the detected failed trajectories, the time of the failure frame minus the time of
  the alarm frame (``frame_time``, s), mean; negative when the alarm comes after;
* **false-alarm rate**: share of successful trajectories on which the alarm fires (the calibration
  promises at most alpha on average over calibration sets).

Each comes with a 95 % percentile interval over bootstrap resamples of the test trajectories (the
threshold held fixed). :func:`compare_monitors` calibrates the margin and the distance baseline on
one dataset for each alpha and reports both on another.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.validation import require_valid
from energy_margin.errors import InvalidParameterError, check_int, check_seed
from energy_margin.evaluation.baselines import distance_scores
from energy_margin.evaluation.bootstrap import percentile_interval
from energy_margin.evaluation.monitor import (
    SCORERS,
    MonitorCalibration,
    alarm_frames,
    alarm_measures,
    calibrate_monitor,
    failure_frames,
    monitored_grid,
)
from energy_margin.evaluation.monitor_select import AlarmChoice, select_alarms
from energy_margin.runs.results import TypedResult, plain_result

__all__ = [
    "MonitorComparison",
    "MonitorEvaluation",
    "alarm_measures",
    "compare_monitors",
    "evaluate_monitor",
    "failure_frames",
    "format_table",
]

_MEASURES = ("detection_rate", "early_detection_rate", "lead_time_s", "false_alarm_rate")


@dataclass(frozen=True, kw_only=True)
class MonitorEvaluation(TypedResult):
    """A calibrated alarm on a test set; each measure with its 95 % bootstrap interval (``_low``, ``_high``).

    Rates are shares in [0, 1], lead times seconds; a measure is ``None`` when the test set has no
    trajectory it is defined on (no failure, no detection, no success).
    """

    scorer: str
    score: str
    alpha: float
    threshold: float
    start_frame: int
    persistence: int
    can_fire: bool
    detection_rate: float | None
    detection_rate_low: float | None
    detection_rate_high: float | None
    early_detection_rate: float | None
    early_detection_rate_low: float | None
    early_detection_rate_high: float | None
    lead_time_s: float | None
    lead_time_s_low: float | None
    lead_time_s_high: float | None
    false_alarm_rate: float | None
    false_alarm_rate_low: float | None
    false_alarm_rate_high: float | None
    n_failed: int
    n_successful: int
    resamples: int
    seed: int


def evaluate_monitor(
    calibration: MonitorCalibration, path: Path | str, *, resamples: int = 1000, seed: int = 0
) -> MonitorEvaluation:
    """The alarm of ``calibration`` on the analysed dataset directory ``path``.

    Args:
        calibration: from :func:`~energy_margin.evaluation.monitor.calibrate_monitor`.
        path: the test dataset (``scores.csv`` needed for a ``margin`` calibration).
        resamples: bootstrap resamples of the test trajectories, >= 1.
        seed: seeds the resamples.

    """
    check_int("resamples", resamples, minimum=1)
    check_seed(seed)
    dataset = require_valid(path, overlaps=True, scores=True if calibration.scorer == "margin" else None)
    grid = monitored_grid(dataset, path, scorer=calibration.scorer, score=calibration.score)
    alarms = alarm_frames(
        grid, calibration.threshold, start_frame=calibration.start_frame, persistence=calibration.persistence
    )
    failures = failure_frames(dataset.arrays["captured"], dataset.success_labels())
    times = np.asarray(dataset.arrays["frame_time"], dtype=float)
    found: dict[str, Any] = dict(alarm_measures(alarms, failures, times))
    rng = np.random.default_rng(seed)
    drawn = rng.integers(0, alarms.size, size=(resamples, alarms.size))
    samples = {name: np.full(resamples, np.nan) for name in _MEASURES}
    for number, rows in enumerate(drawn):
        for name, value in alarm_measures(alarms[rows], failures[rows], times[rows]).items():
            if value is not None:
                samples[name][number] = value
    for name in _MEASURES:
        found[f"{name}_low"], found[f"{name}_high"] = percentile_interval(samples[name])
    return MonitorEvaluation.from_dict(
        found
        | {
            "scorer": calibration.scorer,
            "score": calibration.score,
            "alpha": calibration.alpha,
            "threshold": calibration.threshold,
            "start_frame": calibration.start_frame,
            "persistence": calibration.persistence,
            "can_fire": calibration.can_fire,
            "n_failed": int((failures >= 0).sum()),
            "n_successful": int((failures < 0).sum()),
            "resamples": resamples,
            "seed": seed,
        }
    )


@dataclass(frozen=True, kw_only=True)
class MonitorComparison(TypedResult):
    """Margin and distance alarms, each calibrated on one dataset and evaluated on another, per alpha.

    Attributes:
        calibration_dataset: the calibration set's directory.
        test_dataset: the test set's directory.
        calibration_seed: the calibration set's generation seed (``None``: not recorded).
        test_seed: the test set's generation seed.
        task: the calibration set's task.
        calibrations: one :class:`~energy_margin.evaluation.monitor.MonitorCalibration` dictionary
            per scorer and alpha.
        evaluations: one :class:`MonitorEvaluation` dictionary per scorer and alpha, same order.
        choices: with a selection set, one
            :class:`~energy_margin.evaluation.monitor_select.AlarmChoice` dictionary per scorer and
            alpha, same order, without its candidates; empty without one.

    """

    calibration_dataset: str
    test_dataset: str
    calibration_seed: int | None
    test_seed: int | None
    task: str
    calibrations: list[dict[str, Any]]
    evaluations: list[dict[str, Any]]
    choices: list[dict[str, Any]] = field(default_factory=list)


def compare_monitors(
    calibration_path: Path | str,
    test_path: Path | str,
    *,
    alphas: tuple[float, ...] = (0.05, 0.1),
    score: str = "success",
    start_frame: int = 0,
    persistence: int = 1,
    selection: Path | str | None = None,
    max_persistence: int = 3,
    resamples: int = 1000,
    seed: int = 0,
) -> MonitorComparison:
    """Calibrate on ``calibration_path``'s successes, report on ``test_path``: margin, then distance.

    The distance alarm is left out for a task whose regions measure no distance. See
    :func:`~energy_margin.evaluation.monitor.calibrate_monitor` for ``score``, ``start_frame`` and
    ``persistence``. With ``selection``, a third analysed dataset, each alarm's score, start frame
    and persistence (up to ``max_persistence``) are chosen on it instead, per scorer and alpha
    (:func:`~energy_margin.evaluation.monitor_select.select_alarms`).

    Raises:
        InvalidParameterError: ``selection`` is the calibration set, or a bad option.

    """
    if selection is not None and Path(selection).resolve() == Path(calibration_path).resolve():
        raise InvalidParameterError(
            "selection", "is the calibration set: choose on a set of its own, or the false-alarm guarantee is spent"
        )
    test = require_valid(test_path, overlaps=True, scores=True)
    scorers = SCORERS if distance_scores(test) is not None else ("margin",)
    calibrations: list[MonitorCalibration] = []
    choices: list[dict[str, Any]] = []
    for scorer in scorers:
        chosen: list[AlarmChoice | None] = [None] * len(alphas)
        if selection is not None:
            chosen = list(select_alarms(selection, alphas=alphas, scorer=scorer, max_persistence=max_persistence))
        for alpha, choice in zip(alphas, chosen, strict=True):
            watched, first, frames_below = score, start_frame, persistence
            if choice is not None:
                watched, first, frames_below = choice.score, choice.start_frame, choice.persistence
                choices.append({key: value for key, value in choice.to_dict().items() if key != "candidates"})
            found = calibrate_monitor(
                calibration_path,
                alpha=alpha,
                scorer=scorer,
                score=watched,
                start_frame=first,
                persistence=frames_below,
            )
            calibrations.append(found)
    evaluations = [evaluate_monitor(found, test_path, resamples=resamples, seed=seed) for found in calibrations]
    test_seed = test.metadata.get("seed")
    return MonitorComparison(
        calibration_dataset=str(calibration_path),
        test_dataset=str(test_path),
        calibration_seed=calibrations[0].dataset_seed,
        test_seed=test_seed if isinstance(test_seed, int) else None,
        task=calibrations[0].task,
        calibrations=[found.to_dict() for found in calibrations],
        evaluations=[found.to_dict() for found in evaluations],
        choices=choices,
    )


def _cell(value: float | None, low: float | None, high: float | None, unit: str = "") -> str:
    if value is None:
        return "n/a"
    interval = "" if low is None or high is None else f" [{low:.2f}, {high:.2f}]"
    return f"{value:.2f}{unit}{interval}"


def format_table(result: MonitorComparison | dict[str, Any]) -> str:
    """A text table of :func:`compare_monitors`: one row per scorer and alpha."""
    result = plain_result(result)
    header = (
        f"{'alarm':10s} {'alpha':>5s} {'watched':19s} {'n':>3s} {'threshold':>10s}  {'detection':22s} "
        f"{'early detection':22s} {'lead time s':22s} false alarms"
    )
    lines = [
        f"{result['task']}: calibrated on the successes of {result['calibration_dataset']} (seed "
        f"{result['calibration_seed']}), tested on {result['test_dataset']} (seed {result['test_seed']})",
        header,
        "-" * len(header),
    ]
    for calibration, found in zip(result["calibrations"], result["evaluations"], strict=True):
        cells = [_cell(found[name], found[f"{name}_low"], found[f"{name}_high"]) for name in _MEASURES]
        watched = f"{found['score']} {found['start_frame']}+ x{found['persistence']}"
        lines.append(
            f"{found['scorer']:10s} {found['alpha']:5.2f} {watched:19s} {calibration['n_successes']:3d} "
            f"{found['threshold']:10.4g}  {cells[0]:22s} {cells[1]:22s} {cells[2]:22s} {cells[3]}"
        )
    first = result["evaluations"][0]
    lines.append(
        "watched: the score, from its first monitored frame (+), alarmed at that many frames below the threshold (x)"
    )
    if result.get("choices"):
        chosen = result["choices"][0]
        lines.append(
            f"chosen on {chosen['selection_dataset']} (seed {chosen['selection_seed']}): the most failures detected "
            "at or before their failure frame there, among those with room above the score's floor"
        )
        for choice in result["choices"]:
            if not choice.get("eligible", True):
                lines.append(
                    f"no {choice['scorer']} alarm at alpha {choice['alpha']:g} left room above the score's floor "
                    "on the selection set: the chosen one may not fire on another set"
                )
    lines.append(
        f"test set: {first['n_failed']} failed, {first['n_successful']} successful; 95 % intervals over "
        f"{first['resamples']} resamples of the test trajectories (seed {first['seed']})"
    )
    for found in result["evaluations"]:
        if not found["can_fire"]:
            lines.append(
                f"the {found['scorer']} alarm at alpha {found['alpha']:g} cannot fire: its threshold is 0 "
                f"(a calibration success scores 0 at {found['persistence']} or more monitored frames); "
                "calibrate with a larger persistence or a later start frame, or choose them on a selection set"
            )
    return "\n".join(lines)
