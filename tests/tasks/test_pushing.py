from __future__ import annotations

import math

import numpy as np
import pytest

from energy_margin.errors import InvalidDataError
from energy_margin.tasks import RobotState, all_inside
from energy_margin.tasks.base import sample_separated as _sample_separated
from energy_margin.tasks.pushing import PushingConfig, PushingTask, SweptRegion, WallBand
from energy_margin.world.state import FrameState

CONFIG = PushingConfig()


def _points(*xy: tuple[float, float]) -> np.ndarray:
    """Positions (n, 3) at the objects' resting height."""
    return np.array([[x, y, 0.0] for x, y in xy])


def _polar(centre: tuple[float, float], radius: float, angle: float) -> tuple[float, float]:
    return centre[0] + radius * math.cos(angle), centre[1] + radius * math.sin(angle)


# ---------------------------------------------------------------- capture region: disc


def test_low_speed_region_is_a_disc_of_radius_0_6() -> None:
    pusher = (1.0, 0.8)
    region = SweptRegion(CONFIG, np.array(pusher), np.array([0.1, 0.2, 0.5]))  # speed 0.22 < 0.3
    assert region.is_disc
    inside = [_polar(pusher, 0.59, a) for a in np.linspace(0, 2 * math.pi, 12, endpoint=False)]
    outside = [_polar(pusher, 0.61, a) for a in np.linspace(0, 2 * math.pi, 12, endpoint=False)]
    assert region.contains(_points(*inside, pusher)).all()
    assert not region.contains(_points(*outside)).any()


def test_speed_threshold_switches_from_disc_to_band() -> None:
    assert SweptRegion(CONFIG, np.zeros(2), np.array([0.0, 0.2999, 0.0])).is_disc
    assert not SweptRegion(CONFIG, np.zeros(2), np.array([0.0, 0.3, 0.0])).is_disc
    # Yaw rate alone does not make the pusher fast.
    assert SweptRegion(CONFIG, np.zeros(2), np.array([0.0, 0.0, 5.0])).is_disc


def test_disc_region_also_requires_the_workspace() -> None:
    # Pusher at the workspace corner, slow: a point 0.3 m away lies in the disc but outside
    # the workspace [-0.1, 2.1]^2.
    region = SweptRegion(CONFIG, np.array([0.0, 0.0]), np.array([0.0, 0.1, 0.0]))
    assert region.is_disc
    assert not region.contains(_points((-0.3, 0.0)))[0]


# ---------------------------------------------------------------- capture region: straight band


@pytest.mark.parametrize("heading", [math.pi / 2, 0.0, 2.4, -1.0])
def test_straight_motion_gives_a_band_ahead_of_the_pusher(heading: float) -> None:
    pusher = np.array([1.0, 1.0])
    speed = 0.5
    forward = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-forward[1], forward[0]])
    region = SweptRegion(CONFIG, pusher, np.array([*(speed * forward), 0.0]))
    assert not region.is_disc

    def at(ahead: float, lateral: float) -> tuple[float, float]:
        x, y = pusher + ahead * forward + lateral * left
        return float(x), float(y)

    # Reach ahead: speed * 1 s = 0.5 m; behind: 0.06 m; half width 0.4 m.
    inside = [at(0.0, 0.0), at(0.49, 0.0), at(-0.05, 0.0), at(0.25, 0.39), at(0.25, -0.39), at(0.45, 0.35)]
    outside = [at(0.51, 0.0), at(-0.07, 0.0), at(0.25, 0.41), at(0.25, -0.41), at(-0.5, 0.0), at(1.0, 0.0)]
    assert region.contains(_points(*inside)).all(), region.contains(_points(*inside))
    assert not region.contains(_points(*outside)).any(), region.contains(_points(*outside))


def test_straight_band_length_scales_with_speed() -> None:
    pusher = np.array([1.0, 0.5])
    fast = SweptRegion(CONFIG, pusher, np.array([0.0, 0.9, 0.0]))
    slow = SweptRegion(CONFIG, pusher, np.array([0.0, 0.4, 0.0]))
    probe = _points((1.0, 0.5 + 0.6), (1.0, 0.5 + 0.85), (1.0, 0.5 + 0.95))
    np.testing.assert_array_equal(fast.contains(probe), [True, True, False])
    np.testing.assert_array_equal(slow.contains(probe), [False, False, False])


def test_straight_band_is_clipped_to_the_workspace() -> None:
    # Moving along +x at y = 2.05: the band reaches y = 2.45, but the workspace ends at 2.1.
    region = SweptRegion(CONFIG, np.array([1.0, 2.05]), np.array([0.5, 0.0, 0.0]))
    np.testing.assert_array_equal(region.contains(_points((1.2, 2.09), (1.2, 2.11))), [True, False])


# ---------------------------------------------------------------- capture region: turning


@pytest.mark.parametrize("yaw_rate", [1.0, -1.0])
def test_turning_motion_gives_an_annular_sector(yaw_rate: float) -> None:
    # Pusher at (1, 1) moving along +y at 0.6 m/s with |omega| = 1 rad/s: radius R = 0.6 m. The
    # centre is to the left of the velocity (-x) for omega > 0, to the right for omega < 0.
    pusher = (1.0, 1.0)
    region = SweptRegion(CONFIG, np.array(pusher), np.array([0.0, 0.6, yaw_rate]))
    turn = 1.0 if yaw_rate > 0 else -1.0
    centre = (1.0 - turn * 0.6, 1.0)
    np.testing.assert_allclose(region.centre, centre)
    assert region.radius == pytest.approx(0.6)
    start = 0.0 if yaw_rate > 0 else math.pi  # angle of the pusher seen from the centre

    def at(radius: float, swept: float) -> tuple[float, float]:
        # ``swept`` is the angle travelled along the motion (CCW for omega > 0, CW for omega < 0).
        return _polar(centre, radius, start + turn * swept)

    # Sweep in 1 s: omega * 1 s = 1 rad; behind: 0.06 m / 0.6 m = 0.1 rad; radial band 0.6 +- 0.4.
    inside = [pusher, at(0.6, 0.5), at(0.6, 0.95), at(0.6, -0.09), at(0.21, 0.5), at(0.99, 0.5), at(0.9, 0.2)]
    outside = [at(0.6, 1.05), at(0.6, -0.11), at(0.19, 0.5), at(1.01, 0.5), at(0.6, math.pi)]
    assert region.contains(_points(*inside)).all(), region.contains(_points(*inside))
    assert not region.contains(_points(*outside)).any(), region.contains(_points(*outside))
    # A point on the inner side of the turn is inside; its mirror image across the line of motion
    # is 1.04 m from the centre (beyond R + 0.4): outside. Only the correct side passes both.
    inner = at(0.3, 0.9)
    mirrored = (2 * pusher[0] - inner[0], inner[1])
    np.testing.assert_array_equal(region.contains(_points(inner, mirrored)), [True, False])


def test_turn_radius_is_capped_for_slow_turns() -> None:
    region = SweptRegion(CONFIG, np.array([1.0, 1.0]), np.array([0.5, 0.0, 1e-6]))
    assert region.radius == CONFIG.max_turn_radius
    np.testing.assert_allclose(region.centre, [1.0, 1.0 + CONFIG.max_turn_radius])


def test_long_sweep_is_capped_at_a_full_circle() -> None:
    # omega = 10 rad/s covers more than 2 pi in 1 s: the whole annulus is inside.
    region = SweptRegion(CONFIG, np.array([1.0, 1.0]), np.array([0.0, 3.0, 10.0]))
    centre = region.centre
    ring = [_polar(tuple(centre), 0.3, a) for a in np.linspace(0, 2 * math.pi, 16, endpoint=False)]
    assert region.contains(_points(*ring)).all()


def test_capture_region_contains_accepts_any_leading_shape() -> None:
    region = SweptRegion(CONFIG, np.array([1.0, 1.0]), np.array([0.0, 0.5, 0.0]))
    positions = np.zeros((2, 4, 3))
    positions[..., 0] = 1.0
    positions[..., 1] = 1.0 + np.array([0.1, 0.3, 0.7, 0.45])
    result = region.contains(positions)
    assert result.shape == (2, 4)
    np.testing.assert_array_equal(result, [[True, True, False, True]] * 2)


# ---------------------------------------------------------------- success region


def test_wall_band_bounds() -> None:
    band = WallBand(CONFIG)
    assert band.low == pytest.approx(1.6 - 0.05 - 0.1)
    assert band.high == pytest.approx(1.6 - 0.05 + 0.1)
    ys = [1.45 - 1e-6, 1.45 + 1e-6, 1.55, 1.65 - 1e-6, 1.65 + 1e-6, 1.0, 1.7]
    np.testing.assert_array_equal(
        band.contains(_points(*[(1.0, y) for y in ys])), [False, True, True, True, False, False, False]
    )


def test_wall_band_requires_the_workspace() -> None:
    band = WallBand(CONFIG)
    xs = [-0.2, -0.09, 1.0, 2.09, 2.2]
    np.testing.assert_array_equal(band.contains(_points(*[(x, 1.55) for x in xs])), [False, True, True, True, False])


def test_wall_band_follows_the_configuration() -> None:
    band = WallBand(PushingConfig(wall_y=2.0, object_radius=0.1, success_half_width=0.05))
    np.testing.assert_array_equal(band.contains(_points((1.0, 1.86), (1.0, 1.96), (1.0, 1.55))), [True, False, False])


def test_all_inside_reduces_over_objects() -> None:
    band = WallBand(CONFIG)
    good, bad = (1.0, 1.55), (1.0, 1.0)
    positions = np.stack([_points(good, good), _points(good, bad), _points(bad, bad)])  # (3, n=2, 3)
    np.testing.assert_array_equal(all_inside(band, positions), [True, False, False])
    nested = positions.reshape(3, 1, 2, 3).repeat(2, axis=1)  # (3, 2, n=2, 3)
    assert all_inside(band, nested).shape == (3, 2)
    np.testing.assert_array_equal(all_inside(band, nested)[:, 1], [True, False, False])
    assert all_inside(band, _points(good)).shape == ()


# ---------------------------------------------------------------- the task


def _frame(object_xy: list[tuple[float, float]], pusher_q: list[float], pusher_v: list[float]) -> FrameState:
    n = len(object_xy)
    return FrameState(
        object_pos=_points(*object_xy),
        object_quat=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        object_vel=np.zeros((n, 6)),
        robot_q=np.array(pusher_q),
        robot_v=np.array(pusher_v),
    )


def test_is_captured_and_is_successful_use_every_object() -> None:
    task = PushingTask()
    # Pusher slow at (1, 1.3): disc of 0.6 m.
    frame = _frame([(1.0, 1.5), (1.2, 1.55)], [1.0, 1.3, 0.0, 0.0], [0.0, 0.1, 0.0, 0.0])
    assert task.is_captured(frame)
    assert task.is_successful(frame)
    far = _frame([(1.0, 1.5), (2.0, 1.0)], [1.0, 1.3, 0.0, 0.0], [0.0, 0.1, 0.0, 0.0])
    assert not task.is_captured(far)
    assert not task.is_successful(far)
    # The capture region uses (vx, vy, yaw rate) = robot_v[[0, 1, 3]], not the z velocity.
    moving = _frame([(1.0, 1.5)], [1.0, 1.0, 0.0, 0.0], [0.0, 0.8, 5.0, 0.0])
    region = task.capture_region(moving)
    assert not region.is_disc
    assert region.radius == CONFIG.max_turn_radius


def test_build_scene() -> None:
    task = PushingTask()
    scene = task.build_scene(3, 0.25)
    assert scene.n_objects == 3
    assert scene.friction == 0.25
    assert scene.timestep == pytest.approx(1 / 120)
    assert scene.object_motion == "upright"
    assert scene.robot_joint_names == ("pusher_x", "pusher_y", "pusher_z", "pusher_yaw")
    assert {g.name for g in scene.statics} == {"ground", "wall"}
    np.testing.assert_allclose(scene.object_masses, 0.2)
    wall = next(g for g in scene.statics if g.name == "wall")
    assert wall.pos[1] - wall.size[1] == pytest.approx(1.6)  # the wall's face


def test_sample_trajectory_is_valid_and_seeded() -> None:
    task = PushingTask()
    n = 6
    first = task.sample_trajectory(np.random.default_rng(3), n)
    again = task.sample_trajectory(np.random.default_rng(3), n)
    other = task.sample_trajectory(np.random.default_rng(4), n)
    np.testing.assert_array_equal(first.initial.object_pos, again.initial.object_pos)
    np.testing.assert_array_equal(first.drive, again.drive)
    assert not np.array_equal(first.initial.object_pos, other.initial.object_pos)

    first.initial.validate(n_objects=n, n_robot_dofs=4)
    xy = first.initial.object_pos[:, :2]
    distances = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(n)
    assert distances.min() > CONFIG.min_separation
    assert np.all((xy[:, 0] >= 0.7) & (xy[:, 0] <= 1.3))
    assert np.all((xy[:, 1] <= 1.0) & (xy[:, 1] >= 1.0 - 0.04 * 10))
    np.testing.assert_allclose(first.initial.object_pos[:, 2], CONFIG.ground_z + CONFIG.object_half_height)
    assert np.all(np.abs(first.initial.object_vel[:, :2]) <= 0.05)
    np.testing.assert_array_equal(first.initial.object_vel[:, 2:], 0.0)
    pusher_gap = xy[:, 1].min() - first.initial.robot_q[1]
    assert 0.2 <= pusher_gap <= 0.3
    assert first.initial.robot_q[0] == pytest.approx(xy[:, 0].mean())
    assert 0.1 <= first.friction <= 0.3
    forward = first.drive[1]
    friction_load = first.friction * 9.81 * (4.0 + n * 0.2)
    assert first.drive[0] == 0.0
    assert 1.1 * friction_load <= forward <= 1.6 * friction_load


def test_robot_force_nominal_and_jittered() -> None:
    task = PushingTask()
    drive = np.array([0.0, 10.0])
    nominal = task.robot_force(RobotState(drive, 0.5, np.zeros(4), np.zeros(4)), None)
    np.testing.assert_array_equal(nominal, [0.0, 10.0, 0.0, 0.0])
    rng = np.random.default_rng(0)
    forces = np.array([task.robot_force(RobotState(drive, 0.0, np.zeros(4), np.zeros(4)), rng) for _ in range(200)])
    assert np.all(np.abs(forces[:, 0]) <= 0.4)
    assert np.all((forces[:, 1] >= 8.0) & (forces[:, 1] <= 12.0))
    assert forces[:, 1].std() > 0.5  # actually random
    np.testing.assert_array_equal(forces[:, 2:], 0.0)


def test_wrench_limits_scale_with_mass_and_inertia() -> None:
    task = PushingTask()
    scene = task.build_scene(2, 0.2)
    limits = task.wrench_limits(scene)
    izz = 0.5 * 0.2 * 0.05**2
    np.testing.assert_allclose(limits.max_wrench, [[0.4, 0.4, 0.0, 0.0, 0.0, izz * 0.667]] * 2)
    assert limits.max_duration == 0.1
    assert limits.control_dimension == 6


def test_within_bounds() -> None:
    task = PushingTask()
    pos = _points((1.0, 1.0), (2.0, -0.05))
    vel = np.zeros((2, 6))
    assert task.within_bounds(pos, vel)
    assert not task.within_bounds(_points((1.0, 1.0), (2.2, 1.0)), vel)
    assert not task.within_bounds(_points((1.0, -0.2)), vel[:1])
    fast = vel.copy()
    fast[1, 2] = -101.0
    assert not task.within_bounds(pos, fast)


def test_frame_steps() -> None:
    task = PushingTask()
    assert task.n_steps == 240
    np.testing.assert_array_equal(task.frame_steps(3), [0, 120, 240])
    np.testing.assert_array_equal(task.frame_steps(1), [240])
    steps = task.frame_steps(7)
    assert steps[0] == 0
    assert steps[-1] == 240
    assert np.all(np.diff(steps) > 0)


def test_separated_sampling_gives_up_when_impossible() -> None:
    with pytest.raises(InvalidDataError, match="cannot place 5 objects"):
        _sample_separated(np.random.default_rng(0), 5, np.zeros(2), np.full(2, 0.1), 0.2)


def test_batched_capture_regions_equal_one_region_per_frame() -> None:
    from energy_margin.tasks.base import FrameRegions
    from energy_margin.world.state import FrameState

    task = PushingTask()
    rng = np.random.default_rng(4)
    dofs = task.robot_dofs()
    frames = []
    # Slow (disc), straight, turning left and right, and a yaw rate of exactly zero.
    for velocity in ([0.05, 0.1, 0.0], [0.0, 0.6, 0.0], [0.2, 0.5, 0.8], [-0.3, 0.4, -1.5], [0.5, 0.5, 3.0]):
        robot_q, robot_v = np.zeros(dofs), np.zeros(dofs)
        robot_q[:2] = rng.uniform(-0.5, 0.5, 2)
        robot_v[[0, 1, 3]] = velocity
        pos = np.column_stack([robot_q[:2] + rng.uniform(-0.8, 0.8, (6, 2)), np.full(6, 0.05)])
        frames.append(FrameState(pos, np.tile([1.0, 0, 0, 0], (6, 1)), np.zeros((6, 6)), robot_q, robot_v))
    positions = np.stack([frame.object_pos for frame in frames])  # (F, 6, 3)
    batched = task.capture_regions(frames)
    assert isinstance(batched, SweptRegion) and batched.is_disc.tolist() == [True, False, False, False, False]
    one_by_one = FrameRegions([task.capture_region(frame) for frame in frames])
    np.testing.assert_array_equal(batched.contains(positions), one_by_one.contains(positions))
    np.testing.assert_array_equal(batched.signed_distance(positions), one_by_one.signed_distance(positions))
    inside = batched.contains(positions)
    assert inside.any() and not inside.all()
    with pytest.raises(NotImplementedError, match="one frame"):
        batched.shapes()
