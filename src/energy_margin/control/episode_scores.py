"""The scores of closed-loop episodes: their frames' capture and success scores, a run's summary."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.control.episode_draws import ControlSettings
from energy_margin.evaluation.statistics import wilson_interval
from energy_margin.runs.results import TypedResult
from energy_margin.tasks import Task
from energy_margin.world.state import FrameState

__all__ = ["ControlResult", "summarize"]


def _frame_scores(
    task: Task,
    frames: list[FrameState],
    times: list[float],
    friction: float,
    drive: np.ndarray,
    settings: ControlSettings,
    seed: np.random.SeedSequence,
) -> tuple[list[float], list[float]]:
    """Capture and success scores of the recorded frames from a short analysis."""
    # The tree's own capture score, with which the recorded episodes' scores were measured.
    config = AnalyzerConfig(expansions=settings.score_expansions, capture_gate="none")
    simulator = task.make_simulator(settings.n_objects, friction, drive, "mujoco")
    capture, success = [], []
    for frame, start, child in zip(frames, times, seed.spawn(len(frames)), strict=True):
        scores, _ = analyze_frame(
            task,
            frame,
            friction=friction,
            drive=drive,
            seed=int(child.generate_state(1)[0]),
            config=config,
            start_time=start,
            simulator=simulator,
        )
        capture.append(float(scores.capture_score))
        success.append(float(scores.success_score))
    return capture, success


@dataclass(frozen=True, kw_only=True)
class ControlResult(TypedResult):
    """What :func:`~energy_margin.control.episodes.run_control` measured over a run's episodes.

    ``to_dict()`` is the ``summary`` of ``control.json`` (and of the dataset's ``control``
    metadata), and the JSON ``control`` prints.

    Attributes:
        task: the task's registered name.
        n_objects: objects per episode.
        policy: the policy that drove the episodes.
        disturbance: the disturbance level's name.
        episodes: episodes run.
        successes: episodes that ended in the success region.
        success_rate: ``successes / episodes`` in [0, 1] (``None`` without episodes).
        success_interval: its 95 % Wilson interval, ``[low, high]``.
        captured_fraction: fraction of the recorded frames (every episode's) whose objects were
            captured, in [0, 1] (``None`` without episodes).
        mean_capture_score: mean over the episodes of their frames' mean capture score (``None``
            when the frames were not scored, ``score_expansions=0``).
        decisions: the controller's decisions over every episode (0 for ``scripted``).
        seconds_per_decision: mean wall time of a decision, s (``None`` without decisions).

    """

    task: str
    n_objects: int
    policy: str
    disturbance: str
    episodes: int
    successes: int
    success_rate: float | None
    success_interval: list[float]
    captured_fraction: float | None
    mean_capture_score: float | None
    decisions: int
    seconds_per_decision: float | None


def summarize(settings: ControlSettings, infos: list[dict[str, Any]]) -> ControlResult:
    """Success rate with its 95 % Wilson interval, capture along the episodes, time per decision."""
    successes = sum(1 for info in infos if info["success"])
    low, high = wilson_interval(successes, len(infos)) if infos else (0.0, 1.0)
    decisions = sum(info["decisions"] for info in infos)
    seconds = sum(info["decision_seconds"] for info in infos)
    scores = [np.mean(info["capture_scores"]) for info in infos if "capture_scores" in info]
    return ControlResult(
        task=settings.task,
        n_objects=settings.n_objects,
        policy=settings.policy,
        disturbance=settings.disturbance["name"],
        episodes=len(infos),
        successes=successes,
        success_rate=successes / len(infos) if infos else None,
        success_interval=[low, high],
        captured_fraction=float(np.mean([info["captured_fraction"] for info in infos])) if infos else None,
        mean_capture_score=float(np.mean(scores)) if scores else None,
        decisions=decisions,
        seconds_per_decision=seconds / decisions if decisions else None,
    )
