"""A scene's motion at many times at once: the same numbers as one time after another, to the last bit."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.sim.base import BatchedRollout, require
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_motion import Motion
from tiny_scene import SLIDE_PAD

# Two mocap bodies whose quaternions turn the long way (negative dot: flipped), a little (slerp) and
# not at all (linear), and controls of three actuators, at uneven keyframe times.
_TIMES = np.array([0.0, 0.3, 0.45, 1.2])


def _motion(hold: bool) -> Motion:
    rng = np.random.default_rng(7)
    quat = rng.normal(size=(4, 2, 4))
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    quat[2, 0] = -quat[1, 0]  # the same orientation, the other sign
    quat[3, 1] = quat[2, 1] + 1e-9  # nearly equal: linear, then normalised
    return Motion(
        ctrl_times=_TIMES,
        ctrl=rng.normal(size=(4, 3)),
        mocap_times=_TIMES,
        mocap_pos=rng.normal(size=(4, 2, 3)),
        mocap_quat=quat,
        hold=hold,
    )


def _times() -> np.ndarray:
    # Before, at and after every keyframe, between them, and past the end.
    between = np.random.default_rng(3).uniform(-0.2, 1.5, size=200)
    return np.concatenate([_TIMES, _TIMES + 1e-12, _TIMES - 1e-12, between, [-1.0, 2.0]])


@pytest.mark.parametrize("hold", [False, True])
def test_controls_and_mocap_poses_at_many_times_equal_those_at_each_time(hold: bool) -> None:
    motion = _motion(hold)
    times = _times()
    ctrl = motion.ctrl_at_times(times)
    mocap = motion.mocap_at_times(times)
    assert ctrl is not None and mocap is not None
    assert ctrl.shape == (times.size, 3)
    assert mocap[0].shape == (times.size, 2, 3) and mocap[1].shape == (times.size, 2, 4)
    for row, time in enumerate(times.tolist()):
        one_ctrl = motion.ctrl_at(time)
        one_mocap = motion.mocap_at(time)
        assert one_ctrl is not None and one_mocap is not None
        assert np.array_equal(ctrl[row], one_ctrl), time
        assert np.array_equal(mocap[0][row], one_mocap[0]), time
        assert np.array_equal(mocap[1][row], one_mocap[1]), time


def test_a_motion_without_controls_or_mocap_rows_has_none_at_many_times() -> None:
    empty = Motion(np.zeros(0), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 1, 3)), np.zeros((0, 1, 4)), False)
    assert empty.ctrl_at_times(np.array([0.1])) is None
    assert empty.mocap_at_times(np.array([0.1])) is None


def test_a_scene_tasks_batched_model_command_is_its_model_command_of_each_row(make_scene) -> None:
    task = get_task("scene", {"scene_file": str(make_scene())})
    rng = np.random.default_rng(2)
    drives = np.stack([task.sample_trajectory(rng, 2).drive for _ in range(5)])
    times = np.array([0.0, 0.37, 0.8, 1.5, 3.0])
    batched = task.batched_model_command(drives, times)
    assert batched is not None and batched.mocap_pos is not None and batched.mocap_quat is not None
    for row in range(times.size):
        one = task.model_command(drives[row], float(times[row]))
        assert one is not None and one.mocap_pos is not None
        assert np.array_equal(batched.mocap_pos[row], one.mocap_pos)
        assert np.array_equal(batched.mocap_quat[row], one.mocap_quat)


def test_a_subclass_that_commands_otherwise_gets_no_batched_command(make_scene) -> None:
    from energy_margin.integrations.live_model import HeldCommandTask

    task = get_task("scene", {"scene_file": str(make_scene())})
    held = HeldCommandTask(loaded=task.loaded)
    assert held.batched_model_command(np.ones((2, 1)), np.zeros(2)) is None

    class Pushed(type(task)):  # type: ignore[misc]
        def robot_force(self, state, rng=None):  # type: ignore[no-untyped-def]
            return np.ones(self.robot_dofs())

    assert Pushed(loaded=task.loaded).batched_model_command(np.ones((2, 1)), np.zeros(2)) is None


class _RowByRow:
    """The task, without its batched model command: the propagator evaluates it one row at a time."""

    def __init__(self, task: object) -> None:
        self._task = task

    def __getattr__(self, name: str) -> object:
        if name == "batched_model_command":
            raise AttributeError(name)
        return getattr(self._task, name)


@pytest.mark.parametrize("control_steps", [1, 3, None])
def test_propagations_with_the_batched_command_equal_those_commanded_row_by_row(make_scene, control_steps) -> None:
    scene = make_scene(
        replace={
            "mocap.pusher.pos = [0.0, -0.15, 0.03]": "mocap.pusher.pos = [0.0, -0.15, 0.03]\nctrl = [0.0]",
            "mocap.pusher.pos = [0.0, 0.3, 0.03]": "mocap.pusher.pos = [0.0, 0.3, 0.03]\nctrl = [0.1]",
        },
        model_replace=SLIDE_PAD,
    )
    task = get_task("scene", {"scene_file": str(scene)})
    trajectory = task.sample_trajectory(np.random.default_rng(1), 2)
    simulator = task.make_simulator(2, trajectory.friction, trajectory.drive)
    simulator.reset(trajectory.initial)
    propagator = require(simulator, BatchedRollout, purpose="the test").rollout_propagator(1)
    rng = np.random.default_rng(4)
    k = 5
    states = np.stack([propagator.current_state()] * k)
    times = np.array([0.0, 0.21, 0.5, 0.9, 1.45])  # the last runs past the motion's end
    wrenches = rng.uniform(-0.1, 0.1, size=(k, 2, 6))
    n_steps = np.array([4, 9, 1, 12, 7])
    inputs = (trajectory.drive, states, times, wrenches, n_steps, control_steps)
    batched = propagator.propagate(task, *inputs)
    batched_mocap = propagator.end_robot_positions(batched[3]).copy()
    row_by_row = propagator.propagate(_RowByRow(task), *inputs)
    for found, expected in zip(batched, row_by_row, strict=True):
        assert np.array_equal(found, expected)
    assert np.array_equal(batched_mocap, propagator.end_robot_positions(row_by_row[3]))
    assert np.ptp(batched[0][:, :, 1]) > 0.0  # the rows did move differently
