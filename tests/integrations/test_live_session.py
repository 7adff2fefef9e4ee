"""The live session's alarm, with the scorer faked: which capture score it watches."""

from __future__ import annotations

import math
from typing import Any

import pytest

from energy_margin.evaluation.monitor import MonitorCalibration
from energy_margin.integrations.live_session import LiveSession


class _Scorer:
    """Scores every call alike: the gated capture 0, the tree's own ``tree_capture``."""

    def __init__(self, tree_capture: float) -> None:
        self.tree_capture = tree_capture
        self.horizons: list[float | None] = []

    def score(self, data: Any, *, horizon_s: float | None = None) -> dict[str, Any]:
        self.horizons.append(horizon_s)
        return {"capture_score": 0.0, "success_score": 1.0, "tree_capture_score": self.tree_capture}


def _capture_alarm() -> MonitorCalibration:
    return MonitorCalibration(
        threshold=0.5,
        alpha=0.1,
        rank=1,
        n_successes=9,
        n_trajectories=9,
        scorer="margin",
        score="capture",
        start_frame=0,
    )


def test_a_capture_alarm_watches_the_trees_own_capture_score() -> None:
    # Gated to 0 (the objects out of their region for a moment), the tree's own score is 0.9: no alarm.
    session = LiveSession(_Scorer(0.9), every=1, record=False, calibration=_capture_alarm())  # type: ignore[arg-type]
    assert session.reset(None)["alarm"] is False  # type: ignore[index]
    assert session.step(None)["alarm"] is False  # type: ignore[index]


def test_without_a_tree_the_alarm_watches_the_capture_score() -> None:
    # A learned margin grows no tree: its capture score is all there is (0, below the threshold).
    session = LiveSession(_Scorer(math.nan), every=1, record=False, calibration=_capture_alarm())  # type: ignore[arg-type]
    assert session.reset(None)["alarm"] is True  # type: ignore[index]


def test_a_scored_call_s_horizon_is_the_rest_of_the_episode_where_its_length_is_known() -> None:
    scorer = _Scorer(0.9)
    session = LiveSession(scorer, every=2, record=False, step_s=0.05, episode_steps=6)  # type: ignore[arg-type]
    session.reset(None)
    for _ in range(6):
        session.step(None)
    assert scorer.horizons == pytest.approx([0.3, 0.2, 0.1, 0.0])
    unknown = _Scorer(0.9)
    LiveSession(unknown, every=1, record=False, step_s=0.05).reset(None)  # type: ignore[arg-type]
    assert unknown.horizons == [None]
