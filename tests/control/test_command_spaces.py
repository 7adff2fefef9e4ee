"""Command spaces: bounds, per-step inputs, and the registry."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.control.commands import (
    PushingCommands,
    ScoopingCommands,
    command_space,
    controllable_tasks,
    register_command_space,
)
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks import RobotState, get_task


def test_pushing_inputs_hold_each_command_for_its_period() -> None:
    task = get_task("pushing")
    space = command_space(task, 3)
    assert isinstance(space, PushingCommands)
    commands = np.array([[[1.0, 2.0, 0.1], [3.0, 4.0, -0.1]]])
    inputs = space.inputs(commands, held=None, start_time=0.0, dt=0.01, period_steps=5)
    assert inputs.forces.shape == (1, 10, 4)
    assert inputs.targets is None
    np.testing.assert_array_equal(inputs.forces[0, :5], np.tile([1.0, 2.0, 0.0, 0.1], (5, 1)))
    np.testing.assert_array_equal(inputs.forces[0, 5:], np.tile([3.0, 4.0, 0.0, -0.1], (5, 1)))


def test_pushing_commands_are_clipped_to_the_bounds() -> None:
    space = command_space(get_task("pushing"), 10)
    huge = np.full((1, 1, 3), 1e6)
    inputs = space.inputs(huge, held=None, start_time=0.0, dt=0.01, period_steps=1)
    np.testing.assert_allclose(inputs.forces[0, 0, [0, 1, 3]], space.high)
    # Bound: twice the friction of the whole pile at the top of the friction range.
    cfg = get_task("pushing").config
    assert space.high[0] == pytest.approx(2.0 * 0.3 * 9.81 * (cfg.pusher_mass + 10 * cfg.object_mass))


def test_scooping_targets_integrate_speeds_within_the_stroke() -> None:
    task = get_task("scooping")
    space = command_space(task, 2)
    assert isinstance(space, ScoopingCommands)
    cfg = task.config
    held = np.array([task.contact_height, 0.0, cfg.scoop_angle, 0.0, cfg.scoop_angle])
    closing = space.high[1]
    commands = np.array([[[1.0, closing, 0.0]] * 4])
    dt, steps = 0.002, 50
    inputs = space.inputs(commands, held=held, start_time=cfg.approach_end, dt=dt, period_steps=steps)
    assert inputs.targets is not None and inputs.held is not None
    finger = inputs.targets[0, :, 1]
    expected = np.minimum(closing * dt * np.arange(1, 4 * steps + 1), task.closed_travel)
    np.testing.assert_allclose(finger, expected)
    np.testing.assert_allclose(inputs.targets[0, :, 2], 1.0)
    np.testing.assert_allclose(inputs.targets[0, :, 1], inputs.targets[0, :, 3])
    np.testing.assert_array_equal(inputs.held[0], inputs.targets[0, -1])
    np.testing.assert_array_equal(inputs.forces, 0.0)


def test_scooping_descent_follows_the_script_before_approach_end() -> None:
    task = get_task("scooping")
    space = command_space(task, 2)
    trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
    held = space.initial_targets(trajectory)
    commands = np.array([[[0.5, 0.0, space.high[2]]] * 2])
    dt = task.config.timestep
    inputs = space.inputs(commands, held=held, start_time=0.0, dt=dt, period_steps=100)
    assert inputs.targets is not None
    times = dt * np.arange(1, 201)
    for index in (0, 50, 148):
        assert times[index] < task.config.approach_end
        scripted = task.robot_targets(RobotState(trajectory.drive, times[index], held, held), None)
        assert inputs.targets[0, index, 0] == pytest.approx(scripted[0])
        assert inputs.targets[0, index, 2] == pytest.approx(task.config.scoop_angle)
    # After the descent the base lifts from the contact height.
    assert inputs.targets[0, -1, 0] > task.contact_height


def test_unknown_task_cannot_be_controlled_and_a_new_one_registers() -> None:
    task = get_task("pushing")
    task.name = "my_pushing"  # type: ignore[misc]
    with pytest.raises(EnergyMarginError, match="cannot be controlled"):
        command_space(task, 2)
    register_command_space("my_pushing", PushingCommands)
    try:
        assert isinstance(command_space(task, 2), PushingCommands)
        assert "my_pushing" in controllable_tasks()
    finally:
        from energy_margin.control import commands

        del commands._COMMAND_SPACES["my_pushing"]
