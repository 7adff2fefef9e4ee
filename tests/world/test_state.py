from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from energy_margin.errors import InvalidParameterError
from energy_margin.world.state import FrameState, relative_rotation_vector, yaw_from_quat


def _axis_angle_quat(axis: list[float], angle: float) -> np.ndarray:
    axis_array = np.asarray(axis, dtype=float)
    axis_array = axis_array / np.linalg.norm(axis_array)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis_array])


def _hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternion product written out by hand (w, x, y, z)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def _frame(n: int = 2, r: int = 1) -> FrameState:
    return FrameState(
        object_pos=np.zeros((n, 3)),
        object_quat=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        object_vel=np.zeros((n, 6)),
        robot_q=np.zeros(r),
        robot_v=np.zeros(r),
    )


def test_rotation_about_z_gives_z_rotation_vector() -> None:
    identity = np.array([[1.0, 0.0, 0.0, 0.0]])
    rotated = _axis_angle_quat([0, 0, 1], 0.3)[None]
    np.testing.assert_allclose(relative_rotation_vector(identity, rotated), [[0.0, 0.0, 0.3]], atol=1e-15)
    np.testing.assert_allclose(relative_rotation_vector(rotated, identity), [[0.0, 0.0, -0.3]], atol=1e-15)


def test_identity_rotation_is_exactly_zero() -> None:
    quat = _axis_angle_quat([1, 2, 3], 1.1)[None]
    assert np.array_equal(relative_rotation_vector(quat, quat), np.zeros((1, 3)))
    identity = np.array([[1.0, 0.0, 0.0, 0.0]])
    assert np.array_equal(relative_rotation_vector(identity, identity), np.zeros((1, 3)))


def test_sign_of_quaternions_does_not_matter() -> None:
    start = _axis_angle_quat([0.2, -1.0, 0.4], 0.7)
    end = _hamilton(_axis_angle_quat([0, 0, 1], 0.3), start)
    expected = np.array([[0.0, 0.0, 0.3]])
    for q_from, q_to in ((start, end), (-start, end), (start, -end), (-start, -end)):
        np.testing.assert_allclose(relative_rotation_vector(q_from[None], q_to[None]), expected, atol=1e-12)
    # q and -q are the same orientation: zero rotation.
    np.testing.assert_allclose(relative_rotation_vector(start[None], -start[None]), np.zeros((1, 3)), atol=1e-15)


def test_world_frame_rotation_vector_for_arbitrary_start() -> None:
    # R_to = R(axis, angle) R_from: the rotation vector is axis * angle in the world frame.
    start = _axis_angle_quat([1.0, 1.0, 0.0], 2.0)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    end = _hamilton(_axis_angle_quat(list(axis), 1.2), start)
    np.testing.assert_allclose(relative_rotation_vector(start[None], end[None]), [axis * 1.2], atol=1e-12)


def test_rotation_beyond_pi_wraps_to_shortest() -> None:
    identity = np.array([[1.0, 0.0, 0.0, 0.0]])
    rotated = _axis_angle_quat([0, 0, 1], 3.5)[None]
    np.testing.assert_allclose(relative_rotation_vector(identity, rotated), [[0.0, 0.0, 3.5 - 2 * math.pi]], atol=1e-12)


def test_rotation_vector_is_batched_and_accurate_for_tiny_angles() -> None:
    angles = np.array([1e-9, 0.1, -0.4, 1.5])
    q_from = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1))
    q_to = np.stack([_axis_angle_quat([1, 0, 0], a) for a in angles])
    result = relative_rotation_vector(q_from, q_to)
    assert result.shape == (4, 3)
    np.testing.assert_allclose(result[:, 0], angles, rtol=1e-12, atol=1e-20)
    np.testing.assert_array_equal(result[:, 1:], 0.0)


def test_yaw_from_quat() -> None:
    quats = np.stack([_axis_angle_quat([0, 0, 1], a) for a in (0.0, 0.7, -2.0, 3.0)])
    np.testing.assert_allclose(yaw_from_quat(quats), [0.0, 0.7, -2.0, 3.0], atol=1e-12)
    # A roll about x does not change the yaw.
    tilted = _hamilton(_axis_angle_quat([0, 0, 1], 0.5), _axis_angle_quat([1, 0, 0], 0.1))
    assert yaw_from_quat(tilted) == pytest.approx(0.5)
    assert yaw_from_quat(quats.reshape(2, 2, 4)).shape == (2, 2)


def test_validate_accepts_a_good_frame() -> None:
    frame = _frame(2, 1)
    frame.validate(n_objects=2, n_robot_dofs=1)
    assert frame.n_objects == 2


@pytest.mark.parametrize("name", ["object_pos", "object_quat", "object_vel", "robot_q", "robot_v"])
def test_validate_names_the_array_with_a_wrong_shape(name: str) -> None:
    good = _frame(2, 1)
    wrong = np.zeros((3, *getattr(good, name).shape[1:]))
    frame = dataclasses.replace(good, **{name: wrong})
    with pytest.raises(InvalidParameterError, match=f"^{name} must have shape"):
        frame.validate(n_objects=2, n_robot_dofs=1)


@pytest.mark.parametrize("name", ["object_pos", "object_vel", "robot_q", "robot_v"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_validate_names_the_array_with_a_non_finite_value(name: str, bad: float) -> None:
    frame = _frame(2, 1)
    getattr(frame, name).flat[0] = bad
    with pytest.raises(InvalidParameterError, match=f"^{name} contains NaN"):
        frame.validate(n_objects=2, n_robot_dofs=1)


def test_validate_rejects_non_unit_quaternions() -> None:
    frame = _frame(2, 0)
    frame.object_quat[1] = [1.0, 0.1, 0.0, 0.0]
    with pytest.raises(InvalidParameterError, match="unit quaternions"):
        frame.validate(n_objects=2, n_robot_dofs=0)
