"""A control run's episodes as a dataset: every recorded frame physically possible, or the episode left out.

An episode runs on a plant that is pushed and whose friction the controller does not know; under a
hard push MuJoCo's soft contacts can press an object into the end-effector deeper than the dataset
check allows, or a blown-up step can throw one out of the task's bounds. Such a frame never becomes
a label: :func:`write_episodes_dataset` leaves its episode out of the dataset, lists it under
``dropped`` in ``dataset.json`` (``{"rollout": "episode i", "reason": ...}``, as ``record`` lists
roll-outs), and the dataset stays one that ``analyze`` accepts. The run's summary in
``control.json`` still counts every episode: it measures the controller on its plant.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from energy_margin.compat import save_npz
from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE
from energy_margin.data.generate import records_dataset
from energy_margin.data.record import DROPPED_KEY
from energy_margin.data.validation import unphysical_trajectories
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.files import atomic_path, write_json
from energy_margin.tasks import Task

__all__ = ["write_episodes_dataset"]


def write_episodes_dataset(
    task: Task, records: list[dict[str, Any]], out: Path, *, extra: dict[str, Any]
) -> list[dict[str, str]]:
    """Write the episodes' records as a dataset at ``out``, those with an impossible frame left out.

    Args:
        task: the task of every episode.
        records: one trajectory record per episode, in episode order.
        out: the run's directory.
        extra: further metadata (the run's settings and summary).

    Returns:
        The episodes left out, ``{"rollout": "episode i", "reason": ...}`` each (empty: none).

    Raises:
        EnergyMarginError: every episode has a physically impossible frame (nothing is written).

    """
    dataset = records_dataset(task, records, out, engine="mujoco", extra=extra)
    unphysical = unphysical_trajectories(dataset)
    dropped = [{"rollout": f"episode {index}", "reason": reason} for index, reason in sorted(unphysical.items())]
    if dropped:
        kept = [record for index, record in enumerate(records) if index not in unphysical]
        if not kept:
            raise EnergyMarginError(
                f"every episode has a physically impossible frame (the first: {dropped[0]['rollout']}: "
                f"{dropped[0]['reason']}); a physically impossible frame never becomes data"
            )
        dataset = records_dataset(task, kept, out, engine="mujoco", extra={**extra, DROPPED_KEY: dropped})
    with atomic_path(out / FRAMES_FILE) as temporary, open(temporary, "wb") as stream:
        save_npz(stream, dataset.arrays, compressed=True)
    write_json(out / METADATA_FILE, dataset.metadata)
    return dropped
