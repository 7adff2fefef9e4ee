from __future__ import annotations

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.live import score_state
from energy_margin.tasks import get_task


@pytest.fixture(scope="module")
def pushing_state():
    task = get_task("pushing")
    trajectory = task.sample_trajectory(np.random.default_rng(3), 3)
    simulator = task.make_simulator(3, trajectory.friction, trajectory.drive)
    return task, trajectory, simulator


def test_wall_clock_budget_is_respected(pushing_state) -> None:
    task, trajectory, simulator = pushing_state
    options = {"friction": trajectory.friction, "drive": trajectory.drive, "simulator": simulator}
    result = score_state(task, trajectory.initial, budget_s=0.03, seed=1, **options)
    assert result.stopped_by == "budget"
    # Loosely: the deadline passed, then one expansion and the scoring (a shared machine may be slow).
    assert 0.03 <= result.seconds < 0.03 + 1.0
    assert result.expansions >= 1 and 0.0 <= result.capture <= 1.0 and 0.0 <= result.success <= 1.0
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
        config=AnalyzerConfig(iterations=12),
    )
    assert (scores.capture_score, scores.success_score, scores.nodes) == (first.capture, first.success, first.nodes)


def test_score_state_validates_its_budget(pushing_state) -> None:
    task, trajectory, _ = pushing_state
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="budget_s"):
            score_state(task, trajectory.initial, friction=trajectory.friction, drive=trajectory.drive, budget_s=bad)
    with pytest.raises(ValueError, match="max_expansions"):
        score_state(task, trajectory.initial, friction=trajectory.friction, drive=trajectory.drive, max_expansions=0)


def test_analyze_frame_stop_rule_beside_convergence(pushing_state) -> None:
    task, trajectory, simulator = pushing_state
    common = {"friction": trajectory.friction, "drive": trajectory.drive, "seed": 2, "simulator": simulator}
    scores, _ = analyze_frame(
        task, trajectory.initial, stop=lambda field: field.iterations >= 7, check_every=1, **common
    )
    assert scores.iterations == 7
    # With a convergence rule too, the caller's rule still stops growth at its own period.
    config = AnalyzerConfig(iterations=40, converge=0.5, converge_window=10, converge_every=10)
    scores, _ = analyze_frame(
        task, trajectory.initial, config=config, stop=lambda field: field.iterations >= 4, check_every=2, **common
    )
    assert scores.iterations == 4
