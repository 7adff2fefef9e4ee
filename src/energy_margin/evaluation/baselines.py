"""Geometric heuristic baselines: how far the frame's objects are inside the capture and success regions.

For every frame the ``distance`` baseline scores capture by the smallest signed distance of an
object to the capture region built from that frame, and success by the smallest signed distance of
an object to the success region (positive inside, negative outside, metres; see
:class:`~energy_margin.tasks.base.MeasurableRegion`). They need no physics: a frame whose objects
are all deep inside scores high, one with an object just outside scores slightly negative.
"""

from __future__ import annotations

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.tasks.base import MeasurableRegion, Region

__all__ = [
    "baseline_grids",
    "distance_scores",
]


def _min_distance(region: Region, positions: np.ndarray) -> float:
    if not isinstance(region, MeasurableRegion):
        raise TypeError(f"{type(region).__name__} has no signed_distance")
    return float(np.min(region.signed_distance(positions)))


def distance_scores(dataset: Dataset) -> tuple[np.ndarray, np.ndarray] | None:
    """Capture and success heuristic scores, each shape (T, K); ``None`` when a region cannot measure distances."""
    task = dataset.task
    capture = np.empty((dataset.n_trajectories, dataset.n_frames))
    success = np.empty_like(capture)
    if not isinstance(task.success_region_at(dataset.frame(0, 0)), MeasurableRegion):
        return None
    try:
        for trajectory in range(dataset.n_trajectories):
            for index in range(dataset.n_frames):
                frame = dataset.frame(trajectory, index)
                capture[trajectory, index] = _min_distance(task.capture_region(frame), frame.object_pos)
                success[trajectory, index] = _min_distance(task.success_region_at(frame), frame.object_pos)
    except TypeError:
        return None
    return capture, success


def baseline_grids(dataset: Dataset) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Capture and success score grids (each (T, K)) of the baselines: ``current_state`` and ``distance``.

    ``distance`` is left out for a task whose regions measure no distance (:func:`distance_scores`).
    """
    grids = {
        "current_state": (
            dataset.arrays["captured"].astype(float),
            dataset.arrays["in_success"].astype(float),
        )
    }
    heuristic = distance_scores(dataset)
    if heuristic is not None:
        grids["distance"] = heuristic
    return grids
