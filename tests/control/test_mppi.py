"""The controller's predictions: the horizon, and the look-ahead on the script's commands."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.control.commands import command_space
from energy_margin.control.costs import CostContext, CostWeights, task_cost
from energy_margin.control.mppi import Controller, ControllerConfig
from energy_margin.errors import InvalidParameterError
from energy_margin.tasks import get_task


def _controller(lookahead: int, task_name: str = "scooping") -> Controller:
    task = get_task(task_name)
    trajectory = task.sample_trajectory(np.random.default_rng(4), 2)
    space = command_space(task, 2)
    context = CostContext(
        task,
        length_scale=space.length_scale,
        weights=CostWeights(),
        friction=trajectory.friction,
        drive=trajectory.drive,
        analysis_drive=lambda force: space.analysis_drive(trajectory, force),
        margin_expansions=5,
        margin_samples=1,
        seed_sequence=np.random.SeedSequence(0),
    )
    config = ControllerConfig(samples=3, horizon=2, lookahead=lookahead)
    return Controller(task, space, trajectory, task_cost, context, config, np.random.default_rng(1))


def test_lookahead_extends_the_predictions_with_the_script_and_stops_at_the_episode_end() -> None:
    short, long = _controller(0), _controller(5)
    time = 0.6
    commands, scripted = short.sample(time)
    observed = short.trajectory.initial
    held = short.space.initial_targets(short.trajectory)
    horizon = short.predict(observed, time, held, commands, scripted)
    ahead = long.predict(observed, time, held, commands, scripted)
    assert horizon.object_pos.shape[1] == 2 and ahead.object_pos.shape[1] == 7
    assert ahead.end_time == pytest.approx(time + 0.7)
    # The first H periods are the same roll-out; the deviations cover the sampled periods only.
    np.testing.assert_allclose(ahead.object_pos[:, :2], horizon.object_pos)
    assert ahead.commands.shape == horizon.commands.shape
    # The look-ahead follows the script: the fingers keep closing after the horizon.
    assert ahead.robot_q[0, -1, 1] > horizon.robot_q[0, -1, 1] + 1e-3
    # Near the end of the episode the look-ahead is cut at the episode's end (2.3 s).
    late = long.predict(observed, 1.9, held, commands, scripted)
    assert late.object_pos.shape[1] == 4 and late.end_time == pytest.approx(2.3)


def test_lookahead_must_not_be_negative() -> None:
    with pytest.raises(InvalidParameterError, match="lookahead"):
        ControllerConfig(lookahead=-1)
