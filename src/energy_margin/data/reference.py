"""Import the authors' published frames, labels and scores (their CSV layout) as a dataset.

A reference folder (e.g. ``energy_margin_workshop/planepush-10objects``) holds, per task
(``PlanePushMulti`` = pushing, ``GripperMulti`` = scooping):

* ``scripted_movement_viapoints_<Task>.csv``: ``num_traj, data_id`` then the frame state;
* ``scripted_movement_capture_labels_<Task>.csv``: ``num_traj, data_id, capture_exists_label,
  capture_all_label, lateral_friction_coef``;
* ``scripted_movement_success_labels_<Task>.csv``: ``num_traj, success_all_label, success_exists_label``;
* ``ao_est.csv`` in the folder or in a sub-folder (``original``/``original-data`` = true states,
  ``1``..``5`` = perturbed states): ``data_id, trial, plan_iters, plan_time, best_cost,
  capture_exists_score, capture_score, success_exists_score, success_score, runtime``.

The mapping to this project's dataset (documented in docs/reference.md):

* pushing, per object ``x, y, theta, vx, vy, omega`` -> centre ``(x, y, rest height)``, yaw
  ``theta``, velocity ``(vx, vy, 0, 0, 0, omega)``; pusher ``xg, yg, thetag, vxg, vyg, omegag`` ->
  ``robot_q = (x, y, 0, yaw)``, ``robot_v = (vx, vy, 0, omega)``. Lengths are metres already.
* scooping (their simulation is 10x larger): per object 12 columns whose header reads
  ``x, z, y`` but whose values are ``x, y, z`` (the third is the height: 0.35 = resting on the
  table top at 0.3), Euler angles (PyBullet: R = Rz Ry Rx), linear and angular velocity. Lengths
  and linear velocities are divided by 10 and the table top moved to this task's ``table_top``.
  Gripper ``j0..j3, zt`` and velocities -> ``robot_q = (base z, right finger, right tip, left
  finger, left tip)``: base z is this gripper's blade-on-table height plus the authors' lift above
  their own pressed-on-table height (``zt`` = 1.776, the lowest in their data), fingers at this
  gripper's closed travel plus their (always 0) prismatic travel, tip angles unchanged. The
  blades and finger plates are widened to ``SCOOP_BLADE_HALF_WIDTH`` (their blades carry boxes
  further off the centre line than this task's default blades reach). During analysis the
  gripper's servos replay its recorded motion (``recorded_waypoints`` = the frames), since their
  timing is not this task's script.
* labels: ``captured`` <- ``capture_all_label`` (their k-hat = 0 label of the frame);
  ``in_success`` at the last frame <- ``success_all_label`` (their trajectory label, "ever reached"),
  earlier frames <- their success test applied to the frame.
* friction: their per-body ``lateral_friction_coef`` mu_b; Bullet multiplies two bodies'
  coefficients, so the stored (effective) coefficient is mu_b^2 (0.4 -> 0.16 for pushing).
* their scores -> ``scores.csv`` (``nodes`` 301, ``iterations`` = ``plan_iters``, ``runtime_s`` =
  ``runtime``, ``physics_s`` 0.0 (not recorded), ``seed`` 0 (their runs were unseeded)).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.data.dataset import FORMAT, SCHEMA_VERSION, Dataset, validate
from energy_margin.data.dataset import check_target as _check_target
from energy_margin.data.dataset import write_directory as _write_directory
from energy_margin.data.scores_file import COLUMNS, CONFIG_FILE, SCORES_FILE, UNKNOWN_COUNT
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice
from energy_margin.runs.files import atomic_write_text, write_json
from energy_margin.runs.versions import VERSIONS_KEY, engine_versions
from energy_margin.tasks import PushingTask, ReferenceLayout, ScoopingTask, available_tasks, get_task, task_class

#: Sub-folders holding the true-state scores, in order of preference.
DEFAULT_SCORES = ("original", "original-data", ".")
SCORES_NAME = "ao_est.csv"
#: How the end-effector is driven when imported frames are analysed.
DRIVES = ("nominal", "coast")
AO_EST_COLUMNS = (
    "data_id",
    "trial",
    "plan_iters",
    "plan_time",
    "best_cost",
    "capture_exists_score",
    "capture_score",
    "success_exists_score",
    "success_score",
    "runtime",
)

# Pushing (their geometry equals this task's defaults).
PUSH_FRAME_PERIOD = 0.2  # s, frames recorded every 48 steps at 240 Hz from t = 0
PUSH_SUCCESS_HALF_WIDTH = 0.13  # their label: |y - 1.6| < 0.13 for every object
PUSH_WALL_Y = 1.6
# Scooping (their simulation units are 10x the real ones).
SCOOP_SCALE = 10.0
SCOOP_TABLE_TOP = 0.3  # sim units
SCOOP_PRESSED_ZT = 1.776  # their lowest recorded base height (blades pressed on the table), sim units
SCOOP_SUCCESS_Z = 0.7  # sim units, every box centre above it
SCOOP_CAPTURE_Z = 0.375  # sim units
SCOOP_CAPTURE_VZ = -0.1  # sim units per second
SCOOP_FIRST_FRAME = 0.6  # s, frames every 0.15 s after the press phase
SCOOP_FRAME_PERIOD = 0.15
# Their blades are wider than this task's default (2 cm half width): boxes their frames count as
# captured sit up to 2.62 cm off the gripper's centre line, so their blades reach at least that far.
# The imported scene's blades and finger plates get this half width (m), which carries every such
# box with its centre over a blade and makes this scene's capture region reproduce their capture
# label on all 200 frames (docs/reference.md).
SCOOP_BLADE_HALF_WIDTH = 0.03


@dataclass(frozen=True)
class ReferenceSet:
    """Parsed reference files of one task folder."""

    task: str
    suffix: str
    states: np.ndarray  # (T, K, columns) frame state columns after num_traj, data_id
    capture_label: np.ndarray  # (T, K) bool
    friction_per_body: np.ndarray  # (T,)
    success_label: np.ndarray  # (T,) bool
    scores: np.ndarray | None  # (T * K, 10) ao_est rows in data_id order, or None


def _fail(path: Path, message: str) -> EnergyMarginError:
    return EnergyMarginError(f"{path}: {message}")


def _read_csv(path: Path, expected_header: tuple[str, ...] | None = None) -> tuple[list[str], np.ndarray]:
    """Header and float rows of a CSV file; every problem raises :class:`EnergyMarginError`."""
    if not path.is_file():
        raise _fail(path, "does not exist")
    try:
        with path.open(encoding="utf-8", newline="") as stream:
            rows = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise _fail(path, f"cannot be read as CSV ({error})") from None
    rows = [row for row in rows if row]
    if len(rows) < 2:
        raise _fail(path, "has no data rows")
    header = [name.strip() for name in rows[0]]
    if expected_header is not None and tuple(header) != expected_header:
        raise _fail(path, f"unexpected header (expected {','.join(expected_header)})")
    values = np.empty((len(rows) - 1, len(header)))
    for number, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise _fail(path, f"line {number} has {len(row)} fields, expected {len(header)}")
        for column, text in enumerate(row):
            try:
                value = float(text)
            except ValueError:
                raise _fail(path, f"line {number}, column {header[column]}: {text[:40]!r} is not a number") from None
            if not math.isfinite(value) and header[column] != "best_cost":
                raise _fail(path, f"line {number}, column {header[column]}: NaN or infinite value")
            values[number - 2, column] = value
    return header, values


def reference_tasks() -> dict[str, str]:
    """Their task names (file suffixes) -> the registered task that declares that layout.

    A task that inherits its layout (a variant of a task) imports their files when asked for by
    name (``import_reference(..., task=NAME)``); the one that declares it is the default.
    """
    found: dict[str, str] = {}
    for name in available_tasks():
        layout = vars(task_class(name)).get("reference_layout")
        if isinstance(layout, ReferenceLayout) and layout.suffix in _CONVERTERS:
            found.setdefault(layout.suffix, name)
    return found


def _layout(task: str) -> ReferenceLayout:
    """The reference layout of the registered task ``task``."""
    layout = task_class(task).reference_layout
    if layout is None or layout.suffix not in _CONVERTERS:
        raise EnergyMarginError(f"task {task!r} has no import of the authors' files")
    return layout


def detect_task(folder: Path, task: str | None = None) -> tuple[str, str]:
    """(their suffix, this project's task) of a reference folder, from its file names.

    Args:
        folder: the reference folder.
        task: the task to import their files as (it must read their layout); ``None``: the task
            that declares the layout of the files found.

    """
    if not folder.is_dir():
        raise EnergyMarginError(f"{folder} does not exist or is not a directory")
    tasks = reference_tasks()
    suffixes = [_layout(task).suffix] if task is not None else list(tasks)
    found = [suffix for suffix in suffixes if (folder / f"scripted_movement_viapoints_{suffix}.csv").is_file()]
    if len(found) != 1:
        raise EnergyMarginError(
            f"{folder} is not a reference folder: expected one scripted_movement_viapoints_<Task>.csv "
            f"with Task in {', '.join(suffixes)}"
        )
    return found[0], task if task is not None else tasks[found[0]]


def _scores_path(folder: Path, scores: str | None) -> Path | None:
    if scores is not None:
        path = folder / scores / SCORES_NAME if scores != "." else folder / SCORES_NAME
        if not path.is_file():
            raise EnergyMarginError(f"{folder}: no {SCORES_NAME} in {scores!r}")
        return path
    for name in DEFAULT_SCORES:
        path = folder / name / SCORES_NAME if name != "." else folder / SCORES_NAME
        if path.is_file():
            return path
    return None


def _grid(path: Path, values: np.ndarray, trajectories: np.ndarray, frames: np.ndarray) -> tuple[int, int]:
    """Check that rows are trajectory-major with equal frame counts; return (T, K)."""
    if np.any(trajectories != np.round(trajectories)) or np.any(frames != np.round(frames)):
        raise _fail(path, "num_traj and data_id must be integers")
    n_traj = int(trajectories.max()) + 1
    if values.shape[0] % n_traj:
        raise _fail(path, f"{values.shape[0]} rows do not split into {n_traj} trajectories of equal length")
    n_frames = values.shape[0] // n_traj
    expected_traj = np.repeat(np.arange(n_traj), n_frames)
    if not np.array_equal(trajectories, expected_traj):
        raise _fail(path, "rows must be ordered by num_traj with the same number of frames each")
    local = frames - frames.reshape(n_traj, n_frames)[:, :1].repeat(n_frames, axis=1).ravel()
    if not np.array_equal(local, np.tile(np.arange(n_frames), n_traj)):
        raise _fail(path, "data_id must count the frames of each trajectory in order")
    return n_traj, n_frames


def read_reference(
    folder: Path | str, *, scores: str | None = None, with_scores: bool = True, task: str | None = None
) -> ReferenceSet:
    """Parse a reference folder as ``task`` (default: the task its files name).

    Every problem raises :class:`EnergyMarginError`.
    """
    folder = Path(folder)
    suffix, task = detect_task(folder, task)
    via_path = folder / f"scripted_movement_viapoints_{suffix}.csv"
    header, via = _read_csv(via_path)
    if header[:2] != ["num_traj", "data_id"]:
        raise _fail(via_path, "the first two columns must be num_traj, data_id")
    width = len(header) - 2
    layout = _layout(task)
    per_object, robot = layout.object_columns, layout.robot_columns
    if width <= robot or (width - robot) % per_object:
        raise _fail(via_path, f"{width} state columns do not fit n objects x {per_object} + {robot} robot columns")
    n_traj, n_frames = _grid(via_path, via, via[:, 0], via[:, 1])
    cap_path = folder / f"scripted_movement_capture_labels_{suffix}.csv"
    _, cap = _read_csv(
        cap_path, ("num_traj", "data_id", "capture_exists_label", "capture_all_label", "lateral_friction_coef")
    )
    if cap.shape[0] != via.shape[0] or not np.array_equal(cap[:, :2], via[:, :2]):
        raise _fail(cap_path, f"rows do not match {via_path.name} (num_traj, data_id)")
    suc_path = folder / f"scripted_movement_success_labels_{suffix}.csv"
    _, suc = _read_csv(suc_path, ("num_traj", "success_all_label", "success_exists_label"))
    if not np.array_equal(suc[:, 0], np.arange(n_traj)):
        raise _fail(suc_path, f"expected one row per trajectory 0..{n_traj - 1}")
    for path, column in ((cap_path, cap[:, 3]), (suc_path, suc[:, 1])):
        if not np.all(np.isin(column, (0.0, 1.0))):
            raise _fail(path, "labels must be 0 or 1")
    friction = cap[:, 4].reshape(n_traj, n_frames)
    if np.any(friction < 0) or np.any(friction != friction[:, :1]):
        raise _fail(cap_path, "lateral_friction_coef must be >= 0 and constant within a trajectory")
    score_rows = None
    score_path = _scores_path(folder, scores) if with_scores else None
    if score_path is not None:
        _, score_rows = _read_csv(score_path, AO_EST_COLUMNS)
        if score_rows.shape[0] != via.shape[0] or not np.array_equal(score_rows[:, 0], np.arange(via.shape[0])):
            raise _fail(score_path, f"expected one row per frame, data_id 0..{via.shape[0] - 1} in order")
        for name in ("capture_score", "success_score"):
            column = score_rows[:, AO_EST_COLUMNS.index(name)]
            if np.any((column < 0) | (column > 1 + 1e-9)):
                raise _fail(score_path, f"{name} outside [0, 1]")
    return ReferenceSet(
        task=task,
        suffix=suffix,
        states=via[:, 2:].reshape(n_traj, n_frames, width),
        capture_label=cap[:, 3].reshape(n_traj, n_frames).astype(bool),
        friction_per_body=friction[:, 0].copy(),
        success_label=suc[:, 1].astype(bool),
        scores=score_rows,
    )


def _yaw_quat(yaw: np.ndarray) -> np.ndarray:
    half = 0.5 * yaw
    zeros = np.zeros_like(half)
    return np.stack([np.cos(half), zeros, zeros, np.sin(half)], axis=-1)


def _euler_xyz_quat(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Quaternion (w, x, y, z) of R = Rz(yaw) Ry(pitch) Rx(roll) (PyBullet's Euler convention)."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def _pushing_arrays(ref: ReferenceSet, n_objects: int) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    task = get_task(ref.task)
    if not isinstance(task, PushingTask):
        raise EnergyMarginError(f"{task.label} cannot hold their {ref.suffix} frames: it is no PushingTask subclass")
    cfg = task.config
    states = ref.states
    n_traj, n_frames = states.shape[:2]
    objects = states[..., : 6 * n_objects].reshape(n_traj, n_frames, n_objects, 6)
    pusher = states[..., 6 * n_objects :]
    rest_z = cfg.ground_z + cfg.object_half_height
    object_pos = np.concatenate([objects[..., :2], np.full((n_traj, n_frames, n_objects, 1), rest_z)], axis=-1)
    object_vel = np.zeros((n_traj, n_frames, n_objects, 6))
    object_vel[..., :2] = objects[..., 3:5]
    object_vel[..., 5] = objects[..., 5]
    robot_q = np.stack([pusher[..., 0], pusher[..., 1], np.zeros((n_traj, n_frames)), pusher[..., 2]], axis=-1)
    robot_v = np.stack([pusher[..., 3], pusher[..., 4], np.zeros((n_traj, n_frames)), pusher[..., 5]], axis=-1)
    friction = ref.friction_per_body**2
    total_mass = cfg.pusher_mass + n_objects * cfg.object_mass
    forward = float(np.mean(cfg.drive_factor)) * friction * 9.81 * total_mass
    drive = np.column_stack([np.zeros(n_traj), forward])
    in_success = np.all(np.abs(objects[..., 1] - PUSH_WALL_Y) < PUSH_SUCCESS_HALF_WIDTH, axis=-1)
    arrays = {
        "object_pos": object_pos,
        "object_quat": _yaw_quat(objects[..., 2]),
        "object_vel": object_vel,
        "robot_q": robot_q,
        "robot_v": robot_v,
        "frame_time": np.tile(PUSH_FRAME_PERIOD * np.arange(n_frames), (n_traj, 1)),
        "friction": friction,
        "drive": drive,
        "in_success": in_success,
    }
    return arrays, {"friction_range": [float(friction.min()), float(friction.max())]}


def _scooping_arrays(ref: ReferenceSet, n_objects: int) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    task = get_task(ref.task)
    if not isinstance(task, ScoopingTask):
        raise EnergyMarginError(f"{task.label} cannot hold their {ref.suffix} frames: it is no ScoopingTask subclass")
    cfg = task.config
    states = ref.states
    n_traj, n_frames = states.shape[:2]
    boxes = states[..., : 12 * n_objects].reshape(n_traj, n_frames, n_objects, 12)
    gripper = states[..., 12 * n_objects :]
    scale = SCOOP_SCALE
    # Header x, z, y; values x, y, z (the third column is the height).
    object_pos = boxes[..., 0:3] / scale
    object_pos[..., 2] += cfg.table_top - SCOOP_TABLE_TOP / scale
    object_vel = np.concatenate([boxes[..., 6:9] / scale, boxes[..., 9:12]], axis=-1)
    quat = _euler_xyz_quat(boxes[..., 3], boxes[..., 4], boxes[..., 5])
    joints, base, joint_rates, base_rate = gripper[..., 0:4], gripper[..., 4], gripper[..., 5:9], gripper[..., 9]
    closed = task.closed_travel
    robot_q = np.stack(
        [
            task.contact_height + (base - SCOOP_PRESSED_ZT) / scale,
            closed + joints[..., 0] / scale,
            joints[..., 1],
            closed + joints[..., 2] / scale,
            joints[..., 3],
        ],
        axis=-1,
    )
    robot_v = np.stack(
        [
            base_rate / scale,
            joint_rates[..., 0] / scale,
            joint_rates[..., 1],
            joint_rates[..., 2] / scale,
            joint_rates[..., 3],
        ],
        axis=-1,
    )
    friction = ref.friction_per_body**2
    frame_times = np.tile(SCOOP_FIRST_FRAME + SCOOP_FRAME_PERIOD * np.arange(n_frames), (n_traj, 1))
    in_success = np.all(boxes[..., 2] > SCOOP_SUCCESS_Z, axis=-1)
    rest = SCOOP_TABLE_TOP + cfg.box_half_edge * scale
    arrays = {
        "object_pos": object_pos,
        "object_quat": quat,
        "object_vel": object_vel,
        "robot_q": robot_q,
        "robot_v": robot_v,
        "frame_time": frame_times,
        "friction": friction,
        # The gripper replays its recorded motion during analysis: their frames' timing is not
        # this task's script (which would reopen the fingers at their first frames and hold the
        # base on the table while theirs is already lifting).
        "drive": np.concatenate(
            [
                np.full((n_traj, 1), task.finger_stiffness(None)),
                frame_times,
                robot_q.reshape(n_traj, n_frames * robot_q.shape[-1]),
            ],
            axis=-1,
        ),
        "in_success": in_success,
    }
    overrides = {
        "friction_range": [float(friction.min()), float(friction.max())],
        "success_height": (SCOOP_SUCCESS_Z - rest) / scale,
        "capture_margin": (SCOOP_CAPTURE_Z - rest) / scale,
        "fall_speed": -SCOOP_CAPTURE_VZ / scale,
        "tip_half_width": SCOOP_BLADE_HALF_WIDTH,
        "finger_half_extents": [
            cfg.finger_half_extents[0],
            SCOOP_BLADE_HALF_WIDTH,
            cfg.finger_half_extents[2],
        ],
        "recorded_waypoints": n_frames,
    }
    return arrays, overrides


#: The mapping of their columns onto this project's frames, by their task name (file suffix).
_CONVERTERS: dict[str, Callable[[ReferenceSet, int], tuple[dict[str, np.ndarray], dict[str, Any]]]] = {
    "PlanePushMulti": _pushing_arrays,
    "GripperMulti": _scooping_arrays,
}


def import_reference(
    folder: Path | str,
    out: Path | str,
    *,
    scores: str | None = None,
    with_scores: bool = True,
    overwrite: bool = False,
    drive: str = "nominal",
    task: str | None = None,
) -> Dataset:
    """Convert a reference folder into a dataset directory (plus ``scores.csv`` from their scores).

    Args:
        folder: a task folder such as ``energy_margin_workshop/planepush-10objects``.
        out: the dataset directory to create.
        scores: sub-folder of the ``ao_est.csv`` to import (``"."`` for the folder itself);
            default: ``original``, ``original-data`` or the folder itself, whichever exists.
        with_scores: import their scores as ``scores.csv`` (when a file is found).
        overwrite: replace an existing ``out``.
        drive: ``"nominal"``: this project's nominal drive for the trajectory's friction (the
            end-effector keeps following the manipulation during analysis); ``"coast"`` (pushing
            only): no drive force, the pusher coasts from its recorded velocity, as in the
            authors' planner. Scooping always replays the gripper's recorded motion
            (``imported_drive`` = ``"recorded"``).
        task: the task to import their files as (one that reads their layout, such as a variant
            of the task they name); ``None``: the task their file names map to.

    Returns:
        The written dataset.
    """
    folder, out = Path(folder), Path(out)
    check_choice("drive", drive, DRIVES)
    ref = read_reference(folder, scores=scores, with_scores=with_scores, task=task)
    layout = _layout(ref.task)
    if drive not in layout.drives:
        following = " (its end-effector replays its recorded motion)" if layout.replays_recorded else ""
        raise InvalidParameterError(
            "drive", f"{drive} does not apply to {ref.task}{following}; its drives: {', '.join(layout.drives)}"
        )
    n_objects = (ref.states.shape[-1] - layout.robot_columns) // layout.object_columns
    arrays, overrides = _CONVERTERS[layout.suffix](ref, n_objects)
    if drive == "coast":
        arrays["drive"] = np.zeros_like(arrays["drive"])
    arrays["in_success"][:, -1] = ref.success_label
    arrays["captured"] = ref.capture_label.copy()
    arrays["in_success"] = arrays["in_success"].astype(bool)
    imported = get_task(ref.task, overrides)
    n_traj, n_frames = ref.states.shape[:2]
    metadata = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "task": ref.task,
        "task_config": imported.config.to_dict(),
        "engine": "pybullet",
        "seed": 0,
        "n_trajectories": n_traj,
        "n_frames": n_frames,
        "n_objects": n_objects,
        "n_robot_dofs": int(arrays["robot_q"].shape[-1]),
        "n_drive": int(arrays["drive"].shape[-1]),
        "package_version": __version__,
        # The software that imported the set (the frames are the authors' own).
        VERSIONS_KEY: engine_versions("pybullet"),
        "imported_from": str(folder),
        "imported_drive": "recorded" if layout.replays_recorded else drive,
    }
    arrays = {key: np.ascontiguousarray(value) for key, value in arrays.items()}
    dataset = Dataset(path=out, metadata=metadata, arrays=arrays)
    validate(dataset)
    _check_target(out, overwrite=overwrite)
    _write_directory(out, metadata, arrays, overwrite=overwrite)
    if ref.scores is not None:
        _write_scores(out, ref, n_frames)
    return Dataset(path=out, metadata=metadata, arrays=arrays)


def _write_scores(out: Path, ref: ReferenceSet, n_frames: int) -> None:
    assert ref.scores is not None
    index = {name: i for i, name in enumerate(AO_EST_COLUMNS)}
    lines = [",".join(COLUMNS)]
    for row_number, row in enumerate(ref.scores):
        trajectory, frame = divmod(row_number, n_frames)
        values = {
            "trajectory": trajectory,
            "frame": frame,
            "capture_score": min(1.0, float(row[index["capture_score"]])),
            "success_score": min(1.0, float(row[index["success_score"]])),
            "nodes": int(row[index["plan_iters"]]) + 1,
            "iterations": int(row[index["plan_iters"]]),
            "runtime_s": float(row[index["runtime"]]),
            "physics_s": 0.0,
            "seed": 0,
            "rejected": UNKNOWN_COUNT,
            "diverged": UNKNOWN_COUNT,
        }
        lines.append(",".join(repr(v) if isinstance(v, float) else str(v) for v in (values[c] for c in COLUMNS)))
    atomic_write_text(out / SCORES_FILE, "\n".join(lines) + "\n")
    # Marks the scores as not this analyzer's: `analyze` refuses to mix them without --overwrite.
    write_json(out / CONFIG_FILE, {"analyzer": "reference scores (ao_est.csv)", "source": str(ref.task)})
