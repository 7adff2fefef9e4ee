"""A learned margin: a small regressor from frame features to the analysed capture and success scores.

:func:`fit_margin_model` fits one (an MLP or gradient-boosted trees, scikit-learn) to the scores of
analysed datasets of one task, holding out whole trajectories, and reports how close it comes on
them: R² of both scores, and the Average Precision of the learned scores against the labels beside
that of the tree's scores on the same frames. :class:`MarginModel` predicts both scores of many
frames in one vectorised call; :meth:`MarginModel.score_state` is the learned path of live scoring
(:mod:`energy_margin.analysis.live`).

This module fits the model; :mod:`~energy_margin.learning.margin_file` holds the model and its saved
``.npz`` file, :mod:`~energy_margin.learning.margin_frames` the training frames and
:mod:`~energy_margin.learning.margin_report` the held-out report (their public names are importable
from here as before).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.data.dataset import Dataset
from energy_margin.errors import EnergyMarginError, check_choice, check_float, check_positive_int
from energy_margin.learning.features import FrameFeatures
from energy_margin.learning.margin_file import (
    FEATURES_OF_KIND,
    FORMAT,
    SCHEMA_VERSION,
    MarginModel,
    load_margin_model,
)
from energy_margin.learning.margin_frames import (
    _concatenate,
    _Frames,
    _take,
    check_same_task,
    load_training_datasets,
    training_frames,
)
from energy_margin.learning.margin_report import (
    MarginModelReport,
    _held_out_report,
)
from energy_margin.learning.regressors import DEFAULT_KIND, KINDS, fit_regressor

__all__ = [
    "DEFAULT_KIND",
    "FEATURES_OF_KIND",
    "FORMAT",
    "KINDS",
    "SCHEMA_VERSION",
    "MarginModel",
    "MarginModelReport",
    "check_same_task",
    "fit_margin_model",
    "load_margin_model",
    "load_training_datasets",
    "training_frames",
]


def fit_margin_model(
    datasets: Sequence[Dataset],
    *,
    seed: int,
    kind: str = DEFAULT_KIND,
    holdout: float = 0.25,
    success_frames: int = 3,
    **options: Any,
) -> tuple[MarginModel, MarginModelReport]:
    """Fit a learned margin to analysed datasets of one task and measure it on held-out trajectories.

    Args:
        datasets: analysed datasets (``load_dataset``; each with ``scores.csv`` beside it), one
            task and one task configuration; their numbers of objects may differ.
        seed: seed of the split and of the regressor.
        kind: ``"mlp"`` (a ReLU perceptron), ``"boosting"`` (gradient-boosted trees) or ``"set"``
            (the network over the objects, :mod:`energy_margin.learning.set_network`; needs PyTorch),
            by default :data:`DEFAULT_KIND` (``"set"``, as ``learn`` on the command line).
        holdout: fraction of the trajectories (whole trajectories, never single frames) held out
            for the report, in (0, 1); at least one trajectory is held out and one kept.
        success_frames: k-bar of the trajectory success AP (as in ``evaluate``), >= 1.
        options: regressor settings (:func:`energy_margin.learning.regressors.fit_regressor`).

    Returns:
        The model (fitted on the kept trajectories) and its
        :class:`~energy_margin.learning.margin_report.MarginModelReport` on the held-out
        trajectories: R² of both scores, the learned AP beside the tree's AP of the questions
        ``evaluate`` asks, the time per query beside the tree's time per frame, the split's sizes.

    Raises:
        EnergyMarginError: datasets of different tasks, without scores, or too few trajectories.
        InvalidParameterError: a bad ``kind``, ``holdout`` or ``success_frames``.
    """
    check_choice("kind", kind, KINDS)
    check_float("holdout", holdout, minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True)
    check_positive_int("success_frames", success_frames)
    frames = training_frames(datasets, kind=kind)
    groups, held, n_held = _held_out_split(frames, seed=seed, holdout=holdout)
    train_x, train_y, train_groups, train_labels = _select(frames, held, False)
    test_x, test_y, _, _ = _select(frames, held, True)
    started = time.perf_counter()
    if kind == "set":
        # The labels the scores answer (the objects stay captured two more frames; the trajectory
        # succeeds) as auxiliary targets: on held-out pushing trajectories they raised future
        # capture AP by about 0.015 (docs/howto/control.md).
        options = {"groups": train_groups, "auxiliary": train_labels, **options}
    regressor = fit_regressor(kind, train_x, train_y, seed=seed, **options)
    fit_seconds = time.perf_counter() - started
    task = frames[0].dataset.task
    definition = FEATURES_OF_KIND[kind](task)
    model = _margin_model(frames, kind, regressor, definition)
    report = MarginModelReport(
        **_held_out_report(model, frames, held, test_x, test_y, success_frames=success_frames),
        task=task.name,
        kind=kind,
        seed=seed,
        holdout=float(holdout),
        feature_set=definition.identifier,
        n_features=definition.dimension,
        n_trajectories={"train": len(groups) - n_held, "held_out": n_held},
        n_frames={"train": len(train_x), "held_out": len(test_x)},
        fit_seconds=fit_seconds,
        fit={key: value for key, value in getattr(regressor, "fit_info", {}).items() if key != "fit_seconds"},
        datasets=[str(item.dataset.path) for item in frames],
    )
    model.report = report.to_dict()
    return model, report


def _margin_model(frames: list[_Frames], kind: str, regressor: Any, definition: FrameFeatures) -> MarginModel:
    """The model of a ``regressor`` of ``kind`` fitted to the ``definition`` features of ``frames``."""
    task = frames[0].dataset.task
    return MarginModel(
        task_name=task.name,
        task_config=task.config.to_dict(),
        feature_set=definition.identifier,
        package_version=__version__,
        kind=kind,
        feature_names=definition.names,
        regressor=regressor,
        n_objects_range=(
            min(item.dataset.n_objects for item in frames),
            max(item.dataset.n_objects for item in frames),
        ),
    )


def _held_out_split(
    frames: list[_Frames], *, seed: int, holdout: float
) -> tuple[list[tuple[int, int]], set[tuple[int, int]], int]:
    """Every ``(dataset, trajectory)`` in order, the held-out ones (whole trajectories) and their number."""
    groups = [(d, t) for d, item in enumerate(frames) for t in range(item.dataset.n_trajectories)]
    if len(groups) < 2:
        raise EnergyMarginError("a margin model needs at least 2 trajectories (one is held out)")
    order = np.random.default_rng(seed).permutation(len(groups))
    n_held = min(len(groups) - 1, max(1, round(holdout * len(groups))))
    held = {groups[i] for i in order[:n_held]}
    return groups, held, n_held


def _select(
    frames: list[_Frames], held: set[tuple[int, int]], is_held: bool
) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
    """Features, scores, trajectory numbers and labels of the held-out frames or of the kept ones."""
    rows: list[Any] = []
    targets: list[np.ndarray] = []
    trajectory: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    for d, item in enumerate(frames):
        dataset, k = item.dataset, item.dataset.n_frames
        future, success = dataset.capture_labels(min(2, k - 1)), dataset.success_labels()
        for t in range(dataset.n_trajectories):
            if ((d, t) in held) == is_held:
                rows.append(_take(item.features, slice(t * k, (t + 1) * k)))
                targets.append(np.stack([item.capture[t], item.success[t]], axis=1))
                trajectory.append(np.full(k, len(trajectory)))
                labels.append(np.column_stack([future[t], np.full(k, success[t])]).astype(float))
    return _concatenate(rows), np.concatenate(targets), np.concatenate(trajectory), np.concatenate(labels)
