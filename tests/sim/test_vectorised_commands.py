"""A batched call builds every propagation's controls from the task's vectorised script, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.sim.mujoco_rollout import RolloutPropagator
from energy_margin.tasks import get_task
from energy_margin.world.state import RobotState


def _calls(name: str, n_objects: int):  # type: ignore[no-untyped-def]
    task = get_task(name)
    rng = np.random.default_rng(3)
    trajectory = task.sample_trajectory(rng, n_objects)
    simulator = task.make_simulator(n_objects, trajectory.friction, trajectory.drive)
    simulator.reset(simulator.frame_state())
    propagator = simulator.rollout_propagator(1)
    k = 9
    state = propagator.current_state()
    states = np.repeat(state[None], k, axis=0)
    states[:, 1:] += rng.normal(0, 1e-3, states[:, 1:].shape)  # each its own robot pose
    limits = task.wrench_limits(simulator.scene)
    drives = np.stack([task.sample_trajectory(rng, n_objects).drive for _ in range(k)])
    control_steps = max(1, round(task.control_period / simulator.timestep)) if task.control_period else None
    inputs = (
        task,
        drives,
        states,
        rng.uniform(0.0, 2.0, k),
        rng.uniform(-1, 1, (k, *limits.max_wrench.shape)) * limits.max_wrench,
        rng.integers(1, 40, k),
        control_steps,
    )
    return task, propagator, inputs


def _controls(propagator: RolloutPropagator, inputs, monkeypatch: pytest.MonkeyPatch, *, vectorised: bool):  # type: ignore[no-untyped-def]
    seen = {}

    def keep(initial, chunks, period, n_steps, models=None):  # type: ignore[no-untyped-def]
        seen["controls"] = np.repeat(chunks, period, axis=1)[:, : int(n_steps.max())].copy()
        return initial

    monkeypatch.setattr(propagator, "_roll_to", keep)
    if not vectorised:
        monkeypatch.setattr(type(inputs[0]), "robot_commands", lambda self, *args: None)
    propagator.propagate(*inputs)
    monkeypatch.undo()
    return seen["controls"]


@pytest.mark.parametrize(("name", "n_objects"), [("pushing", 3), ("scooping", 2)])
def test_vectorised_controls_equal_the_loop_s(name: str, n_objects: int, monkeypatch: pytest.MonkeyPatch) -> None:
    _, propagator, inputs = _calls(name, n_objects)
    fast = _controls(propagator, inputs, monkeypatch, vectorised=True)
    slow = _controls(propagator, inputs, monkeypatch, vectorised=False)
    assert fast.shape == slow.shape
    np.testing.assert_array_equal(fast, slow)
    assert np.ptp(fast, axis=(0, 1)).any()  # the rows differ (wrenches, commands)


@pytest.mark.parametrize(("name", "n_objects"), [("pushing", 2), ("scooping", 2)])
def test_the_vectorised_script_is_the_script(name: str, n_objects: int) -> None:
    task = get_task(name)
    rng = np.random.default_rng(0)
    drives = np.stack([task.sample_trajectory(rng, n_objects).drive for _ in range(50)])
    times = np.r_[0.0, rng.uniform(0.0, 5.0, 49)]
    dofs = task.robot_dofs()
    q, v = rng.normal(size=(50, dofs)), rng.normal(size=(50, dofs))
    commands = task.robot_commands(drives, times, q, v)
    assert commands is not None
    forces, targets = commands
    for j in range(50):
        state = RobotState(drives[j], float(times[j]), q[j], v[j])
        np.testing.assert_array_equal(forces[j], task.robot_force(state, None))
        expected = task.robot_targets(state, None)
        if expected is None:
            assert targets is None
        else:
            assert targets is not None
            np.testing.assert_array_equal(targets[j], expected)
