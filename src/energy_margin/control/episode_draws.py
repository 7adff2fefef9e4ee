"""An episode's settings and random draws: its seeds, its start, its plant and its observations.

:class:`ControlSettings` is everything that determines a run's episodes; episode i's generators
are spawned from its seed sequence in the order of :data:`EPISODE_STREAMS`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from energy_margin.control.costs import CostWeights
from energy_margin.control.disturbances import Disturbance, Push, draw_plant, observe
from energy_margin.control.mppi import ControllerConfig
from energy_margin.tasks import Task, Trajectory
from energy_margin.world.state import FrameState

__all__ = ["EPISODE_STREAMS", "ControlSettings", "draw_episode", "episode_seeds", "observed_frame"]


@dataclass(frozen=True)
class ControlSettings:
    """Everything that determines a run's episodes.

    Attributes:
        task: task name.
        task_config: the task's resolved settings.
        n_objects: objects per episode.
        episodes: number of episodes E.
        policy: one of :data:`POLICIES`.
        disturbance: the disturbance level's settings.
        seed: the run's seed.
        n_frames: frames recorded per episode.
        score_expansions: expansions of the energy-margin analysis of every recorded frame (0:
            none), which gives the mean capture score along the episodes.
        controller: the MPPI settings (unused by ``scripted``).
        weights: the cost weights.
        model: the learned margin's file and its fingerprint (``learned`` only).

    """

    task: str
    task_config: dict[str, Any]
    n_objects: int
    episodes: int
    policy: str
    disturbance: dict[str, Any]
    seed: int
    n_frames: int = 10
    score_expansions: int = 30
    controller: dict[str, Any] = field(default_factory=lambda: ControllerConfig().to_dict())
    weights: dict[str, Any] = field(default_factory=lambda: asdict(CostWeights()))
    model: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-ready dict."""
        return asdict(self)


def observed_frame(frame: FrameState, disturbance: Disturbance, rng: np.random.Generator) -> FrameState:
    """``frame`` as the controller sees it: object positions with the level's observation noise."""
    return FrameState(
        observe(frame.object_pos, disturbance, rng), frame.object_quat, frame.object_vel, frame.robot_q, frame.robot_v
    )


#: What each of an episode's generators draws, in the order they are spawned from its seed.
EPISODE_STREAMS = ("trajectory", "plant", "observe", "sample", "script", "cost", "score")


def episode_seeds(seed: np.random.SeedSequence) -> dict[str, np.random.SeedSequence]:
    """The episode's seed sequences by :data:`EPISODE_STREAMS` name."""
    return dict(zip(EPISODE_STREAMS, seed.spawn(len(EPISODE_STREAMS)), strict=True))


def draw_episode(
    task: Task, n_objects: int, disturbance: Disturbance, seeds: dict[str, np.random.SeedSequence]
) -> tuple[Trajectory, float, list[Push]]:
    """An episode's start (its friction is the controller's nominal one), plant friction and pushes."""
    trajectory = task.sample_trajectory(np.random.default_rng(seeds["trajectory"]), n_objects)
    duration = task.n_steps * task.config.timestep
    scratch = task.make_simulator(n_objects, trajectory.friction, trajectory.drive, "mujoco")
    friction, pushes = draw_plant(
        disturbance,
        np.random.default_rng(seeds["plant"]),
        nominal_friction=trajectory.friction,
        duration=duration,
        masses=scratch.scene.object_masses,
    )
    return trajectory, friction, pushes
