"""Average Precision of the scores against the ground-truth labels, with baselines beside them.

Questions answered (each with the energy-margin score and every baseline):

* capture at k-hat = ``capture_window`` (default 0: the frame alone) and at k-hat = 2 (the objects
  stay captured for two more frames), once when ``capture_window`` is 2;
* trajectory success from the weighted last k-bar frames, and from the first half of the frames
  only (an early prediction).

Baselines: ``current_state`` (the indicator that the frame itself is inside the set, scored the
same way), ``chance`` (a constant score, whose AP equals the positive rate) and ``distance`` (the
smallest signed distance of an object to the capture or success region, :mod:`energy_margin.evaluation.baselines`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import Dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.data.validation import require_valid
from energy_margin.errors import (
    EnergyMarginError,
    InvalidParameterError,
    check_choice,
    check_int,
    check_positive_int,
    check_seed,
)
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import evaluate_capture_windows
from energy_margin.evaluation.explain import explain_failures, format_explanations
from energy_margin.evaluation.verdict import verdicts
from energy_margin.runs.results import TypedResult, plain_result

__all__ = ["Evaluation", "average_precision", "check_options", "evaluate", "question_aps", "score_grid"]


def average_precision(labels: np.ndarray, scores: np.ndarray) -> float | None:
    """scikit-learn's Average Precision, or ``None`` when the labels hold a single class."""
    from sklearn.metrics import average_precision_score

    labels = np.asarray(labels, dtype=bool).ravel()
    scores = np.asarray(scores, dtype=float).ravel()
    if labels.all() or not labels.any():
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(average_precision_score(labels, scores))


@dataclass(frozen=True, kw_only=True)
class Evaluation(TypedResult):
    """What :func:`evaluate` measured: the margin's AP per question, its baselines', the verdict.

    ``to_dict()`` is the JSON of ``evaluate --json`` (documented in ``docs/results/results.md``). An AP is
    ``None`` when the labels of its question hold a single class.

    Attributes:
        capture_ap: AP of the capture score at k-hat ``capture_window``.
        capture_ap_window2: AP at k-hat 2; absent when ``capture_window`` is 2.
        success_ap: AP of the trajectory success score (the last ``success_frames`` frames).
        success_ap_first_half: the same from the first half of the frames (an early prediction).
        baselines: the same questions per baseline (``current_state``, ``chance``, ``distance``).
        verdict: per question, the margin against the best baseline (paired bootstrap); ``None``
            without resamples.
        verdict_resamples: the resamples behind the verdict; ``None`` without one.
        seed: the resamples' seed; ``None`` without a verdict.
        capture_window: k-hat of ``capture_ap``.
        success_frames: k-bar of the success score.
        weights: the success score's weighting (``linear`` or ``uniform``).
        capture_positive_rate: share of frames captured at k-hat ``capture_window``.
        capture_positive_rate_window2: the share at k-hat 2; absent when ``capture_window`` is 2.
        success_positive_rate: share of successful trajectories.
        n_frames: frames scored.
        n_trajectories: trajectories of the dataset.
        n_objects: objects per scene.
        task: the dataset's task.
        runtime_per_frame_s: mean wall time of a frame's analysis, s.
        runtime_per_frame_std_s: its standard deviation, s.
        physics_per_frame_s: mean time of a frame spent in the physics engine, s.
        explanations: with ``explain``, each failed trajectory's account
            (:meth:`energy_margin.evaluation.explain.FailureExplanation.to_dict`); absent without.

    """

    capture_ap: float | None
    capture_ap_window2: float | None = None
    success_ap: float | None
    success_ap_first_half: float | None
    baselines: dict[str, dict[str, float | None]]
    verdict: dict[str, dict[str, Any]] | None = None
    verdict_resamples: int | None = None
    seed: int | None = None
    capture_window: int
    success_frames: int
    weights: str
    capture_positive_rate: float
    capture_positive_rate_window2: float | None = None
    success_positive_rate: float
    n_frames: int
    n_trajectories: int
    n_objects: int
    task: str
    runtime_per_frame_s: float
    runtime_per_frame_std_s: float
    physics_per_frame_s: float
    explanations: list[dict[str, Any]] | None = None

    def absent(self) -> set[str]:
        """The k-hat 2 fields when ``capture_window`` is 2, the verdict's without one, explanations without them."""
        left_out = set()
        if self.explanations is None:
            left_out.add("explanations")
        if self.capture_window == 2:
            left_out |= {"capture_ap_window2", "capture_positive_rate_window2"}
        if self.verdict is None:
            left_out |= {"verdict", "verdict_resamples", "seed"}
        return left_out


def score_grid(dataset: Dataset, scores: dict[str, np.ndarray], column: str) -> np.ndarray:
    """Arrange a scores column as (n_trajectories, n_frames); every frame must be present once."""
    grid = np.full((dataset.n_trajectories, dataset.n_frames), np.nan)
    seen = np.zeros(grid.shape, dtype=int)
    for trajectory, frame, value in zip(scores["trajectory"], scores["frame"], scores[column], strict=True):
        if not (0 <= trajectory < grid.shape[0] and 0 <= frame < grid.shape[1]):
            raise EnergyMarginError(f"scores row for trajectory {trajectory}, frame {frame} is outside the dataset")
        grid[trajectory, frame] = value
        seen[trajectory, frame] += 1
    if np.any(seen != 1):
        trajectory, frame = (int(i) for i in np.argwhere(seen != 1)[0])
        raise EnergyMarginError(
            f"scores.csv has {seen[trajectory, frame]} rows for trajectory {trajectory}, frame {frame} (expected 1)"
        )
    if not np.all(np.isfinite(grid)):
        raise EnergyMarginError(f"scores.csv has a NaN or infinite {column}")
    return grid


def question_aps(
    dataset: Dataset,
    capture: np.ndarray,
    success: np.ndarray,
    *,
    capture_window: int,
    success_frames: int,
    weights: str,
) -> dict[str, float | None]:
    """The AP of every question of :func:`evaluate` for one set of scores, without baselines.

    Args:
        dataset: the dataset whose labels are the truth.
        capture: capture scores, shape (n_trajectories, n_frames).
        success: success scores, shape (n_trajectories, n_frames).
        capture_window: k-hat of the capture question (k-hat = 2 is answered too).
        success_frames: k-bar, the last frames weighted into a trajectory's success score.
        weights: how the k-bar frames are weighted (:func:`trajectory_success_score`'s ``scheme``).

    Returns:
        ``{"capture_ap": ..., "capture_ap_window2": ..., "success_ap": ..., "success_ap_first_half": ...}``
        (the keys of :func:`evaluate`), ``None`` where the labels hold one class.

    """
    half = max(1, dataset.n_frames // 2)
    success_labels = dataset.success_labels()
    return {
        **{
            key: average_precision(dataset.capture_labels(window), capture)
            for key, window in evaluate_capture_windows(capture_window).items()
        },
        "success_ap": average_precision(
            success_labels, trajectory_success_score(success, last=success_frames, scheme=weights)
        ),
        "success_ap_first_half": average_precision(
            success_labels, trajectory_success_score(success[:, :half], last=success_frames, scheme=weights)
        ),
    }


def check_options(dataset: Dataset, *, capture_window: int, success_frames: int) -> None:
    """Refuse a k-hat or k-bar that does not fit the dataset's frames.

    Raises:
        EnergyMarginError: when ``capture_window`` >= the frames per trajectory (the window would
            reach past every trajectory's end) or ``success_frames`` exceeds them.
    """
    frames = dataset.n_frames
    if capture_window >= frames:
        raise InvalidParameterError(
            "capture_window",
            f"{capture_window} needs more than {capture_window} frames per trajectory; "
            f"{dataset.path} has {frames} (largest window {frames - 1})",
        )
    if success_frames > frames:
        raise InvalidParameterError(
            "success_frames", f"{success_frames} exceeds the {frames} frames per trajectory of {dataset.path}"
        )


def evaluate(
    path: Path | str,
    *,
    capture_window: int = 0,
    success_frames: int = 3,
    weights: str = "linear",
    resamples: int = 1000,
    seed: int = 0,
    explain: bool = False,
) -> Evaluation:
    """AP of a scored dataset, its baselines' and the verdict of the margin against the best of them.

    Args:
        path: dataset directory holding ``scores.csv``.
        capture_window: k-hat of the capture label, >= 0.
        success_frames: k-bar, frames averaged by the trajectory success score, >= 1.
        weights: ``"linear"`` (increasing towards the end) or ``"uniform"``.
        resamples: bootstrap resamples of the trajectories behind the verdict's paired intervals
            (:mod:`energy_margin.evaluation.verdict`), >= 0; 0 gives no verdict.
        seed: seeds the resamples.
        explain: also account for each failed trajectory: which object left the capture region
            or missed the success region, at which frame, time and position
            (:func:`energy_margin.evaluation.explain.explain_failures`).

    Returns:
        The :class:`Evaluation`; ``.to_dict()`` is the JSON of ``evaluate --json`` (keys in
        ``docs/reference/commands.md`` and ``docs/results/results.md``).

    """
    check_int("capture_window", capture_window, minimum=0)
    check_positive_int("success_frames", success_frames)
    check_choice("weights", weights, ("linear", "uniform"))
    check_int("resamples", resamples, minimum=0)
    check_seed(seed)
    dataset = require_valid(path, overlaps=True, scores=None)
    check_options(dataset, capture_window=capture_window, success_frames=success_frames)
    scores = load_scores(path)
    capture = score_grid(dataset, scores, "capture_score")
    success = score_grid(dataset, scores, "success_score")
    runtime = score_grid(dataset, scores, "runtime_s")
    physics = score_grid(dataset, scores, "physics_s")
    options: dict[str, Any] = {"capture_window": capture_window, "success_frames": success_frames, "weights": weights}
    result: dict[str, Any] = dict(question_aps(dataset, capture, success, **options))
    grids = baseline_grids(dataset)
    constant = np.zeros_like(capture)
    result["baselines"] = {
        "current_state": question_aps(dataset, *grids["current_state"], **options),
        "chance": question_aps(dataset, constant, constant, **options),
    }
    if "distance" in grids:
        result["baselines"]["distance"] = question_aps(dataset, *grids["distance"], **options)
    if resamples:
        found = verdicts(dataset, (capture, success), grids, **options, resamples=resamples, seed=seed)
        result["verdict"] = {question: found[question].to_dict() for question in found}
        result["verdict_resamples"] = resamples
        result["seed"] = seed
    rates = {
        key.replace("capture_ap", "capture_positive_rate"): float(dataset.capture_labels(window).mean())
        for key, window in evaluate_capture_windows(capture_window).items()
    }
    result.update(
        {
            "capture_window": capture_window,
            "success_frames": success_frames,
            "weights": weights,
            **rates,
            "success_positive_rate": float(dataset.success_labels().mean()),
            "n_frames": int(capture.size),
            "n_trajectories": dataset.n_trajectories,
            "n_objects": dataset.n_objects,
            "task": dataset.metadata["task"],
            "runtime_per_frame_s": float(runtime.mean()),
            "runtime_per_frame_std_s": float(runtime.std()),
            "physics_per_frame_s": float(physics.mean()),
        }
    )
    if explain:
        result["explanations"] = [item.to_dict() for item in explain_failures(dataset)]
    return Evaluation.from_dict(result)


def _cell(value: float | None) -> str:
    return "  n/a" if value is None else f"{value:5.3f}"


def verdict_cell(verdict: dict[str, Any], drawn: int | None = None) -> str:
    """One verdict as ``+0.100 [+0.020, +0.200] ahead (distance)``; ``n/a`` where it is undefined.

    The difference is the margin's AP minus the best baseline's (named in brackets), then its paired
    95 % interval and the word. ``drawn``: the resamples drawn; when the interval rests on fewer
    (a resample whose labels are all one class has no AP, so no difference), the brackets say so:
    ``(distance; interval from 998 of 1000 resamples, 2 had labels of one class: no AP)``.
    """
    if verdict["difference"] is None or verdict["low"] is None or verdict["high"] is None:
        return "n/a"
    used = verdict.get("resamples", drawn)
    fewer = ""
    if drawn is not None and used is not None and used < drawn:
        fewer = f"; interval from {used} of {drawn} resamples, {drawn - used} had labels of one class: no AP"
    return (
        f"{verdict['difference']:+.3f} [{verdict['low']:+.3f}, {verdict['high']:+.3f}] "
        f"{verdict['word']} ({verdict['baseline']}{fewer})"
    )


def format_table(result: Evaluation | dict[str, Any]) -> str:
    """A human-readable table of :func:`evaluate`'s result (or its dictionary)."""
    result = plain_result(result)
    k_hat, k_bar = result["capture_window"], result["success_frames"]
    rows = [
        *((f"capture AP, k-hat={window}", key) for key, window in evaluate_capture_windows(k_hat).items()),
        (f"success AP, last {k_bar} frames", "success_ap"),
        ("success AP, first half of frames", "success_ap_first_half"),
    ]
    names = list(result["baselines"])
    verdict = result.get("verdict")
    header = f"{'question':34s} {'energy-margin':>13s} " + " ".join(f"{n:>13s}" for n in names)
    if verdict:
        header += "  margin - best baseline [95 %]"
    lines = [
        f"{result['task']}: {result['n_trajectories']} trajectories, {result['n_frames']} frames, "
        f"{result['n_objects']} objects",
        header,
        "-" * len(header),
    ]
    for label, key in rows:
        baseline_cells = " ".join(f"{_cell(result['baselines'][n][key]):>13s}" for n in names)
        line = f"{label:34s} {_cell(result[key]):>13s} {baseline_cells}"
        if verdict:
            line += f"  {verdict_cell(verdict[key], int(result['verdict_resamples']))}"
        lines.append(line)
    if verdict:
        lines.append(
            f"verdict: paired bootstrap over trajectories ({result['verdict_resamples']} resamples, seed "
            f"{result['seed']}); ahead / behind: the interval lies above / below 0, level: it holds 0"
        )
    lines.append(
        f"positive rate: capture {result['capture_positive_rate']:.3f} (k-hat={k_hat}), "
        f"success {result['success_positive_rate']:.3f}"
    )
    lines.append(
        f"runtime per frame: {result['runtime_per_frame_s']:.3f} +- {result['runtime_per_frame_std_s']:.3f} s "
        f"(physics {result['physics_per_frame_s']:.3f} s)"
    )
    if result.get("explanations") is not None:
        lines.append(format_explanations(result["explanations"], int(result["n_objects"])))
    return "\n".join(lines)
