from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from energy_margin import compat
from energy_margin.errors import EnergyMarginError, InvalidDataError, InvalidParameterError
from energy_margin.sim import Simulator, make_simulator
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.sim.mujoco_spec import build_model
from energy_margin.tasks import PushingTask
from energy_margin.world.scene import Geom, Joint, Link, RigidObject, Scene
from energy_margin.world.state import FrameState

G = 9.81


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z), written out by hand."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _axis_angle_quat(axis: list[float], angle: float) -> np.ndarray:
    axis_array = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis_array])


def _pushing_frame(n_objects: int = 3, seed: int = 1) -> tuple[MujocoSimulator, FrameState, np.ndarray]:
    task = PushingTask()
    trajectory = task.sample_trajectory(np.random.default_rng(seed), n_objects)
    simulator = MujocoSimulator(task.build_scene(n_objects, trajectory.friction))
    return simulator, trajectory.initial, trajectory.drive


def _snapshot(simulator: MujocoSimulator) -> list[np.ndarray]:
    return [
        simulator.get_state(),
        simulator.object_positions().copy(),
        simulator.object_quaternions().copy(),
        simulator.object_velocities(),
        simulator.robot_positions(),
        simulator.robot_velocities(),
    ]


# ---------------------------------------------------------------- model construction


def test_build_model_bodies_and_joints(make_block_scene: Callable[..., Scene]) -> None:
    free = build_model(make_block_scene(3, motion="free"))
    assert free.nbody == 1 + 3  # world + objects
    assert free.njnt == 3
    assert free.nq == 3 * 7
    assert free.nv == 3 * 6
    upright = build_model(make_block_scene(2, motion="upright"))
    assert upright.nbody == 1 + 2
    assert upright.nq == upright.nv == 2 * 4  # x, y, z, yaw
    assert upright.opt.timestep == pytest.approx(1 / 120)
    assert upright.geom_friction[0, 0] == pytest.approx(0.3)


def test_build_model_of_the_pushing_scene() -> None:
    scene = PushingTask().build_scene(4, 0.2)
    model = build_model(scene)
    assert model.nbody == 1 + 1 + 4  # world, pusher, objects
    assert model.nq == 4 + 4 * 4
    assert model.ngeom == 2 + 1 + 4  # ground and wall, pusher, objects
    names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(model.nbody)}
    assert {"pusher", "object0", "object3"} <= names
    np.testing.assert_allclose(model.body_mass[2:], 0.2)
    np.testing.assert_allclose(model.geom_friction[:, 0], 0.2)


def test_build_model_nested_robot_links() -> None:
    tip = Link("tip", (Geom("sphere", (0.01,)),), 0.05, pos=(0.1, 0, 0), joints=(Joint("t", "hinge", (0, 0, 1)),))
    arm = Link(
        "arm",
        (Geom("box", (0.05, 0.01, 0.01)),),
        0.5,
        pos=(0, 0, 0.5),
        joints=(Joint("a", "slide", (1, 0, 0), limits=(-1.0, 1.0), damping=0.1),),
        children=(tip,),
    )
    scene = Scene(objects=(RigidObject("box", Geom("box", (0.1, 0.1, 0.1)), 1.0),), robot=arm, statics=(), friction=0.5)
    model = build_model(scene)
    assert model.nbody == 4
    assert model.nq == 2 + 7
    joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "a")
    np.testing.assert_allclose(model.jnt_range[joint], [-1.0, 1.0])
    assert model.dof_damping[model.jnt_dofadr[joint]] == pytest.approx(0.1)


def test_build_model_rejects_offset_object_geoms() -> None:
    scene = Scene(
        objects=(RigidObject("o", Geom("sphere", (0.1,), pos=(0.1, 0.0, 0.0)), 1.0),),
        robot=None,
        statics=(),
        friction=0.5,
    )
    with pytest.raises(InvalidDataError, match="centred at the body origin"):
        build_model(scene)


def test_make_simulator(make_block_scene: Callable[..., Scene]) -> None:
    simulator = make_simulator(make_block_scene(1))
    assert isinstance(simulator, MujocoSimulator)
    assert isinstance(simulator, Simulator)
    assert simulator.timestep == pytest.approx(1 / 120)
    assert simulator.state_size == mujoco.mj_stateSize(simulator.model, mujoco.mjtState.mjSTATE_INTEGRATION)
    with pytest.raises(EnergyMarginError, match="unknown engine 'bullet'"):
        make_simulator(make_block_scene(1), "bullet")


# ---------------------------------------------------------------- states and replays


def test_restored_state_replays_bit_identically() -> None:
    simulator, frame, drive = _pushing_frame()
    simulator.reset(frame)
    simulator.set_robot_force(np.array([0.0, drive[1], 0.0, 0.0]))
    simulator.step(5)
    start = simulator.get_state()
    wrenches = np.random.default_rng(0).uniform(-0.4, 0.4, (3, 6))

    def replay() -> tuple[list[np.ndarray], float]:
        simulator.set_state(start)
        simulator.set_object_wrenches(wrenches)
        work = simulator.step(10, track_friction_work=True)
        return _snapshot(simulator), work

    first, first_work = replay()
    assert first_work < 0.0  # the objects slide on the ground
    # The wrenches matter: the same replay without them ends elsewhere.
    simulator.set_state(start)
    simulator.set_object_wrenches(np.zeros((3, 6)))
    simulator.step(10)
    assert not np.array_equal(simulator.object_positions(), first[1])
    # Unrelated dynamics in between: other wrenches, other robot force, many steps.
    simulator.set_object_wrenches(-3 * wrenches)
    simulator.set_robot_force(np.array([5.0, -20.0, 0.0, 0.1]))
    simulator.step(37)
    second, second_work = replay()
    for a, b in zip(first, second, strict=True):
        assert np.array_equal(a, b)
    assert first_work == second_work

    # A fresh simulator built from the same scene replays the same state identically.
    fresh = MujocoSimulator(simulator.scene)
    fresh.set_state(start)
    fresh.set_object_wrenches(wrenches)
    fresh_work = fresh.step(10, track_friction_work=True)
    for a, b in zip(first, _snapshot(fresh), strict=True):
        assert np.array_equal(a, b)
    assert fresh_work == first_work


def test_replays_without_friction_tracking_match_tracked_steps() -> None:
    simulator, frame, _ = _pushing_frame()
    simulator.reset(frame)
    start = simulator.get_state()
    simulator.step(12)
    bulk = simulator.get_state()
    simulator.set_state(start)
    assert simulator.step(12, track_friction_work=False) == 0.0
    assert np.array_equal(simulator.get_state(), bulk)


def test_state_restores_the_applied_wrenches(
    make_block_scene: Callable[..., Scene], make_resting_frame: Callable[..., FrameState]
) -> None:
    scene = make_block_scene(1, friction=0.0)
    simulator = MujocoSimulator(scene)
    simulator.reset(make_resting_frame(scene))
    simulator.set_object_wrenches(np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]]))
    pushed = simulator.get_state()
    simulator.set_object_wrenches(np.zeros((1, 6)))
    simulator.set_state(pushed)
    simulator.step(12)
    assert simulator.object_velocities()[0, 0] > 0.4  # the 1 N force came back with the state


def test_get_state_returns_a_copy(
    make_block_scene: Callable[..., Scene], make_resting_frame: Callable[..., FrameState]
) -> None:
    scene = make_block_scene(1)
    simulator = MujocoSimulator(scene)
    simulator.reset(make_resting_frame(scene))
    state = simulator.get_state()
    kept = state.copy()
    state[:] = 123.0
    assert np.array_equal(simulator.get_state(), kept)
    assert state.dtype == np.float64
    assert state.shape == (simulator.state_size,)


# ---------------------------------------------------------------- reset and read-back


def test_reset_round_trip_free_objects(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(3, shape="box", motion="free")
    simulator = MujocoSimulator(scene)
    rng = np.random.default_rng(5)
    quats = rng.standard_normal((3, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    frame = FrameState(
        object_pos=rng.uniform(-1, 1, (3, 3)) + np.array([0.0, 0.0, 2.0]),
        object_quat=quats,
        object_vel=rng.uniform(-2, 2, (3, 6)),
        robot_q=np.zeros(0),
        robot_v=np.zeros(0),
    )
    simulator.reset(frame)
    back = simulator.frame_state()
    np.testing.assert_array_equal(back.object_pos, frame.object_pos)
    np.testing.assert_allclose(back.object_quat, quats, atol=1e-15)
    # Angular velocity is given and read in the world frame, whatever the orientation.
    np.testing.assert_allclose(back.object_vel, frame.object_vel, atol=1e-12)
    # ... and stored in the body frame by MuJoCo's free joint.
    body_omega = simulator.data.qvel.reshape(3, 6)[:, 3:]
    for q, omega_world, omega_body in zip(quats, frame.object_vel[:, 3:], body_omega, strict=True):
        np.testing.assert_allclose(omega_body, _quat_matrix(q).T @ omega_world, atol=1e-12)


def test_reset_normalises_quaternions(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(1, motion="free")
    simulator = MujocoSimulator(scene)
    quat = np.array([[1.0, 0.0005, 0.0, 0.0]])  # passes validation (|q| - 1 < 1e-3)
    simulator.reset(FrameState(np.zeros((1, 3)), quat, np.zeros((1, 6)), np.zeros(0), np.zeros(0)))
    assert np.linalg.norm(simulator.object_quaternions()[0]) == pytest.approx(1.0, abs=1e-15)


def test_reset_round_trip_upright_objects_and_robot() -> None:
    task = PushingTask()
    simulator = MujocoSimulator(task.build_scene(2, 0.2))
    yaws = np.array([0.4, -2.5])
    quats = np.stack([_axis_angle_quat([0, 0, 1], y) for y in yaws])
    velocity = np.array([[0.1, -0.2, 0.0, 0.0, 0.0, 1.5], [0.0, 0.3, 0.01, 0.0, 0.0, -0.7]])
    frame = FrameState(
        object_pos=np.array([[1.0, 1.0, 0.0], [1.3, 0.9, 0.0]]),
        object_quat=quats,
        object_vel=velocity,
        robot_q=np.array([1.1, 0.6, 0.001, 0.05]),
        robot_v=np.array([0.05, 0.2, 0.0, -0.1]),
    )
    simulator.reset(frame)
    back = simulator.frame_state()
    np.testing.assert_array_equal(back.object_pos, frame.object_pos)
    np.testing.assert_allclose(back.object_quat, quats, atol=1e-15)
    np.testing.assert_allclose(back.object_vel, velocity, atol=1e-15)
    np.testing.assert_array_equal(back.robot_q, frame.robot_q)
    np.testing.assert_array_equal(back.robot_v, frame.robot_v)


def test_upright_objects_keep_only_yaw() -> None:
    task = PushingTask()
    simulator = MujocoSimulator(task.build_scene(1, 0.2))
    tilted = np.array([0.9, 0.1, 0.1, 0.4])
    tilted /= np.linalg.norm(tilted)
    frame = FrameState(
        object_pos=np.array([[1.0, 1.0, 0.0]]),
        object_quat=tilted[None],
        object_vel=np.array([[0.0, 0.0, 0.0, 0.3, -0.2, 0.5]]),
        robot_q=np.zeros(4),
        robot_v=np.zeros(4),
    )
    simulator.reset(frame)
    quat = simulator.object_quaternions()[0]
    yaw = math.atan2(2 * (tilted[0] * tilted[3] + tilted[1] * tilted[2]), 1 - 2 * (tilted[2] ** 2 + tilted[3] ** 2))
    np.testing.assert_allclose(quat, [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)], atol=1e-15)
    np.testing.assert_array_equal(simulator.object_velocities()[0, 3:], [0.0, 0.0, 0.5])


def test_reset_rejects_a_bad_frame(
    make_block_scene: Callable[..., Scene], make_resting_frame: Callable[..., FrameState]
) -> None:
    scene = make_block_scene(2)
    simulator = MujocoSimulator(scene)
    frame = make_resting_frame(scene)
    frame.object_pos[1, 0] = np.nan
    with pytest.raises(InvalidParameterError, match="object_pos contains NaN"):
        simulator.reset(frame)


def test_reset_clears_wrenches(
    make_block_scene: Callable[..., Scene], make_resting_frame: Callable[..., FrameState]
) -> None:
    scene = make_block_scene(1, friction=0.0)
    simulator = MujocoSimulator(scene)
    frame = make_resting_frame(scene)
    simulator.reset(frame)
    simulator.set_object_wrenches(np.array([[5.0, 0.0, 0.0, 0.0, 0.0, 0.0]]))
    simulator.step(5)
    assert simulator.object_positions()[0, 0] > 0.01
    simulator.reset(frame)
    simulator.step(12)
    assert abs(simulator.object_positions()[0, 0]) < 1e-9


# ---------------------------------------------------------------- wrenches and forces


@pytest.mark.parametrize("friction", [0.0, 0.2])
@pytest.mark.parametrize("motion", ["free", "upright"])
@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, -1.0), (0.6, 0.8)])
def test_wrench_moves_object_along_the_force(
    make_block_scene: Callable[..., Scene],
    make_resting_frame: Callable[..., FrameState],
    motion: str,
    direction: tuple[float, float],
    friction: float,
) -> None:
    if friction == 0.0 and not compat.mujoco_at_least(compat.FRICTIONLESS_SLIDING_SINCE):
        pytest.skip("frictionless contacts resist sliding in some poses in MuJoCo 3.3.0 to 3.3.5")
    scene = make_block_scene(2, motion=motion, friction=friction)
    simulator = MujocoSimulator(scene)
    simulator.reset(make_resting_frame(scene))
    start = simulator.object_positions().copy()
    force = 2.0 * np.array([*direction, 0.0])  # 2 N on 0.2 kg: well above friction (0.39 N)
    simulator.set_object_wrenches(np.array([[*force, 0.0, 0.0, 0.0], [0.0] * 6]))
    simulator.step(12)
    moved = simulator.object_positions() - start
    along = moved[0, :2] @ np.array(direction)
    across = moved[0, :2] @ np.array([-direction[1], direction[0]])
    assert along > 0.02
    if friction == 0.0:
        assert abs(across) < 1e-4 * along
    else:
        # MuJoCo's pyramidal friction cone is anisotropic: off the contact frame's axes the
        # object veers (measured 0.0055 m across for 0.046 m along on the diagonal).
        assert abs(across) < 0.15 * along
    assert np.abs(moved[1]).max() < 1e-4  # the other object is untouched


@pytest.mark.parametrize("motion", ["free", "upright"])
def test_torque_spins_object_about_z(
    make_block_scene: Callable[..., Scene], make_resting_frame: Callable[..., FrameState], motion: str
) -> None:
    scene = make_block_scene(1, shape="box", motion=motion, friction=0.2)
    simulator = MujocoSimulator(scene)
    simulator.reset(make_resting_frame(scene))
    simulator.set_object_wrenches(np.array([[0.0, 0.0, 0.0, 0.0, 0.0, -0.05]]))
    simulator.step(12)
    omega = simulator.object_velocities()[0, 3:]
    assert omega[2] < -1.0
    assert np.abs(omega[:2]).max() < 1e-6
    assert np.abs(simulator.object_velocities()[0, :2]).max() < 1e-6


def test_robot_force_drives_the_pusher() -> None:
    simulator, frame, _ = _pushing_frame(n_objects=1)
    frame = FrameState(
        frame.object_pos + np.array([0.0, 0.5, 0.0]),
        frame.object_quat,
        frame.object_vel * 0,
        frame.robot_q,
        frame.robot_v * 0,
    )
    simulator.reset(frame)
    simulator.set_robot_force(np.array([0.0, 40.0, 0.0, 0.0]))  # 10 m/s^2 on 4 kg, above friction
    simulator.step(12)
    assert simulator.robot_velocities()[1] > 0.3
    assert simulator.robot_positions()[1] > frame.robot_q[1] + 0.01


# ---------------------------------------------------------------- energy


def test_mechanical_energy_of_a_hand_set_free_state(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(2, shape="box", motion="free", mass=0.7)
    simulator = MujocoSimulator(scene)
    quats = np.stack([_axis_angle_quat([1, 0, 0], math.pi / 2), _axis_angle_quat([0.3, -1.0, 2.0], 1.3)])
    velocity = np.array([[1.0, 2.0, 0.5, 0.0, 0.0, 1.0], [-0.4, 0.1, 0.0, 0.3, -0.2, 0.5]])
    pos = np.array([[0.0, 0.0, 0.3], [2.0, 0.0, 1.2]])
    simulator.reset(FrameState(pos, quats, velocity, np.zeros(0), np.zeros(0)))
    inertia = np.array(scene.objects[0].inertia)
    expected = 0.0
    for q, v, p in zip(quats, velocity, pos, strict=True):
        omega_body = _quat_matrix(q).T @ v[3:]
        expected += 0.5 * 0.7 * v[:3] @ v[:3] + 0.5 * omega_body @ (inertia * omega_body) + 0.7 * G * p[2]
    assert simulator.mechanical_energy() == pytest.approx(expected, rel=1e-12)
    # The first box spins about world z, which is its body y axis: I_yy, not I_zz.
    first = 0.5 * 0.7 * 5.25 + 0.5 * inertia[1] + 0.7 * G * 0.3
    assert inertia[1] != pytest.approx(inertia[2])
    single = MujocoSimulator(make_block_scene(1, shape="box", motion="free", mass=0.7))
    single.reset(FrameState(pos[:1], quats[:1], velocity[:1], np.zeros(0), np.zeros(0)))
    assert single.mechanical_energy() == pytest.approx(first, rel=1e-12)


def test_mechanical_energy_of_a_hand_set_upright_state(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(1, motion="upright", mass=0.2)
    simulator = MujocoSimulator(scene)
    velocity = np.array([[0.3, -0.4, 0.1, 0.0, 0.0, 2.0]])
    simulator.reset(
        FrameState(np.array([[0.5, 0.5, 0.25]]), np.array([[1.0, 0, 0, 0]]), velocity, np.zeros(0), np.zeros(0))
    )
    izz = 0.5 * 0.2 * 0.05**2
    expected = 0.5 * 0.2 * 0.26 + 0.5 * izz * 4.0 + 0.2 * G * 0.25
    assert simulator.mechanical_energy() == pytest.approx(expected, rel=1e-12)


# ---------------------------------------------------------------- friction work of a sliding object


@pytest.mark.parametrize("timestep", [1 / 120, 1 / 240], ids=["120Hz", "240Hz"])
@pytest.mark.parametrize("motion", ["free", "upright"])
@pytest.mark.parametrize("shape", ["box", "cylinder"])
def test_sliding_object_friction_work_and_distance(
    make_block_scene: Callable[..., Scene], shape: str, motion: str, timestep: float
) -> None:
    # A block launched at v0 on the ground slides to rest: friction removes all the kinetic energy
    # (W = -1/2 m v0^2) over the distance d = v0^2 / (2 mu g).
    mass, mu, v0 = 0.5, 0.3, 1.0
    scene = make_block_scene(1, shape=shape, motion=motion, friction=mu, timestep=timestep, mass=mass)
    simulator = MujocoSimulator(scene)
    half_height = scene.objects[0].geom.size[-1]
    velocity = np.array([[v0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    simulator.reset(
        FrameState(np.array([[0.0, 0.0, half_height]]), np.array([[1.0, 0, 0, 0]]), velocity, np.zeros(0), np.zeros(0))
    )
    energy_before = simulator.mechanical_energy()
    work = simulator.step(round(0.6 / timestep), track_friction_work=True)  # stops after ~0.34 s
    assert np.abs(simulator.object_velocities()[0]).max() < 1e-3
    # Measured: |W + 0.25| <= 6.1e-4 J (0.25 %) for every variant; tolerance 2 %.
    assert work == pytest.approx(-0.5 * mass * v0**2, rel=0.02)
    # Measured distances 0.1658-0.1680 m against 0.1699 m (1-2.5 % short); tolerance 5 %.
    distance = simulator.object_positions()[0, 0]
    assert distance == pytest.approx(v0**2 / (2 * mu * G), rel=0.05)
    # Friction removed what the object lost (the rest is the contact settling by ~1e-5 m).
    assert simulator.mechanical_energy() - energy_before == pytest.approx(work, rel=0.02)


def test_friction_work_is_never_positive(
    make_block_scene: Callable[..., Scene], make_resting_frame: Callable[..., FrameState]
) -> None:
    scene = make_block_scene(2, friction=0.3)
    simulator = MujocoSimulator(scene)
    simulator.reset(make_resting_frame(scene))
    rng = np.random.default_rng(2)
    for _ in range(20):
        simulator.set_object_wrenches(rng.uniform(-1.5, 1.5, (2, 6)) * [1, 1, 0, 0, 0, 0.01])
        assert simulator.step(3, track_friction_work=True) <= 1e-12


def test_no_contact_means_no_friction_work(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(1, friction=0.5)
    simulator = MujocoSimulator(scene)
    velocity = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    # High above the ground: a free fall with horizontal velocity.
    simulator.reset(
        FrameState(np.array([[0.0, 0.0, 3.0]]), np.array([[1.0, 0, 0, 0]]), velocity, np.zeros(0), np.zeros(0))
    )
    energy = simulator.mechanical_energy()
    n, dt = 20, scene.timestep
    assert simulator.step(n, track_friction_work=True) == 0.0
    assert simulator.object_velocities()[0, 0] == pytest.approx(1.0)
    # Free flight: semi-implicit Euler loses exactly 1/2 m g^2 dt^2 n of energy in n steps.
    drift = 0.5 * 0.2 * G**2 * dt**2 * n
    assert simulator.mechanical_energy() == pytest.approx(energy - drift, rel=1e-12)


def test_roll_commands_matches_stepping_the_simulator() -> None:
    """A batch of command sequences through mujoco.rollout lands where stepping one by one does."""
    from energy_margin.tasks import get_task

    task = get_task("pushing")
    trajectory = task.sample_trajectory(np.random.default_rng(0), 3)
    simulator = task.make_simulator(3, trajectory.friction, trajectory.drive, "mujoco")
    simulator.reset(trajectory.initial)
    propagator = simulator.rollout_propagator(1)
    start = propagator.current_state()
    forces = np.zeros((2, 30, 4))
    forces[0, :, 1] = 20.0
    forces[1, :, 0] = -5.0
    states, final = propagator.roll_commands(start, forces)
    assert states.shape == (2, 30, propagator.state_size)
    np.testing.assert_array_equal(final, states[:, -1])
    pos, quat, vel, robot_q, robot_v = propagator.object_states(final)
    assert robot_v.shape == (2, 4)
    assert pos.shape == (2, 3, 3) and quat.shape == (2, 3, 4) and vel.shape == (2, 3, 6)
    for sample in range(2):
        simulator.reset(trajectory.initial)
        for step in range(30):
            simulator.set_robot_force(forces[sample, step])
            simulator.step(1)
        # The one-at-a-time path warm-starts its solver, the batch starts cold: equal to ~1e-6 m.
        np.testing.assert_allclose(robot_q[sample], simulator.robot_positions(), atol=1e-5)
        np.testing.assert_allclose(pos[sample], simulator.object_positions(), atol=1e-5)
    # The first sequence pushed forward, the second sideways.
    assert robot_q[0, 1] > start[1 + simulator.index.robot_qpos[1]] + 0.01
    assert robot_q[1, 0] < robot_q[0, 0]
