"""The pool of a learning curve: the held-out trajectories and the training frames of the rest.

:func:`held_out_trajectories` reimplements the split of
:func:`~energy_margin.learning.margin_model.fit_margin_model`; :func:`_pool` gathers every frame
of the other trajectories with its features and revealed scores.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.errors import (
    EnergyMarginError,
)
from energy_margin.learning.curve_results import (
    FrameId,
)
from energy_margin.learning.features import SetInputs
from energy_margin.learning.margin_frames import (
    _concatenate,
    _Frames,
    training_frames,
)

__all__ = ["held_out_trajectories"]


def held_out_trajectories(datasets: Sequence[Dataset], *, seed: int, holdout: float) -> list[tuple[int, int]]:
    """The ``(dataset, trajectory)`` pairs ``fit_margin_model`` holds out with ``seed`` and ``holdout``, sorted.

    Raises:
        EnergyMarginError: fewer than 2 trajectories in all.
    """
    groups = [(d, t) for d, dataset in enumerate(datasets) for t in range(dataset.n_trajectories)]
    if len(groups) < 2:
        raise EnergyMarginError("a margin model needs at least 2 trajectories (one is held out)")
    order = np.random.default_rng(seed).permutation(len(groups))
    n_held = min(len(groups) - 1, max(1, round(holdout * len(groups))))
    return sorted(groups[i] for i in order[:n_held])


@dataclass(frozen=True)
class _Pool:
    """The training pool and the held-out test set of one split."""

    frames: list[_Frames]
    held: set[tuple[int, int]]
    ids: list[FrameId]  # pool row -> frame, in (dataset, trajectory, frame) order
    features: Any  # (P, D) array or SetInputs of the pool frames, in pool order
    flat: np.ndarray  # (P, D) frame-statistics features of the pool frames
    targets: np.ndarray  # (P, 2)
    groups: np.ndarray  # (P,) pool trajectory of every row
    test_x: Any
    test_y: np.ndarray


def _pool(datasets: Sequence[Dataset], held: set[tuple[int, int]], kind: str) -> _Pool:
    frames = training_frames(datasets, kind=kind)
    ids: list[FrameId] = []
    parts: list[Any] = []
    targets: list[np.ndarray] = []
    groups: list[np.ndarray] = []
    test_parts: list[Any] = []
    test_targets: list[np.ndarray] = []
    trajectory = 0
    for d, item in enumerate(frames):
        k = item.dataset.n_frames
        for t in range(item.dataset.n_trajectories):
            block = _rows(item.features, np.arange(t * k, (t + 1) * k))
            scores = np.stack([item.capture[t], item.success[t]], axis=1)
            if (d, t) in held:
                test_parts.append(block)
                test_targets.append(scores)
                continue
            ids.extend((d, t, i) for i in range(k))
            parts.append(block)
            targets.append(scores)
            groups.append(np.full(k, trajectory))
            trajectory += 1
    features = _concatenate(parts)
    return _Pool(
        frames=frames,
        held=held,
        ids=ids,
        features=features,
        flat=features.frame if isinstance(features, SetInputs) else features,
        targets=np.concatenate(targets),
        groups=np.concatenate(groups),
        test_x=_concatenate(test_parts),
        test_y=np.concatenate(test_targets),
    )


def _rows(features: Any, rows: np.ndarray) -> Any:
    """The rows ``rows`` of features (F, D) or of set inputs."""
    return features.take(rows) if isinstance(features, SetInputs) else features[rows]
