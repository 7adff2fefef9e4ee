"""Success continuation by default where the trees reach no success: the rule ``analyze`` applies.

A tree reaches about a second past its frame. Where the nominal motion reaches the success region
later, no tree state of an early frame lies in it, the tree's success score is exactly 0 on those
frames and early success cannot be ranked; continuing the motion from the tree's nodes
(:mod:`energy_margin.analysis.continuation`) can. ``analyze`` with ``continuation=None`` (its
default, ``--continuation auto``) grows the trees of a *pilot* first, the first-half frames of the
first :data:`PILOT_TRAJECTORIES` roll-outs with the tree's own success score, and continues with
:data:`AUTO_SAMPLES` draws per frame where at least :data:`UNREACHED_SHARE` of them score success
exactly 0. Otherwise the pilot's rows are the run's own (the same frames, seeds and settings) and
nothing is grown twice. The rule reads no label: only the trees' scores.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.data.scores_file import UNREACHED_SHARE
from energy_margin.runs.results import TypedResult

__all__ = ["AUTO_SAMPLES", "PILOT_TRAJECTORIES", "UNREACHED_SHARE", "ContinuationChoice", "choose", "pilot_frames"]

#: Continuations drawn per frame when the rule turns them on (chosen on generation seed 11,
#: docs/howto/scenes.md, "Success beyond a tree's reach").
AUTO_SAMPLES = 16
#: Roll-outs whose first-half frames make the pilot.
PILOT_TRAJECTORIES = 5


@dataclass(frozen=True, kw_only=True)
class ContinuationChoice(TypedResult):
    """What the rule chose for a dataset, and on what.

    Attributes:
        continuation: the continuations drawn per frame (0: the tree's own success score).
        unreached_share: share of the pilot frames whose success score is exactly 0, in [0, 1].
        pilot_frames: how many frames the pilot grew.
        threshold: the share at or above which continuations are drawn.

    """

    continuation: int
    unreached_share: float
    pilot_frames: int
    threshold: float


def pilot_frames(dataset: Dataset) -> list[int]:
    """The pilot's frame indices (trajectory-major): frames 0 .. ceil(K / 2) - 1 of the first roll-outs."""
    half = -(-dataset.n_frames // 2)
    trajectories = min(dataset.n_trajectories, PILOT_TRAJECTORIES)
    return [trajectory * dataset.n_frames + frame for trajectory in range(trajectories) for frame in range(half)]


def choose(rows: Iterable[dict[str, Any]]) -> ContinuationChoice:
    """The rule on the pilot's score rows (each with ``success_score``): :data:`AUTO_SAMPLES` or 0."""
    success = np.array([float(row["success_score"]) for row in rows])
    share = float(np.mean(success == 0.0)) if success.size else 0.0
    return ContinuationChoice(
        continuation=AUTO_SAMPLES if success.size and share >= UNREACHED_SHARE else 0,
        unreached_share=share,
        pilot_frames=int(success.size),
        threshold=UNREACHED_SHARE,
    )
