"""A live alarm calibrated on the live scorer's own calls (evaluation/live_calibration.py)."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
import pytest

from energy_margin.errors import InvalidParameterError
from energy_margin.evaluation.live_calibration import calibrate_episodes, live_scores
from energy_margin.evaluation.monitor import write_calibration
from energy_margin.integrations.live_model import LiveModelScorer, LiveOptions
from energy_margin.integrations.live_session import LiveSession
from tiny_scene import ARM_OVER_PUCK


def _calls(*success: float, capture: float = 1.0) -> list[dict[str, float]]:
    return [{"capture_score": 0.0, "tree_capture_score": capture, "success_score": value} for value in success]


def test_the_threshold_is_the_conformal_rank_of_the_successes_worst_monitored_calls() -> None:
    # Ten successes whose worst call from call 1 on is 0.1 .. 1.0 (call 0 is lower still and not monitored).
    episodes = [_calls(0.0, 1.0, value, 0.95) for value in np.linspace(0.1, 1.0, 10)]
    failure = _calls(0.0, 0.0, 0.0)
    found = calibrate_episodes([*episodes, failure], [True] * 10 + [False], alpha=0.2)
    assert (found.rank, found.n_successes, found.n_trajectories) == (2, 10, 11)  # floor(11 * 0.2) = 2
    assert found.threshold == pytest.approx(0.2) and found.scorer == "margin" and found.start_frame == 1
    second = calibrate_episodes(episodes, [True] * 10, alpha=0.2, persistence=2)
    assert second.threshold == pytest.approx(0.95)  # each one's second smallest monitored call
    # The tree's own capture is watched; a learned margin's call (no tree) falls back on capture_score.
    capture = calibrate_episodes([_calls(1.0, 1.0, capture=0.7)] * 9, [True] * 9, alpha=0.1, score="capture")
    assert capture.threshold == pytest.approx(0.7)
    assert live_scores({"capture_score": 0.4, "tree_capture_score": math.nan, "success_score": 0.1}) == (0.4, 0.1)


def test_an_episode_too_short_to_alarm_never_does() -> None:
    episodes = [_calls(0.0, 0.5)] * 9 + [_calls(0.0)]  # the last has no monitored call
    assert calibrate_episodes(episodes, [True] * 10, alpha=0.1).threshold == pytest.approx(0.5)
    with pytest.raises(InvalidParameterError, match=r"^episodes hold too few successful ones with 2 scored calls"):
        calibrate_episodes([_calls(0.0)] * 10, [True] * 10, alpha=0.1)


def test_bad_calibration_sets_are_refused_in_one_line() -> None:
    with pytest.raises(InvalidParameterError, match=r"^alpha 0.1 needs at least 9 successful calibration roll-outs"):
        calibrate_episodes([_calls(1.0, 1.0)] * 12, [True] * 8 + [False] * 4, alpha=0.1)
    with pytest.raises(InvalidParameterError, match=r"^success has 2 labels for 3 episodes"):
        calibrate_episodes([_calls(1.0)] * 3, [True, True], alpha=0.5)
    with pytest.raises(InvalidParameterError, match=r"^score "):
        calibrate_episodes([_calls(1.0)] * 3, [True] * 3, alpha=0.5, score="reward")


class _Replay:
    """A faked scorer that returns one episode's recorded calls in order."""

    def __init__(self, calls: list[dict[str, Any]]) -> None:
        self.calls = iter(calls)

    def score(self, data: Any, *, horizon_s: float | None = None) -> dict[str, Any]:
        return dict(next(self.calls))


def _alarms(episodes: list[list[dict[str, Any]]], calibration: Any) -> list[bool]:
    """Whether a live session with ``calibration`` raises the alarm in each replayed episode."""
    raised = []
    for calls in episodes:
        session = LiveSession(_Replay(calls), every=1, record=False, calibration=calibration)  # type: ignore[arg-type]
        scored = [session.reset(None)] + [session.step(None) for _ in calls[1:]]
        raised.append(bool(scored[-1]["alarm"]))  # type: ignore[index]
    return raised


def test_the_live_session_alarms_on_exactly_the_successes_below_the_calibrated_rank(tmp_path: Any) -> None:
    """On the calibration successes themselves: rank - 1 alarms (no ties), so at most alpha (n + 1) - 1."""
    model = mujoco.MjModel.from_xml_string(ARM_OVER_PUCK)
    data = mujoco.MjData(model)
    options = LiveOptions(budget_s=None, max_expansions=8, seed=3)
    scorer = LiveModelScorer(model, objects="puck", capture={"type": "distance", "site": "tip", "max": 0.5},
                             success={"type": "distance", "site": "tip", "max": 0.12}, options=options)  # fmt: skip
    episodes = []
    for start in np.linspace(-0.1, 0.6, 12):  # the arm's angle: the tip nearer the puck from episode to episode
        calls = []
        for step in range(4):
            data.qpos[:] = 0.0
            data.qpos[0] = start + 0.05 * step
            mujoco.mj_forward(model, data)
            calls.append(scorer.score(data))
        episodes.append(calls)
    worst = [min(live_scores(call)[1] for call in calls[1:]) for calls in episodes]
    assert len(set(worst)) > 3  # the real scores spread
    found = calibrate_episodes(episodes, [True] * 12, alpha=0.4)
    assert found.rank == 5  # floor(13 * 0.4)
    write_calibration(tmp_path / "alarm.json", [found])  # what the wrappers' calibration= loads
    if not found.can_fire:  # the tiny arm scores 0 on too many episodes: a persistence-free alarm cannot fire
        pytest.fail(f"the test's episodes give an alarm that cannot fire: worst scores {sorted(worst)}")
    assert sum(_alarms(episodes, found)) == sum(value < found.threshold for value in worst) <= found.rank - 1
