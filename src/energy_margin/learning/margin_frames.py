"""The training frames of a learned margin: features and tree scores of every frame of analysed datasets.

:func:`training_frames` reads them (one task, one configuration, :func:`check_same_task`);
:func:`load_training_datasets` loads and checks the datasets.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.metrics import score_grid
from energy_margin.learning.features import SetInputs
from energy_margin.learning.margin_file import (
    FEATURES_OF_KIND,
)

__all__ = ["check_same_task", "load_training_datasets", "training_frames"]


@dataclass(frozen=True)
class _Frames:
    """The frames of one analysed dataset with their features and scores, trajectory-major."""

    dataset: Dataset
    features: np.ndarray | SetInputs  # (T * K, D), or the set inputs of the T * K frames
    capture: np.ndarray  # (T, K) tree capture scores
    success: np.ndarray  # (T, K) tree success scores
    runtime: np.ndarray  # (T, K) tree seconds per frame


def check_same_task(datasets: Sequence[Dataset]) -> None:
    """Refuse no datasets, or datasets of different tasks or task settings (one line).

    Raises:
        EnergyMarginError: as above.
    """
    if not datasets:
        raise EnergyMarginError("give at least one analysed dataset")
    first = datasets[0]
    for other in datasets[1:]:
        if other.metadata["task"] != first.metadata["task"]:
            raise EnergyMarginError(
                f"datasets {first.path} and {other.path} are of different tasks "
                f"({first.metadata['task']!r} and {other.metadata['task']!r}): a margin model is fitted on one task"
            )
        if other.task.config.to_dict() != first.task.config.to_dict():
            a, b = first.task.config.to_dict(), other.task.config.to_dict()
            key = next(k for k in a if a[k] != b.get(k))
            raise EnergyMarginError(
                f"datasets {first.path} and {other.path} were generated with different {first.metadata['task']} "
                f"settings ({key}: {a[key]!r} and {b.get(key)!r})"
            )


def training_frames(datasets: Sequence[Dataset], *, kind: str = "mlp") -> list[_Frames]:
    """Features and scores of every frame of analysed ``datasets`` (one task, one configuration).

    ``kind`` chooses the feature definition (:data:`FEATURES_OF_KIND`).

    Raises:
        EnergyMarginError: no datasets, datasets of different tasks or settings, or one without
            ``scores.csv``.
    """
    check_same_task(datasets)
    first = datasets[0]
    task = first.task
    features = FEATURES_OF_KIND[kind](task)
    frames = []
    for dataset in datasets:
        if dataset.path is None:
            raise EnergyMarginError("a dataset read from disk is needed (its scores.csv sits beside it)")
        scores = load_scores(dataset.path)
        states = [
            dataset.frame(trajectory, index)
            for trajectory in range(dataset.n_trajectories)
            for index in range(dataset.n_frames)
        ]
        frames.append(
            _Frames(
                dataset=dataset,
                features=features(states),
                capture=score_grid(dataset, scores, "capture_score"),
                success=score_grid(dataset, scores, "success_score"),
                runtime=score_grid(dataset, scores, "runtime_s"),
            )
        )
    return frames


def _take(features: np.ndarray | SetInputs, rows: slice) -> np.ndarray | SetInputs:
    """The rows ``rows`` of features (F, D) or of set inputs."""
    return features.take(rows) if isinstance(features, SetInputs) else features[rows]


def _concatenate(parts: list[Any]) -> Any:
    """Features of many frames in order: one array (F, D), or set inputs padded to one width."""
    return SetInputs.concatenate(parts) if isinstance(parts[0], SetInputs) else np.concatenate(parts)


def load_training_datasets(paths: Sequence[Path | str]) -> list[Dataset]:
    """Load analysed datasets of one task for :func:`fit_margin_model`.

    Raises:
        EnergyMarginError: a dataset with a problem (its ``scores.csv`` included), datasets of
            different tasks, or one without ``scores.csv`` (one line).
    """
    from energy_margin.data.validation import require_valid

    if not paths:
        raise EnergyMarginError("give at least one analysed dataset")
    datasets = [require_valid(path, overlaps=False, scores=None) for path in paths]
    check_same_task(datasets)
    for path in paths:
        require_valid(path, overlaps=False, scores=True)
    return datasets
