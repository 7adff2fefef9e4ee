from __future__ import annotations

import time

import numpy as np
import pytest

from energy_margin.analysis import frame
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.live import score_state
from energy_margin.errors import InvalidParameterError
from energy_margin.planning import tree
from energy_margin.tasks import get_task


@pytest.fixture(scope="module")
def pushing_state():
    task = get_task("pushing")
    trajectory = task.sample_trajectory(np.random.default_rng(3), 3)
    simulator = task.make_simulator(3, trajectory.friction, trajectory.drive)
    return task, trajectory, simulator


# What the overrun bound leaves to the timers: reading them, and the few operations between the
# last deadline check and the scoring, and after the scoring (about 0.1 ms measured).
TIMER_SLACK_S = 0.005


def test_wall_clock_budget_is_respected(pushing_state, monkeypatch: pytest.MonkeyPatch) -> None:
    task, trajectory, simulator = pushing_state
    options = {"friction": trajectory.friction, "drive": trajectory.drive, "simulator": simulator}
    checks: list[float] = []
    reached: list[bool] = []
    offer = tree._Growth.offer

    def timed_offer(growth, round_, outcomes) -> None:  # the deadline is checked at the end of an offer
        offer(growth, round_, outcomes)
        checks.append(time.perf_counter())
        reached.append(growth.stopped)

    scoring: list[float] = []
    score_field = frame.score_field

    def timed_score_field(*args, **kwargs):
        started = time.perf_counter()
        scores = score_field(*args, **kwargs)
        scoring.append(time.perf_counter() - started)
        return scores

    monkeypatch.setattr(tree._Growth, "offer", timed_offer)
    monkeypatch.setattr(frame, "score_field", timed_score_field)
    budget = 0.03
    result = score_state(task, trajectory.initial, budget_s=budget, seed=1, **options)
    assert result.stopped_by == "budget"
    assert result.expansions >= 2 and 0.0 <= result.capture <= 1.0 and 0.0 <= result.success <= 1.0
    # The deadline is checked after every expansion, and growth stops at the first check past it.
    assert len(checks) == result.expansions and len(scoring) == 1
    assert reached == [False] * (len(reached) - 1) + [True]
    # So the call overruns its budget by at most its longest expansion plus the scoring.
    longest_expansion = float(np.max(np.diff(checks)))
    assert budget <= result.seconds <= budget + longest_expansion + scoring[0] + TIMER_SLACK_S, (
        result.seconds,
        longest_expansion,
        scoring[0],
    )
    capped = score_state(task, trajectory.initial, budget_s=10.0, max_expansions=3, seed=1, **options)
    assert capped.stopped_by == "max_expansions" and capped.expansions == 3 and capped.seconds < 10.0


def test_max_expansions_is_deterministic_with_a_seed(pushing_state) -> None:
    task, trajectory, simulator = pushing_state
    options = {"friction": trajectory.friction, "drive": trajectory.drive, "budget_s": None, "max_expansions": 12}
    first = score_state(task, trajectory.initial, seed=5, simulator=simulator, **options)
    again = score_state(task, trajectory.initial, seed=5, **options)  # a fresh simulator
    assert (first.capture, first.success, first.expansions, first.nodes) == (
        again.capture,
        again.success,
        again.expansions,
        again.nodes,
    )
    assert first.expansions == 12 and first.stopped_by == "max_expansions"
    # The same tree as a 12-expansion analysis of the frame.
    scores, _ = analyze_frame(
        task,
        trajectory.initial,
        friction=trajectory.friction,
        drive=trajectory.drive,
        seed=5,
        config=AnalyzerConfig(expansions=12),
    )
    assert (scores.capture_score, scores.success_score, scores.nodes) == (first.capture, first.success, first.nodes)


def test_score_state_validates_its_budget(pushing_state) -> None:
    task, trajectory, _ = pushing_state
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(InvalidParameterError, match="budget_s"):
            score_state(task, trajectory.initial, friction=trajectory.friction, drive=trajectory.drive, budget_s=bad)
    with pytest.raises(InvalidParameterError, match="max_expansions"):
        score_state(task, trajectory.initial, friction=trajectory.friction, drive=trajectory.drive, max_expansions=0)


def test_analyze_frame_stop_rule_beside_convergence(pushing_state) -> None:
    task, trajectory, simulator = pushing_state
    common = {"friction": trajectory.friction, "drive": trajectory.drive, "seed": 2, "simulator": simulator}
    scores, _ = analyze_frame(
        task, trajectory.initial, stop=lambda field: field.expansions >= 7, check_every=1, **common
    )
    assert scores.expansions == 7
    # With a convergence rule too, the caller's rule still stops growth at its own period.
    config = AnalyzerConfig(expansions=40, converge=0.5, converge_window=10, converge_every=10)
    scores, _ = analyze_frame(
        task, trajectory.initial, config=config, stop=lambda field: field.expansions >= 4, check_every=2, **common
    )
    assert scores.expansions == 4


def test_a_deadline_grows_the_tree_a_field_rule_grows(pushing_state) -> None:
    # A deadline is checked without costing the tree; the tree and its costs are those of a
    # stopping rule that reads the field after every expansion, to the last bit.
    task, trajectory, simulator = pushing_state
    common = {"friction": trajectory.friction, "drive": trajectory.drive, "seed": 4, "simulator": simulator}
    config = AnalyzerConfig(expansions=60)
    viewed: list[int] = []

    def never(field) -> bool:
        viewed.append(field.costs.size)
        return False

    _, by_rule = analyze_frame(task, trajectory.initial, config=config, stop=never, check_every=1, **common)
    far = time.perf_counter() + 3600.0
    _, by_deadline = analyze_frame(task, trajectory.initial, config=config, deadline=far, **common)
    assert len(viewed) == 60 and by_rule.expansions == by_deadline.expansions == 60
    for name in ("costs", "object_pos", "object_vel", "parents", "times", "states"):
        np.testing.assert_array_equal(getattr(by_rule, name), getattr(by_deadline, name), err_msg=name)
    # A deadline already passed still lets the first round run, then ends growth.
    _, passed = analyze_frame(task, trajectory.initial, config=config, deadline=time.perf_counter() - 1.0, **common)
    assert passed.expansions == 1
