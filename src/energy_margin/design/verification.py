"""The real success rate of a design: closed-loop episodes of ``control`` under its disturbance levels.

:class:`EpisodeVerifier` is what ``energy-margin design`` verifies its designs with: episode i of
a design at a disturbance level runs :func:`~energy_margin.control.episodes.run_episode` with the
design's task configuration and the i-th child of the seed sequence it is given, so every design
meets the same starts, plant frictions, pushes and noise (common random numbers), and the
successes do not depend on the number of worker processes. Nothing is written here: the caller
journals each episode's outcome as it arrives.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.analysis.executors import pool_results
from energy_margin.control.commands import command_space, controllable_tasks
from energy_margin.control.disturbances import get_disturbance
from energy_margin.control.episodes import ControlSettings, run_episode
from energy_margin.errors import Constraint, EnergyMarginError, check_fields, constrained
from energy_margin.tasks import Task

__all__ = [
    "VERIFY_FRAMES",
    "VERIFY_POLICIES",
    "EpisodeVerifier",
]

#: The policies a design is verified with: its own script (the default), or MPPI with the task cost.
VERIFY_POLICIES = ("scripted", "task")
#: Frames recorded per episode (only the last one's success label is used).
VERIFY_FRAMES = 2


@dataclass(frozen=True)
class EpisodeVerifier:
    """Runs a design's verification episodes.

    Attributes:
        policy: ``"scripted"`` (the task's script, as the margin's roll-outs run it) or ``"task"``.

    """

    policy: str = constrained("scripted", Constraint("choice", choices=VERIFY_POLICIES))

    def __post_init__(self) -> None:
        check_fields(self)

    def settings(self) -> dict[str, Any]:
        """What decides the episodes besides the design, the level and the seeds (saved with the run)."""
        return {"policy": self.policy, "frames": VERIFY_FRAMES}

    def check(self, task: Task, levels: Sequence[str], *, n_objects: int) -> None:
        """Refuse a task without a command space, or an unknown disturbance level, before anything runs.

        The command space is built for ``task`` (its fixed settings applied): a scene whose motion
        moves mocap bodies has none, and is refused here rather than after the search.
        """
        if task.name not in controllable_tasks():
            raise EnergyMarginError(
                f"task {task.name!r} cannot be verified by control episodes; controllable tasks: "
                f"{', '.join(controllable_tasks())}"
            )
        command_space(task, n_objects)
        for level in levels:
            get_disturbance(level)

    def successes(
        self,
        task: Task,
        overrides: dict[str, Any],
        *,
        n_objects: int,
        level: str,
        seeds: Sequence[tuple[int, np.random.SeedSequence]],
        workers: int = 1,
    ) -> Iterator[tuple[int, bool]]:
        """``(index, success)`` of each episode ``(index, seed)``, in completion order."""
        task = task.configured(overrides)
        settings = ControlSettings(
            task=task.name,
            task_config=task.config.to_dict(),
            n_objects=n_objects,
            episodes=max(1, len(seeds)),
            policy=self.policy,
            disturbance=get_disturbance(level).to_dict(),
            seed=0,
            n_frames=VERIFY_FRAMES,
            score_expansions=0,
        )
        jobs = list(seeds)
        if workers == 1 or len(jobs) <= 1:
            for index, seed in jobs:
                yield index, bool(run_episode(task, settings, seed)["info"]["success"])
            return
        yield from pool_results(_episode_in_worker, jobs, workers=workers, initializer=_init, initargs=(task, settings))


_WORKER: dict[str, Any] = {}


def _init(task: Any, settings: ControlSettings) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER.update(task=task, settings=settings)


def _episode_in_worker(job: tuple[int, np.random.SeedSequence]) -> tuple[int, bool]:
    index, seed = job
    return index, bool(run_episode(_WORKER["task"], _WORKER["settings"], seed)["info"]["success"])
