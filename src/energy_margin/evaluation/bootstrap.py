"""AP questions of a dataset with bootstrap intervals that resample whole trajectories.

:class:`Questions` holds a dataset's labels and answers capture questions (every frame against
the capture label with a look-ahead window k-hat) and success questions (every trajectory from the
weighted last frame scores of a span of its frames) on any resample of the trajectories.
:func:`summarize` gives point estimates with 95 % percentile intervals (``budget``);
:func:`score_questions` keeps every resample's answer, so that :func:`paired_difference` can
compare two scorers resample by resample (``study``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import Dataset

__all__ = [
    "SECOND_CAPTURE_WINDOW",
    "Questions",
    "Scored",
    "average_precision",
    "bootstrap_answers",
    "evaluate_capture_windows",
    "paired_difference",
    "percentile_interval",
    "score_questions",
    "summarize",
]


def average_precision(labels: np.ndarray, scores: np.ndarray) -> float | None:
    """Average Precision as scikit-learn computes it (ties form one threshold); ``None`` for one class."""
    labels = np.asarray(labels, dtype=bool).ravel()
    scores = np.asarray(scores, dtype=float).ravel()
    positives = int(labels.sum())
    if positives == 0 or positives == labels.size:
        return None
    order = np.argsort(-scores, kind="mergesort")
    ordered = scores[order]
    hits = np.cumsum(labels[order])
    last = np.r_[np.flatnonzero(np.diff(ordered)), labels.size - 1]
    true_positives = hits[last]
    precision = true_positives / (last + 1.0)
    recall = true_positives / positives
    return float(np.sum(np.diff(np.r_[0.0, recall]) * precision))


#: k-hat of ``evaluate``'s second capture question: do the objects stay captured two more frames?
SECOND_CAPTURE_WINDOW = 2


def evaluate_capture_windows(capture_window: int) -> dict[str, int]:
    """``evaluate``'s capture questions, JSON key -> k-hat, one per distinct k-hat.

    ``capture_ap`` at k-hat ``capture_window``, then ``capture_ap_window2`` at k-hat 2 unless
    ``capture_window`` is 2 itself (then ``capture_ap`` is that question: no second key holds it).
    """
    windows = {"capture_ap": capture_window}
    if capture_window != SECOND_CAPTURE_WINDOW:
        windows["capture_ap_window2"] = SECOND_CAPTURE_WINDOW
    return windows


class Questions:
    """Labels of one dataset and the AP of score grids on a resample of its trajectories.

    Capture questions score every frame against the capture label with a look-ahead window
    (k-hat); success questions score every trajectory from the weighted last ``success_frames``
    frame scores of a span of its frames.

    Args:
        dataset: the dataset.
        success_frames: k-bar, the frames averaged by a success question.
        capture_windows: question name -> k-hat (default: budget's two capture questions).
        success_spans: question name -> frame slice ``(start, stop)`` (``None`` bounds as in Python
            slices; default: the first half of the frames).
        weights: weights of the frames a success question averages, ``"linear"`` or ``"uniform"``.

    """

    def __init__(
        self,
        dataset: Dataset,
        success_frames: int = 3,
        *,
        capture_windows: dict[str, int] | None = None,
        success_spans: dict[str, tuple[int | None, int | None]] | None = None,
        weights: str = "linear",
    ) -> None:
        half = max(1, dataset.n_frames // 2)
        windows = capture_windows if capture_windows is not None else {"capture_ap": 0, "capture_ap_window2": 2}
        spans = success_spans if success_spans is not None else {"success_ap_first_half": (0, half)}
        self.capture = {name: dataset.capture_labels(window) for name, window in windows.items()}
        self.spans = {name: slice(*span) for name, span in spans.items()}
        self.success = dataset.success_labels()
        self.success_frames = success_frames
        self.weights = weights
        self.names: tuple[str, ...] = (*self.capture, *self.spans)

    @classmethod
    def of_evaluate(
        cls, dataset: Dataset, *, capture_window: int = 0, success_frames: int = 3, weights: str = "linear"
    ) -> Questions:
        """``evaluate``'s questions, under its keys.

        The capture questions of :func:`evaluate_capture_windows`, then ``success_ap`` (all frames)
        and ``success_ap_first_half``.
        """
        half = max(1, dataset.n_frames // 2)
        return cls(
            dataset,
            success_frames,
            capture_windows=evaluate_capture_windows(capture_window),
            success_spans={"success_ap": (None, None), "success_ap_first_half": (0, half)},
            weights=weights,
        )

    def answer(self, capture: np.ndarray, success: np.ndarray, rows: np.ndarray) -> dict[str, float | None]:
        """AP of each question on trajectories ``rows`` (indices, repeats allowed).

        Args:
            capture: capture scores, shape (T, K).
            success: success scores, shape (T, K).
            rows: trajectory indices, shape (n,).

        """
        result: dict[str, float | None] = {
            name: average_precision(labels[rows], capture[rows]) for name, labels in self.capture.items()
        }
        for name, span in self.spans.items():
            scores = trajectory_success_score(success[rows, span], last=self.success_frames, scheme=self.weights)
            result[name] = average_precision(self.success[rows], scores)
        return result


def bootstrap_answers(
    questions: Questions, capture: np.ndarray, success: np.ndarray, resamples: np.ndarray
) -> dict[str, np.ndarray]:
    """Each question's AP on every resample, shape (n_resamples,), NaN where the resample has one class.

    Args:
        questions: the questions.
        capture: capture scores, shape (T, K).
        success: success scores, shape (T, K).
        resamples: trajectory indices of each resample, shape (n_resamples, T).

    """
    samples = {name: np.full(len(resamples), np.nan) for name in questions.names}
    for number, rows in enumerate(resamples):
        for name, value in questions.answer(capture, success, rows).items():
            if value is not None:
                samples[name][number] = value
    return samples


def percentile_interval(values: np.ndarray) -> tuple[float | None, float | None]:
    """The 95 % percentile interval of the finite ``values`` (shape (n,)); ``(None, None)`` if none."""
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return None, None
    low, high = np.percentile(finite, [2.5, 97.5])
    return float(low), float(high)


def summarize(
    questions: Questions, capture: np.ndarray, success: np.ndarray, resamples: np.ndarray
) -> dict[str, float | None]:
    """Point estimates and 95 % percentile intervals over ``resamples`` (n, T) of trajectory indices."""
    point = questions.answer(capture, success, np.arange(capture.shape[0]))
    samples = bootstrap_answers(questions, capture, success, resamples)
    result: dict[str, float | None] = {}
    for name in questions.names:
        result[name] = point[name]
        result[f"{name}_low"], result[f"{name}_high"] = percentile_interval(samples[name])
    return result


@dataclass
class Scored:
    """The answers of one scorer on one dataset.

    Attributes:
        point: AP of each question on all trajectories (``None``: one class).
        samples: AP of each question on every resample, shape (n_resamples,), NaN where undefined.

    """

    point: dict[str, float | None]
    samples: dict[str, np.ndarray]

    def row(self) -> dict[str, float | None]:
        """Point estimates and 95 % percentile intervals."""
        result: dict[str, float | None] = {}
        for name, value in self.point.items():
            result[name] = value
            result[f"{name}_low"], result[f"{name}_high"] = percentile_interval(self.samples[name])
        return result


def score_questions(questions: Questions, capture: np.ndarray, success: np.ndarray, resamples: np.ndarray) -> Scored:
    """AP of grids ``capture`` and ``success`` (each (T, K)) on all trajectories and on every resample (n, T)."""
    point = questions.answer(capture, success, np.arange(capture.shape[0]))
    return Scored(point, bootstrap_answers(questions, capture, success, resamples))


def paired_difference(first: Scored, second: Scored) -> dict[str, float | None]:
    """``first`` minus ``second`` with a paired 95 % interval (both scored on the same resamples).

    The point is the difference of the APs on all trajectories; the interval is the 2.5-97.5
    percentile of the per-resample differences (resamples where either is undefined are skipped).
    Identical scorers give exactly [0, 0].
    """
    result: dict[str, float | None] = {}
    for name, value in first.point.items():
        other = second.point[name]
        result[name] = None if value is None or other is None else value - other
        low, high = percentile_interval(first.samples[name] - second.samples[name])
        result[f"{name}_low"], result[f"{name}_high"] = low, high
    return result
