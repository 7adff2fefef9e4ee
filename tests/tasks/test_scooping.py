"""Scooping task: gripper kinematics, scripted lifts, labels, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.sim import make_simulator
from energy_margin.tasks import RobotState, ScoopingTask, command_robot, get_task
from energy_margin.world.state import FrameState

# robot_q = (base z, right finger, right tip, left finger, left tip)
BASE, RIGHT_FINGER, RIGHT_TIP, LEFT_FINGER, LEFT_TIP = range(5)


def _frame(task: ScoopingTask, xy: np.ndarray, robot_q: np.ndarray | None = None) -> FrameState:
    n = len(xy)
    pos = np.column_stack([xy, np.full(n, task.rest_height)])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    start = RobotState(np.array([1000.0]), 0.0, np.zeros(5), np.zeros(5))
    q = task.robot_targets(start, None) if robot_q is None else robot_q
    return FrameState(pos, quat, np.zeros((n, 6)), q, np.zeros(5))


def _roll_out(task: ScoopingTask, frame: FrameState, friction: float, stiffness: float) -> FrameState:
    drive = np.array([stiffness])
    simulator = make_simulator(task.build_scene(frame.n_objects, friction, drive))
    simulator.reset(frame)
    for step in range(task.n_steps):
        command_robot(task, simulator, drive, step * simulator.timestep, None)
        simulator.step(1)
    return simulator.frame_state()


def test_registered_with_free_boxes_and_servos() -> None:
    task = get_task("scooping")
    assert isinstance(task, ScoopingTask)
    scene = task.build_scene(5, 0.5, np.array([500.0]))
    assert scene.object_motion == "free"
    assert scene.n_robot_dofs == 5
    assert all(joint.servoed for joint in scene.robot_joints)
    assert scene.robot_joints[RIGHT_FINGER].servo_stiffness == 500.0
    # 1 cm boxes of 2 g.
    np.testing.assert_allclose(scene.objects[0].geom.size, (0.005, 0.005, 0.005))
    assert scene.objects[0].mass == pytest.approx(0.002)


def test_fingers_close_in_parallel_and_tips_stay_within_limits() -> None:
    task = ScoopingTask()
    frame = _frame(task, np.array([[0.0, 0.04]]))  # one box out of the way
    drive = np.array([800.0])
    simulator = make_simulator(task.build_scene(1, 0.5, drive))
    simulator.reset(frame)
    low, high = task.config.tip_limits
    fingers = []
    for step in range(task.n_steps):
        command_robot(task, simulator, drive, step * simulator.timestep, None)
        simulator.step(1)
        q = simulator.robot_positions()
        fingers.append(q[[RIGHT_FINGER, LEFT_FINGER]])
        assert low - 1e-6 <= q[RIGHT_TIP] <= high + 1e-6
        assert low - 1e-6 <= q[LEFT_TIP] <= high + 1e-6
    fingers_arr = np.array(fingers)
    # Symmetric (parallel) closing throughout, and it really closes.
    np.testing.assert_allclose(fingers_arr[:, 0], fingers_arr[:, 1], atol=1e-6)
    assert fingers_arr[-1, 0] > 0.9 * task.closed_travel
    # Blades hold the scoop angle; the base has risen by the lift height.
    q = simulator.robot_positions()
    assert q[RIGHT_TIP] == pytest.approx(task.config.scoop_angle, abs=0.05)
    assert q[BASE] == pytest.approx(task.contact_height + task.config.lift_height, abs=2e-3)


def test_servo_targets_drive_the_joints_and_are_restored_with_the_state() -> None:
    task = ScoopingTask()
    frame = _frame(task, np.array([[0.0, 0.04]]))
    simulator = make_simulator(task.build_scene(1, 0.5, np.array([1000.0])))
    simulator.reset(frame)
    saved = simulator.get_state()
    targets = frame.robot_q + np.array([0.01, 0.01, -0.2, 0.01, -0.2])
    simulator.set_robot_targets(targets)
    simulator.step(500)
    moved = simulator.robot_positions()
    assert moved[BASE] == pytest.approx(targets[BASE], abs=1e-3)
    assert moved[RIGHT_TIP] == pytest.approx(targets[RIGHT_TIP], abs=0.02)
    simulator.set_state(saved)
    simulator.step(100)
    # The restored state holds the frame's pose (targets are part of the state).
    np.testing.assert_allclose(simulator.robot_positions(), frame.robot_q, atol=2e-3)


@pytest.mark.parametrize("angle", [-0.1, 1.8])
def test_scoop_angle_must_be_reachable_by_the_blades(angle: float) -> None:
    with pytest.raises(EnergyMarginError, match=r"scoop_angle must lie within tip_limits \[0.0, 1.75\] rad"):
        get_task("scooping", {"scoop_angle": angle})
    get_task("scooping", {"scoop_angle": 1.75})  # the limit itself is reachable


def test_wrench_limits_scale_with_mass_and_true_inertia() -> None:
    task = ScoopingTask()
    scene = task.build_scene(3, 0.5)
    limits = task.wrench_limits(scene).max_wrench
    assert limits.shape == (3, 6)
    np.testing.assert_allclose(limits[:, :3], 0.002 * 2.0)
    inertia = 0.002 * 0.01**2 / 6.0  # solid cube, edge 1 cm
    np.testing.assert_allclose(limits[:, 3:], inertia * task.config.max_angular_acceleration)


def test_within_bounds_rejects_boxes_under_the_table_or_far_away() -> None:
    task = ScoopingTask()
    pos = np.array([[0.0, 0.0, 0.005], [0.01, 0.0, 0.05]])
    vel = np.zeros((2, 6))
    assert task.within_bounds(pos, vel)
    assert not task.within_bounds(pos - np.array([0.0, 0.0, 0.02]), vel)
    assert not task.within_bounds(pos + np.array([0.5, 0.0, 0.0]), vel)
    assert not task.within_bounds(pos, vel + 10.0)


def test_labels_on_hand_built_frames() -> None:
    task = ScoopingTask()
    xy = np.array([[0.0, 0.0], [0.015, 0.0]])
    on_table = _frame(task, xy)
    assert not task.is_captured(on_table)
    assert not task.is_successful(on_table)
    up = np.array([0.0, 0.0, 1.0])
    lifted_pos = on_table.object_pos + 0.06 * up
    lifted = FrameState(lifted_pos, on_table.object_quat, on_table.object_vel, on_table.robot_q, on_table.robot_v)
    assert task.is_captured(lifted)
    assert task.is_successful(lifted)
    # Only 2 cm up: captured, not yet successful.
    low = FrameState(
        on_table.object_pos + 0.02 * up, lifted.object_quat, lifted.object_vel, lifted.robot_q, lifted.robot_v
    )
    assert task.is_captured(low)
    assert not task.is_successful(low)
    # Falling boxes are neither.
    falling_vel = lifted.object_vel.copy()
    falling_vel[1, 2] = -0.5
    falling = FrameState(lifted_pos, lifted.object_quat, falling_vel, lifted.robot_q, lifted.robot_v)
    assert not task.is_captured(falling)
    assert not task.is_successful(falling)
    # A box outside the gripper's footprint is not captured.
    away = lifted_pos.copy()
    away[0, 1] = 0.05
    assert not task.is_captured(FrameState(away, lifted.object_quat, lifted.object_vel, lifted.robot_q, lifted.robot_v))


def test_lift_succeeds_with_high_friction_and_centred_boxes() -> None:
    task = ScoopingTask()
    xy = np.array([[-0.015, 0.0], [0.0, 0.0], [0.015, 0.0]])
    final = _roll_out(task, _frame(task, xy), friction=0.9, stiffness=2000.0)
    assert task.is_successful(final)
    assert task.is_captured(final)


def test_lift_fails_with_very_low_friction() -> None:
    # A sampled layout (yawed boxes): with almost no friction the blades push boxes around instead
    # of carrying them; the same layout and drive succeed with ordinary friction.
    task = ScoopingTask()
    initial = task.sample_trajectory(np.random.default_rng(0), 3).initial
    assert not task.is_successful(_roll_out(task, initial, friction=0.02, stiffness=1000.0))
    assert task.is_successful(_roll_out(task, initial, friction=0.9, stiffness=1000.0))


@pytest.mark.slow
def test_generate_and_analyze_are_deterministic(tmp_path) -> None:
    kwargs = {"n_objects": 3, "n_trajectories": 2, "n_frames": 3, "seed": 7}
    first = generate_dataset("scooping", out=tmp_path / "a", **kwargs)
    second = generate_dataset("scooping", out=tmp_path / "b", **kwargs)
    for name, array in first.arrays.items():
        np.testing.assert_array_equal(array, second.arrays[name], err_msg=name)
    loaded = load_dataset(tmp_path / "a")
    assert loaded.metadata["task"] == "scooping"
    assert loaded.metadata["n_robot_dofs"] == 5 and loaded.metadata["n_drive"] == 1
    config = AnalyzerConfig(expansions=20)
    analyze(tmp_path / "a", config, seed=3, workers=1, progress=False)
    analyze(tmp_path / "b", config, seed=3, workers=2, progress=False)
    scores_a, scores_b = load_scores(tmp_path / "a"), load_scores(tmp_path / "b")
    for column in ("capture_score", "success_score", "nodes", "expansions", "seed"):
        np.testing.assert_array_equal(scores_a[column], scores_b[column], err_msg=column)
    assert np.all((scores_a["capture_score"] >= 0) & (scores_a["capture_score"] <= 1 + 1e-9))


# ---------------------------------------------------------------- recorded motion


def _recorded(times: list[float], positions: np.ndarray) -> np.ndarray:
    return np.concatenate([[1000.0], times, np.asarray(positions, dtype=float).ravel()])


def test_recorded_motion_is_interpolated_held_and_continued() -> None:
    task = get_task("scooping", {"recorded_waypoints": 3})
    assert isinstance(task, ScoopingTask)
    positions = np.array(
        [
            [0.08, 0.044, 1.10, 0.044, 1.10],
            [0.09, 0.044, 1.12, 0.044, 1.11],
            [0.11, 0.044, 1.13, 0.044, 1.13],
        ]
    )
    drive = _recorded([0.6, 0.75, 0.9], positions)
    zeros = np.zeros(5)

    def targets(time: float) -> np.ndarray:
        return task.robot_targets(RobotState(drive, time, zeros, zeros), None)

    np.testing.assert_allclose(targets(0.0), positions[0])  # held before the first waypoint
    np.testing.assert_allclose(targets(0.75), positions[1])
    np.testing.assert_allclose(targets(0.675), 0.5 * (positions[0] + positions[1]))
    # After the last waypoint the motion goes on at the last segment's rate.
    np.testing.assert_allclose(targets(1.2), positions[2] + (positions[2] - positions[1]) * 2.0)
    # The script is not followed: it would open the fingers at 0.6 s.
    assert task._targets(0.6)[RIGHT_FINGER] < 0.02


def test_recorded_motion_drives_the_gripper_in_a_roll_out() -> None:
    task = get_task("scooping", {"recorded_waypoints": 2})
    assert isinstance(task, ScoopingTask)
    start = task._targets(1.2)
    end = start + np.array([0.02, 0.0, 0.0, 0.0, 0.0])
    drive = _recorded([1.0, 1.5], np.stack([start, end]))
    simulator = make_simulator(task.build_scene(1, 0.5, drive))
    simulator.reset(_frame(task, np.array([[0.0, 0.06]]), robot_q=start))
    for step in range(400):  # 0.8 s from t = 1.0 s: the base follows the rising waypoints
        command_robot(task, simulator, drive, 1.0 + step * simulator.timestep, None)
        simulator.step(1)
    assert simulator.robot_positions()[BASE] == pytest.approx(start[BASE] + 0.02 * 1.6, abs=3e-3)


def test_generated_trajectories_record_the_script_as_waypoints() -> None:
    task = get_task("scooping", {"recorded_waypoints": 24})
    assert isinstance(task, ScoopingTask)
    assert task.drive_size() == 1 + 6 * 24
    trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
    times, positions = task.waypoints(trajectory.drive)
    for time, position in zip(times, positions, strict=True):
        np.testing.assert_allclose(position, task._targets(float(time)))


@pytest.mark.parametrize(
    ("value", "message"), [(1, "0 or at least 2"), (-2, "must be a non-negative integer"), (2.5, "must be an integer")]
)
def test_recorded_waypoints_must_be_a_count(value: float, message: str) -> None:
    with pytest.raises(EnergyMarginError, match=message):
        get_task("scooping", {"recorded_waypoints": value})


def test_a_bad_recorded_motion_is_refused_where_the_scene_is_built() -> None:
    task = get_task("scooping", {"recorded_waypoints": 2})
    still = task._targets(1.2)  # type: ignore[attr-defined]
    with pytest.raises(InvalidParameterError, match="increase strictly"):
        task.build_scene(1, 0.5, _recorded([1.0, 1.0], np.stack([still, still])))
    with pytest.raises(InvalidParameterError, match=r"1 \+ 6 x 2 values"):
        task.build_scene(1, 0.5, np.array([1000.0]))
