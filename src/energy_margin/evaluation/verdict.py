"""The verdict of ``evaluate``: the margin against the best baseline, question by question.

For each question the best baseline is the one with the highest AP on all trajectories (the
current-state indicator or the distance check; chance is no contender). The margin's AP minus
that baseline's comes with a paired 95 % interval: both are scored on the same bootstrap
resamples of whole trajectories, and the interval is the 2.5-97.5 percentile of the per-resample
differences. One word sums it up: ``ahead`` (the interval lies above 0), ``behind`` (below 0) or
``level`` (it holds 0); ``n/a`` where either AP is undefined (one class).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.evaluation.bootstrap import Questions, paired_difference, score_questions

__all__ = [
    "NOT_CONTENDERS",
    "WORDS",
    "Verdict",
    "verdicts",
    "word",
]

#: The words of a verdict.
WORDS = ("ahead", "level", "behind", "n/a")
#: Baselines that never contend for "best" (a constant score: its AP is the positive rate).
NOT_CONTENDERS = frozenset({"chance"})


@dataclass(frozen=True)
class Verdict:
    """The margin against the best baseline on one question.

    Attributes:
        question: the question's key (``capture_ap``, ``capture_ap_window2`` unless k-hat is 2,
            ``success_ap``, ``success_ap_first_half``).
        baseline: the best baseline's name (``None`` when no baseline has an AP).
        difference: margin AP minus the baseline's, on all trajectories.
        low: lower end of the paired 95 % interval of the difference.
        high: upper end.
        word: ``ahead``, ``level``, ``behind`` or ``n/a``.
        resamples: the resamples behind the interval: those on which both APs are defined (a
            resample whose labels are all one class has none; on few trajectories with a rare
            class, fewer than drawn).
    """

    question: str
    baseline: str | None
    difference: float | None
    low: float | None
    high: float | None
    word: str
    resamples: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible fields (without the question, the key it is stored under)."""
        return {
            "baseline": self.baseline,
            "difference": self.difference,
            "low": self.low,
            "high": self.high,
            "word": self.word,
            "resamples": self.resamples,
        }


def word(difference: float | None, low: float | None, high: float | None) -> str:
    """``ahead`` if the interval lies above 0, ``behind`` if below, ``level`` if it holds 0, else ``n/a``."""
    if difference is None or low is None or high is None:
        return "n/a"
    if low > 0.0:
        return "ahead"
    if high < 0.0:
        return "behind"
    return "level"


def verdicts(
    dataset: Dataset,
    margin: tuple[np.ndarray, np.ndarray],
    baselines: dict[str, tuple[np.ndarray, np.ndarray]],
    *,
    capture_window: int,
    success_frames: int,
    weights: str,
    resamples: int,
    seed: int,
    questions: Questions | None = None,
) -> dict[str, Verdict]:
    """The verdict of every question of ``evaluate``.

    Args:
        dataset: the scored dataset.
        margin: the margin's capture and success scores, each shape (T, K).
        baselines: baseline name -> its capture and success scores, each shape (T, K).
        capture_window: k-hat of the first capture question (the second, k-hat = 2, only when this is not 2).
        success_frames: k-bar of the success questions.
        weights: ``"linear"`` or ``"uniform"``.
        resamples: bootstrap resamples of the trajectories, >= 1.
        seed: seeds the resamples (``numpy.random.default_rng``).
        questions: other questions than ``evaluate``'s (then ``capture_window``, ``success_frames``
            and ``weights`` are not used).

    Returns:
        Question key -> :class:`Verdict`, in ``evaluate``'s order of questions.
    """
    if questions is None:
        questions = Questions.of_evaluate(
            dataset, capture_window=capture_window, success_frames=success_frames, weights=weights
        )
    rng = np.random.default_rng(seed)
    drawn = rng.integers(0, dataset.n_trajectories, size=(resamples, dataset.n_trajectories))
    scored_margin = score_questions(questions, *margin, drawn)
    scored = {
        name: score_questions(questions, *scores, drawn)
        for name, scores in baselines.items()
        if name not in NOT_CONTENDERS
    }
    result: dict[str, Verdict] = {}
    for question in questions.names:
        contenders: list[tuple[float, str]] = []
        for name, answers in scored.items():
            value = answers.point[question]
            if value is not None:
                contenders.append((value, name))
        if not contenders:
            result[question] = Verdict(question, None, None, None, None, "n/a")
            continue
        best = max(contenders, key=lambda pair: pair[0])[1]  # the first of equals, in the baselines' order
        difference = paired_difference(scored_margin, scored[best])
        value, low, high = difference[question], difference[f"{question}_low"], difference[f"{question}_high"]
        used = int(np.count_nonzero(np.isfinite(scored_margin.samples[question] - scored[best].samples[question])))
        result[question] = Verdict(question, best, value, low, high, word(value, low, high), used)
    return result
