"""The PyBullet backend, and cross-engine agreement with MuJoCo on small scenes.

Tolerances (measured with pybullet 3.2.7 and mujoco 4.0.0, stated here and in docs/reference/engines.md):

* one wrench (1.2 N along x, 2e-4 N m about z) on one resting object, 0.15 s: the final horizontal
  positions agree within 2 mm of a 35 mm displacement (measured: 0.9 mm upright cylinder, 1.6 mm
  free box), heights within 5 mm (Bullet lets a pushed body sink 3-4.5 mm into the ground plane);
  a diagonal force is not compared: MuJoCo's pyramidal friction cone is anisotropic (12 mm apart);
* a block sliding to rest from 0.5 m/s: friction work within 10 % of -1/2 m v0^2 in both engines,
  slide distance within 10 % of v0^2 / (2 mu g).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pybullet", reason="the pybullet extra is not installed")

from energy_margin.planning import TreeBudget, grow_tree
from energy_margin.planning.costs import make_cost_model
from energy_margin.sim import ENGINES, make_simulator
from energy_margin.sim.base import Simulator
from energy_margin.sim.pybullet_backend import PybulletSimulator
from energy_margin.tasks import PushingTask, RobotState, ScoopingTask, command_robot
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState

G = 9.81


def _pushing(n_objects: int = 3, seed: int = 1) -> tuple[PybulletSimulator, FrameState, np.ndarray, PushingTask]:
    task = PushingTask()
    trajectory = task.sample_trajectory(np.random.default_rng(seed), n_objects)
    simulator = PybulletSimulator(task.build_scene(n_objects, trajectory.friction))
    return simulator, trajectory.initial, trajectory.drive, task


def _snapshot(simulator: PybulletSimulator) -> list[np.ndarray]:
    return [
        simulator.object_positions(),
        simulator.object_quaternions(),
        simulator.object_velocities(),
        simulator.robot_positions(),
        simulator.robot_velocities(),
    ]


def test_engine_is_registered(make_block_scene: Callable[..., Scene]) -> None:
    assert "pybullet" in ENGINES
    simulator = make_simulator(make_block_scene(2), "pybullet")
    assert isinstance(simulator, PybulletSimulator)
    assert isinstance(simulator, Simulator)


def test_reset_round_trip_of_the_pushing_scene() -> None:
    simulator, frame, _, _ = _pushing(4)
    simulator.reset(frame)
    state = simulator.frame_state()
    np.testing.assert_allclose(state.object_pos, frame.object_pos, atol=1e-12)
    np.testing.assert_allclose(state.object_vel, frame.object_vel, atol=1e-12)
    np.testing.assert_allclose(state.robot_q, frame.robot_q, atol=1e-12)
    np.testing.assert_allclose(state.robot_v, frame.robot_v, atol=1e-12)
    np.testing.assert_allclose(np.abs(state.object_quat[:, 0]), 1.0, atol=1e-12)


def test_restored_state_replays_bit_identically() -> None:
    simulator, frame, drive, task = _pushing(3)
    simulator.reset(frame)
    command_robot(task, simulator, drive, 0.0, None)
    simulator.step(5)
    start = simulator.get_state()
    wrenches = np.random.default_rng(0).uniform(-0.3, 0.3, (3, 6))
    wrenches[:, 3:5] = 0.0

    def replay() -> list[np.ndarray]:
        simulator.set_state(start)
        simulator.set_object_wrenches(wrenches)
        simulator.step(10)
        return _snapshot(simulator)

    first = replay()
    other = np.random.default_rng(1)
    for _ in range(5):  # unrelated propagations in between
        simulator.set_state(start)
        simulator.set_object_wrenches(other.uniform(-0.4, 0.4, (3, 6)))
        simulator.step(12)
        simulator.get_state()
    second = replay()
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.allclose(first[0], frame.object_pos)


def test_state_restores_wrenches_targets_and_forces() -> None:
    simulator, frame, _, _ = _pushing(2)
    simulator.reset(frame)
    simulator.set_object_wrenches(np.full((2, 6), 0.1))
    simulator.set_robot_force(np.array([1.0, 2.0, 0.0, 0.0]))
    state = simulator.get_state()
    assert state.shape == (simulator.state_size,)
    simulator.set_object_wrenches(np.zeros((2, 6)))
    simulator.set_robot_force(np.zeros(4))
    simulator.set_state(state)
    np.testing.assert_array_equal(simulator.get_state()[2:], state[2:])


def test_saved_states_are_released_after_a_tree() -> None:
    simulator, frame, drive, task = _pushing(2)
    field = grow_tree(
        simulator,
        task,
        frame,
        drive,
        np.random.default_rng(0),
        budget=TreeBudget(expansions=20),
        cost_model=make_cost_model("wrench"),
    )
    assert field.nodes > 5
    assert simulator.saved_states == 0
    # A second tree on the same simulator starts from an empty registry too.
    simulator.get_state()
    assert simulator.saved_states == 1
    simulator.release_states()
    assert simulator.saved_states == 0


def _one_object(make_block_scene: Callable[..., Scene], engine: str, shape: str, motion: str) -> np.ndarray:
    scene = make_block_scene(1, shape=shape, motion=motion, friction=0.3, timestep=1.0 / 240.0)
    simulator = make_simulator(scene, engine)
    half_height = scene.objects[0].geom.size[-1]
    frame = FrameState(
        np.array([[0.0, 0.0, half_height]]),
        np.array([[1.0, 0.0, 0.0, 0.0]]),
        np.zeros((1, 6)),
        np.zeros(0),
        np.zeros(0),
    )
    simulator.reset(frame)
    simulator.set_object_wrenches(np.array([[1.2, 0.0, 0.0, 0.0, 0.0, 2e-4]]))
    simulator.step(36)  # 0.15 s
    return simulator.object_positions()[0]


@pytest.mark.parametrize(("shape", "motion"), [("cylinder", "upright"), ("box", "free")])
def test_one_wrench_moves_an_object_alike_in_both_engines(
    make_block_scene: Callable[..., Scene], shape: str, motion: str
) -> None:
    mujoco_pos = _one_object(make_block_scene, "mujoco", shape, motion)
    bullet_pos = _one_object(make_block_scene, "pybullet", shape, motion)
    assert mujoco_pos[0] > 0.03  # it moved
    np.testing.assert_allclose(bullet_pos[:2], mujoco_pos[:2], atol=0.002)
    assert bullet_pos[2] == pytest.approx(mujoco_pos[2], abs=0.005)


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
@pytest.mark.parametrize("motion", ["upright", "free"])
def test_sliding_block_friction_work_matches_the_kinetic_energy(
    make_block_scene: Callable[..., Scene], engine: str, motion: str
) -> None:
    mu, v0, mass = 0.5, 0.5, 0.2
    shape = "cylinder" if motion == "upright" else "box"
    scene = make_block_scene(1, shape=shape, motion=motion, friction=mu, timestep=1.0 / 240.0, mass=mass)
    simulator = make_simulator(scene, engine)
    half_height = scene.objects[0].geom.size[-1]
    velocity = np.zeros((1, 6))
    velocity[0, 0] = v0
    frame = FrameState(
        np.array([[0.0, 0.0, half_height]]), np.array([[1.0, 0.0, 0.0, 0.0]]), velocity, np.zeros(0), np.zeros(0)
    )
    simulator.reset(frame)
    work = simulator.step(60, track_friction_work=True)  # stops after v0 / (mu g) = 0.10 s
    assert abs(simulator.object_velocities()[0, 0]) < 0.01
    assert work == pytest.approx(-0.5 * mass * v0**2, rel=0.10)
    assert simulator.object_positions()[0, 0] == pytest.approx(v0**2 / (2 * mu * G), rel=0.10)


def test_friction_is_combined_to_the_scene_coefficient(make_block_scene: Callable[..., Scene]) -> None:
    simulator = make_simulator(make_block_scene(1, friction=0.16), "pybullet")
    assert isinstance(simulator, PybulletSimulator)
    pb = simulator._pb
    body = simulator._object_ids[0]
    ground = simulator._statics[0]
    mu_object = pb.getDynamicsInfo(body, -1, physicsClientId=simulator._client)[1]
    mu_ground = pb.getDynamicsInfo(ground, -1, physicsClientId=simulator._client)[1]
    assert mu_object * mu_ground == pytest.approx(0.16)


def test_penetrations_are_reported(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(2)
    simulator = make_simulator(scene, "pybullet")
    # Radii 0.05 m, 0.03 m high: 40 mm overlap sideways, so the shortest way out is 30 mm upwards.
    pos = np.array([[0.0, 0.0, 0.015], [0.06, 0.0, 0.015]])
    frame = FrameState(pos, np.tile([1.0, 0, 0, 0], (2, 1)), np.zeros((2, 6)), np.zeros(0), np.zeros(0))
    simulator.reset(frame)
    found = {(a, b): depth for a, b, depth in simulator.object_penetrations()}
    assert found[(0, 1)] == pytest.approx(0.03, abs=2e-3)


def test_pusher_drive_moves_it_forward() -> None:
    simulator, frame, drive, task = _pushing(1)
    frame = FrameState(
        frame.object_pos + np.array([5.0, 0.0, 0.0]),  # keep the object out of the way
        frame.object_quat,
        np.zeros_like(frame.object_vel),
        frame.robot_q,
        np.zeros(4),
    )
    simulator.reset(frame)
    simulator.set_robot_force(task.robot_force(RobotState(drive, 0.0, frame.robot_q, frame.robot_v), None))
    simulator.step(60)
    q = simulator.robot_positions()
    assert q[1] - frame.robot_q[1] > 0.01
    assert abs(q[3] - frame.robot_q[3]) < 0.01  # no spurious turning


def test_scooping_gripper_holds_its_pose() -> None:
    task = ScoopingTask()
    trajectory = task.sample_trajectory(np.random.default_rng(0), 3)
    simulator = make_simulator(task.build_scene(3, trajectory.friction, trajectory.drive), "pybullet")
    simulator.reset(trajectory.initial)
    for step in range(50):
        command_robot(task, simulator, trajectory.drive, step * simulator.timestep, None)
        simulator.step(1)
    q = simulator.robot_positions()
    targets = task.robot_targets(RobotState(trajectory.drive, 50 * simulator.timestep, q, q), None)
    np.testing.assert_allclose(q, targets, atol=5e-3)
    assert np.all(np.isfinite(simulator.object_positions()))


def test_generate_and_analyze_with_pybullet(tmp_path: Path) -> None:
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import analyze
    from energy_margin.data.generate import generate_dataset
    from energy_margin.data.scores_file import load_scores

    out = tmp_path / "pb"
    dataset = generate_dataset("pushing", n_objects=2, n_trajectories=1, n_frames=2, seed=0, out=out, engine="pybullet")
    assert dataset.metadata["engine"] == "pybullet"
    analyze(out, AnalyzerConfig(expansions=15, engine="pybullet"), progress=False)
    scores = load_scores(out)
    assert scores["nodes"].min() > 1
    assert np.all((scores["capture_score"] >= 0) & (scores["capture_score"] <= 1))
