"""A scene's robot follows the path each roll-out was recorded on (``motion.robot = "recorded"``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.errors import EnergyMarginError, InvalidDataError
from energy_margin.tasks import command_robot, get_task
from energy_margin.tasks.recorded_path import (
    RECORDED_ARMATURE,
    PathForceTable,
    path_drive,
    path_drive_size,
    path_forces,
    path_velocities,
)
from energy_margin.tasks.scene_file import read_scene_file
from tiny_scene import ARM_OVER_PUCK, ARM_SCENE, write_arm_rollouts, write_tiny_scene


def _recorded_path(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The arm's recorded angle and speed: it speeds up, turns through the puck and comes back."""
    return 1.2 * np.sin(1.5 * t), 1.8 * np.cos(1.5 * t)


def _task(tmp_path: Path, robot: str):  # type: ignore[no-untyped-def]
    scene = write_tiny_scene(tmp_path, scene=ARM_SCENE.replace("ROBOT", robot), model=ARM_OVER_PUCK)
    return get_task("scene", {"scene_file": str(scene)})


def test_the_drive_carries_the_knots_and_the_path_s_velocities_between_them() -> None:
    time = np.arange(0.0, 2.0 + 1e-9, 0.01)
    q, v = _recorded_path(time)
    drive = path_drive(time, q[:, None], v[:, None], points=41)
    assert drive.shape == (path_drive_size(41, 1),) == (2 + 41 * 3,)
    np.testing.assert_array_equal(drive[:2], [1.0, 1.0])
    np.testing.assert_allclose(drive[2:43], np.linspace(0.0, 2.0, 41), atol=1e-9)  # the rows at 41 even times
    between = np.array([0.013, 0.51, 1.234, 1.99])
    found = path_velocities(np.repeat(drive[None], 4, axis=0), between, 1)[:, 0]
    np.testing.assert_allclose(found, _recorded_path(between)[1], atol=2e-4)
    # Before the first knot the first knot's velocity, after the last the last's.
    outside = path_velocities(np.repeat(drive[None], 2, axis=0), np.array([-1.0, 5.0]), 1)[:, 0]
    np.testing.assert_allclose(outside, [1.8, 1.8 * np.cos(3.0)])


def test_a_roll_out_of_fewer_rows_than_knots_repeats_its_last_row() -> None:
    time = np.array([0.0, 0.5, 1.0])
    q, v = _recorded_path(time)
    drive = path_drive(time, q[:, None], v[:, None], points=6)
    np.testing.assert_array_equal(drive[2:8], [0.0, 0.5, 1.0, 1.0, 1.0, 1.0])
    speeds = path_velocities(np.repeat(drive[None], 3, axis=0), np.array([0.5, 0.99, 1.5]), 1)[:, 0]
    assert np.all(np.isfinite(speeds))
    assert speeds[0] == pytest.approx(v[1]) and speeds[2] == pytest.approx(v[2])


def test_the_forces_change_the_velocity_as_the_path_does_over_a_period() -> None:
    time = np.arange(0.0, 2.0 + 1e-9, 0.01)
    q, v = _recorded_path(time)
    drive = path_drive(time, q[:, None], v[:, None], points=41)[None]
    forces = path_forces(drive, np.array([0.7]), n_joints=1, period=0.05, armature=10.0)
    change = path_velocities(drive, np.array([0.75]), 1) - path_velocities(drive, np.array([0.7]), 1)
    np.testing.assert_allclose(forces, 10.0 * change / 0.05)


@pytest.mark.parametrize("robot", ["recorded", "coasting"])
def test_a_recorded_arm_follows_its_path_through_the_puck(tmp_path: Path, robot: str) -> None:
    """From a frame at 0.1 s, the arm follows its recorded turn through the puck; a coasting one overshoots it."""
    task = _task(tmp_path, f'robot = "{robot}"')
    time = np.arange(0.0, 2.0 + 1e-9, 0.01)
    angle, speed = _recorded_path(time)
    qpos = np.column_stack([angle, np.zeros((time.size, 2))])
    qvel = np.column_stack([speed, np.zeros((time.size, 2))])
    drive = task.recorded_drive(time, qpos, qvel)
    assert drive.shape == (task.drive_size(),)
    simulator = task.make_simulator(1, task.default_friction(), drive)
    frame = simulator.frame_state()
    start = 0.1  # the arm at 0.18 rad, the puck at 0.46 rad
    at = _recorded_path(np.array([start]))
    simulator.reset(type(frame)(frame.object_pos, frame.object_quat, frame.object_vel, at[0], at[1]))
    for step in range(100):  # 1 s, one command per step (the scene's control period, 0.01 s)
        command_robot(task, simulator, drive, start + 0.01 * step, None)
        simulator.step(1)
    end = float(simulator.robot_positions()[0])
    pushed = float(np.linalg.norm(simulator.frame_state().object_pos[0, :2] - frame.object_pos[0, :2]))
    if robot == "recorded":
        assert end == pytest.approx(1.2 * np.sin(1.5 * 1.1), abs=0.01)  # 1.014 rad: the recorded angle at 1.1 s
        assert pushed > 0.02
    else:
        assert end > 1.5  # kept turning at the frame's 1.78 rad/s


def _propagated_controls(simulator, task, drives: np.ndarray, times: np.ndarray, n_steps: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The control vectors a batched propagation hands MuJoCo, shape (rows, n_chunks, control_size)."""
    propagator = simulator.rollout_propagator(1)
    seen = {}

    def keep(initial, chunks, period, n_steps, models=None):  # type: ignore[no-untyped-def]
        seen["controls"] = chunks.copy()
        return initial

    propagator._roll_to = keep  # type: ignore[method-assign]
    rows = len(times)
    states = np.repeat(propagator.current_state()[None], rows, axis=0)
    propagator.propagate(task, drives, states, times, np.zeros((rows, 1, 6)), np.full(rows, n_steps), 1)
    return seen["controls"]


def test_batched_propagation_applies_the_path_s_forces_bit_for_bit(tmp_path: Path) -> None:
    task = _task(tmp_path, 'robot = "recorded"\npath_points = 30')
    time = np.arange(0.0, 2.0 + 1e-9, 0.01)
    rng = np.random.default_rng(0)
    drives = []
    for _ in range(5):
        angle, speed = _recorded_path(time * rng.uniform(0.5, 1.5))
        drives.append(task.recorded_drive(time, np.column_stack([angle, 0 * time, 0 * time]),
                                          np.column_stack([speed, 0 * time, 0 * time])))  # fmt: skip
    drives_array = np.stack(drives)
    times = rng.uniform(0.0, 2.0, 5)
    forces = task.batched_robot_force(drives_array, times)
    assert np.abs(forces[:, 0]).max() > 0.5 * RECORDED_ARMATURE  # armature x accelerations of about 1 rad/s^2
    for j in range(5):
        from energy_margin.world.state import RobotState

        one = task.robot_force(RobotState(drives_array[j], float(times[j]), np.zeros(1), np.zeros(1)), None)
        np.testing.assert_array_equal(one, forces[j])
    # The batched call writes them into each propagation's control vector.
    simulator = task.make_simulator(1, task.default_friction(), drives_array[0])
    controls = _propagated_controls(simulator, task, drives_array, times, 3)
    nu, qfrc = int(simulator.model.nu), simulator.index.robot_qvel
    for chunk in range(3):
        expected = task.batched_robot_force(drives_array, times + 0.01 * chunk)[:, 0]
        np.testing.assert_array_equal(controls[:, chunk, nu + qfrc[0]], expected)
    assert simulator.model.dof_armature[qfrc[0]] == RECORDED_ARMATURE


def test_path_points_apply_to_a_recorded_robot_only(tmp_path: Path) -> None:
    scene = write_tiny_scene(tmp_path, scene=ARM_SCENE.replace("ROBOT", 'robot = "coasting"\npath_points = 10'),
                             model=ARM_OVER_PUCK)  # fmt: skip
    with pytest.raises(EnergyMarginError, match=r'scene.toml:11: motion.path_points: applies to robot = "recorded"'):
        read_scene_file(scene)
    fewer = write_tiny_scene(tmp_path, scene=ARM_SCENE.replace("ROBOT", 'robot = "recorded"\npath_points = 1'),
                             model=ARM_OVER_PUCK)  # fmt: skip
    with pytest.raises(EnergyMarginError, match=r"scene.toml:11: motion.path_points: must be an integer >= 2"):
        read_scene_file(fewer)


def test_a_recorded_robot_has_no_path_to_generate_from(tmp_path: Path) -> None:
    task = _task(tmp_path, 'robot = "recorded"')
    with pytest.raises(InvalidDataError, match=r'motion.robot: "recorded" follows the paths of recorded roll-outs'):
        task.sample_trajectory(np.random.default_rng(0), 1)


def test_record_keeps_each_roll_outs_own_path(tmp_path: Path) -> None:
    from energy_margin.data.record import record_dataset

    text = ARM_SCENE.replace("ROBOT", 'robot = "recorded"\npath_points = 20')
    scene = write_tiny_scene(tmp_path / "scene", scene=text, model=ARM_OVER_PUCK)
    rollouts = write_arm_rollouts(tmp_path / "rollouts", count=2)
    dataset = record_dataset(scene, rollouts, n_frames=4, out=tmp_path / "set")
    drives = dataset.arrays["drive"]
    assert drives.shape == (2, 2 + 20 * 3)
    for index, path in enumerate(rollouts):
        recorded = np.load(path)
        at = np.searchsorted(recorded["time"], drives[index, 2:22])
        np.testing.assert_array_equal(drives[index, 22:42], recorded["qpos"][at, 0])  # the shoulder's angles
        np.testing.assert_array_equal(drives[index, 42:62], recorded["qvel"][at, 0])
    assert drives[0, 22:42].max() < drives[1, 22:42].max()  # 0.9 against 1.0 rad


def test_scene_says_the_robot_follows_each_roll_outs_path(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from energy_margin.cli import main

    scene = write_tiny_scene(tmp_path, scene=ARM_SCENE.replace("ROBOT", 'robot = "recorded"'), model=ARM_OVER_PUCK)
    assert main(["scene", str(scene), "--no-picture"]) == 0
    assert (
        "robot during analysis recorded (each roll-out's own joint path, 64 (default) knots)" in capsys.readouterr().out
    )


def test_the_force_table_holds_the_path_s_forces_at_every_time_step() -> None:
    time = np.arange(0.0, 2.0 + 1e-9, 0.01)
    q, v = _recorded_path(time)
    drive = path_drive(time, q[:, None], v[:, None], points=41)
    table = PathForceTable.of(drive, n_joints=1, dt=0.004, hold_steps=2, armature=10.0)
    assert table.first_step == 0 and table.forces.shape == (round(2.0 / 0.004) + 2 + 1, 1)
    steps = np.array([0, 1, 137, 250, 499])
    direct = path_forces(drive[None], steps * 0.004, n_joints=1, period=0.008, armature=10.0)
    np.testing.assert_array_equal(table.at(steps * 0.004)[:, 0], np.repeat(direct[:, 0], 1))
    np.testing.assert_array_equal(table.at(137 * 0.004 + np.array([-0.0015, 0.0015])), table.forces[[137, 137]])
    np.testing.assert_array_equal(table.at(np.array([2.1, 30.0])), 0.0)  # past the path: no velocity change


def test_a_task_commanding_by_model_commands_alone_gets_zero_forces_in_a_batched_call(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A task with ``batched_model_command`` but no ``batched_robot_force`` (another package's) propagates."""
    task = _task(tmp_path, "")
    simulator = task.make_simulator(1, task.default_friction(), np.ones(2))
    monkeypatch.setattr(type(task), "batched_robot_force", None)
    controls = _propagated_controls(simulator, task, np.ones((3, 2)), np.zeros(3), 2)
    qfrc = int(simulator.model.nu) + simulator.index.robot_qvel[0]
    np.testing.assert_array_equal(controls[:, :, qfrc], 0.0)
