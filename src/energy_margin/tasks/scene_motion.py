"""The robot's motion of a scene as arrays: controls and mocap poses over time, interpolated.

:func:`_motion` turns the scene file's keyframes or ``motion.ctrl_file`` into a :class:`Motion`
for the compiled model, checking actuator and mocap body names against it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.runs.npz import NpzError, read_npz
from energy_margin.tasks.scene_spec import SceneSpec

__all__ = ["Motion"]


@dataclass(frozen=True)
class Motion:
    """The robot's motion as arrays (the model's actuators and mocap bodies).

    Attributes:
        ctrl_times: times of the control rows, shape (n_ctrl,), s (empty: no controls).
        ctrl: control rows for every actuator of the model, shape (n_ctrl, nu).
        mocap_times: times of the mocap rows, shape (n_mocap_rows,), s.
        mocap_pos: mocap positions, shape (n_mocap_rows, nmocap, 3), m (the model's own pose for a
            mocap body the file does not move).
        mocap_quat: mocap quaternions, shape (n_mocap_rows, nmocap, 4), (w, x, y, z).
        hold: zero-order hold instead of linear interpolation.

    """

    ctrl_times: np.ndarray
    ctrl: np.ndarray
    mocap_times: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    hold: bool

    def ctrl_at(self, time: float) -> np.ndarray | None:
        """Controls (nu,) at ``time`` (s), held at the ends; ``None`` without controls."""
        if self.ctrl_times.size == 0:
            return None
        return _interpolate(self.ctrl_times, self.ctrl, time, hold=self.hold)

    def mocap_at(self, time: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Mocap positions (nmocap, 3) and unit quaternions (nmocap, 4) at ``time``; ``None`` without mocap."""
        if self.mocap_times.size == 0:
            return None
        pos = _interpolate(self.mocap_times, self.mocap_pos, time, hold=self.hold)
        quat = _interpolate_quat(self.mocap_times, self.mocap_quat, time, hold=self.hold)
        return pos, quat / np.linalg.norm(quat, axis=-1, keepdims=True)

    def ctrl_at_times(self, times: np.ndarray) -> np.ndarray | None:
        """:meth:`ctrl_at` of every time of ``times`` (k,), s: shape (k, nu), the same numbers to the last bit."""
        if self.ctrl_times.size == 0:
            return None
        return _interpolate_rows(self.ctrl_times, self.ctrl, np.asarray(times, dtype=float), hold=self.hold)

    def mocap_at_times(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`mocap_at` of every time of ``times`` (k,), s: (k, nmocap, 3) and (k, nmocap, 4), bit for bit."""
        if self.mocap_times.size == 0:
            return None
        times = np.asarray(times, dtype=float)
        pos = _interpolate_rows(self.mocap_times, self.mocap_pos, times, hold=self.hold)
        quat = _interpolate_quat_rows(self.mocap_times, self.mocap_quat, times, hold=self.hold)
        return pos, quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def _interpolate(times: np.ndarray, values: np.ndarray, time: float, *, hold: bool) -> np.ndarray:
    """Values (n, ...) at ``time`` between rows at ``times`` (n,), held before the first and after the last."""
    if time <= times[0]:
        return values[0].copy()
    if time >= times[-1]:
        return values[-1].copy()
    upper = int(np.searchsorted(times, time, side="right"))
    lower = upper - 1
    if hold:
        return values[lower].copy()
    weight = (time - times[lower]) / (times[upper] - times[lower])
    result: np.ndarray = (1.0 - weight) * values[lower] + weight * values[upper]
    return result


#: Quaternions whose dot product exceeds this are interpolated linearly (then normalised): slerp's
#: weights divide by the sine of an angle that is then below about 1e-3 rad.
_NEARLY_EQUAL = 1.0 - 1e-6


def _interpolate_quat(times: np.ndarray, quats: np.ndarray, time: float, *, hold: bool) -> np.ndarray:
    """Unit quaternions (n, 4) at ``time`` between rows (n_rows, n, 4) at ``times``, along the shortest arc.

    q and -q are the same orientation: the row after is negated where its dot product with the row
    before is negative, so the interpolation never passes through zero. Nearly equal quaternions
    are interpolated linearly (normalised by the caller); the others by spherical linear
    interpolation.
    """
    if hold or time <= times[0] or time >= times[-1]:
        return _interpolate(times, quats, time, hold=hold)
    upper = int(np.searchsorted(times, time, side="right"))
    lower = upper - 1
    weight = (time - times[lower]) / (times[upper] - times[lower])
    start, end = quats[lower], quats[upper].copy()
    dot = np.sum(start * end, axis=-1)
    flip = dot < 0
    end[flip] = -end[flip]
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    result: np.ndarray = (1.0 - weight) * start + weight * end
    arc = dot <= _NEARLY_EQUAL
    if np.any(arc):
        angle = np.arccos(dot[arc])[:, None]
        sine = np.sin(angle)
        result[arc] = (np.sin((1.0 - weight) * angle) * start[arc] + np.sin(weight * angle) * end[arc]) / sine
    return result


def _between(times: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which of ``at`` (k,) lie strictly inside ``times``, and for those the rows before and after and the weight."""
    inside = (at > times[0]) & (at < times[-1])
    between = at[inside]
    upper = np.searchsorted(times, between, side="right")
    lower = upper - 1
    weight = (between - times[lower]) / (times[upper] - times[lower])
    return inside, lower, upper, weight


def _held_ends(times: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Values (k, ...) at ``at`` (k,) as held past the ends: the first row up to ``times[0]``, else the last."""
    return np.where((at <= times[0]).reshape(-1, *[1] * (values.ndim - 1)), values[0], values[-1])


def _interpolate_rows(times: np.ndarray, values: np.ndarray, at: np.ndarray, *, hold: bool) -> np.ndarray:
    """:func:`_interpolate` at every time of ``at`` (k,): values (k, ...), the same arithmetic per row."""
    result = _held_ends(times, values, at)
    inside, lower, upper, weight = _between(times, at)
    if hold:
        result[inside] = values[lower]
        return result
    weight = weight.reshape(-1, *[1] * (values.ndim - 1))
    result[inside] = (1.0 - weight) * values[lower] + weight * values[upper]
    return result


def _interpolate_quat_rows(times: np.ndarray, quats: np.ndarray, at: np.ndarray, *, hold: bool) -> np.ndarray:
    """:func:`_interpolate_quat` at every time of ``at`` (k,): quaternions (k, n, 4), the same arithmetic per row."""
    if hold:
        return _interpolate_rows(times, quats, at, hold=hold)
    result = _held_ends(times, quats, at)
    inside, lower, upper, weight = _between(times, at)
    start, end = quats[lower], quats[upper].copy()
    dot = np.sum(start * end, axis=-1)
    flip = dot < 0
    end[flip] = -end[flip]
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    weights = np.broadcast_to(weight[:, None], dot.shape)
    blended = (1.0 - weight[:, None, None]) * start + weight[:, None, None] * end
    arc = dot <= _NEARLY_EQUAL
    if np.any(arc):
        angle = np.arccos(dot[arc])[:, None]
        sine = np.sin(angle)
        share = weights[arc][:, None]
        blended[arc] = (np.sin((1.0 - share) * angle) * start[arc] + np.sin(share * angle) * end[arc]) / sine
    result[inside] = blended
    return result


def _check_file(spec: SceneSpec, key: str, path: Path, what: str = "") -> None:
    """Refuse a ``path`` (named by ``key``) that is not a readable regular file."""
    try:
        if path.is_file():
            return
        problem = "is not a file" if path.exists() else "does not exist"
    except OSError as error:
        problem = f"cannot be read ({error.strerror})"
    raise spec.error(key, f"{what}{path} {problem}")


def _motion(spec: SceneSpec, model: mujoco.MjModel) -> Motion:
    motion = spec.motion
    nu = int(model.nu)
    columns = np.arange(nu)
    if motion.actuators is not None:
        columns = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) for name in motion.actuators])
        for name, index in zip(motion.actuators, columns, strict=True):
            if index < 0:
                raise spec.error("motion.actuators", f"no actuator {name!r} in {spec.mjcf.name}")
    width = int(columns.size)
    what = (
        f"{width} actuators in motion.actuators"
        if motion.actuators is not None
        else f"{nu} actuators in {spec.mjcf.name}"
    )
    if motion.ctrl_file is not None:
        times, ctrl = _read_ctrl_file(spec, width, what)
    else:
        rows = [k for k in motion.keyframes if k.ctrl is not None]
        times = np.array([k.time for k in rows])
        for keyframe in rows:
            if len(keyframe.ctrl or ()) != width:
                raise spec.error(f"{keyframe.key}.ctrl", f"has {len(keyframe.ctrl or ())} values for the {what}")
        ctrl = np.array([k.ctrl for k in rows], dtype=float) if rows else np.zeros((0, width))
    full = np.zeros((ctrl.shape[0], nu))
    full[:, columns] = ctrl
    ctrl = full
    mocap_rows = [k for k in motion.keyframes if k.mocap]
    nmocap = int(model.nmocap)
    # The model's own mocap poses, in mocap-index order (a mocap body is a child of the world).
    mocap_bodies = np.flatnonzero(model.body_mocapid >= 0)
    mocap_bodies = mocap_bodies[np.argsort(model.body_mocapid[mocap_bodies])]
    default_pos, default_quat = model.body_pos[mocap_bodies], model.body_quat[mocap_bodies]
    mocap_pos = np.tile(default_pos, (len(mocap_rows), 1, 1)).reshape(len(mocap_rows), nmocap, 3)
    mocap_quat = np.tile(default_quat, (len(mocap_rows), 1, 1)).reshape(len(mocap_rows), nmocap, 4)
    for row, keyframe in enumerate(mocap_rows):
        for body_name, (pos, quat) in keyframe.mocap.items():
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body_name)
            key = f"{keyframe.key}.mocap.{body_name}"
            if body < 0:
                raise spec.error(key, f"no body {body_name!r} in {spec.mjcf.name}")
            mocap_id = int(model.body_mocapid[body])
            if mocap_id < 0:
                raise spec.error(key, f'body {body_name!r} in {spec.mjcf.name} is not a mocap body (mocap="true")')
            mocap_pos[row, mocap_id] = pos
            if quat is not None:
                mocap_quat[row, mocap_id] = np.asarray(quat) / np.linalg.norm(quat)
    mocap_times = np.array([k.time for k in mocap_rows])
    return Motion(times, ctrl, mocap_times, mocap_pos, mocap_quat, motion.interpolation == "hold")


def _read_ctrl_file(spec: SceneSpec, nu: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    path = spec.motion.ctrl_file
    assert path is not None
    key = "motion.ctrl_file"
    _check_file(spec, key, path)
    try:
        archive = read_npz(path)
    except NpzError as error:
        raise spec.error(key, f"{path.name} is not a readable .npz file ({error})") from None
    missing = [name for name in ("time", "ctrl") if name not in archive]
    if missing:
        raise spec.error(key, f"{path.name} has no array {missing[0]!r} (it needs time (n,) and ctrl (n, nu))")
    for name in ("time", "ctrl"):
        if archive[name].dtype.kind not in "fiu":
            raise spec.error(key, f"{path.name}: {name} must hold numbers, got {archive[name].dtype}")
    times = archive["time"].astype(float)
    ctrl = archive["ctrl"].astype(float)
    if times.ndim != 1 or times.size == 0 or not np.all(np.isfinite(times)):
        raise spec.error(key, f"{path.name}: time must be a non-empty 1-d array of finite seconds")
    if np.any(np.diff(times) <= 0):
        row = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise spec.error(key, f"{path.name}: time is not increasing (row {row})")
    if ctrl.ndim != 2 or ctrl.shape[0] != times.size or ctrl.shape[1] != nu:
        raise spec.error(
            key,
            f"{path.name}: ctrl has shape {ctrl.shape}, expected ({times.size}, {nu}) for the {what}",
        )
    if not np.all(np.isfinite(ctrl)):
        raise spec.error(key, f"{path.name}: ctrl holds NaN or infinite values")
    return times, ctrl
